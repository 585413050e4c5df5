//! Typed errors of the photogrammetric core. Every variant names the item at fault.

use thiserror::Error;

use crate::contract::truncate_for_message as cut;

/// The upload form is not a valid epoch.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EpochError {
    /// No images.
    #[error("the epoch has no images")]
    Empty,
    /// More images or cameras than one epoch may hold (the adjustment's dense camera block
    /// grows with the square of their number).
    #[error("{what}: {count} given, at most {limit}")]
    TooMany {
        /// `images` or `cameras`.
        what: &'static str,
        /// How many were given.
        count: usize,
        /// The limit.
        limit: usize,
    },
    /// `observed_at` is not RFC 3339.
    #[error("observed_at '{}' is not an RFC 3339 time", cut(.0))]
    BadTimestamp(String),
    /// `observed_at` falls outside the years 0000–9999 once converted to UTC: RFC 3339 cannot
    /// write it with a four-digit year, so it could not be stored or sorted.
    #[error("observed_at '{}' falls outside the years 0000–9999 in UTC", cut(.0))]
    TimestampOutOfRange(String),
    /// `observed_at` lies further after the server's clock than an epoch may
    /// (the daemon's `MAX_DAYS_AHEAD`): a mistyped year or a camera clock set wrong.
    #[error(
        "observed_at '{}' lies more than {days} days after the server's clock ({now})",
        cut(.observed_at)
    )]
    TimestampAhead {
        /// The time given.
        observed_at: String,
        /// The server's clock, RFC 3339.
        now: String,
        /// The tolerance in days.
        days: i64,
    },
    /// A label holding a control character (U+0000–U+001F, U+007F–U+009F).
    #[error("label: control characters (U+0000–U+001F, U+007F–U+009F) are not allowed")]
    BadLabel,
    /// A label longer than [`crate::photogrammetry::input::epoch::MAX_LABEL_CHARS`].
    #[error("label: {chars} characters; at most {max}")]
    LabelTooLong {
        /// Its length in characters.
        chars: usize,
        /// The limit.
        max: usize,
    },
    /// An identifier outside `[A-Za-z0-9._-]{{1,64}}`.
    #[error("{0}: identifiers must match [A-Za-z0-9._-]{{1,64}} and not be . or ..")]
    BadIdentifier(String),
    /// Two cameras with one id.
    #[error("camera '{}' is defined twice", cut(.0))]
    DuplicateCamera(String),
    /// Two images with one id.
    #[error("image '{}' is defined twice", cut(.0))]
    DuplicateImage(String),
    /// A point listed twice in `control` or twice in `approx`.
    #[error("point '{}' is listed twice", cut(.0))]
    DuplicatePoint(String),
    /// An image refers to a camera that is not defined.
    #[error("image '{image}' refers to unknown camera '{}'", cut(.camera))]
    UnknownCamera {
        /// Image id.
        image: String,
        /// The unknown camera id.
        camera: String,
    },
    /// One point observed twice in one image.
    #[error("image '{image}' observes point '{point}' twice")]
    DuplicateObservation {
        /// Image id.
        image: String,
        /// Point name.
        point: String,
    },
    /// NaN or infinite number.
    #[error("{item}: {field} is not a finite number")]
    NotFinite {
        /// The item (camera, image and point, control point).
        item: String,
        /// The field name.
        field: String,
    },
    /// A value out of its range.
    #[error("{item}: {field} {reason}")]
    OutOfRange {
        /// The item at fault.
        item: String,
        /// The field name.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// An observation without a complete (x_mm, y_mm) or (col, row) pair.
    #[error("{item}: give either x_mm and y_mm or col and row")]
    MissingCoordinate {
        /// Image and point.
        item: String,
    },
    /// A value of the right type and range whose order of magnitude does not fit the rest of the
    /// epoch: a unit mistaken (`photogrammetry::input::plausible`).
    #[error("{field}: {found}; expected {expected}")]
    Implausible {
        /// The field at fault, e.g. `cameras[0].c_mm (camera 'cam')` or `approx`.
        field: String,
        /// What looks wrong, with the figures that show it.
        found: String,
        /// What was expected.
        expected: String,
    },
    /// Pixel observations for a camera without pixel size or image size.
    #[error("image '{image}' has pixel observations but camera '{camera}' lacks pixel_size_mm, width_px or height_px")]
    PixelWithoutGeometry {
        /// Image id.
        image: String,
        /// Camera id.
        camera: String,
    },
}

/// The epoch is valid but cannot be adjusted.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AdjustError {
    /// The upload form is invalid.
    #[error(transparent)]
    Invalid(#[from] EpochError),
    /// An image sees fewer than four points of known (control, approximate or prior) coordinates.
    #[error("image '{image}' sees {known} points of known coordinates; at least 4 are needed")]
    TooFewKnownPoints {
        /// Image id.
        image: String,
        /// How many known points it sees.
        known: usize,
    },
    /// A point observed in fewer than two images.
    #[error("point '{point}' is observed in {images} image(s); at least 2 are needed")]
    PointInTooFewImages {
        /// Point name.
        point: String,
        /// Number of images that observe it.
        images: usize,
    },
    /// A point observed in several images, all taken from one station: its rays coincide.
    #[error(
        "point '{point}' is observed only from station '{station}' ({images} images); its depth \
         needs images from at least 2 stations"
    )]
    PointFromOneStation {
        /// Point name.
        point: String,
        /// The one station.
        station: String,
        /// Number of images that observe it.
        images: usize,
    },
    /// An image whose known points are degenerate (collinear) so no start can be found.
    #[error("image '{image}': no start values: {reason}")]
    NoStart {
        /// Image id.
        image: String,
        /// What went wrong.
        reason: String,
    },
    /// Not enough observations for the unknowns.
    #[error("the epoch has {observations} observation equations for {unknowns} unknowns")]
    TooFewObservations {
        /// Number of observation equations.
        observations: usize,
        /// Number of unknowns (after the datum).
        unknowns: usize,
    },
    /// The iteration did not converge.
    #[error("the adjustment did not converge in {iterations} iterations (last σ0 {sigma0_mm} mm)")]
    NoConvergence {
        /// Iterations done.
        iterations: usize,
        /// σ0 of the last iterate in mm.
        sigma0_mm: f64,
    },
    /// The iteration ended in a solution that fails the global test with more than a tenth of the
    /// observations beyond the critical |w| (dropped by data snooping, or kept without it): a wrong
    /// basin, not an answer.
    #[error("no consistent solution: σ0 {sigma0_mm} mm fails the global test with {outliers} observations beyond the critical |w| (dropped by data snooping, or kept without it)")]
    Inconsistent {
        /// σ0 of the best solution found, mm.
        sigma0_mm: f64,
        /// Observations whose |w| exceeds the critical value.
        outliers: usize,
    },
    /// The normal equations are singular.
    #[error("the normal equations are singular: {0}")]
    Singular(String),
    /// The caller cancelled the adjustment ([`crate::photogrammetry::Cancel`]) before it ended:
    /// its deadline passed (`deadline`) or it was no longer wanted.
    #[error("{}", if *.deadline { "the adjustment ran out of its compute budget" } else { "the adjustment was cancelled" })]
    Cancelled {
        /// Whether the deadline, not a cancellation, stopped it.
        deadline: bool,
    },
}

//! Detected targets and the options of detection.

use crate::photogrammetry::Camera;

/// Default [`DetectOptions::sigma_floor_px`], px: calibrated on dbat-camcal, where the
/// self-calibrating adjustment's residuals are 0.133 px (col) and 0.115 px (row) rms while the
/// centring's own σ is a few hundredths of a pixel, and PhotoModeler's residuals of the same marks
/// correlate 0.9 with cliffwatch's (`tests/detect/real_adjust.rs`).
pub const SIGMA_FLOOR_PX: f64 = 0.13;

/// Which targets to look for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Polarity {
    /// Bright targets on a darker background (retro-reflective with flash).
    #[default]
    BrightOnDark,
    /// Dark targets on a brighter background.
    DarkOnBright,
}

impl Polarity {
    /// `"bright"` or `"dark"`.
    pub fn name(self) -> &'static str {
        match self {
            Polarity::BrightOnDark => "bright",
            Polarity::DarkOnBright => "dark",
        }
    }

    /// The factor that turns grey levels into a signal in which the targets are bright: +1 or −1.
    pub fn sign(self) -> f64 {
        match self {
            Polarity::BrightOnDark => 1.0,
            Polarity::DarkOnBright => -1.0,
        }
    }
}

/// How a centre was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CentreMethod {
    /// Background-subtracted (local plane), Gaussian-windowed intensity centroid, iterated on the
    /// re-centred window.
    WindowedCentroid,
    /// Least-squares fit of a blurred-ellipse model (centre, conic, edge blur, amplitude, background
    /// plane) to the grey values; used for targets of at least
    /// [`DetectOptions::edge_fit_min_diameter_px`], whose centre information lies in the edge.
    EllipseFit,
    /// Least-squares dual-conic fit to the grey-level gradients of the edge (`detect::dual_conic`);
    /// used for targets of at least [`DetectOptions::dual_conic_min_diameter_px`], where the edge
    /// holds hundreds of pixels and the shape of a real (compressed, unevenly lit) edge, not the
    /// noise, limits a model fit.
    DualConic,
}

impl CentreMethod {
    /// Short name: `"windowed_centroid"`, `"ellipse_fit"` or `"dual_conic"`.
    pub fn name(self) -> &'static str {
        match self {
            CentreMethod::WindowedCentroid => "windowed_centroid",
            CentreMethod::EllipseFit => "ellipse_fit",
            CentreMethod::DualConic => "dual_conic",
        }
    }
}

/// Options of [`super::detect`].
#[derive(Debug, Clone, PartialEq)]
pub struct DetectOptions {
    /// Target polarity; `None` (the default): both are searched and the one that yields more
    /// targets is kept ([`super::Detections::polarity`] says which).
    pub polarity: Option<Polarity>,
    /// Smallest target diameter in px.
    pub min_diameter_px: f64,
    /// Largest target diameter in px.
    pub max_diameter_px: f64,
    /// Least distance of the threshold from the local background, in noise σ.
    pub threshold_sigma: f64,
    /// Where the threshold lies between the local background (0) and the local extreme (1): the
    /// most extreme grey level within about 1.5 background cells (`threshold::Background::levels`).
    pub threshold_fraction: f64,
    /// Least peak contrast of a target, in noise σ.
    pub min_snr: f64,
    /// Largest axis ratio of a target's region.
    pub max_aspect: f64,
    /// Accepted range of area over moment-ellipse area (for regions of ≥ 12 px).
    pub fill_range: (f64, f64),
    /// Cell size of the background grid in px (≥ 2 × the largest target is safe).
    pub background_cell_px: usize,
    /// Targets whose thresholded region is at least this wide (equivalent diameter, px) are centred
    /// by [`CentreMethod::EllipseFit`], smaller ones by [`CentreMethod::WindowedCentroid`]
    /// (`f64::INFINITY`: never).
    pub edge_fit_min_diameter_px: f64,
    /// Targets whose thresholded region is at least this wide (equivalent diameter, px) are centred
    /// by [`CentreMethod::DualConic`] (`f64::INFINITY`: never).
    pub dual_conic_min_diameter_px: f64,
    /// The part of each centre coordinate's σ that no single image shows, px, added in quadrature
    /// to the centring's own σ in [`Target::sigma_col_px`] and [`Target::sigma_row_px`]: on real
    /// photographs the lens beyond its model, the sensor and the compression move every target's
    /// image by about a tenth of a pixel, whichever detector measures it (default
    /// [`SIGMA_FLOOR_PX`], from dbat-camcal; 0: the centring's σ alone, as on rendered
    /// images).
    pub sigma_floor_px: f64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        Self {
            polarity: None,
            min_diameter_px: 2.5,
            max_diameter_px: 64.0,
            threshold_sigma: 5.0,
            threshold_fraction: 0.4,
            min_snr: 30.0,
            max_aspect: 2.0,
            fill_range: (0.7, 1.35),
            background_cell_px: 128,
            edge_fit_min_diameter_px: 5.0,
            dual_conic_min_diameter_px: 16.0,
            sigma_floor_px: SIGMA_FLOOR_PX,
        }
    }
}

/// One detected target.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// Centre column in px (the centre of the top-left pixel is (0, 0)).
    pub col: f64,
    /// Centre row in px (grows downward).
    pub row: f64,
    /// Equivalent diameter in px (from the background-subtracted intensity: 4·√(mean second moment),
    /// blur included).
    pub diameter_px: f64,
    /// Peak signal above the local background in grey levels (dark targets: below it, as a
    /// positive figure).
    pub contrast: f64,
    /// Peak contrast over the image noise σ.
    pub snr: f64,
    /// Quality: the expected standard deviation of each centre coordinate in px (the mean of
    /// `sigma_col_px` and `sigma_row_px`; smaller is better).
    pub sigma_px: f64,
    /// Expected standard deviation of the centre column in px: the centring's propagated σ
    /// (calibrated against truth on rendered images) and [`DetectOptions::sigma_floor_px`], in
    /// quadrature.
    pub sigma_col_px: f64,
    /// Expected standard deviation of the centre row in px.
    pub sigma_row_px: f64,
    /// Axis ratio of the thresholded region (≥ 1).
    pub aspect: f64,
    /// Method of the centre.
    pub method: CentreMethod,
}

impl Target {
    /// Centre in image mm (x right, y up, from the image centre) per the contract and
    /// [`Camera::pixel_to_mm`]; None without the camera's pixel size and image size.
    pub fn image_mm(&self, camera: &Camera) -> Option<[f64; 2]> {
        camera.pixel_to_mm(self.col, self.row)
    }
}

/// Why a detection result is implausible: the caller should look at the image (or the options)
/// before trusting it.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectWarning {
    /// No target was found.
    NoTargets,
    /// Far more candidate regions than a target field holds (texture, print, noise).
    ManyCandidates {
        /// Candidate regions that passed the shape tests.
        candidates: usize,
    },
    /// Both polarities gave comparable numbers of targets: the kept one may be the wrong one.
    BothPolarities {
        /// The polarity kept.
        kept: Polarity,
        /// Targets of the kept polarity.
        kept_targets: usize,
        /// Targets of the other polarity.
        other_targets: usize,
    },
    /// One polarity's search was refused (too many runs or blobs); the other was kept.
    PolarityRefused {
        /// The refused polarity.
        polarity: Polarity,
        /// Why.
        reason: String,
    },
}

impl std::fmt::Display for DetectWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DetectWarning::NoTargets => write!(f, "no targets found"),
            DetectWarning::ManyCandidates { candidates } => write!(
                f,
                "{candidates} candidate regions: texture or print rather than targets?"
            ),
            DetectWarning::BothPolarities {
                kept,
                kept_targets,
                other_targets,
            } => write!(
                f,
                "both polarities give targets: {kept_targets} {} kept, {other_targets} of the other",
                kept.name()
            ),
            DetectWarning::PolarityRefused { polarity, reason } => {
                write!(f, "{} targets not searched: {reason}", polarity.name())
            }
        }
    }
}

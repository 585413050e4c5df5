//! Plausibility of an epoch's units, checked at the door (after [`super::epoch::EpochInput::validate`]
//! has checked the form): a principal distance in metres, image coordinates in pixels where mm are
//! expected, or object coordinates in millimetres where metres are expected each give a problem
//! that the adjustment would either solve to nonsense (all object coordinates × 1000 solve as
//! well as the right ones) or refuse with a message pointing elsewhere.
//!
//! The checks compare orders of magnitude only, with wide margins, so that every real network
//! passes: the image coordinates against c (a view angle), and the camera distance the object
//! coordinates imply (object extent × c / image extent) against the range of close-range and
//! terrestrial photogrammetry.

use crate::photogrammetry::error::EpochError;
use crate::photogrammetry::input::epoch::{EpochInput, EpochProblem};

/// Most an image coordinate may lie from the principal point, as a multiple of c: the tangent of
/// a half angle of view of 84°, wider than any lens the central model (Brown distortion) holds
/// (a 14 mm lens on a full-frame sensor reaches 1.5).
pub const MAX_IMAGE_RADIUS_PER_C: f64 = 10.0;

/// Farthest an image coordinate given in mm may lie from the principal point, in mm: beyond the
/// half diagonal of a 23 cm × 23 cm aerial film frame (163 mm), the largest format there is;
/// pixel positions (thousands) given as mm lie far beyond it.
pub const MAX_IMAGE_RADIUS_MM: f64 = 200.0;

/// Smallest principal distance in mm a real camera has (phone cameras have about 4 mm): below it,
/// with image coordinates beyond [`MAX_IMAGE_RADIUS_PER_C`] × c, c is taken to be in metres.
pub const MIN_PLAUSIBLE_C_MM: f64 = 1.0;

/// Farthest plausible distance in m from a camera to the points it sees (5 km): terrestrial
/// monitoring photogrammetry works at metres to a few kilometres; a network given in mm instead
/// of m puts a camera 10 m from its targets at 10 km.
pub const MAX_CAMERA_DISTANCE_M: f64 = 5_000.0;

/// Fewest points of known coordinates an image needs for its distance to be estimated (as many as
/// its adjustment needs): with four, one grossly wrong point is in half of the pairs.
const MIN_POINTS_FOR_DISTANCE: usize = 4;

/// Most points of one image paired for its distance (2016 pairs).
const MAX_POINTS_FOR_DISTANCE: usize = 64;

/// Validates the upload form ([`EpochInput::validate`]) and checks its units ([`check_units`]):
/// the problem the adjustment solves, from a form whose units fit.
pub fn validate(input: &EpochInput) -> Result<EpochProblem, EpochError> {
    let problem = input.validate()?;
    check_units(input, &problem)?;
    Ok(problem)
}

/// Checks the epoch's units by orders of magnitude (module documentation); the error names the
/// field at fault, what looks wrong and what was expected. `input` is the form `problem` was
/// validated from (it says whether an image's observations were given in mm or in pixels).
pub fn check_units(input: &EpochInput, problem: &EpochProblem) -> Result<(), EpochError> {
    check_view_angles(input, problem)?;
    check_camera_distances(problem)
}

/// Image coordinates against c: each observation within [`MAX_IMAGE_RADIUS_PER_C`] × c of the
/// principal point.
fn check_view_angles(input: &EpochInput, problem: &EpochProblem) -> Result<(), EpochError> {
    for (k, camera) in problem.cameras.iter().enumerate() {
        let c = camera.c();
        // The farthest observation of the camera's images: (radius mm, image, point, given in mm).
        let mut farthest: Option<(f64, usize, usize, bool)> = None;
        for (j, image) in problem.images.iter().enumerate() {
            if image.camera != k {
                continue;
            }
            for (n, o) in image.observations.iter().enumerate() {
                let r = o.xy[0].hypot(o.xy[1]);
                if farthest.is_none_or(|(best, ..)| r > best) {
                    let in_mm = input.images[j].observations[n].x_mm.is_some();
                    farthest = Some((r, j, n, in_mm));
                }
            }
        }
        let Some((r, j, n, in_mm)) = farthest else {
            continue;
        };
        let image = &problem.images[j];
        let point = &problem.points[image.observations[n].point];
        if in_mm && r > MAX_IMAGE_RADIUS_MM {
            return Err(pixels_for_mm(
                j,
                n,
                format!(
                    "image '{}' point '{point}' lies {r:.1} mm from the principal point, beyond \
                     any sensor",
                    image.id
                ),
            ));
        }
        if r <= MAX_IMAGE_RADIUS_PER_C * c {
            continue;
        }
        let angle = 2.0 * (r / c).atan().to_degrees();
        let seen = format!(
            "image '{}' point '{point}' lies {r:.3} mm from the principal point, {:.0} × c \
             (a view {angle:.1}° wide)",
            image.id,
            r / c
        );
        if c < MIN_PLAUSIBLE_C_MM && r <= MAX_IMAGE_RADIUS_PER_C * c * 1000.0 {
            return Err(EpochError::Implausible {
                field: format!("cameras[{k}].c_mm (camera '{}')", camera.id),
                found: format!("{c} mm looks like metres: {seen}"),
                expected: format!(
                    "the principal distance in millimetres (here perhaps {} mm)",
                    c * 1000.0
                ),
            });
        }
        if in_mm {
            return Err(pixels_for_mm(
                j,
                n,
                format!("{seen} with c_mm {c} of camera '{}'", camera.id),
            ));
        }
        return Err(EpochError::Implausible {
            field: format!("cameras[{k}].c_mm (camera '{}')", camera.id),
            found: format!("{c} mm is too short for its sensor: {seen}"),
            expected: format!(
                "the principal distance in mm, at least a tenth of the image coordinates' reach \
                 ({:.3} mm)",
                r / MAX_IMAGE_RADIUS_PER_C
            ),
        });
    }
    Ok(())
}

/// Image coordinates given as mm that look like pixels: observation `n` of image `j`, `seen`
/// saying why.
fn pixels_for_mm(j: usize, n: usize, seen: String) -> EpochError {
    EpochError::Implausible {
        field: format!("images[{j}].observations[{n}].x_mm, y_mm"),
        found: format!("they look like pixels: {seen}"),
        expected: "image coordinates in mm from the principal point (or col and row in pixels \
                   with the camera's pixel_size_mm, width_px and height_px)"
            .into(),
    }
}

/// Where a point's coordinates in the upload come from.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Source {
    Control,
    Approx,
}

impl Source {
    fn field(self) -> &'static str {
        match self {
            Source::Control => "control",
            Source::Approx => "approx",
        }
    }
}

/// The distance in m from image `j`'s camera to the points of `source` it sees, estimated as
/// c × the lower median, over pairs of those points, of object distance / image distance: a unit
/// error scales every pair, a single grossly wrong point only the pairs it is in (a minority from
/// four points on). At most [`MAX_POINTS_FOR_DISTANCE`] points are paired. None with fewer than
/// [`MIN_POINTS_FOR_DISTANCE`] such points or no pair apart in the image.
fn image_distance(problem: &EpochProblem, j: usize, source: Source) -> Option<f64> {
    let image = &problem.images[j];
    let known: Vec<([f64; 3], [f64; 2])> = image
        .observations
        .iter()
        .filter_map(|o| {
            let xyz = match (source, &problem.control[o.point]) {
                (Source::Control, Some(c)) => c.xyz,
                (Source::Approx, None) => problem.approx[o.point]?,
                _ => return None,
            };
            Some((xyz, o.xy))
        })
        .take(MAX_POINTS_FOR_DISTANCE)
        .collect();
    if known.len() < MIN_POINTS_FOR_DISTANCE {
        return None;
    }
    let mut ratios = Vec::with_capacity(known.len() * (known.len() - 1) / 2);
    for (i, (p, x)) in known.iter().enumerate() {
        for (q, y) in &known[i + 1..] {
            let image_mm = (x[0] - y[0]).hypot(x[1] - y[1]);
            if image_mm > 1e-9 {
                let object_m = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
                ratios.push(object_m / image_mm);
            }
        }
    }
    if ratios.is_empty() {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    Some(problem.cameras[image.camera].c() * ratios[(ratios.len() - 1) / 2])
}

/// The camera distances implied by the object coordinates of each source: the median over the
/// images within [`MAX_CAMERA_DISTANCE_M`].
fn check_camera_distances(problem: &EpochProblem) -> Result<(), EpochError> {
    for source in [Source::Control, Source::Approx] {
        let mut distances: Vec<(f64, usize)> = (0..problem.images.len())
            .filter_map(|j| image_distance(problem, j, source).map(|d| (d, j)))
            .collect();
        if distances.is_empty() {
            continue;
        }
        distances.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (median, j) = distances[distances.len() / 2];
        if median <= MAX_CAMERA_DISTANCE_M {
            continue;
        }
        let unit = if median / 1000.0 <= MAX_CAMERA_DISTANCE_M {
            "millimetres"
        } else {
            "a unit much smaller than the metre"
        };
        let image = &problem.images[j];
        return Err(EpochError::Implausible {
            field: source.field().to_string(),
            found: format!(
                "the coordinates look like {unit}: with c_mm {} and the image coordinates of \
                 image '{}' they put its camera {:.1} km from the points it sees (the median of \
                 {} images)",
                problem.cameras[image.camera].c(),
                image.id,
                median / 1000.0,
                distances.len()
            ),
            expected: format!(
                "coordinates in metres, cameras within {} km of their targets",
                MAX_CAMERA_DISTANCE_M / 1000.0
            ),
        });
    }
    Ok(())
}

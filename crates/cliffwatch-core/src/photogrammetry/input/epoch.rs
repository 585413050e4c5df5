//! The upload form of an epoch (`docs/api.md`) and its validation into an [`EpochProblem`].
//!
//! Object coordinates are metres in the site frame; image coordinates are mm (x right, y up, from the
//! principal point) or pixels (`col`, `row`, top-left pixel centre at (0, 0), row down).

use std::collections::{BTreeMap, HashMap, HashSet};

use chrono::{DateTime, Datelike, Utc};
use serde::{Deserialize, Serialize};

use crate::contract::truncate_for_message;
use crate::photogrammetry::error::EpochError;
pub use crate::photogrammetry::model::camera::CameraInput;
use crate::photogrammetry::model::camera::{Camera, MIN_SIGMA_MM};

/// One campaign at one site as uploaded (JSON form of the contract; the OpenAPI document's
/// upload form is derived from these types).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct EpochInput {
    /// When the images were taken (RFC 3339, UTC), unique within the site.
    #[cfg_attr(feature = "openapi", schema(format = DateTime))]
    pub observed_at: String,
    /// Free text label, without control characters, at most [`MAX_LABEL_CHARS`] (200) characters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(
        feature = "openapi",
        schema(pattern = "^[^\\u0000-\\u001F\\u007F-\\u009F]*$", max_length = 200)
    )]
    pub label: Option<String>,
    /// Cameras (interior orientation) used by the images, at most [`MAX_CAMERAS`].
    #[serde(default)]
    #[cfg_attr(
        feature = "openapi",
        schema(required = true, min_items = 1, max_items = 200)
    )]
    pub cameras: Vec<CameraInput>,
    /// Images with their target observations, at most [`MAX_IMAGES`].
    #[serde(default)]
    #[cfg_attr(
        feature = "openapi",
        schema(required = true, min_items = 1, max_items = 200)
    )]
    pub images: Vec<ImageInput>,
    /// Points with known coordinates, weighted by `sigma_m`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub control: Vec<ControlInput>,
    /// Start values only.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub approx: Vec<ApproxInput>,
}

/// One image of the upload form.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ImageInput {
    /// Image identifier, unique within the epoch.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub id: String,
    /// The camera id that took it.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub camera: String,
    /// The station (camera set-up position) name; defaults to the image id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub station: Option<String>,
    /// Target observations.
    #[serde(default)]
    #[cfg_attr(feature = "openapi", schema(required = true))]
    pub observations: Vec<ObservationInput>,
}

/// One target observation: either (`x_mm`, `y_mm`) or (`col`, `row`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ObservationInput {
    /// Point name.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub point: String,
    /// Image x in mm (right, from the principal point).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1e7, maximum = 1e7))]
    pub x_mm: Option<f64>,
    /// Image y in mm (up, from the principal point).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1e7, maximum = 1e7))]
    pub y_mm: Option<f64>,
    /// Pixel column (centre of the top-left pixel is 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1e7, maximum = 1e7))]
    pub col: Option<f64>,
    /// Pixel row (grows downward).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = -1e7, maximum = 1e7))]
    pub row: Option<f64>,
    /// A-priori standard deviation of each of this observation's coordinates in mm (default: its
    /// camera's `sigma_mm`), from [`MIN_SIGMA_MM`] to 1000 mm: e.g. a detected target's own σ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1e-6, maximum = 1000.0))]
    pub sigma_mm: Option<f64>,
}

/// A control point: known coordinates (m) weighted by `sigma_m`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
#[allow(non_snake_case)]
pub struct ControlInput {
    /// Point name.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub point: String,
    /// X in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub X: f64,
    /// Y in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub Y: f64,
    /// Z in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub Z: f64,
    /// Standard deviation of each coordinate in m (default 0.001 m), at least
    /// [`MIN_CONTROL_SIGMA_M`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(minimum = 1e-9))]
    pub sigma_m: Option<f64>,
}

/// Approximate coordinates (m): start values only.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
#[allow(non_snake_case)]
pub struct ApproxInput {
    /// Point name.
    #[cfg_attr(feature = "openapi", schema(pattern = "^[A-Za-z0-9._-]{1,64}$"))]
    pub point: String,
    /// X in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub X: f64,
    /// Y in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub Y: f64,
    /// Z in m.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e8, maximum = 1e8))]
    pub Z: f64,
}

/// Smallest σ of a control coordinate in m (1 nm): a smaller one made weights (σ⁻²) the normal
/// equations cannot hold; a point meant to be fixed is well served by it.
pub const MIN_CONTROL_SIGMA_M: f64 = 1e-9;

/// Default σ of a control coordinate when `sigma_m` is absent, in m.
pub const DEFAULT_CONTROL_SIGMA_M: f64 = 0.001;

/// One validated observation: point index and image coordinates in mm
/// (x right, y up, from the principal point, *before* distortion correction).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    /// Index into [`EpochProblem::points`].
    pub point: usize,
    /// Measured image coordinates in mm.
    pub xy: [f64; 2],
    /// Its own a-priori σ of each coordinate in mm; None: its camera's `sigma_mm`.
    pub sigma_mm: Option<f64>,
}

/// One validated image.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Image identifier.
    pub id: String,
    /// Station name (defaults to the image id).
    pub station: String,
    /// Index into [`EpochProblem::cameras`].
    pub camera: usize,
    /// Observations, at most one per point.
    pub observations: Vec<Observation>,
}

/// A control point of the validated epoch: coordinates in m and σ per coordinate in m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Control {
    /// Known coordinates in m (site frame).
    pub xyz: [f64; 3],
    /// σ of each coordinate in m.
    pub sigma_m: f64,
}

/// A validated epoch: everything indexed, image coordinates in mm, ready for the adjustment.
#[derive(Debug, Clone, PartialEq)]
pub struct EpochProblem {
    /// Observation time.
    pub observed_at: DateTime<Utc>,
    /// Cameras in input order.
    pub cameras: Vec<Camera>,
    /// Images in input order.
    pub images: Vec<Image>,
    /// Point names; indices are used everywhere else.
    pub points: Vec<String>,
    /// Control per point (None if the point is not a control point).
    pub control: Vec<Option<Control>>,
    /// Approximate coordinates per point in m (from `approx`, or `control`).
    pub approx: Vec<Option<[f64; 3]>>,
}

impl EpochProblem {
    /// Index of a point by name.
    pub fn point_index(&self, name: &str) -> Option<usize> {
        self.points.iter().position(|p| p == name)
    }

    /// Number of observations (each has two coordinates).
    pub fn observation_count(&self) -> usize {
        self.images.iter().map(|i| i.observations.len()).sum()
    }

    /// The a-priori σ that σ0 is expressed in, in image mm: the quadratic mean of the
    /// observations' a-priori σ (each its own `sigma_mm`, or its camera's), so that σ0 = this × √(vᵀPv/dof)
    /// is the typical a-posteriori σ of one image coordinate whatever the order of the cameras.
    /// With one camera, or cameras of one σ, it is that σ.
    pub fn reference_sigma_mm(&self) -> f64 {
        let (sum, n) = self.images.iter().fold((0.0, 0usize), |(sum, n), image| {
            let sigma = self.cameras[image.camera].sigma_mm;
            let s2: f64 = image
                .observations
                .iter()
                .map(|o| o.sigma_mm.unwrap_or(sigma).powi(2))
                .sum();
            (sum + s2, n + image.observations.len())
        });
        if n == 0 {
            return self.cameras.first().map_or(f64::NAN, |c| c.sigma_mm);
        }
        (sum / n as f64).sqrt()
    }
}

/// True when `s` is a valid user identifier (`[A-Za-z0-9._-]{1,64}`, other than `.` and `..`:
/// ids are path segments of the API and the dashboard, where those two name the folder itself or
/// its parent and no URL could reach the thing they named).
pub fn is_valid_identifier(s: &str) -> bool {
    !s.is_empty()
        && s != "."
        && s != ".."
        && s.len() <= 64
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '_' || c == '-')
}

/// Largest accepted magnitude of an image coordinate: 10 m in mm or 10⁷ pixels, beyond any sensor.
pub const MAX_IMAGE_COORDINATE: f64 = 1e7;
/// Most images of one epoch (the OpenAPI schema's `maxItems` says the same). The normal
/// equations hold a dense block of 6 parameters per image: 200 images make it 1200 × 1200.
pub const MAX_IMAGES: usize = 200;
/// Most cameras of one epoch (the OpenAPI schema's `maxItems` says the same).
pub const MAX_CAMERAS: usize = 200;
/// Longest label of an epoch, in characters (the OpenAPI schema's `maxLength` says the same).
pub const MAX_LABEL_CHARS: usize = 200;
const _: () = assert!(
    MAX_LABEL_CHARS == 200,
    "EpochInput's schema states the label's limit as a literal"
);
/// Largest accepted magnitude of an object coordinate in m (UTM northings are below 10⁷).
pub const MAX_OBJECT_COORDINATE_M: f64 = 1e8;

fn finite(value: f64, item: &str, field: &str) -> Result<f64, EpochError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(EpochError::NotFinite {
            item: item.to_string(),
            field: field.to_string(),
        })
    }
}

/// A finite number no larger than `max` in magnitude.
fn bounded(value: f64, max: f64, item: &str, field: &str) -> Result<f64, EpochError> {
    let v = finite(value, item, field)?;
    if v.abs() <= max {
        Ok(v)
    } else {
        Err(EpochError::OutOfRange {
            item: item.to_string(),
            field: field.to_string(),
            reason: format!("is beyond ±{max:e}"),
        })
    }
}

impl EpochInput {
    /// Parses the observation time, in UTC within the years 0000–9999 (an offset can carry
    /// `9999-12-31T23:30:00-01:00` into year 10 000, which RFC 3339 cannot write).
    pub fn observed_at(&self) -> Result<DateTime<Utc>, EpochError> {
        let t = DateTime::parse_from_rfc3339(&self.observed_at)
            .map(|t| t.with_timezone(&Utc))
            .map_err(|_| EpochError::BadTimestamp(self.observed_at.clone()))?;
        if (0..=9999).contains(&t.year()) {
            Ok(t)
        } else {
            Err(EpochError::TimestampOutOfRange(self.observed_at.clone()))
        }
    }

    /// Validates the upload form into an [`EpochProblem`]: identifiers, finite numbers, known cameras,
    /// no duplicate observations, pixel geometry where pixel observations are used. The adjustment
    /// and the service take the form through `plausible::validate`, which checks its units too.
    ///
    /// Geometric sufficiency (≥ 4 known points per image, each point in ≥ 2 images) is checked by the
    /// adjustment, because earlier epochs of a site may supply the known points.
    pub fn validate(&self) -> Result<EpochProblem, EpochError> {
        let observed_at = self.observed_at()?;
        if let Some(label) = self.label.as_deref() {
            if label.chars().any(char::is_control) {
                return Err(EpochError::BadLabel);
            }
            let chars = label.chars().count();
            if chars > MAX_LABEL_CHARS {
                return Err(EpochError::LabelTooLong {
                    chars,
                    max: MAX_LABEL_CHARS,
                });
            }
        }
        if self.images.is_empty() {
            return Err(EpochError::Empty);
        }
        for (what, count, limit) in [
            ("images", self.images.len(), MAX_IMAGES),
            ("cameras", self.cameras.len(), MAX_CAMERAS),
        ] {
            if count > limit {
                return Err(EpochError::TooMany { what, count, limit });
            }
        }
        let (cameras, camera_index) = self.validate_cameras()?;
        let mut names = PointNames::default();
        let mut images = Vec::with_capacity(self.images.len());
        let mut image_ids = HashSet::new();
        for im in &self.images {
            if !is_valid_identifier(&im.id) {
                return Err(EpochError::BadIdentifier(format!(
                    "image '{}'",
                    truncate_for_message(&im.id)
                )));
            }
            if let Some(station) = im.station.as_deref().filter(|s| !is_valid_identifier(s)) {
                return Err(EpochError::BadIdentifier(format!(
                    "station '{}' of image '{}'",
                    truncate_for_message(station),
                    im.id
                )));
            }
            if !image_ids.insert(im.id.clone()) {
                return Err(EpochError::DuplicateImage(im.id.clone()));
            }
            images.push(im.validate(&cameras, &camera_index, &mut names)?);
        }
        let (control, approx) = self.known_points(&names)?;
        Ok(EpochProblem {
            observed_at,
            cameras,
            images,
            points: names.names,
            control,
            approx,
        })
    }

    /// The cameras, with their index by id; ids must be valid and unique.
    fn validate_cameras(&self) -> Result<(Vec<Camera>, HashMap<String, usize>), EpochError> {
        let mut cameras = Vec::with_capacity(self.cameras.len());
        let mut camera_index = HashMap::new();
        for c in &self.cameras {
            if !is_valid_identifier(&c.id) {
                return Err(EpochError::BadIdentifier(format!(
                    "camera '{}'",
                    truncate_for_message(&c.id)
                )));
            }
            if camera_index.insert(c.id.clone(), cameras.len()).is_some() {
                return Err(EpochError::DuplicateCamera(c.id.clone()));
            }
            cameras.push(Camera::from_input(c)?);
        }
        Ok((cameras, camera_index))
    }

    /// Control coordinates and approximations by point index (control doubles as approximation);
    /// points nobody observed are ignored, since they carry no information.
    #[allow(clippy::type_complexity)]
    fn known_points(
        &self,
        names: &PointNames,
    ) -> Result<(Vec<Option<Control>>, Vec<Option<[f64; 3]>>), EpochError> {
        let mut control = vec![None; names.names.len()];
        let mut approx = vec![None; names.names.len()];
        let mut seen_control = HashSet::new();
        for c in &self.control {
            let item = format!("control point '{}'", truncate_for_message(&c.point));
            let xyz = object_xyz([c.X, c.Y, c.Z], &item)?;
            let sigma_m = finite(
                c.sigma_m.unwrap_or(DEFAULT_CONTROL_SIGMA_M),
                &item,
                "sigma_m",
            )?;
            if sigma_m < MIN_CONTROL_SIGMA_M {
                return Err(EpochError::OutOfRange {
                    item,
                    field: "sigma_m".into(),
                    reason: format!("must be at least {MIN_CONTROL_SIGMA_M} m"),
                });
            }
            if !seen_control.insert(c.point.clone()) {
                return Err(EpochError::DuplicatePoint(c.point.clone()));
            }
            if let Some(i) = names.get(&c.point) {
                control[i] = Some(Control { xyz, sigma_m });
                approx[i] = Some(xyz);
            }
        }
        let mut seen_approx = HashSet::new();
        for a in &self.approx {
            let item = format!("approx point '{}'", truncate_for_message(&a.point));
            let xyz = object_xyz([a.X, a.Y, a.Z], &item)?;
            if !seen_approx.insert(a.point.clone()) {
                return Err(EpochError::DuplicatePoint(a.point.clone()));
            }
            if let Some(i) = names.get(&a.point) {
                approx[i].get_or_insert(xyz);
            }
        }
        Ok((control, approx))
    }

    /// The canonical form used for idempotency: the parsed body re-serialized (key order fixed by the
    /// types), so that bodies compare as parsed JSON, not bytes.
    pub fn canonical_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }
}

/// Known coordinates (m) of points from earlier epochs of the site, used as start values.
pub type PriorCoordinates = BTreeMap<String, [f64; 3]>;

/// X, Y, Z of `item` in m: finite and within [`MAX_OBJECT_COORDINATE_M`] (beyond it, the unit is
/// the likely mistake: UTM coordinates in mm pass 10⁸).
fn object_xyz([x, y, z]: [f64; 3], item: &str) -> Result<[f64; 3], EpochError> {
    let one = |v: f64, field: &str| {
        bounded(v, MAX_OBJECT_COORDINATE_M, item, field).map_err(|e| match e {
            EpochError::OutOfRange { item, field, .. } => EpochError::OutOfRange {
                item,
                field,
                reason: format!(
                    "{v:e} is beyond ±{MAX_OBJECT_COORDINATE_M:e}: it looks like millimetres \
                     or another unit; expected metres"
                ),
            },
            other => other,
        })
    };
    Ok([one(x, "X")?, one(y, "Y")?, one(z, "Z")?])
}

/// The epoch's point names in order of first observation, with their indices.
#[derive(Default)]
struct PointNames {
    names: Vec<String>,
    index: HashMap<String, usize>,
}

impl PointNames {
    /// The index of `name`, added if new (after checking it is a valid identifier).
    fn intern(&mut self, name: &str) -> Result<usize, EpochError> {
        if let Some(&i) = self.index.get(name) {
            return Ok(i);
        }
        if !is_valid_identifier(name) {
            return Err(EpochError::BadIdentifier(format!(
                "point '{}'",
                truncate_for_message(name)
            )));
        }
        self.index.insert(name.to_string(), self.names.len());
        self.names.push(name.to_string());
        Ok(self.names.len() - 1)
    }

    /// The index of an observed point.
    fn get(&self, name: &str) -> Option<usize> {
        self.index.get(name).copied()
    }
}

impl ImageInput {
    /// The image with its camera resolved and its observations in image mm, one per point.
    fn validate(
        &self,
        cameras: &[Camera],
        camera_index: &HashMap<String, usize>,
        names: &mut PointNames,
    ) -> Result<Image, EpochError> {
        let &cam = camera_index
            .get(&self.camera)
            .ok_or_else(|| EpochError::UnknownCamera {
                image: self.id.clone(),
                camera: self.camera.clone(),
            })?;
        let camera = &cameras[cam];
        let mut seen = HashSet::new();
        let mut observations = Vec::with_capacity(self.observations.len());
        for o in &self.observations {
            let p = names.intern(&o.point)?;
            if !seen.insert(p) {
                return Err(EpochError::DuplicateObservation {
                    image: self.id.clone(),
                    point: o.point.clone(),
                });
            }
            let xy = o.image_mm(&self.id, camera)?;
            on_sensor(xy, camera, || {
                format!("image '{}' point '{}'", self.id, o.point)
            })?;
            let sigma_mm = match o.sigma_mm {
                Some(s) if !(s.is_finite() && (MIN_SIGMA_MM..=1e3).contains(&s)) => {
                    return Err(EpochError::OutOfRange {
                        item: format!("image '{}' point '{}'", self.id, o.point),
                        field: "sigma_mm".into(),
                        reason: format!("must be from {MIN_SIGMA_MM} to 1000 mm"),
                    })
                }
                s => s,
            };
            observations.push(Observation {
                point: p,
                xy,
                sigma_mm,
            });
        }
        Ok(Image {
            id: self.id.clone(),
            station: self.station.clone().unwrap_or_else(|| self.id.clone()),
            camera: cam,
            observations,
        })
    }
}

/// How far beyond the sensor's edge (as a share of its half width or height) an observation may
/// lie: the principal point may sit off the centre, a target may be centred on the border.
const SENSOR_MARGIN: f64 = 0.1;

/// Checks that an observation (image mm) lies on the sensor when the camera gives its size (pixel
/// size and image size), within [`SENSOR_MARGIN`]: a point far off it is a typo or a wrong unit,
/// which the adjustment would only drop as an outlier.
fn on_sensor(xy: [f64; 2], camera: &Camera, item: impl Fn() -> String) -> Result<(), EpochError> {
    let Some(half) = camera.half_sensor_mm() else {
        return Ok(());
    };
    let off = (0..2).any(|k| xy[k].abs() > (1.0 + SENSOR_MARGIN) * half[k]);
    if off {
        return Err(EpochError::OutOfRange {
            item: item(),
            field: "position".into(),
            reason: format!(
                "({:.3}, {:.3}) mm lies off the sensor of camera '{}' (±{:.3} × ±{:.3} mm)",
                xy[0], xy[1], camera.id, half[0], half[1]
            ),
        });
    }
    Ok(())
}

impl ObservationInput {
    /// The observation in image mm: given in mm, or in pixels through the camera's geometry.
    fn image_mm(&self, image: &str, camera: &Camera) -> Result<[f64; 2], EpochError> {
        let item = format!("image '{image}' point '{}'", self.point);
        match (self.x_mm, self.y_mm, self.col, self.row) {
            (Some(x), Some(y), None, None) => Ok([
                bounded(x, MAX_IMAGE_COORDINATE, &item, "x_mm")?,
                bounded(y, MAX_IMAGE_COORDINATE, &item, "y_mm")?,
            ]),
            (None, None, Some(col), Some(row)) => {
                let col = bounded(col, MAX_IMAGE_COORDINATE, &item, "col")?;
                let row = bounded(row, MAX_IMAGE_COORDINATE, &item, "row")?;
                camera
                    .pixel_to_mm(col, row)
                    .ok_or_else(|| EpochError::PixelWithoutGeometry {
                        image: image.to_string(),
                        camera: camera.id.clone(),
                    })
            }
            _ => Err(EpochError::MissingCoordinate { item }),
        }
    }
}

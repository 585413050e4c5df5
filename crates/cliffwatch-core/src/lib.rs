//! # cliffwatch-core
//!
//! The pure core of cliffwatch, a monitor of rock cliffs: the bundle adjustment with the orthogonal
//! projection model (Ono & Hattori) and a self-calibrated principal distance, the detection and
//! identification of circular targets in images, and the analysis of displacement series (datum
//! on stable points, congruence test, velocity, time to failure, alert rules). No I/O, no async, no
//! database: every function takes values and returns values.
//!
//! ## Modules
//! - [`photogrammetry`]: the epoch form, start values, the orthogonal and central bundle
//!   adjustments, datum, precision, blunder detection, the adjustment report.
//! - [`detect`]: images → circular targets with sub-pixel centres → identified observations.
//! - [`analysis`]: stable-point datum, congruence test, displacements, velocity, time to failure,
//!   alert rules.
//! - [`plan`]: campaign design, the predicted precision and minimum detectable displacement of a
//!   planned camera network (pre-analysis with zero residuals).
//! - [`contract`]: the names of the domain's enums (levels, states, roles, models) as the API, the
//!   webhooks and the database spell them; the integers of JSON bodies.
//!
//! The feature `openapi` derives the OpenAPI schemas (utoipa) of the types the daemon's API
//! carries; it is off by default.
//!
//! ## A worked example: adjust an epoch from image coordinates
//! Three cameras with a 300 mm lens stand 150 m from a cliff face; they see twelve targets, four
//! of them with known coordinates. The adjustment needs no camera position to start: it
//! resects each image from the known points with the orthogonal model, then estimates every
//! target, every orientation and the principal distance c (self-calibrated, started 2 % off).
//!
//! ```
//! use cliffwatch_core::photogrammetry::input::epoch::{
//!     CameraInput, ControlInput, ImageInput, ObservationInput,
//! };
//! use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, EpochInput};
//! use nalgebra::Vector3;
//!
//! // The face: targets on a 24 m × 12 m slope with 2 m of relief (site frame, metres; the
//! // cameras look along +Y).
//! let targets: Vec<(String, Vector3<f64>)> = (0..12)
//!     .map(|k| {
//!         let (i, j) = ((k % 4) as f64, (k / 4) as f64);
//!         let relief = 2.0 * ((i * 1.3 + j * 0.7).sin());
//!         (format!("T{k:02}"), Vector3::new(-12.0 + 8.0 * i, relief, -6.0 + 6.0 * j))
//!     })
//!     .collect();
//! // Each station's image of them through a true 300 mm lens (x right, y up, in mm).
//! let c_true = 300.0;
//! let images = [-40.0, 0.0, 40.0].iter().enumerate().map(|(s, &x)| {
//!     let centre = Vector3::new(x, -150.0, 3.0);
//!     let ahead = (Vector3::zeros() - centre).normalize();
//!     let right = ahead.cross(&Vector3::z()).normalize();
//!     let up = right.cross(&ahead);
//!     let observations = targets.iter().map(|(name, p)| {
//!         let d = p - centre;
//!         let depth = d.dot(&ahead);
//!         ObservationInput {
//!             point: name.clone(),
//!             x_mm: Some(c_true * d.dot(&right) / depth),
//!             y_mm: Some(c_true * d.dot(&up) / depth),
//!             col: None, row: None, sigma_mm: None,
//!         }
//!     });
//!     ImageInput {
//!         id: format!("img{s}"),
//!         camera: "tele".into(),
//!         station: None,
//!         observations: observations.collect(),
//!     }
//! });
//! // Four known points are enough to start.
//! let control = targets.iter().filter(|(n, _)| ["T00", "T03", "T08", "T11"].contains(&n.as_str()));
//! let epoch = EpochInput {
//!     observed_at: "2026-11-01T09:00:00Z".into(),
//!     label: None,
//!     cameras: vec![CameraInput {
//!         id: "tele".into(),
//!         c_mm: 294.0, // 2 % off: the adjustment calibrates c
//!         calibrate_c: true,
//!         calibrate: None,
//!         pixel_size_mm: None, width_px: None, height_px: None,
//!         x0_mm: 0.0, y0_mm: 0.0, k1: 0.0, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0,
//!         sigma_mm: Some(0.001),
//!     }],
//!     images: images.collect(),
//!     control: control
//!         .map(|(n, p)| ControlInput { point: n.clone(), X: p.x, Y: p.y, Z: p.z, sigma_m: Some(0.001) })
//!         .collect(),
//!     approx: Vec::new(),
//! };
//!
//! let adjustment = adjust(&epoch, &AdjustOptions::default()).expect("the epoch adjusts");
//! let report = &adjustment.report;
//! assert!(report.converged);
//! // Every target within 5 mm of the truth, with its precision (m²) beside it.
//! for (name, truth) in &targets {
//!     let point = adjustment.point(name).expect("every target is estimated");
//!     let error_mm = (Vector3::from(point.xyz) - truth).norm() * 1000.0;
//!     assert!(error_mm < 5.0, "{name}: {error_mm:.2} mm");
//!     assert!(point.covariance_m2[0][0] > 0.0);
//! }
//! // c found again from the images alone.
//! assert!((report.cameras[0].c_mm - c_true).abs() < 1.0, "c = {}", report.cameras[0].c_mm);
//! ```

#![warn(missing_docs)]

pub mod analysis;
pub mod contract;
pub mod detect;
pub mod photogrammetry;
pub mod plan;

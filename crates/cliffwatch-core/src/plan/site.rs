//! An existing site's network as a plan: its latest epoch's cameras, stations and observations,
//! its adjusted coordinates and its stable points. The stations' orientations are not stored, so
//! the epoch is adjusted once more from its stored observations (start values: the epoch's own
//! adjusted coordinates); each station then becomes a planned station at its adjusted position
//! and rotation that sees exactly the targets it observed.

use std::collections::BTreeMap;

use nalgebra::Vector3;

use super::input::{Plan, PlanCamera, PlanDatum, PlanError, PlanStation, PlanTarget};
use crate::analysis::sensitivity::DEFAULT_POWER;
use crate::photogrammetry::input::epoch::DEFAULT_CONTROL_SIGMA_M;
use crate::photogrammetry::{adjust, AdjustOptions, Cancel, EpochInput, Model};

/// Pixel size in mm assumed for a camera of the site whose pixel size is unknown (observations
/// in mm): 1 µm, so that its σ in pixels reads as σ in µm.
pub const NOMINAL_PIXEL_SIZE_MM: f64 = 0.001;

/// Sensor size in pixels assumed for a camera whose image size is unknown: large enough that a
/// station added with it sees every target in front of it.
pub const UNBOUNDED_SENSOR_PX: u32 = 1_000_000;

/// What the service reads of a site for its pre-analysis (`src/store`, no I/O here).
#[derive(Debug, Clone)]
pub struct SiteNetwork {
    /// The site's projection model.
    pub model: Model,
    /// The latest epoch rebuilt: its cameras (with the a-priori σ the site uses), its images with
    /// the observations the adjustment kept, and the epoch's adjusted coordinates as `approx`.
    pub epoch: EpochInput,
    /// The site's stable points (the datum's points).
    pub stable: Vec<String>,
    /// Whether that epoch was adjusted on control points (else: free network).
    pub control_datum: bool,
    /// The site's confidence level (0–1).
    pub confidence: f64,
    /// The site's declared outward face normal (site frame), if any.
    pub face_normal: Option<[f64; 3]>,
}

/// The plan of a site's current network (see the module documentation). `cancel` stops the
/// re-adjustment early. Errors: the epoch cannot be adjusted again (observations pruned, …).
pub fn site_plan(net: &SiteNetwork, cancel: Cancel) -> Result<Plan, PlanError> {
    let options = AdjustOptions {
        model: net.model,
        snooping: false,
        cancel,
        ..AdjustOptions::default()
    };
    let adjusted = adjust(&net.epoch, &options)?;
    let cameras: Vec<PlanCamera> = adjusted
        .cameras
        .iter()
        .map(|c| {
            let pixel = c.pixel_size_mm.unwrap_or(NOMINAL_PIXEL_SIZE_MM);
            let (w, h) = c
                .size_px
                .unwrap_or((UNBOUNDED_SENSOR_PX, UNBOUNDED_SENSOR_PX));
            PlanCamera {
                id: c.id.clone(),
                c_mm: c.params[0],
                calibrate_c: c.calibrate[0],
                pixel_size_mm: pixel,
                width_px: w,
                height_px: h,
                sigma_px: Some(c.sigma_mm / pixel),
            }
        })
        .collect();
    let xyz: BTreeMap<&str, [f64; 3]> = adjusted
        .points
        .iter()
        .map(|p| (p.name.as_str(), p.xyz))
        .collect();
    let mut stations = Vec::new();
    for image in &net.epoch.images {
        let Some(o) = adjusted.orientations.iter().find(|o| o.image == image.id) else {
            continue;
        };
        let sees: Vec<String> = image.observations.iter().map(|o| o.point.clone()).collect();
        let centre = Vector3::from(o.center);
        let distance = sees
            .iter()
            .filter_map(|p| xyz.get(p.as_str()))
            .map(|x| (Vector3::from(*x) - centre).norm())
            .sum::<f64>()
            / sees.len().max(1) as f64;
        let r3 = Vector3::from(o.rotation[2]);
        stations.push(PlanStation {
            name: image.station.clone().unwrap_or_else(|| image.id.clone()),
            camera: o.camera.clone(),
            position: o.center,
            aim: (centre - r3 * distance.max(1.0)).into(),
            up: Some(o.rotation[1]),
            sees: Some(sees),
        });
    }
    let targets = adjusted
        .points
        .iter()
        .map(|p| PlanTarget {
            point: p.name.clone(),
            xyz: p.xyz,
            known: net.stable.contains(&p.name),
            sigma_m: None,
        })
        .collect();
    Ok(Plan {
        model: net.model,
        sigma_px: cameras.first().and_then(|c| c.sigma_px).unwrap_or(1.0),
        confidence: net.confidence,
        power: DEFAULT_POWER,
        known_sigma_m: DEFAULT_CONTROL_SIGMA_M,
        datum: if net.control_datum {
            PlanDatum::Control
        } else {
            PlanDatum::Free
        },
        face_normal: net.face_normal,
        cameras,
        stations,
        targets,
    })
}

//! The planned network as an epoch: each station's rotation from its position and aim, each
//! target's exact image coordinates (collinearity, eq 2 of the paper, no noise), the targets a
//! station cannot see (behind it, or off its sensor), and the epoch the adjustment takes.

use std::collections::BTreeMap;

use nalgebra::Vector3;

use super::input::{Plan, PlanCamera, PlanDatum, PlanError};
use crate::photogrammetry::input::epoch::{
    ApproxInput, CameraInput, ControlInput, EpochInput, ImageInput, ObservationInput,
};
use crate::photogrammetry::model::camera::Camera;
use crate::photogrammetry::ImageOrientation;

/// The time stamp of a planned epoch (the adjustment wants one; a plan has none).
const PLANNED_AT: &str = "2000-01-01T00:00:00Z";

/// The planned network made into the noise-free epoch the pre-analysis adjusts.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedEpoch {
    /// The epoch: one image per station (id = station name), exact image coordinates in mm,
    /// known targets as control, every target's planned coordinates as start values. Targets seen
    /// by fewer than two stations are left out of it.
    pub epoch: EpochInput,
    /// Each target (plan order) with the stations that see it.
    pub seen_by: Vec<(String, Vec<String>)>,
}

/// The rotation R (rows r1, r2, r3; camera coordinates `R (X − Xo)`, the camera looks along −r3)
/// of a camera at `position` aimed at `aim` with `up` (m, site frame) as the image's upward
/// direction: r3 = −(aim − position)/|…|, r1 = (forward × up)/|…| (image x to the right),
/// r2 = r3 × r1 (image y up). None when the aim is the position or `up` is along the view.
pub fn look_at(position: [f64; 3], aim: [f64; 3], up: [f64; 3]) -> Option<[[f64; 3]; 3]> {
    let forward = Vector3::from(aim) - Vector3::from(position);
    let up = Vector3::from(up);
    if forward.norm() == 0.0 || up.norm() == 0.0 {
        return None;
    }
    let f = forward.normalize();
    let right = f.cross(&up);
    // Up within about half a degree of the view direction leaves the image's roll undefined.
    if right.norm() < 1e-2 * up.norm() {
        return None;
    }
    let r1 = right.normalize();
    let r3 = -f;
    let r2 = r3.cross(&r1);
    Some([r1.into(), r2.into(), r3.into()])
}

/// The camera of the plan as the adjustment's validated [`Camera`] (c and no distortion), used
/// only to project.
fn projection_camera(c_mm: f64) -> Camera {
    Camera {
        id: String::new(),
        params: [c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        calibrate: [false; 8],
        pixel_size_mm: None,
        size_px: None,
        sigma_mm: 1.0,
    }
}

/// Builds the noise-free epoch of a checked plan. Errors name the station or camera at fault.
pub fn planned_epoch(plan: &Plan) -> Result<PlannedEpoch, PlanError> {
    let cameras: BTreeMap<&str, &PlanCamera> =
        plan.cameras.iter().map(|c| (c.id.as_str(), c)).collect();
    let mut seen: BTreeMap<&str, Vec<String>> = BTreeMap::new();
    let mut images = Vec::new();
    for s in &plan.stations {
        let cam = cameras
            .get(s.camera.as_str())
            .ok_or_else(|| PlanError::UnknownCamera {
                station: s.name.clone(),
                camera: s.camera.clone(),
            })?;
        let rotation =
            look_at(s.position, s.aim, s.up.unwrap_or([0.0, 0.0, 1.0])).ok_or_else(|| {
                PlanError::BadAim {
                    station: s.name.clone(),
                }
            })?;
        let orientation = ImageOrientation {
            image: s.name.clone(),
            station: s.name.clone(),
            camera: cam.id.clone(),
            rotation,
            center: s.position,
        };
        let projector = projection_camera(cam.c_mm);
        let half = [
            f64::from(cam.width_px) * cam.pixel_size_mm / 2.0,
            f64::from(cam.height_px) * cam.pixel_size_mm / 2.0,
        ];
        let mut observations = Vec::new();
        for t in &plan.targets {
            let listed = s.sees.as_ref().map(|v| v.contains(&t.point));
            if listed == Some(false) {
                continue;
            }
            let Some(xy) = orientation.project(&projector, t.xyz) else {
                if listed == Some(true) {
                    return Err(PlanError::Behind {
                        station: s.name.clone(),
                        point: t.point.clone(),
                    });
                }
                continue;
            };
            // A station's own list stands for its sensor: what it observed was on it.
            if listed.is_none() && (xy[0].abs() > half[0] || xy[1].abs() > half[1]) {
                continue;
            }
            seen.entry(t.point.as_str())
                .or_default()
                .push(s.name.clone());
            observations.push(ObservationInput {
                point: t.point.clone(),
                x_mm: Some(xy[0]),
                y_mm: Some(xy[1]),
                col: None,
                row: None,
                sigma_mm: None,
            });
        }
        if observations.is_empty() {
            return Err(PlanError::SeesNothing {
                station: s.name.clone(),
            });
        }
        images.push(ImageInput {
            id: s.name.clone(),
            camera: cam.id.clone(),
            station: Some(s.name.clone()),
            observations,
        });
    }
    let seen_by: Vec<(String, Vec<String>)> = plan
        .targets
        .iter()
        .map(|t| {
            (
                t.point.clone(),
                seen.get(t.point.as_str()).cloned().unwrap_or_default(),
            )
        })
        .collect();
    let usable = |name: &str| seen.get(name).is_some_and(|v| v.len() >= 2);
    for image in &mut images {
        image.observations.retain(|o| usable(&o.point));
    }
    images.retain(|i| !i.observations.is_empty());
    let free = plan.datum == PlanDatum::Free;
    let control = plan
        .targets
        .iter()
        .filter(|t| t.known && !free && usable(&t.point))
        .map(|t| ControlInput {
            point: t.point.clone(),
            X: t.xyz[0],
            Y: t.xyz[1],
            Z: t.xyz[2],
            sigma_m: Some(t.sigma_m.unwrap_or(plan.known_sigma_m)),
        })
        .collect();
    let approx = plan
        .targets
        .iter()
        .filter(|t| (free || !t.known) && usable(&t.point))
        .map(|t| ApproxInput {
            point: t.point.clone(),
            X: t.xyz[0],
            Y: t.xyz[1],
            Z: t.xyz[2],
        })
        .collect();
    let used: Vec<&str> = images.iter().map(|i| i.camera.as_str()).collect();
    let epoch = EpochInput {
        observed_at: PLANNED_AT.into(),
        label: Some("planned network".into()),
        cameras: plan
            .cameras
            .iter()
            .filter(|c| used.contains(&c.id.as_str()))
            .map(|c| CameraInput {
                id: c.id.clone(),
                c_mm: c.c_mm,
                calibrate_c: c.calibrate_c,
                calibrate: None,
                pixel_size_mm: Some(c.pixel_size_mm),
                width_px: Some(c.width_px),
                height_px: Some(c.height_px),
                x0_mm: 0.0,
                y0_mm: 0.0,
                k1: 0.0,
                k2: 0.0,
                k3: 0.0,
                p1: 0.0,
                p2: 0.0,
                sigma_mm: Some(c.sigma_px.unwrap_or(plan.sigma_px) * c.pixel_size_mm),
            })
            .collect(),
        images,
        control,
        approx,
    };
    Ok(PlannedEpoch { epoch, seen_by })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera on +Z looking at the origin with Y up sees +X to the right and +Y up, and the
    /// rotation is proper (r1 × r2 = r3).
    #[test]
    fn look_at_gives_a_proper_rotation_with_x_right() {
        let r = look_at([0.0, 0.0, 10.0], [0.0; 3], [0.0, 1.0, 0.0]).expect("rotation");
        assert_eq!(r[0], [1.0, 0.0, 0.0]);
        assert_eq!(r[1], [0.0, 1.0, 0.0]);
        assert_eq!(r[2], [0.0, 0.0, 1.0]);
        let r = look_at([3.0, -40.0, 2.0], [1.0, 2.0, 5.0], [0.0, 0.0, 1.0]).expect("rotation");
        let v = |i: usize| Vector3::from(r[i]);
        assert!((v(0).cross(&v(1)) - v(2)).norm() < 1e-12);
        assert!(v(0).dot(&v(1)).abs() < 1e-12);
        assert!(look_at([0.0; 3], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]).is_none());
    }
}

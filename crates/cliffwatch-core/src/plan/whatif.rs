//! What-ifs on a plan (`POST /api/v1/sites/{site}/plan`, `docs/api.md`, "Campaign design"): a
//! station dropped or added, a lens changed, another σ of the image coordinates. Each change is
//! applied to a copy of the plan in order; an error names the change at fault.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::input::{Plan, PlanError, PlanStation};

/// One change to a plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(tag = "change", rename_all = "snake_case", deny_unknown_fields)]
pub enum PlanChange {
    /// Drop one station (its image) from the network.
    DropStation {
        /// Station name.
        station: String,
    },
    /// Drop every station of one camera.
    DropCamera {
        /// Camera id.
        camera: String,
    },
    /// Add a station: `position` and `aim` (m, site frame), or `distance_m` and `direction` (a
    /// station `distance_m` metres from the targets' centroid along `direction`, aimed at it).
    AddStation {
        /// New station name.
        name: String,
        /// Camera id of the plan (lens, sensor and σ).
        camera: String,
        /// Projection centre in m (site frame), with `aim`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        position: Option<[f64; 3]>,
        /// The point aimed at in m (site frame), with `position`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        aim: Option<[f64; 3]>,
        /// Distance from the targets' centroid in m, with `direction`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        distance_m: Option<f64>,
        /// Direction from the targets' centroid toward the station (any length, site frame).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        direction: Option<[f64; 3]>,
        /// The image's upward direction (default `[0, 0, 1]`).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        up: Option<[f64; 3]>,
    },
    /// Another lens on a camera: its principal distance c in mm.
    SetC {
        /// Camera id.
        camera: String,
        /// The new c in mm.
        c_mm: f64,
    },
    /// Another σ of one image coordinate, pixels: of one camera, or of every camera when
    /// `camera` is absent.
    SetSigmaPx {
        /// Camera id (absent: all cameras).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        camera: Option<String>,
        /// σ of one image coordinate in pixels.
        sigma_px: f64,
    },
}

/// The error of change number `i` (0-based, as in the request's list).
fn bad(i: usize, why: String) -> PlanError {
    PlanError::Invalid {
        item: format!("changes[{i}]"),
        why,
    }
}

/// Applies `changes` in order to a copy of `plan`. Errors name the change (`changes[i]`) and the
/// station or camera at fault.
pub fn apply_changes(plan: &Plan, changes: &[PlanChange]) -> Result<Plan, PlanError> {
    let mut out = plan.clone();
    for (i, change) in changes.iter().enumerate() {
        let has_camera = |p: &Plan, id: &str| p.cameras.iter().any(|c| c.id == id);
        match change {
            PlanChange::DropStation { station } => {
                let before = out.stations.len();
                out.stations.retain(|s| &s.name != station);
                if out.stations.len() == before {
                    return Err(bad(i, format!("no station '{station}' to drop")));
                }
            }
            PlanChange::DropCamera { camera } => {
                if !has_camera(&out, camera) {
                    return Err(bad(i, format!("no camera '{camera}' to drop")));
                }
                out.stations.retain(|s| &s.camera != camera);
            }
            PlanChange::AddStation {
                name,
                camera,
                position,
                aim,
                distance_m,
                direction,
                up,
            } => {
                if out.stations.iter().any(|s| &s.name == name) {
                    return Err(bad(i, format!("station '{name}' exists")));
                }
                if !has_camera(&out, camera) {
                    return Err(bad(i, format!("station {name}: no camera '{camera}'")));
                }
                let (position, aim) = match (position, aim, distance_m, direction) {
                    (Some(p), Some(a), None, None) => (*p, *a),
                    (None, None, Some(d), Some(dir)) => {
                        let unit = Vector3::from(*dir)
                            .try_normalize(0.0)
                            .filter(|_| d.is_finite() && *d > 0.0)
                            .ok_or_else(|| {
                                bad(
                                    i,
                                    format!(
                                        "station {name}: distance_m must be positive and \
                                         direction not zero"
                                    ),
                                )
                            })?;
                        let centroid = out
                            .targets
                            .iter()
                            .fold(Vector3::zeros(), |s, t| s + Vector3::from(t.xyz))
                            / out.targets.len().max(1) as f64;
                        ((centroid + unit * *d).into(), centroid.into())
                    }
                    _ => {
                        return Err(bad(
                            i,
                            format!(
                                "station {name}: give position and aim, or distance_m and \
                                 direction"
                            ),
                        ))
                    }
                };
                out.stations.push(PlanStation {
                    name: name.clone(),
                    camera: camera.clone(),
                    position,
                    aim,
                    up: *up,
                    sees: None,
                });
            }
            PlanChange::SetC { camera, c_mm } => {
                if !(c_mm.is_finite() && *c_mm > 0.0) {
                    return Err(bad(i, format!("camera {camera}: c_mm must be positive")));
                }
                let cam = out
                    .cameras
                    .iter_mut()
                    .find(|c| &c.id == camera)
                    .ok_or_else(|| bad(i, format!("no camera '{camera}'")))?;
                cam.c_mm = *c_mm;
            }
            PlanChange::SetSigmaPx { camera, sigma_px } => {
                if !(sigma_px.is_finite() && *sigma_px > 0.0) {
                    return Err(bad(
                        i,
                        "sigma_px must be a positive number of pixels".into(),
                    ));
                }
                match camera {
                    Some(id) => {
                        out.cameras
                            .iter_mut()
                            .find(|c| &c.id == id)
                            .ok_or_else(|| bad(i, format!("no camera '{id}'")))?
                            .sigma_px = Some(*sigma_px);
                    }
                    None => {
                        out.sigma_px = *sigma_px;
                        for c in &mut out.cameras {
                            c.sigma_px = Some(*sigma_px);
                        }
                    }
                }
            }
        }
    }
    Ok(out)
}

//! Design statistics of an adjustment, for the pre-analysis of a planned network
//! (`crate::plan`): the redundancy number of each image coordinate, `r_i = 1 − (A Q Aᵀ)_ii p_i`
//! (its share of the redundancy, 0–1: how much of a blunder in it shows in its residual), and the
//! correlations of the self-calibrated interior parameters with each other and with the images'
//! exterior unknowns, from the cofactors of the final solution.

use serde::{Deserialize, Serialize};

use super::precision::Cofactors;
use crate::photogrammetry::model::bundle::Bundle;
use crate::photogrammetry::model::camera::INTERIOR_NAMES;
use crate::photogrammetry::model::Model;

/// The redundancy of one image observation (its x and y coordinates).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ObservationRedundancy {
    /// Image id.
    pub image: String,
    /// Point name.
    pub point: String,
    /// Redundancy numbers of x and y (dimensionless, 0–1).
    pub redundancy: [f64; 2],
    /// A-priori σ of x and y in mm.
    pub sigma_mm: [f64; 2],
}

/// The correlation of two unknowns of the adjustment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ParameterCorrelation {
    /// The self-calibrated parameter, e.g. `camera cam: c`.
    pub parameter: String,
    /// The other unknown, e.g. `camera cam: x0` or `image S1: m (scale)`.
    pub with: String,
    /// Correlation coefficient, −1–1.
    pub rho: f64,
}

/// The design statistics of one adjustment.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DesignStatistics {
    /// One entry per active image observation, in the bundle's order.
    pub observations: Vec<ObservationRedundancy>,
    /// Every correlation of a self-calibrated interior parameter with another interior
    /// parameter or an exterior unknown, strongest (largest |ρ|) first.
    pub correlations: Vec<ParameterCorrelation>,
}

/// Names of the six exterior unknowns of an image per model (rotation increments first).
fn exterior_names(model: Model) -> [&'static str; 6] {
    match model {
        Model::Orthogonal => [
            "rotation 1",
            "rotation 2",
            "rotation 3",
            "m (scale)",
            "A4",
            "A8",
        ],
        Model::Central => ["rotation 1", "rotation 2", "rotation 3", "X0", "Y0", "Z0"],
    }
}

/// The design statistics of the solved bundle `b` with cofactors `q`; `images`, `points` and
/// `cameras` name the bundle's images, points and cameras in order.
pub fn design_statistics(
    b: &Bundle,
    q: &Cofactors,
    images: &[String],
    points: &[String],
    cameras: &[String],
) -> DesignStatistics {
    let observations = b
        .obs
        .iter()
        .filter(|o| o.active)
        .map(|o| {
            let cam = b.image_camera[o.image];
            let s2 = b.sigma[cam] * b.sigma[cam] / o.prior_weight;
            let aqa = q.predicted_cofactor(b, o);
            ObservationRedundancy {
                image: images[o.image].clone(),
                point: points[o.point].clone(),
                redundancy: [0, 1].map(|c| (1.0 - aqa[(c, c)] / s2).clamp(0.0, 1.0)),
                sigma_mm: [s2.sqrt(); 2],
            }
        })
        .collect();
    let icols = b.interior_columns();
    let names = exterior_names(b.model);
    let interior: Vec<(usize, String)> = icols
        .iter()
        .enumerate()
        .flat_map(|(k, cols)| {
            cols.iter().enumerate().filter_map(move |(p, col)| {
                col.map(|c| (c, format!("camera {}: {}", cameras[k], INTERIOR_NAMES[p])))
            })
        })
        .collect();
    let rho = |a: usize, c: usize| {
        let d = q.qcc[(a, a)] * q.qcc[(c, c)];
        (d > 0.0).then(|| q.qcc[(a, c)] / d.sqrt())
    };
    let mut correlations = Vec::new();
    for (i, (a, name)) in interior.iter().enumerate() {
        for (c, other) in &interior[i + 1..] {
            if let Some(r) = rho(*a, *c) {
                correlations.push(ParameterCorrelation {
                    parameter: name.clone(),
                    with: other.clone(),
                    rho: r,
                });
            }
        }
        for (image, id) in images.iter().enumerate() {
            for (l, lane) in names.iter().enumerate() {
                if let Some(r) = rho(*a, 6 * image + l) {
                    correlations.push(ParameterCorrelation {
                        parameter: name.clone(),
                        with: format!("image {id}: {lane}"),
                        rho: r,
                    });
                }
            }
        }
    }
    correlations.sort_by(|x, y| y.rho.abs().total_cmp(&x.rho.abs()));
    DesignStatistics {
        observations,
        correlations,
    }
}

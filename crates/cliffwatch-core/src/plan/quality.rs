//! What the pre-analysis adds to the precision of the targets: the reliability of the image
//! observations (redundancy numbers, Baarda's smallest detectable blunder), the strongest
//! correlations of the self-calibrated parameters, the intersection angles, and, for the
//! orthogonal model, the conditions under which c cannot be determined — each weakness said in
//! words. Pure functions of the plan and its planned adjustment.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::input::Plan;
use crate::analysis::stats::normal_quantile;
use crate::photogrammetry::statistics::design::{DesignStatistics, ParameterCorrelation};
use crate::photogrammetry::Model;

/// Redundancy number below which an image observation is said to be weakly controlled (a blunder
/// in it shows less than a tenth in its own residual).
pub const LOW_REDUNDANCY: f64 = 0.1;

/// Largest angle between two stations' rays to a target below which its intersection is called
/// weak, degrees: its depth is then several times less precise than its position across the view.
pub const WEAK_INTERSECTION_DEG: f64 = 10.0;

/// Relative depth relief (depth range of the targets along a station's view over their mean
/// distance) below which the orthogonal model cannot determine c from that station: 0.1 %.
pub const FLAT_RELIEF: f64 = 0.001;

/// Largest angle between the viewing axes of a camera's stations below which they are called
/// parallel, degrees.
pub const PARALLEL_VIEWS_DEG: f64 = 2.0;

/// |ρ| of a self-calibrated parameter with another unknown beyond which the report warns.
pub const STRONG_CORRELATION: f64 = 0.95;

/// How many of the strongest correlations the report lists.
pub const CORRELATIONS_LISTED: usize = 10;

/// The reliability of one planned image observation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ObservationReliability {
    /// Station (image) name.
    pub station: String,
    /// Target name.
    pub point: String,
    /// Redundancy numbers of the image x and y coordinates (0–1).
    pub redundancy: [f64; 2],
    /// Smallest detectable blunder of x and y in image mm (Baarda: σ·δ0/√r at the plan's
    /// confidence, two-sided, and power); None where r is zero (a blunder cannot be seen).
    pub mdb_mm: [Option<f64>; 2],
}

/// Baarda's non-centrality δ0 of the one-dimensional test (w-test) at `confidence` (two-sided
/// α = 1 − confidence) and `power`.
pub fn delta0(confidence: f64, power: f64) -> f64 {
    normal_quantile(1.0 - (1.0 - confidence) / 2.0) + normal_quantile(power)
}

/// Each observation's redundancy and smallest detectable blunder, and the warning for weakly
/// controlled ones.
pub fn reliability(
    design: &DesignStatistics,
    confidence: f64,
    power: f64,
    warnings: &mut Vec<String>,
) -> Vec<ObservationReliability> {
    let d0 = delta0(confidence, power);
    let out: Vec<ObservationReliability> = design
        .observations
        .iter()
        .map(|o| ObservationReliability {
            station: o.image.clone(),
            point: o.point.clone(),
            redundancy: o.redundancy,
            mdb_mm: [0, 1].map(|c| {
                (o.redundancy[c] > 1e-9).then(|| o.sigma_mm[c] * d0 / o.redundancy[c].sqrt())
            }),
        })
        .collect();
    let weak: Vec<&ObservationReliability> = out
        .iter()
        .filter(|o| o.redundancy[0].min(o.redundancy[1]) < LOW_REDUNDANCY)
        .collect();
    if !weak.is_empty() {
        let named: Vec<String> = weak
            .iter()
            .take(5)
            .map(|o| {
                format!(
                    "{} in {} (r {:.2})",
                    o.point,
                    o.station,
                    o.redundancy[0].min(o.redundancy[1])
                )
            })
            .collect();
        warnings.push(format!(
            "{} image observation(s) have a redundancy number below {LOW_REDUNDANCY}: {}{}; a \
             blunder in them barely shows in their residuals (more stations seeing those \
             targets strengthen them)",
            weak.len(),
            named.join(", "),
            if weak.len() > 5 { ", …" } else { "" }
        ));
    }
    out
}

/// The strongest correlations (at most [`CORRELATIONS_LISTED`]), and a warning for each
/// self-calibrated c correlated beyond [`STRONG_CORRELATION`].
pub fn strongest_correlations(
    design: &DesignStatistics,
    warnings: &mut Vec<String>,
) -> Vec<ParameterCorrelation> {
    let mut warned = Vec::new();
    for c in &design.correlations {
        if c.rho.abs() > STRONG_CORRELATION
            && c.parameter.ends_with(": c")
            && !warned.contains(&c.parameter)
        {
            warned.push(c.parameter.clone());
            warnings.push(format!(
                "{} correlates with {} at ρ = {:.3} (beyond {STRONG_CORRELATION}): the two are \
                 barely separable, c's σ and the targets' depth suffer",
                c.parameter, c.with, c.rho
            ));
        }
    }
    design
        .correlations
        .iter()
        .take(CORRELATIONS_LISTED)
        .cloned()
        .collect()
}

/// The largest angle (degrees) between two of the rays from `stations` to `xyz`; None with fewer
/// than two stations.
pub fn intersection_deg(plan: &Plan, xyz: [f64; 3], stations: &[String]) -> Option<f64> {
    let rays: Vec<Vector3<f64>> = plan
        .stations
        .iter()
        .filter(|s| stations.contains(&s.name))
        .filter_map(|s| (Vector3::from(s.position) - Vector3::from(xyz)).try_normalize(0.0))
        .collect();
    let mut best: Option<f64> = None;
    for (i, a) in rays.iter().enumerate() {
        for b in &rays[i + 1..] {
            let angle = a.dot(b).clamp(-1.0, 1.0).acos().to_degrees();
            best = Some(best.map_or(angle, |x: f64| x.max(angle)));
        }
    }
    best
}

/// The warning for targets whose intersection angle is below [`WEAK_INTERSECTION_DEG`].
pub fn weak_intersections(angles: &[(String, f64)], warnings: &mut Vec<String>) {
    let weak: Vec<&(String, f64)> = angles
        .iter()
        .filter(|(_, a)| *a < WEAK_INTERSECTION_DEG)
        .collect();
    if weak.is_empty() {
        return;
    }
    let named: Vec<String> = weak
        .iter()
        .take(8)
        .map(|(p, a)| format!("{p} ({a:.1}°)"))
        .collect();
    warnings.push(format!(
        "{} target(s) are intersected at less than {WEAK_INTERSECTION_DEG}° between the \
         widest pair of rays: {}{}; their depth (along the view) is weakly determined — spread \
         the stations further apart",
        weak.len(),
        named.join(", "),
        if weak.len() > 8 { ", …" } else { "" }
    ));
}

/// For the orthogonal model, the conditions under which a self-calibrated c cannot be
/// determined, in words: the orthogonal projection (5)+(9) sees c only through the perspective
/// of the targets' depth differences, so c is not determinable when those differences vanish
/// (the targets lie in a plane across every view of the camera, relief below [`FLAT_RELIEF`] of
/// the distance); when the camera's stations all look the same way (viewing axes within
/// [`PARALLEL_VIEWS_DEG`], no convergence) c rests on that relief alone, which is said too.
pub fn c_determinability(plan: &Plan, seen: &BTreeMap<&str, Vec<[f64; 3]>>) -> Vec<String> {
    let mut warnings = Vec::new();
    if plan.model != Model::Orthogonal {
        return warnings;
    }
    for cam in plan.cameras.iter().filter(|c| c.calibrate_c) {
        let stations: Vec<_> = plan
            .stations
            .iter()
            .filter(|s| s.camera == cam.id)
            .collect();
        if stations.is_empty() {
            continue;
        }
        let mut relief: f64 = 0.0;
        let mut axes = Vec::new();
        for s in &stations {
            let Some(axis) = (Vector3::from(s.aim) - Vector3::from(s.position)).try_normalize(0.0)
            else {
                continue;
            };
            axes.push(axis);
            let depths: Vec<f64> = seen
                .get(s.name.as_str())
                .into_iter()
                .flatten()
                .map(|x| (Vector3::from(*x) - Vector3::from(s.position)).dot(&axis))
                .collect();
            if depths.len() < 2 {
                continue;
            }
            let (lo, hi) = depths
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), d| {
                    (l.min(*d), h.max(*d))
                });
            let mean = depths.iter().sum::<f64>() / depths.len() as f64;
            if mean > 0.0 {
                relief = relief.max((hi - lo) / mean);
            }
        }
        if relief < FLAT_RELIEF {
            warnings.push(format!(
                "camera {}: c is not determinable with the orthogonal model: the targets' depths \
                 along its views differ by at most {:.3} % of their distance (below {} %), and c \
                 shows only through those depth differences (perspective); give the face relief \
                 in the targets, or hold c fixed from a calibration",
                cam.id,
                100.0 * relief,
                100.0 * FLAT_RELIEF
            ));
        }
        let mut spread: f64 = 0.0;
        for (i, a) in axes.iter().enumerate() {
            for b in &axes[i + 1..] {
                spread = spread.max(a.dot(b).clamp(-1.0, 1.0).acos().to_degrees());
            }
        }
        if axes.len() >= 2 && spread < PARALLEL_VIEWS_DEG {
            warnings.push(format!(
                "camera {}: its {} stations' viewing axes converge by only {spread:.2}° (below \
                 {PARALLEL_VIEWS_DEG}°): with the orthogonal model c then rests on the targets' \
                 depth relief alone, and is not determinable without it; converge the views, or \
                 hold c fixed from a calibration",
                cam.id,
                axes.len()
            ));
        }
    }
    warnings
}

//! Identification of a first epoch of a close-range, convergent network through the central model
//! (pure): for views the affine cameras of [`super::first_epoch`] do not fit (near, tilted and
//! rolled views of a flat field, strong lens distortion), as a site on the central model has them.
//!
//! The approximations place a target to a fraction of the targets' spacing, the images far better;
//! so the approximations only start the naming, and the images finish it:
//! 1. each station is resected from its ≥ 4 seeds (snapped to their detections) by collinearity;
//! 2. every known point is projected and named where that is unambiguous: its nearest detection
//!    inside a gate of [`ConvergentOptions::approx_gate`] × the distance to the nearest other
//!    projection, the runner-up at least [`ConvergentOptions::runner_up_ratio`] times as far, and
//!    the point the detection's nearest projection;
//! 3. these names go through the site camera's self-calibrating bundle adjustment with data
//!    snooping: a wrong name is dropped as a blunder, and the lens distortion, the orientations and
//!    the points' coordinates now come from the images;
//! 4. every point is projected again, through the adjusted cameras (an adjusted point with a gate
//!    of a few σ0, a point the adjustment has not placed yet with the gate of step 2), and the
//!    names are made again from scratch (the seeds too: a seed the images contradict refuses the
//!    folder, naming it). Steps 3–4 repeat until the names stop changing.
//!
//! A point is never guessed: a detection that fails the tests is left out and listed.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Vector3;

use super::first_epoch::{snap_seeds, FirstEpoch, FirstEpochError, StationNames, StationView};
use super::identify::{resect_seeds, Identified, Seed};
use super::naming;
use crate::photogrammetry::input::epoch::{
    ApproxInput, CameraInput, ControlInput, ImageInput, ObservationInput,
};
use crate::photogrammetry::{
    adjust, AdjustOptions, Adjustment, Camera, EpochInput, ImageOrientation, Model,
};

/// Options of [`identify_convergent`].
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergentOptions {
    /// Largest distance from a seed to its detection in mm (default 0.1 mm: 10 px of 10 µm).
    pub seed_snap_mm: f64,
    /// Gate of a point placed by its approximation alone, as a fraction of the distance from its
    /// projection to the nearest other projection (default 0.35).
    pub approx_gate: f64,
    /// The runner-up detection (and the runner-up projection of a detection) must lie at least
    /// this many times as far as the match (default 2).
    pub runner_up_ratio: f64,
    /// Gate of an adjusted point in multiples of the adjustment's σ0 (default 10) …
    pub adjusted_gate_sigma0: f64,
    /// … and at least this many mm (default 0.01 mm).
    pub min_adjusted_gate_mm: f64,
    /// Most adjustments (steps 3–4) before the names are taken as they are (default 4).
    pub rounds: usize,
    /// Largest rms misfit of a station's seeds in their resection, as a fraction of the median
    /// spacing of the points on its image, as the seeds' scale has it (default 0.2; lens
    /// distortion and a 1 px hand measurement give
    /// at most 0.04 on DBAT's views, two seeds swapped about 3). A seed on a neighbouring target
    /// may fit; the images contradict it later.
    pub max_seed_misfit: f64,
}

impl Default for ConvergentOptions {
    fn default() -> Self {
        Self {
            seed_snap_mm: 0.1,
            approx_gate: 0.35,
            runner_up_ratio: 2.0,
            adjusted_gate_sigma0: 10.0,
            min_adjusted_gate_mm: 0.01,
            rounds: 4,
            max_seed_misfit: 0.2,
        }
    }
}

/// The parts of the upload form the adjustment of step 3 needs besides the stations.
#[derive(Debug, Clone, Copy)]
pub struct ConvergentSite<'a> {
    /// The epoch's cameras as uploaded (their `calibrate` lists are the site's self-calibration).
    pub cameras: &'a [CameraInput],
    /// Control points (known coordinates with σ); the other known points are approximations.
    pub control: &'a [ControlInput],
    /// The epoch's time (the adjustment's input needs one).
    pub observed_at: &'a str,
}

/// One station's names: point index → detection index.
type Names = BTreeMap<usize, usize>;

/// One station's predictions: (point index, predicted image position in mm, gate in mm).
type Predictions = Vec<(usize, [f64; 2], f64)>;

/// Identifies the detections of `views` (≥ 2 stations, each with ≥ 4 seeds; `cameras[k]` is the
/// camera of `views[k]`) as the `known` points (name → [X, Y, Z] m, site frame: approximations and
/// control) through the central model; see the module's notes. Never guesses.
pub fn identify_convergent(
    views: &[StationView<'_>],
    cameras: &[&Camera],
    known: &BTreeMap<String, [f64; 3]>,
    site: &ConvergentSite<'_>,
    opts: &ConvergentOptions,
) -> Result<FirstEpoch, FirstEpochError> {
    if views.len() < 2 {
        return Err(FirstEpochError::TooFewStations(views.len()));
    }
    if cameras.len() != views.len() {
        return Err(FirstEpochError::Invalid(format!(
            "{} cameras for {} stations",
            cameras.len(),
            views.len()
        )));
    }
    for v in views {
        if let Some(b) = v.blobs_mm.iter().find(|b| !finite2(**b)) {
            return Err(FirstEpochError::Invalid(format!(
                "station {}: detection {b:?} not finite",
                v.station
            )));
        }
    }
    if let Some((n, _)) = known.iter().find(|(_, x)| !x.iter().all(|c| c.is_finite())) {
        return Err(FirstEpochError::Invalid(format!("point {n} not finite")));
    }
    let snapped = snap_seeds(views, known, opts.seed_snap_mm)?;
    let names: Vec<&String> = known.keys().collect();
    let index: BTreeMap<&String, usize> = names.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    // 1–2: resections from the seeds, names from the approximations
    let spacing_m = median_spacing(&known.values().copied().collect::<Vec<_>>());
    let mut current: Vec<Names> = Vec::with_capacity(views.len());
    for ((v, seeds), camera) in views.iter().zip(&snapped).zip(cameras) {
        let (orientation, rms) = resect_seeds(v.seeds, known, camera)
            .map_err(|e| FirstEpochError::SeedsDisagree(format!("station {}: {e}", v.station)))?;
        let predictions = predict(known, &orientation, camera, None, opts);
        let spacing = image_scale(v.seeds, known) * spacing_m;
        if rms > opts.max_seed_misfit * spacing {
            return Err(FirstEpochError::SeedsDisagree(format!(
                "station {}: the seeds {} misfit their resection by {rms:.3} mm rms while the \
                 targets are {spacing:.3} mm apart on the image: a seed is probably measured on \
                 the wrong target, or its approximate coordinates are wrong",
                v.station,
                v.seeds
                    .iter()
                    .map(|s| s.point.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        let mut named = match_predictions(&predictions, v.blobs_mm, opts.runner_up_ratio).0;
        force_seeds(&mut named, seeds, &index);
        current.push(named);
    }
    // 3–4: adjust, name again, until the names hold
    let mut last: Option<(Adjustment, Vec<BTreeSet<usize>>)> = None;
    for _ in 0..opts.rounds.max(1) {
        let adjusted = adjust_names(views, cameras, &current, &names, known, site)?;
        let sigma0_mm = adjusted.report.sigma0_mm;
        let coordinates: BTreeMap<usize, [f64; 3]> = adjusted
            .points
            .iter()
            .filter_map(|p| index.get(&p.name).map(|&i| (i, p.xyz)))
            .collect();
        let gate = (opts.adjusted_gate_sigma0 * sigma0_mm).max(opts.min_adjusted_gate_mm);
        let placed: BTreeMap<String, [f64; 3]> = names
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let xyz = coordinates.get(&i).copied().unwrap_or(known[*n]);
                ((*n).clone(), xyz)
            })
            .collect();
        let gates: Vec<Option<f64>> = (0..names.len())
            .map(|i| coordinates.contains_key(&i).then_some(gate))
            .collect();
        let mut next = Vec::with_capacity(views.len());
        let mut ambiguous = Vec::with_capacity(views.len());
        for (v, camera) in views.iter().zip(cameras) {
            let Some(orientation) = adjusted.orientations.iter().find(|o| o.image == v.station)
            else {
                return Err(FirstEpochError::Adjustment(format!(
                    "station {} has no orientation",
                    v.station
                )));
            };
            let camera = adjusted
                .cameras
                .iter()
                .find(|c| c.id == camera.id)
                .unwrap_or(camera);
            let predictions = predict(&placed, orientation, camera, Some(&gates), opts);
            let (named, amb) = match_predictions(&predictions, v.blobs_mm, opts.runner_up_ratio);
            next.push(named);
            ambiguous.push(amb);
        }
        let settled = next == current;
        current = next;
        last = Some((adjusted, ambiguous));
        if settled {
            break;
        }
    }
    let (adjusted, ambiguous) = last.expect("at least one round");
    check_seeds(views, &snapped, &current, &index, &names)?;
    Ok(report(
        views, &current, &ambiguous, &names, known, &adjusted,
    ))
}

/// `values` are finite.
fn finite2(v: [f64; 2]) -> bool {
    v[0].is_finite() && v[1].is_finite()
}

/// Every seeded detection has its seed's name once the images name the targets: a seed the other
/// stations contradict was measured on the wrong target, and the folder is refused, naming it.
fn check_seeds(
    views: &[StationView<'_>],
    snapped: &[BTreeMap<String, usize>],
    current: &[Names],
    index: &BTreeMap<&String, usize>,
    names: &[&String],
) -> Result<(), FirstEpochError> {
    for ((v, seeds), named) in views.iter().zip(snapped).zip(current) {
        for (point, &blob) in seeds {
            if named.get(&index[point]) == Some(&blob) {
                continue;
            }
            let instead = named
                .iter()
                .find(|(_, b)| **b == blob)
                .map_or("no point".to_string(), |(i, _)| {
                    format!("point {}", names[*i])
                });
            return Err(FirstEpochError::SeedsDisagree(format!(
                "station {}: seed {point} is measured on a target where the other stations place \
                 {instead}: it is probably measured on the wrong target; measure it again",
                v.station
            )));
        }
    }
    Ok(())
}

/// The seeded detections keep their seeds' names (and no other point takes them).
fn force_seeds(
    named: &mut Names,
    seeds: &BTreeMap<String, usize>,
    index: &BTreeMap<&String, usize>,
) {
    for (point, &blob) in seeds {
        let i = index[point];
        named.retain(|p, b| *p == i || *b != blob);
        named.insert(i, blob);
    }
}

/// Predicted image positions (mm, distortion applied) of `points` in front of the camera, each with
/// its gate: `gates[i]` where given (an adjusted point), else the approximation's gate; never more
/// than the approximation's gate.
fn predict(
    points: &BTreeMap<String, [f64; 3]>,
    orientation: &ImageOrientation,
    camera: &Camera,
    gates: Option<&[Option<f64>]>,
    opts: &ConvergentOptions,
) -> Predictions {
    let half = camera.half_sensor_mm();
    let projected: Vec<(usize, [f64; 2])> = points
        .values()
        .enumerate()
        .filter_map(|(i, x)| orientation.project(camera, *x).map(|q| (i, q)))
        .filter(|(_, q)| finite2(*q))
        .collect();
    projected
        .iter()
        .filter(|(_, q)| {
            half.is_none_or(|h| q[0].abs() <= 1.05 * h[0] && q[1].abs() <= 1.05 * h[1])
        })
        .map(|&(i, q)| {
            let spacing = projected
                .iter()
                .filter(|(k, _)| *k != i)
                .map(|(_, p)| (p[0] - q[0]).hypot(p[1] - q[1]))
                .fold(f64::INFINITY, f64::min);
            let wide = opts.approx_gate * spacing;
            let gate = gates.and_then(|g| g[i]).map_or(wide, |g| g.min(wide));
            (i, q, gate)
        })
        .collect()
}

/// Names from predictions: a point takes its nearest detection when it lies inside the gate, the
/// runner-up detection at least `ratio` times as far, and no other prediction within `ratio` times
/// the distance of that detection. Returns the names and the detections inside a gate left out.
fn match_predictions(
    predictions: &Predictions,
    blobs: &[[f64; 2]],
    ratio: f64,
) -> (Names, BTreeSet<usize>) {
    let distance = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    let mut named = Names::new();
    let mut ambiguous = BTreeSet::new();
    for &(i, q, gate) in predictions {
        let mut nearest = (f64::INFINITY, usize::MAX);
        let mut second = f64::INFINITY;
        for (j, b) in blobs.iter().enumerate() {
            let d = distance(q, *b);
            if d < nearest.0 {
                second = nearest.0;
                nearest = (d, j);
            } else if d < second {
                second = d;
            }
        }
        let (d, j) = nearest;
        if d > gate {
            continue;
        }
        let rival = predictions
            .iter()
            .filter(|(k, _, _)| *k != i)
            .map(|(_, p, _)| distance(*p, blobs[j]))
            .fold(f64::INFINITY, f64::min);
        if second >= ratio * d && rival >= ratio * d {
            named.insert(i, j);
        } else {
            ambiguous.insert(j);
        }
    }
    ambiguous.retain(|j| !named.values().any(|b| b == j));
    (named, ambiguous)
}

/// The self-calibrating central adjustment of the names (points named in ≥ 2 stations), with data
/// snooping; the known points not in `site.control` are its approximations.
fn adjust_names(
    views: &[StationView<'_>],
    cameras: &[&Camera],
    current: &[Names],
    names: &[&String],
    known: &BTreeMap<String, [f64; 3]>,
    site: &ConvergentSite<'_>,
) -> Result<Adjustment, FirstEpochError> {
    let mut rays: BTreeMap<usize, usize> = BTreeMap::new();
    for named in current {
        for i in named.keys() {
            *rays.entry(*i).or_default() += 1;
        }
    }
    let images = views
        .iter()
        .zip(cameras)
        .zip(current)
        .map(|((v, camera), named)| ImageInput {
            id: v.station.to_string(),
            camera: camera.id.clone(),
            station: Some(v.station.to_string()),
            observations: named
                .iter()
                .filter(|(i, _)| rays[*i] >= 2)
                .map(|(&i, &j)| ObservationInput {
                    point: names[i].clone(),
                    x_mm: Some(v.blobs_mm[j][0]),
                    y_mm: Some(v.blobs_mm[j][1]),
                    col: None,
                    row: None,
                    sigma_mm: None,
                })
                .collect(),
        })
        .collect();
    let control: BTreeSet<&str> = site.control.iter().map(|c| c.point.as_str()).collect();
    let input = EpochInput {
        observed_at: site.observed_at.to_string(),
        label: None,
        cameras: site.cameras.to_vec(),
        images,
        control: site.control.to_vec(),
        approx: known
            .iter()
            .filter(|(n, _)| !control.contains(n.as_str()))
            .map(|(n, x)| ApproxInput {
                point: n.clone(),
                X: x[0],
                Y: x[1],
                Z: x[2],
            })
            .collect(),
    };
    let options = AdjustOptions {
        model: Model::Central,
        ..AdjustOptions::default()
    };
    adjust(&input, &options).map_err(|e| FirstEpochError::Adjustment(e.to_string()))
}

/// The outcome in the form of [`FirstEpoch`].
fn report(
    views: &[StationView<'_>],
    current: &[Names],
    ambiguous: &[BTreeSet<usize>],
    names: &[&String],
    known: &BTreeMap<String, [f64; 3]>,
    adjusted: &Adjustment,
) -> FirstEpoch {
    let stations: Vec<StationNames> = views
        .iter()
        .zip(current)
        .zip(ambiguous)
        .map(|((v, named), amb)| {
            let mut matched: Vec<Identified> = named
                .iter()
                .map(|(&i, &j)| Identified {
                    point: names[i].clone(),
                    blob: j,
                    x_mm: v.blobs_mm[j][0],
                    y_mm: v.blobs_mm[j][1],
                    offset_mm: 0.0,
                })
                .collect();
            matched.sort_by(|a, b| a.point.cmp(&b.point));
            let taken: BTreeSet<usize> = named.values().copied().collect();
            StationNames {
                station: v.station.to_string(),
                detected: v.blobs_mm.len(),
                matched,
                ambiguous_blobs: amb.iter().copied().collect(),
                unmatched_blobs: (0..v.blobs_mm.len())
                    .filter(|j| !taken.contains(j) && !amb.contains(j))
                    .collect(),
            }
        })
        .collect();
    let named: BTreeSet<usize> = current.iter().flat_map(|n| n.keys().copied()).collect();
    // how far the approximations were from the images' geometry, per coordinate
    let offsets: Vec<f64> = adjusted
        .points
        .iter()
        .filter_map(|p| {
            known
                .get(&p.name)
                .map(|x| (0..3).map(move |k| p.xyz[k] - x[k]))
        })
        .flatten()
        .collect();
    let approx_sigma_m = if offsets.is_empty() {
        0.0
    } else {
        (offsets.iter().map(|d| d * d).sum::<f64>() / offsets.len() as f64).sqrt()
    };
    let spacing_m = median_spacing(&adjusted.points.iter().map(|p| p.xyz).collect::<Vec<_>>());
    FirstEpoch {
        stations,
        tracks: named.len(),
        named: named.iter().map(|&i| names[i].clone()).collect(),
        ambiguous: Vec::new(),
        approx_sigma_m,
        spacing_m,
        max_sigma_m: 0.35 * spacing_m,
        camera_misfit_mm: adjusted.report.sigma0_mm,
    }
}

/// The image scale of a station from its seeds (mm on the image per m on the object): the median
/// over pairs of seeds of their image distance over their object distance.
fn image_scale(seeds: &[Seed], known: &BTreeMap<String, [f64; 3]>) -> f64 {
    let mut ratios = Vec::new();
    for (k, a) in seeds.iter().enumerate() {
        for b in &seeds[k + 1..] {
            let (Some(p), Some(q)) = (known.get(&a.point), known.get(&b.point)) else {
                continue;
            };
            let object =
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            let image = (a.xy_mm[0] - b.xy_mm[0]).hypot(a.xy_mm[1] - b.xy_mm[1]);
            if object > 0.0 {
                ratios.push(image / object);
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    ratios
        .get(ratios.len() / 2)
        .copied()
        .unwrap_or(f64::INFINITY)
}

/// Median distance from a point to its nearest neighbour, m (0 with fewer than 2 points).
fn median_spacing(points: &[[f64; 3]]) -> f64 {
    let points: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(*p)).collect();
    let spacing = naming::median_spacing(&points);
    if spacing.is_finite() {
        spacing
    } else {
        0.0
    }
}

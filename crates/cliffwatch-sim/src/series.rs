//! A simulated monitoring series at the level of image observations (the upload form), with its
//! truth: the long-range cliff of [`super::scenes::long_range`] (28 targets, 5 stations 100–110 m
//! away, 400 mm lens, 10.5 µm pixels, 0.25 px noise) observed epoch after epoch. The targets nearest
//! the face centre form a block that creeps and then accelerates to failure by the inverse-velocity
//! law ([`FailureLaw`]); the targets farthest from it are stable; the rest stay still. Every epoch
//! the cameras are set up again (positions within ± `setup_position_m`, angles within
//! ± `setup_angle_deg`) and the true principal distance drifts within ± `c_drift` (relative); the
//! upload gives the nominal c and asks for its calibration. Only the first epoch carries start
//! values, good to `survey_sigma_m` (later ones start from the site's history, as in the service).
//!
//! Geometry and projection come from [`super::scenes`] ([`long_range`], [`project`]); the sensor is
//! enlarged to 4000 × 3000 pixels so that a camera turned by 1° still sees the whole face.

use std::collections::BTreeMap;

use chrono::{DateTime, Duration, Utc};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use super::monitoring::FailureLaw;
use super::scenes::{long_range, project, LongRangeParams, SceneError, Truth, TruthCamera};
use cliffwatch_core::analysis::{PointConfig, PointRole};
use cliffwatch_core::photogrammetry::input::epoch::{EpochInput, ObservationInput};

/// Parameters of [`image_series`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImageSeriesScenario {
    /// Seed of the geometry (through [`long_range`]) and of every per-epoch draw.
    pub seed: u64,
    /// Number of epochs (the first is the reference).
    pub epochs: usize,
    /// Time between epochs in hours.
    pub interval_hours: f64,
    /// Observation time of the first epoch.
    pub start: DateTime<Utc>,
    /// Kinematics of the block (times in days from the first epoch).
    pub law: FailureLaw,
    /// Direction of the block's movement in the site frame (X along the face, Y up, Z toward the
    /// cameras); need not be normalised.
    pub direction: [f64; 3],
    /// Number of targets on the block (those nearest the face centre).
    pub block_points: usize,
    /// Number of stable targets (those farthest from the face centre).
    pub stable_points: usize,
    /// Half-range of the uniform set-up error of each camera coordinate per epoch, m.
    pub setup_position_m: f64,
    /// Half-range of the uniform set-up error of each camera angle per epoch, degrees.
    pub setup_angle_deg: f64,
    /// Half-range of the uniform relative drift of the true principal distance per epoch.
    pub c_drift: f64,
    /// σ of the first epoch's start values per coordinate, m: they stand for a survey of the
    /// targets. A free network's frame is the similarity onto its start values, so it must be
    /// good: start errors of 0.5 m over a 5 m face would turn and scale every displacement of
    /// the series by several per cent.
    pub survey_sigma_m: f64,
}

impl Default for ImageSeriesScenario {
    /// 40 epochs 12 h apart from 2026-06-01; creep 2 mm/day, acceleration from day 8, failure at
    /// day 20 (12 h after the last epoch, 92 mm by then); block of 5 targets moving down and out
    /// of the face; 10 stable targets; set-up ± 0.2 m and ± 1°; c drift ± 0.2 %; survey σ 2 mm.
    fn default() -> Self {
        ImageSeriesScenario {
            seed: 1,
            epochs: 40,
            interval_hours: 12.0,
            start: DateTime::parse_from_rfc3339("2026-06-01T00:00:00Z")
                .map(|t| t.to_utc())
                .unwrap_or_default(),
            law: FailureLaw {
                creep_mm_per_day: 2.0,
                acceleration_start_days: Some(8.0),
                failure_days: 20.0,
            },
            direction: [0.0, -0.5, 0.866],
            block_points: 5,
            stable_points: 10,
            setup_position_m: 0.2,
            setup_angle_deg: 1.0,
            c_drift: 0.002,
            survey_sigma_m: 0.002,
        }
    }
}

/// A target of the series and its role.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesPoint {
    /// Target name (`T101`, …).
    pub name: String,
    /// `stable` or `monitored` (the contract's roles).
    pub role: String,
    /// `block` for the moving block, None otherwise.
    pub group: Option<String>,
    /// True position at the first epoch, m (site frame).
    pub xyz_m: [f64; 3],
}

/// The truth of one epoch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesEpochTruth {
    /// Observation time.
    pub observed_at: DateTime<Utc>,
    /// True principal distance of this epoch, mm.
    pub c_mm: f64,
    /// True displacement since the first epoch of every target, mm (site frame).
    pub displacement_mm: BTreeMap<String, [f64; 3]>,
    /// True displacement magnitude of the block, mm.
    pub block_displacement_mm: f64,
    /// True velocity of the block, mm/day.
    pub block_velocity_mm_per_day: f64,
}

/// The truth of a whole series (`cliffwatch simulate --scene monitoring-series` writes it as JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesTruth {
    /// The targets.
    pub points: Vec<SeriesPoint>,
    /// Unit direction of the block's movement (site frame).
    pub direction: [f64; 3],
    /// Per epoch, oldest first.
    pub epochs: Vec<SeriesEpochTruth>,
    /// Start of the acceleration (None: creep only).
    pub acceleration_start: Option<DateTime<Utc>>,
    /// True failure time (None: creep only).
    pub failure_at: Option<DateTime<Utc>>,
}

/// A series: one upload per epoch, oldest first, and the truth.
#[derive(Debug, Clone)]
pub struct ImageSeries {
    /// The uploads.
    pub epochs: Vec<EpochInput>,
    /// The truth.
    pub truth: SeriesTruth,
}

impl SeriesTruth {
    /// The analysis' point settings of the series' targets: their roles, and the block's
    /// targets in the group `block` (None: no group) with the direction `direction`.
    pub fn point_configs(
        &self,
        block: Option<&str>,
        direction: Option<[f64; 3]>,
    ) -> Vec<PointConfig> {
        self.points
            .iter()
            .map(|p| {
                let on_block = p.group.is_some();
                PointConfig {
                    name: p.name.clone(),
                    role: if p.role == "stable" {
                        PointRole::Stable
                    } else {
                        PointRole::Monitored
                    },
                    group: block.filter(|_| on_block).map(str::to_string),
                    direction: direction.filter(|_| on_block),
                }
            })
            .collect()
    }
}

fn at(start: DateTime<Utc>, days: f64) -> DateTime<Utc> {
    start + Duration::milliseconds((days * 86_400_000.0).round() as i64)
}

fn uniform(rng: &mut ChaCha8Rng, half: f64) -> f64 {
    if half > 0.0 {
        rng.gen_range(-half..=half)
    } else {
        0.0
    }
}

/// Generates the series (see the module documentation).
pub fn image_series(sc: &ImageSeriesScenario) -> Result<ImageSeries, SceneError> {
    let dir = checked_direction(sc)?;
    let params = LongRangeParams {
        seed: sc.seed,
        width_px: 4000,
        height_px: 3000,
        approx_sigma_m: sc.survey_sigma_m,
        ..LongRangeParams::default()
    };
    if sc.block_points + sc.stable_points > params.n_points {
        return Err(bad(
            "block_points",
            "block and stable targets exceed the 28 targets",
        ));
    }
    let (template, truth) = long_range(&params)?;
    let camera = template
        .cameras
        .first()
        .cloned()
        .ok_or_else(|| bad("cameras", "the scene has no camera"))?;
    let points = series_points(&truth, &params, sc);

    let mut rng = ChaCha8Rng::seed_from_u64(sc.seed);
    rng.set_stream(101);
    let mut epochs = Vec::with_capacity(sc.epochs);
    let mut truths = Vec::with_capacity(sc.epochs);
    for k in 0..sc.epochs {
        let t_days = k as f64 * sc.interval_hours / 24.0;
        let observed_at = at(sc.start, t_days);
        let d_block = sc.law.displacement_mm(t_days);
        let c_true = params.c_mm * (1.0 + uniform(&mut rng, sc.c_drift));
        let interior = [c_true, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut displacement = BTreeMap::new();
        let mut now: Vec<(String, [f64; 3])> = Vec::new();
        for p in &points {
            let d = if p.group.is_some() {
                dir * d_block
            } else {
                Vector3::zeros()
            };
            displacement.insert(p.name.clone(), d.into());
            let x = Vector3::from(p.xyz_m) + d * 1e-3;
            now.push((p.name.clone(), x.into()));
        }
        let mut input = template.clone();
        input.observed_at = observed_at.to_rfc3339_opts(chrono::SecondsFormat::Secs, true);
        input.label = Some(format!(
            "monitoring series seed {} epoch {}",
            sc.seed,
            k + 1
        ));
        if k > 0 {
            input.approx.clear();
        }
        for image in &mut input.images {
            let station = image.station.clone().unwrap_or_else(|| image.id.clone());
            let cam = truth
                .cameras
                .get(&station)
                .ok_or_else(|| bad("station", "no true camera for a station"))?;
            let setup = set_up_again(cam, sc, &mut rng);
            image.observations = photograph(&setup, &interior, &params, &now, &mut rng);
        }
        input.cameras = vec![camera.clone()];
        epochs.push(input);
        truths.push(SeriesEpochTruth {
            observed_at,
            c_mm: c_true,
            displacement_mm: displacement,
            block_displacement_mm: d_block,
            block_velocity_mm_per_day: sc.law.velocity(t_days),
        });
    }
    let accelerating = sc.law.acceleration_start_days;
    Ok(ImageSeries {
        epochs,
        truth: SeriesTruth {
            points,
            direction: dir.into(),
            epochs: truths,
            acceleration_start: accelerating.map(|ta| at(sc.start, ta)),
            failure_at: accelerating.map(|_| at(sc.start, sc.law.failure_days)),
        },
    })
}

fn bad(name: &'static str, reason: &str) -> SceneError {
    SceneError::BadParameter {
        name,
        reason: reason.to_string(),
    }
}

/// The block's unit direction, after checking the epochs and their interval.
fn checked_direction(sc: &ImageSeriesScenario) -> Result<Vector3<f64>, SceneError> {
    if sc.epochs == 0 {
        return Err(bad("epochs", "at least 1"));
    }
    if sc.interval_hours.is_nan() || sc.interval_hours <= 0.0 {
        return Err(bad("interval_hours", "must be positive"));
    }
    let dir = Vector3::from(sc.direction);
    if dir.norm().is_nan() || dir.norm() == 0.0 {
        return Err(bad("direction", "must be a non-zero vector"));
    }
    Ok(dir.normalize())
}

/// The targets with their roles, by distance from the face centre: the block in the middle,
/// the stable ring outside, the others monitored.
fn series_points(
    truth: &Truth,
    params: &LongRangeParams,
    sc: &ImageSeriesScenario,
) -> Vec<SeriesPoint> {
    let centre = [0.0, params.face_height_m / 2.0];
    let mut order: Vec<(&String, f64)> = truth
        .points
        .iter()
        .map(|(n, x)| (n, (x[0] - centre[0]).hypot(x[1] - centre[1])))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1));
    let block: Vec<String> = order[..sc.block_points]
        .iter()
        .map(|(n, _)| n.to_string())
        .collect();
    let stable: Vec<String> = order[order.len() - sc.stable_points..]
        .iter()
        .map(|(n, _)| n.to_string())
        .collect();
    truth
        .points
        .iter()
        .map(|(n, x)| SeriesPoint {
            name: n.clone(),
            role: if stable.contains(n) {
                "stable"
            } else {
                "monitored"
            }
            .into(),
            group: block.contains(n).then(|| "block".to_string()),
            xyz_m: *x,
        })
        .collect()
}

/// This epoch's set-up of a station: its base position `cam` moved (m) and turned (deg) a
/// little, uniformly within the scenario's bounds.
fn set_up_again(cam: &TruthCamera, sc: &ImageSeriesScenario, rng: &mut ChaCha8Rng) -> TruthCamera {
    let xo = [
        cam.xo[0] + uniform(rng, sc.setup_position_m),
        cam.xo[1] + uniform(rng, sc.setup_position_m),
        cam.xo[2] + uniform(rng, sc.setup_position_m),
    ];
    let a = sc.setup_angle_deg.to_radians();
    let turn = Rotation3::from_euler_angles(uniform(rng, a), uniform(rng, a), uniform(rng, a));
    let r0 = Matrix3::from_fn(|i, j| cam.r[i][j]);
    let r1 = turn.matrix() * r0;
    TruthCamera {
        xo,
        r: std::array::from_fn(|i| std::array::from_fn(|j| r1[(i, j)])),
    }
}

/// The pixel observations of the points `now` (name, site-frame m) that fall on the sensor of
/// `params`, seen from `setup` with `interior`, with the scene's image noise.
fn photograph(
    setup: &TruthCamera,
    interior: &[f64; 8],
    params: &LongRangeParams,
    now: &[(String, [f64; 3])],
    rng: &mut ChaCha8Rng,
) -> Vec<ObservationInput> {
    let (pixel, w, h) = (
        params.pixel_size_mm,
        params.width_px as f64,
        params.height_px as f64,
    );
    let mut observations = vec![];
    for (name, x) in now {
        let e: [f64; 2] = [rng.sample(StandardNormal), rng.sample(StandardNormal)];
        let Some(xy) = project(&setup.r, setup.xo, interior, *x) else {
            continue;
        };
        if xy[0].abs() > w * pixel / 2.0 || xy[1].abs() > h * pixel / 2.0 {
            continue;
        }
        observations.push(ObservationInput {
            point: name.clone(),
            x_mm: None,
            y_mm: None,
            col: Some(xy[0] / pixel + (w - 1.0) / 2.0 + params.noise_px * e[0]),
            row: Some((h - 1.0) / 2.0 - xy[1] / pixel + params.noise_px * e[1]),
            sigma_mm: None,
        });
    }
    observations
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roles_truth_and_observations() {
        let s = image_series(&ImageSeriesScenario {
            epochs: 3,
            ..Default::default()
        })
        .unwrap();
        assert_eq!(s.epochs.len(), 3);
        let roles = |r: &str| s.truth.points.iter().filter(|p| p.role == r).count();
        assert_eq!(roles("stable"), 10);
        let block: Vec<_> = s
            .truth
            .points
            .iter()
            .filter(|p| p.group.is_some())
            .collect();
        assert_eq!(block.len(), 5);
        assert!(block.iter().all(|p| p.role == "monitored"));
        // Every target seen in every image of every epoch; start values only in the first.
        for e in &s.epochs {
            assert!(e.images.iter().all(|i| i.observations.len() == 28));
        }
        assert!(!s.epochs[0].approx.is_empty() && s.epochs[1].approx.is_empty());
        // The block moved 2 mm/day × 1 day by the third epoch; stable targets did not.
        let b = &s.truth.epochs[2].displacement_mm[&block[0].name];
        assert!((Vector3::from(*b).norm() - 2.0).abs() < 1e-9);
        let c: Vec<f64> = s.truth.epochs.iter().map(|e| e.c_mm).collect();
        assert!(c.iter().all(|c| (c / 400.0 - 1.0).abs() <= 0.002));
        assert_ne!(c[0], c[1]);
        // The images differ from epoch to epoch beyond the noise (re-set-up cameras).
        let x = |k: usize| s.epochs[k].images[0].observations[0].col.unwrap();
        assert!((x(0) - x(1)).abs() > 5.0);
    }
}

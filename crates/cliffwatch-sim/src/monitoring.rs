//! Simulated monitoring series at the level of adjusted coordinates and covariances: stable points around a
//! moving block, free-network epochs (each with its own small random similarity datum change), a block that
//! creeps and then accelerates to failure by the inverse-velocity law `1/v ∝ (t_f − t)` (Fukuzono 1985).
//! Used by the analysis tests and benchmark; every quantity keeps its truth.

use chrono::{DateTime, Duration, Utc};
use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use cliffwatch_core::analysis::{
    EpochCoordinates, JointCovarianceM2, PointConfig, PointCoordinates, PointRole,
};

/// Parameters of a simulated series.
#[derive(Debug, Clone)]
pub struct MonitoringScenario {
    /// Random seed.
    pub seed: u64,
    /// Stable points (named `R1`, `R2`, …) on a ring around the block.
    pub stable_points: usize,
    /// Points on the moving block (`B1`, …).
    pub block_points: usize,
    /// Other monitored points that do not move (`M1`, …).
    pub other_points: usize,
    /// Number of epochs (the first is the reference).
    pub epochs: usize,
    /// Time between epochs in hours.
    pub interval_hours: f64,
    /// Lateral σ of a coordinate in mm (each point gets 0.7–1.3 × this, the depth direction 2 ×).
    pub sigma_mm: f64,
    /// σ of the per-epoch datum change: translation in mm, rotation in mm over the site radius, scale in
    /// mm over the site radius.
    pub datum_change_mm: f64,
    /// Creep velocity of the block in mm/day (before acceleration); 0 for noise only.
    pub creep_mm_per_day: f64,
    /// Days after the first epoch when the acceleration starts (None: creep only).
    pub acceleration_start_days: Option<f64>,
    /// Failure time in days after the first epoch (must exceed the acceleration start).
    pub failure_days: f64,
    /// Unit direction of the block's movement (site frame).
    pub direction: [f64; 3],
    /// Moves one stable point (index) by this vector (mm) from the given epoch on.
    pub moved_stable: Option<(usize, usize, [f64; 3])>,
    /// Site radius in m (points spread over it).
    pub radius_m: f64,
    /// A tabulated block path with steps and shared errors, in place of the law (the
    /// time-to-failure benchmark, [`super::kinematics`]).
    pub path: Option<MotionPath>,
}

/// A block path and disturbances given epoch by epoch (all in mm, site frame).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MotionPath {
    /// The block's true displacement along `direction` at each epoch (mm; 0 past the end).
    pub block_mm: Vec<f64>,
    /// Steps of single targets: (point index, first epoch, displacement in mm), kept from then on
    /// (a target knocked or set up again).
    pub steps: Vec<(usize, usize, [f64; 3])>,
    /// A measurement error shared by every monitored (not stable) point at each epoch (mm), not
    /// part of the truth: the stable points define the datum, so an error shared with them would
    /// cancel.
    pub shared_mm: Vec<[f64; 3]>,
}

impl Default for MonitoringScenario {
    fn default() -> Self {
        MonitoringScenario {
            seed: 1,
            stable_points: 8,
            block_points: 4,
            other_points: 8,
            epochs: 60,
            interval_hours: 12.0,
            sigma_mm: 0.5,
            datum_change_mm: 2.0,
            creep_mm_per_day: 0.5,
            acceleration_start_days: Some(10.0),
            failure_days: 30.0,
            direction: [0.3, -0.4, -0.866],
            moved_stable: None,
            radius_m: 50.0,
            path: None,
        }
    }
}

/// One simulated epoch with its truth.
#[derive(Debug, Clone)]
pub struct SimulatedEpoch {
    /// The coordinates as an adjustment would give them.
    pub coordinates: EpochCoordinates,
    /// True displacement (mm) of each point since the reference epoch, in the order of the points.
    pub true_displacement_mm: Vec<[f64; 3]>,
    /// True velocity of the block in mm/day at this epoch (a tabulated path's: its mean rate
    /// since the epoch before).
    pub block_velocity_mm_per_day: f64,
}

/// A simulated series.
#[derive(Debug, Clone)]
pub struct MonitoringSeries {
    /// Point configuration (stable ring, block with direction of interest, others).
    pub points: Vec<PointConfig>,
    /// Epochs, oldest first.
    pub epochs: Vec<SimulatedEpoch>,
    /// True failure time (None without acceleration).
    pub failure_at: Option<DateTime<Utc>>,
    /// Time of the first epoch.
    pub start: DateTime<Utc>,
}

/// Kinematics of a block that creeps at a constant velocity and then accelerates to failure by the
/// inverse-velocity law (Fukuzono 1985): after `acceleration_start_days` the velocity is
/// `v(t) = v0 (t_f − t_a)/(t_f − t)`, so `1/v` falls linearly to zero at `t_f`. Times in days from
/// the first epoch, displacements in mm, velocities in mm/day.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FailureLaw {
    /// Creep velocity v0 in mm/day (before acceleration); 0 for nothing moving.
    pub creep_mm_per_day: f64,
    /// Days after the first epoch when the acceleration starts (None: creep only).
    pub acceleration_start_days: Option<f64>,
    /// Failure time t_f in days after the first epoch (must exceed the acceleration start).
    pub failure_days: f64,
}

impl FailureLaw {
    /// Displacement magnitude in mm at `t` days (creep, then the integral of `v0 (t_f − t_a)/(t_f − t)`).
    pub fn displacement_mm(&self, t: f64) -> f64 {
        let v0 = self.creep_mm_per_day;
        match self.acceleration_start_days {
            Some(ta) if t > ta => {
                let tf = self.failure_days;
                let t = t.min(tf - 1e-6);
                v0 * ta + v0 * (tf - ta) * ((tf - ta) / (tf - t)).ln()
            }
            _ => v0 * t,
        }
    }

    /// Velocity in mm/day at `t` days.
    pub fn velocity(&self, t: f64) -> f64 {
        let v0 = self.creep_mm_per_day;
        match self.acceleration_start_days {
            Some(ta) if t > ta => v0 * (self.failure_days - ta) / (self.failure_days - t).max(1e-6),
            _ => v0,
        }
    }
}

impl MonitoringScenario {
    /// The block's kinematics.
    pub fn law(&self) -> FailureLaw {
        FailureLaw {
            creep_mm_per_day: self.creep_mm_per_day,
            acceleration_start_days: self.acceleration_start_days,
            failure_days: self.failure_days,
        }
    }

    /// Block displacement magnitude in mm at `t` days (creep, then 1/v ∝ (t_f − t)).
    pub fn block_displacement_mm(&self, t: f64) -> f64 {
        self.law().displacement_mm(t)
    }

    /// Block velocity in mm/day at `t` days.
    pub fn block_velocity(&self, t: f64) -> f64 {
        self.law().velocity(t)
    }

    /// Generates the series.
    pub fn generate(&self) -> MonitoringSeries {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let start: DateTime<Utc> = DateTime::parse_from_rfc3339("2026-01-01T00:00:00Z")
            .map(|t| t.to_utc())
            .unwrap_or_default();
        let (names, xyz, points) = self.targets(&mut rng);
        let dir = Vector3::from(self.direction).normalize();
        let n_s = self.stable_points;
        let covs = self.point_covariances(names.len(), &mut rng);
        let chols: Vec<Matrix3<f64>> = covs
            .iter()
            .map(|c| c.cholesky().map(|l| l.l()).unwrap_or_else(Matrix3::zeros))
            .collect();
        let n = names.len();
        let mut epochs = vec![];
        for e in 0..self.epochs {
            let t_days = e as f64 * self.interval_hours / 24.0;
            let observed_at =
                start + Duration::milliseconds((t_days * 86_400_000.0).round() as i64);
            let dm = match &self.path {
                Some(p) => p.block_mm.get(e).copied().unwrap_or(0.0),
                None => self.block_displacement_mm(t_days),
            };
            let shared = self
                .path
                .as_ref()
                .and_then(|p| p.shared_mm.get(e))
                .map_or(Vector3::zeros(), |v| Vector3::from(*v));
            let mut gauss = || -> f64 { StandardNormal.sample(&mut rng) };
            let shift = Vector3::new(gauss(), gauss(), gauss()) * self.datum_change_mm;
            let rot =
                Vector3::new(gauss(), gauss(), gauss()) * self.datum_change_mm / self.radius_m;
            let scale = gauss() * self.datum_change_mm / self.radius_m;
            let mut pts = vec![];
            let mut truth = vec![];
            for i in 0..n {
                let mut true_d = Vector3::zeros();
                if names[i].starts_with('B') {
                    true_d = dir * dm;
                }
                if let Some((k, from, v)) = self.moved_stable {
                    if i == k && e >= from {
                        true_d += Vector3::from(v);
                    }
                }
                for &(k, from, v) in self.path.iter().flat_map(|p| &p.steps) {
                    if i == k && e >= from {
                        true_d += Vector3::from(v);
                    }
                }
                let mut noise = chols[i] * Vector3::new(gauss(), gauss(), gauss());
                if i >= n_s {
                    noise += shared;
                }
                let p = xyz[i] - Vector3::new(0.0, 100.0, 20.0);
                let datum = shift + rot.cross(&p) + p * scale;
                let x = xyz[i] + (true_d + noise + datum) * 1e-3;
                pts.push(PointCoordinates {
                    name: names[i].clone(),
                    xyz_m: x.into(),
                    covariance_m2: (covs[i] * 1e-6).into(),
                });
                truth.push(true_d.into());
            }
            epochs.push(SimulatedEpoch {
                coordinates: EpochCoordinates {
                    epoch: e as i64 + 1,
                    observed_at,
                    points: pts,
                    joint: (n_s > 0).then(|| JointCovarianceM2 {
                        points: names[..n_s].to_vec(),
                        matrix_m2: block_diagonal_m2(&covs[..n_s]),
                    }),
                },
                true_displacement_mm: truth,
                block_velocity_mm_per_day: match (&self.path, self.block_points) {
                    (_, 0) => 0.0,
                    // a tabulated path: its rate since the epoch before
                    (Some(p), _) if e > 0 => {
                        let at = |k: usize| p.block_mm.get(k).copied().unwrap_or(0.0);
                        (at(e) - at(e - 1)) * 24.0 / self.interval_hours
                    }
                    (Some(_), _) => 0.0,
                    (None, _) => self.block_velocity(t_days),
                },
            });
        }
        let failure_at = self.acceleration_start_days.map(|_| {
            start + Duration::milliseconds((self.failure_days * 86_400_000.0).round() as i64)
        });
        MonitoringSeries {
            points,
            epochs,
            failure_at,
            start,
        }
    }

    /// The targets' names, true positions (m) and configurations: the stable ring `R…`, the
    /// block `B…` near the centre and the other monitored points `M…`.
    fn targets(&self, rng: &mut ChaCha8Rng) -> (Vec<String>, Vec<Vector3<f64>>, Vec<PointConfig>) {
        let mut names = vec![];
        let mut xyz = vec![];
        let mut points = vec![];
        let n_s = self.stable_points;
        for k in 0..n_s {
            let a = k as f64 / n_s.max(1) as f64 * std::f64::consts::TAU;
            names.push(format!("R{}", k + 1));
            xyz.push(Vector3::new(
                self.radius_m * a.cos(),
                100.0 + 0.3 * self.radius_m * a.sin(),
                20.0 + self.radius_m * a.sin(),
            ));
            points.push(PointConfig {
                name: names[k].clone(),
                role: PointRole::Stable,
                group: Some("reference".into()),
                direction: None,
            });
        }
        for k in 0..self.block_points {
            names.push(format!("B{}", k + 1));
            xyz.push(Vector3::new(
                rng.gen_range(-5.0..5.0),
                100.0 + rng.gen_range(-1.0..1.0),
                20.0 + rng.gen_range(-5.0..5.0),
            ));
            points.push(PointConfig {
                name: names.last().cloned().unwrap_or_default(),
                role: PointRole::Monitored,
                group: Some("block".into()),
                direction: Some(self.direction),
            });
        }
        for k in 0..self.other_points {
            names.push(format!("M{}", k + 1));
            let r = self.radius_m * rng.gen_range(0.2..0.8);
            let a: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
            xyz.push(Vector3::new(
                r * a.cos(),
                100.0 + rng.gen_range(-2.0..2.0),
                20.0 + r * a.sin(),
            ));
            points.push(PointConfig {
                name: names.last().cloned().unwrap_or_default(),
                role: PointRole::Monitored,
                group: None,
                direction: None,
            });
        }
        (names, xyz, points)
    }

    /// Each of `n` points' covariance (mm²): anisotropic, depth (Y, towards the cameras) weaker,
    /// slightly rotated.
    fn point_covariances(&self, n: usize, rng: &mut ChaCha8Rng) -> Vec<Matrix3<f64>> {
        (0..n)
            .map(|_| {
                let s = self.sigma_mm * rng.gen_range(0.7..1.3);
                let d = Matrix3::from_diagonal(&Vector3::new(
                    s * s,
                    4.0 * s * s,
                    s * s * rng.gen_range(0.8..1.5),
                ));
                let r = Rotation3::from_euler_angles(
                    rng.gen_range(-0.3..0.3),
                    rng.gen_range(-0.3..0.3),
                    rng.gen_range(-0.3..0.3),
                );
                r.matrix() * d * r.matrix().transpose()
            })
            .collect()
    }
}

/// The joint covariance (m², row-major 3n × 3n) of points with independent noise of the given
/// covariances (mm²): block diagonal.
fn block_diagonal_m2(covs_mm2: &[Matrix3<f64>]) -> Vec<f64> {
    let n = covs_mm2.len();
    let mut m = vec![0.0; 9 * n * n];
    for (k, cov) in covs_mm2.iter().enumerate() {
        for r in 0..3 {
            for c in 0..3 {
                m[(3 * k + r) * 3 * n + 3 * k + c] = cov[(r, c)] * 1e-6;
            }
        }
    }
    m
}

//! Block motions as real slopes make them, for the time-to-failure benchmark
//! ([`super::ttf_benchmark`]): accelerating creep before a failure by the inverse-velocity law
//! (Fukuzono 1985, `1/v` falling linearly to zero at the failure), and the motions that must not
//! be taken for it: bursts of fast motion that slow down again, targets knocked or set up again
//! (steps), seasonal or thermal cycles, steady creep. Every motion scatters beyond the
//! measurement σ (1–8 × the block's σ along its direction, the scatter of real prism records
//! before a failure, Carlà et al. 2017, *Landslides* 14), and on some days every monitored point
//! shares an error (refraction, a disturbed station).
//!
//! The hourly kinds ([`MotionKind::FailingHourly`], [`MotionKind::BurstHourly`]) are the same
//! motions sampled every hour over the last [`HOURLY_DAYS`] days (the failing ones: before the
//! failure), as an automatic station records a slope once it is watched closely; an hourly
//! campaign is shorter and runs through the day's heat shimmer, so a target's σ is twice the
//! daily one ([`HOURLY_SIGMA_MM`]) and the motion's scatter 1–8 × the block's σ as daily.
//!
//! A case draws its parameters from its seed and gives a [`MonitoringScenario`] with the path
//! tabulated epoch by epoch ([`MotionPath`]); days after the first epoch, displacements in mm.

use std::f64::consts::{PI, TAU};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::monitoring::{MonitoringScenario, MotionPath};

/// Epochs of a series that does not fail (daily).
pub const EPOCHS: usize = 90;
/// Targets on the block.
pub const BLOCK_POINTS: usize = 6;
/// Still monitored targets beside the block.
pub const OTHER_POINTS: usize = 4;
/// Stable targets (the datum).
pub const STABLE_POINTS: usize = 8;
/// Lateral σ of a target's coordinate (mm; depth twice that), as [`MonitoringScenario::sigma_mm`].
pub const SIGMA_MM: f64 = 0.5;
/// Lateral σ of a target's coordinate in an hourly series (mm; depth twice that).
pub const HOURLY_SIGMA_MM: f64 = 1.0;
/// Days an hourly series covers (failing: the last ones before the failure).
pub const HOURLY_DAYS: f64 = 30.0;
/// Probability that an epoch carries an error shared by every monitored point.
pub const SHARED_ERROR_RATE: f64 = 0.1;

/// What the block does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MotionKind {
    /// Creep, then the inverse-velocity law to a failure before the series ends (half of them
    /// with a burst 7–14 days before the failure).
    Failing,
    /// Creep with a burst of 2–6 days at 4–15 × the creep rate that slows down again.
    Burst,
    /// Creep; one block target and one still target step by 4–10 mm.
    Step,
    /// Slow creep with a cycle of 2–6 mm amplitude and a 20–120-day period.
    Cyclic,
    /// Steady creep at 0.2–2 mm/day.
    Creep,
    /// [`MotionKind::Failing`] sampled hourly over the last [`HOURLY_DAYS`] days before the
    /// failure.
    FailingHourly,
    /// [`MotionKind::Burst`] sampled hourly over [`HOURLY_DAYS`] days, the burst starting 10–20
    /// days in.
    BurstHourly,
}

impl MotionKind {
    /// Every kind, the failing one first.
    pub const ALL: [MotionKind; 5] = [
        MotionKind::Failing,
        MotionKind::Burst,
        MotionKind::Step,
        MotionKind::Cyclic,
        MotionKind::Creep,
    ];

    /// The hourly kinds, the failing one first.
    pub const HOURLY: [MotionKind; 2] = [MotionKind::FailingHourly, MotionKind::BurstHourly];

    /// Every kind, daily then hourly.
    pub const EVERY: [MotionKind; 7] = [
        MotionKind::Failing,
        MotionKind::Burst,
        MotionKind::Step,
        MotionKind::Cyclic,
        MotionKind::Creep,
        MotionKind::FailingHourly,
        MotionKind::BurstHourly,
    ];

    /// Whether the block fails.
    pub fn fails(self) -> bool {
        matches!(self, MotionKind::Failing | MotionKind::FailingHourly)
    }

    /// Whether the series is sampled hourly (else daily).
    pub fn hourly(self) -> bool {
        matches!(self, MotionKind::FailingHourly | MotionKind::BurstHourly)
    }

    /// The daily kind whose motion it samples.
    fn motion(self) -> MotionKind {
        match self {
            MotionKind::FailingHourly => MotionKind::Failing,
            MotionKind::BurstHourly => MotionKind::Burst,
            k => k,
        }
    }

    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            MotionKind::Failing => "failing",
            MotionKind::Burst => "burst",
            MotionKind::Step => "step",
            MotionKind::Cyclic => "cyclic",
            MotionKind::Creep => "creep",
            MotionKind::FailingHourly => "failing_hourly",
            MotionKind::BurstHourly => "burst_hourly",
        }
    }
}

/// One simulated series: its kind, seed and drawn parameters.
#[derive(Debug, Clone)]
pub struct MotionCase {
    /// The kind of motion.
    pub kind: MotionKind,
    /// Seed of the draw and of the series' noise.
    pub seed: u64,
    /// Creep rate before any acceleration (mm/day).
    pub creep_mm_per_day: f64,
    /// Scatter of the motion as a multiple of the block's σ along its direction.
    pub scatter: f64,
    /// σ of the scatter (mm).
    pub scatter_mm: f64,
    /// Failure time, days after the first epoch (failing series).
    pub failure_days: Option<f64>,
    /// Onset of the acceleration, days after the first epoch (failing series).
    pub onset_days: Option<f64>,
    /// Unit direction of the block's motion (site frame: X along the face, Y towards the
    /// cameras, Z up).
    pub direction: [f64; 3],
    /// The scenario with the path.
    pub scenario: MonitoringScenario,
}

/// A burst: fast motion over `[start, start + days]` at up to `factor` × the creep rate,
/// `v = v₀ (1 + factor sin²(π (t − start)/days))`, and back to the creep after it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Burst {
    start: f64,
    days: f64,
    factor: f64,
}

impl Burst {
    /// The burst's displacement beyond the creep at `t` days (mm), creep rate `v0`.
    fn extra_mm(&self, v0: f64, t: f64) -> f64 {
        let x = (t - self.start).clamp(0.0, self.days);
        v0 * self.factor * (0.5 * x - self.days / (4.0 * PI) * (TAU * x / self.days).sin())
    }
}

/// σ of the mean of [`BLOCK_POINTS`] targets along `u` (mm): lateral σ `sigma_mm`, depth (Y)
/// twice that, as the scenario draws them on average.
fn block_sigma_along(u: [f64; 3], sigma_mm: f64) -> f64 {
    let var = sigma_mm * sigma_mm * (u[0] * u[0] + 4.0 * u[1] * u[1] + u[2] * u[2]);
    (var / BLOCK_POINTS as f64).sqrt()
}

/// The case of `kind` drawn from `seed`.
pub fn case(kind: MotionKind, seed: u64) -> MotionCase {
    case_with_scatter(kind, seed, None)
}

/// The case of `kind` drawn from `seed`, with the scatter (× the block's σ along its direction)
/// given instead of drawn from 1–8.
pub fn case_with_scatter(kind: MotionKind, seed: u64, scatter: Option<f64>) -> MotionCase {
    case_sampled(kind, seed, scatter, 1.0)
}

/// [`case_with_scatter`], an hourly kind sampled every `spacing_hours` instead (a 6-hourly or
/// 12-hourly station; the same motion, σ and days; daily kinds ignore it).
pub fn case_sampled(
    kind: MotionKind,
    seed: u64,
    scatter: Option<f64>,
    spacing_hours: f64,
) -> MotionCase {
    // An hourly kind draws the motion of its daily kind from the same seed.
    let hourly = kind.hourly();
    let sigma_mm = if hourly { HOURLY_SIGMA_MM } else { SIGMA_MM };
    let kind_drawn = kind;
    let kind = kind.motion();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0005_eed0_f7e5 ^ ((kind as u64) << 40));
    let raw: [f64; 3] = [
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-0.6..0.6),
        rng.gen_range(-1.0..-0.2),
    ];
    let norm = (raw[0] * raw[0] + raw[1] * raw[1] + raw[2] * raw[2]).sqrt();
    let u = [raw[0] / norm, raw[1] / norm, raw[2] / norm];
    let drawn = rng.gen_range(1.0..8.0);
    let scatter = scatter.unwrap_or(drawn);
    let scatter_mm = scatter * block_sigma_along(u, sigma_mm);
    let v0 = match kind {
        MotionKind::Creep => rng.gen_range(0.2..2.0),
        MotionKind::Cyclic => rng.gen_range(0.0..0.5),
        _ => rng.gen_range(0.3..1.0),
    };
    let mut failure_days = None;
    let mut onset_days = None;
    let mut epochs = EPOCHS;
    let mut bursts = vec![];
    let mut cycle = None;
    match kind {
        MotionKind::Failing => {
            let tf: f64 = rng.gen_range(80.0..89.5);
            let ta = tf - rng.gen_range(12.0..25.0);
            failure_days = Some(tf);
            onset_days = Some(ta);
            // Epochs strictly before the failure.
            epochs = (tf.ceil() as usize).min(EPOCHS);
            if seed % 2 == 1 {
                bursts.push(Burst {
                    start: tf - rng.gen_range(10.0..14.0),
                    days: rng.gen_range(2.0..4.0),
                    factor: rng.gen_range(3.0..8.0),
                });
            }
        }
        MotionKind::Burst => {
            bursts.push(Burst {
                start: rng.gen_range(35.0..80.0),
                days: rng.gen_range(2.0..6.0),
                factor: rng.gen_range(4.0..15.0),
            });
        }
        MotionKind::Cyclic => {
            cycle = Some((
                rng.gen_range(2.0..6.0),
                rng.gen_range(20.0..120.0),
                rng.gen_range(0.0..TAU),
            ));
        }
        _ => {}
    }
    // Where the series starts (days on the daily kind's clock) and its epochs' spacing (days).
    let (start, interval) = if hourly {
        let end = match (failure_days, bursts.first()) {
            // The last hour before the failure, at a random phase.
            (Some(tf), _) => tf - rng.gen_range(0.0..1.0) / 24.0,
            (None, Some(b)) => b.start + rng.gen_range(HOURLY_DAYS - 20.0..HOURLY_DAYS - 10.0),
            (None, None) => HOURLY_DAYS,
        };
        (end - HOURLY_DAYS, spacing_hours / 24.0)
    } else {
        (0.0, 1.0)
    };
    if hourly {
        epochs = (HOURLY_DAYS * 24.0 / spacing_hours).round() as usize + 1;
    }
    let law = |t: f64| -> f64 {
        match (onset_days, failure_days) {
            (Some(ta), Some(tf)) if t > ta => {
                let t = t.min(tf - 1e-6);
                v0 * ta + v0 * (tf - ta) * ((tf - ta) / (tf - t)).ln()
            }
            _ => v0 * t,
        }
    };
    let mut gauss = || -> f64 { StandardNormal.sample(&mut rng) };
    let motion = |t: f64| law(t) + bursts.iter().map(|b| b.extra_mm(v0, t)).sum::<f64>();
    let origin = motion(start);
    let mut block_mm = vec![];
    let mut shared_mm = vec![];
    for e in 0..epochs {
        let t = start + e as f64 * interval;
        let mut d = motion(t) - origin;
        if let Some((amp, period, phase)) = cycle {
            d += amp * ((TAU * t / period + phase).sin() - phase.sin());
        }
        // The reference epoch is the origin: no scatter there.
        if e > 0 {
            d += scatter_mm * gauss();
        }
        block_mm.push(d);
        let shared = if e > 0 && gauss().abs() > 1.6449 {
            // P(|z| > 1.645) = 0.1: SHARED_ERROR_RATE
            [
                2.0 * sigma_mm * gauss(),
                4.0 * sigma_mm * gauss(),
                2.0 * sigma_mm * gauss(),
            ]
        } else {
            [0.0; 3]
        };
        shared_mm.push(shared);
    }
    let mut steps = vec![];
    if kind == MotionKind::Step {
        let n_s = STABLE_POINTS;
        let step = |rng: &mut ChaCha8Rng| -> [f64; 3] {
            let size = rng.gen_range(4.0..10.0);
            let a: f64 = rng.gen_range(0.0..TAU);
            [
                size * a.cos(),
                rng.gen_range(-0.5..0.5) * size,
                size * a.sin(),
            ]
        };
        let member = n_s + rng.gen_range(0..BLOCK_POINTS);
        let at = rng.gen_range(30..85);
        steps.push((member, at, step(&mut rng)));
        let other = n_s + BLOCK_POINTS + rng.gen_range(0..OTHER_POINTS);
        let at = rng.gen_range(30..85);
        steps.push((other, at, step(&mut rng)));
    }
    // Onset and failure on the series' own clock (days after its first epoch; an hourly
    // series' onset may lie before it).
    let failure_days = failure_days.map(|tf| tf - start);
    let onset_days = onset_days.map(|ta| ta - start);
    let scenario = MonitoringScenario {
        seed: seed.wrapping_mul(7919).wrapping_add(kind_drawn as u64),
        stable_points: STABLE_POINTS,
        block_points: BLOCK_POINTS,
        other_points: OTHER_POINTS,
        epochs,
        interval_hours: interval * 24.0,
        sigma_mm,
        creep_mm_per_day: v0,
        acceleration_start_days: onset_days,
        failure_days: failure_days.unwrap_or(1e9),
        direction: u,
        path: Some(MotionPath {
            block_mm,
            steps,
            shared_mm,
        }),
        ..MonitoringScenario::default()
    };
    MotionCase {
        kind: kind_drawn,
        seed,
        creep_mm_per_day: v0,
        scatter,
        scatter_mm,
        failure_days,
        onset_days,
        direction: u,
        scenario,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_adds_its_mean_rate_and_then_stops() {
        let b = Burst {
            start: 10.0,
            days: 4.0,
            factor: 8.0,
        };
        assert_eq!(b.extra_mm(0.5, 9.0), 0.0);
        // sin² averages 1/2 over the burst: 0.5 × 8 × 4 / 2 = 8 mm, then no more.
        assert!((b.extra_mm(0.5, 14.0) - 8.0).abs() < 1e-12);
        assert!((b.extra_mm(0.5, 30.0) - 8.0).abs() < 1e-12);
    }

    #[test]
    fn cases_keep_their_kinds_promises() {
        for seed in 0..20 {
            let c = case(MotionKind::Failing, seed);
            let tf = c.failure_days.expect("fails");
            let n = c.scenario.epochs;
            assert!(
                ((n - 1) as f64) < tf && tf <= n as f64,
                "{n} epochs, tf {tf}"
            );
            assert!((1.0..8.0).contains(&c.scatter));
            let creep = case(MotionKind::Creep, seed);
            assert!(creep.failure_days.is_none());
            assert_eq!(creep.scenario.epochs, EPOCHS);
            assert!((0.2..2.0).contains(&creep.creep_mm_per_day));
            let step = case(MotionKind::Step, seed);
            let steps = &step.scenario.path.as_ref().expect("path").steps;
            assert_eq!(steps.len(), 2);
        }
        for seed in 0..20 {
            // Hourly: the last HOURLY_DAYS days before the failure, the last epoch within the
            // hour before it, the same motion as the daily kind of the seed.
            let c = case(MotionKind::FailingHourly, seed);
            let daily = case(MotionKind::Failing, seed);
            let n = c.scenario.epochs;
            assert_eq!(n, 24 * HOURLY_DAYS as usize + 1);
            assert_eq!(c.scenario.interval_hours, 1.0);
            let tf = c.failure_days.expect("fails");
            let last = (n - 1) as f64 / 24.0;
            assert!(last < tf && tf - last <= 1.0 / 24.0, "last {last}, tf {tf}");
            let shift = daily.failure_days.expect("fails") - tf;
            let ta = c.onset_days.expect("onset");
            assert!((daily.onset_days.expect("onset") - shift - ta).abs() < 1e-9);
            assert_eq!(c.creep_mm_per_day, daily.creep_mm_per_day);
            let burst = case(MotionKind::BurstHourly, seed);
            assert_eq!(burst.scenario.epochs, n);
            assert!(burst.failure_days.is_none());
            assert_eq!(burst.scenario.sigma_mm, HOURLY_SIGMA_MM);
        }
        // About one epoch in ten shares an error.
        let shared: usize = (0..20)
            .map(|s| {
                let c = case(MotionKind::Creep, s);
                let p = c.scenario.path.expect("path");
                p.shared_mm.iter().filter(|v| v[0] != 0.0).count()
            })
            .sum();
        let n = 20 * (EPOCHS - 1);
        let rate = shared as f64 / n as f64;
        assert!((0.06..0.14).contains(&rate), "{shared} of {n}");
    }
}

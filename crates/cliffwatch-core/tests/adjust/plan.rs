//! Campaign design (`cliffwatch_core::plan`): the pre-analysis's σ are claims, checked against
//! simulation; dropping a station weakens the network; weak plans are reported, not panicked on.

use cliffwatch_core::analysis::stats::chi2_quantile;
use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, Adjustment};
use cliffwatch_core::plan::{
    planned_epoch, pre_analysis, Plan, PlanError, PlanStation, PlanTarget,
};
use cliffwatch_sim::scenes::{long_range, LongRangeParams, Truth};
use nalgebra::{Matrix3, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The long-range scene of `seed`: 4 stations about 150 m from a 5 m × 3 m face, 16 targets,
/// 400 mm lens, exact image coordinates (no noise, c given exactly).
pub(crate) fn scene(seed: u64) -> (LongRangeParams, Truth) {
    let p = LongRangeParams {
        seed,
        n_points: 16,
        n_stations: 4,
        distance_min_m: 145.0,
        distance_max_m: 155.0,
        c_error: 0.0,
        noise_px: 0.0,
        pixel_observations: false,
        ..LongRangeParams::default()
    };
    let (_, truth) = long_range(&p).expect("scene");
    (p, truth)
}

/// The plan of a scene: its cameras aimed exactly as in the truth, its targets at their true
/// coordinates, four of them known (the simulator's, shared with its `plan_agreement`).
pub(crate) use cliffwatch_sim::plan_agreement::plan_of;
// σ of one image coordinate in the plans, pixels.
use cliffwatch_sim::plan_agreement::SIGMA_PX;

/// The plan's exact image coordinates are the simulator's (noise-free, mm) to 1e-9 mm: the
/// stations' rotations from position, aim and up reproduce the truth; adjusted, they leave
/// σ0 below 1e-7 mm (the premise of the pre-analysis).
#[test]
fn plan_projects_as_the_simulator_does() {
    let (p, truth) = scene(3);
    let (sim, _) = long_range(&p).expect("scene");
    let planned = planned_epoch(&plan_of(&p, &truth)).expect("planned epoch");
    let mut compared = 0;
    for image in &sim.images {
        let mine = planned
            .epoch
            .images
            .iter()
            .find(|i| i.id == image.id)
            .expect("same image");
        for o in &image.observations {
            let m = mine
                .observations
                .iter()
                .find(|m| m.point == o.point)
                .expect("same observation");
            let dx = m.x_mm.unwrap() - o.x_mm.unwrap();
            let dy = m.y_mm.unwrap() - o.y_mm.unwrap();
            assert!(
                dx.abs() < 1e-9 && dy.abs() < 1e-9,
                "{} {}: {dx} {dy}",
                image.id,
                o.point
            );
            compared += 1;
        }
    }
    assert!(compared >= 50, "{compared}");
    // Zero residuals: the noise-free epoch fits the orthogonal model exactly.
    let adjusted = adjust(&planned.epoch, &AdjustOptions::default()).expect("adjusts");
    assert!(
        adjusted.report.sigma0_mm < 1e-7,
        "{}",
        adjusted.report.sigma0_mm
    );
}

/// One simulated epoch of a plan: its exact image coordinates with Gaussian noise of the planned
/// σ (0.25 px of `pixel_size_mm`), its known coordinates with noise of `known_sigma_m`, adjusted
/// with c started 1 % off.
fn simulated_epoch(plan: &Plan, pixel_size_mm: f64, rng: &mut ChaCha8Rng) -> Adjustment {
    let mut epoch = planned_epoch(plan).expect("planned").epoch;
    // c given 1 % off, as a lens's nominal value would be: the adjustment estimates it.
    epoch.cameras[0].c_mm *= 1.01;
    let image_noise = Normal::new(0.0, SIGMA_PX * pixel_size_mm).unwrap();
    for image in &mut epoch.images {
        for o in &mut image.observations {
            *o.x_mm.as_mut().unwrap() += image_noise.sample(rng);
            *o.y_mm.as_mut().unwrap() += image_noise.sample(rng);
        }
    }
    let control_noise = Normal::new(0.0, plan.known_sigma_m).unwrap();
    for c in &mut epoch.control {
        c.X += control_noise.sample(rng);
        c.Y += control_noise.sample(rng);
        c.Z += control_noise.sample(rng);
    }
    adjust(&epoch, &AdjustOptions::default()).expect("adjusts")
}

/// Statistics are claims: over 12 seeds of the long-range scene (4 stations at ≈ 150 m, 16
/// targets, 4 known with σ 1 mm, c self-calibrated), Gaussian noise of the planned σ on the
/// image coordinates (0.25 px) and on the known coordinates (1 mm), adjusted as an epoch; the rms
/// of (error / predicted σ) per axis over all targets and seeds must lie in [0.8, 1.25]; that of
/// c's error / predicted σc over the 12 seeds in [0.45, 1.6] (the 99.9 % range of the rms of 12
/// standard normal values).
#[test]
fn plan_sigma_matches_simulation() {
    let mut sum = [0.0f64; 3];
    let mut n = 0usize;
    let mut c_sum = 0.0;
    for seed in 1..=12u64 {
        let (p, truth) = scene(seed);
        let plan = plan_of(&p, &truth);
        let report = pre_analysis(&plan).expect("pre-analysis");
        assert!(
            report.warnings.iter().all(|w| !w.contains("station(s)")),
            "{:?}",
            report.warnings
        );
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
        let adjusted = simulated_epoch(&plan, p.pixel_size_mm, &mut rng);
        let c_error = adjusted.report.cameras[0].c_mm - p.c_mm;
        c_sum += (c_error / report.sigma_c_mm.unwrap()).powi(2);
        for t in &report.targets {
            let s = t.sigma_mm.expect("measured");
            let est = adjusted.point(&t.point).expect("adjusted").xyz;
            let tru = truth.points[&t.point];
            for (k, sigma) in [s.x, s.y, s.z].into_iter().enumerate() {
                let e = (est[k] - tru[k]) * 1e3 / sigma;
                sum[k] += e * e;
            }
            n += 1;
        }
    }
    let rms = sum.map(|s| (s / n as f64).sqrt());
    eprintln!("plan: rms of error/σ (x, y, z) over {n} targets: {rms:?}");
    for (axis, r) in ["x", "y", "z"].iter().zip(rms) {
        assert!((0.8..=1.25).contains(&r), "{axis}: rms of error/σ {r}");
    }
    let c_rms = (c_sum / 12.0).sqrt();
    eprintln!("plan: rms of (c error)/σc over 12 seeds: {c_rms}");
    assert!((0.45..=1.6).contains(&c_rms), "c: rms of error/σ {c_rms}");
}

/// The MDD is a claim too: a target moved by its predicted `mdd_normal_mm` along the face normal
/// between two simulated epochs (each with noise as planned, the 2nd with the target moved) is
/// detected by the single-point test `dᵀ(2Σ)⁻¹d > χ²(3; 0.95)` at the predicted power, 80 %:
/// over 10 seeds × 20 pairs the detection rate must lie in [0.72, 0.88] (± 2.8 binomial σ).
#[test]
fn plan_mdd_is_detected_at_the_stated_power() {
    let critical = chi2_quantile(0.95, 3.0);
    let (mut detected, mut trials) = (0usize, 0usize);
    for seed in 1..=10u64 {
        let (p, truth) = scene(seed);
        let plan = plan_of(&p, &truth);
        let report = pre_analysis(&plan).expect("pre-analysis");
        let t = report.targets.iter().find(|t| t.point == "T108").unwrap();
        let cov = Matrix3::from_fn(|i, j| t.covariance_mm2.unwrap()[i][j]);
        let inverse = (cov * 2.0).try_inverse().expect("invertible");
        let n = Vector3::from(report.face_normal);
        let mdd = t.mdd_normal_mm.unwrap();
        let mut moved = plan.clone();
        let target = moved
            .targets
            .iter_mut()
            .find(|x| x.point == "T108")
            .unwrap();
        for k in 0..3 {
            target.xyz[k] += mdd * 1e-3 * n[k];
        }
        let mut rng = ChaCha8Rng::seed_from_u64(5000 + seed);
        for _ in 0..20 {
            let a = simulated_epoch(&plan, p.pixel_size_mm, &mut rng);
            let b = simulated_epoch(&moved, p.pixel_size_mm, &mut rng);
            let (xa, xb) = (a.point("T108").unwrap().xyz, b.point("T108").unwrap().xyz);
            let d = Vector3::from_fn(|k, _| (xb[k] - xa[k]) * 1e3);
            if (d.transpose() * inverse * d)[(0, 0)] > critical {
                detected += 1;
            }
            trials += 1;
        }
    }
    let rate = detected as f64 / trials as f64;
    eprintln!(
        "plan: a displacement of the predicted MDD detected in {detected}/{trials} = {rate:.3}"
    );
    assert!((0.72..=0.88).contains(&rate), "detection rate {rate}");
}

/// Dropping a station never improves a target's predicted σ, and worsens some by more than 5 %;
/// the MDDs follow.
#[test]
fn plan_dropping_a_station_raises_sigma() {
    let (p, truth) = scene(5);
    let full = plan_of(&p, &truth);
    let mut fewer = full.clone();
    fewer.stations.remove(1);
    let a = pre_analysis(&full).expect("full");
    let b = pre_analysis(&fewer).expect("fewer");
    let norm = |s: cliffwatch_core::plan::SigmaXyz| (s.x * s.x + s.y * s.y + s.z * s.z).sqrt();
    let mut worse = 0;
    for (ta, tb) in a.targets.iter().zip(&b.targets) {
        let (sa, sb) = (norm(ta.sigma_mm.unwrap()), norm(tb.sigma_mm.unwrap()));
        assert!(sb >= sa * (1.0 - 1e-6), "{}: {sa} → {sb}", ta.point);
        assert!(tb.mdd_3d_mm.unwrap() >= ta.mdd_3d_mm.unwrap() * (1.0 - 1e-6));
        if sb > 1.05 * sa {
            worse += 1;
        }
        assert_eq!(tb.cameras + 1, ta.cameras, "{}", ta.point);
    }
    assert!(worse > 0);
    assert!(b.sigma_c_mm.unwrap() > a.sigma_c_mm.unwrap());
}

/// c is said to be weakly determined exactly when its σ exceeds 1 % of c: a flat face (5 cm of
/// relief) at 150 m gets the warning, and the warning's absence matches the figure.
#[test]
fn plan_warns_when_c_is_weakly_determined() {
    use cliffwatch_core::plan::WEAK_C_RELATIVE_SIGMA;
    let (p, mut truth) = scene(4);
    for (_, xyz) in truth.points.iter_mut() {
        xyz[2] *= 0.05;
    }
    for flat in [false, true] {
        let plan = if flat {
            plan_of(&p, &truth)
        } else {
            plan_of(&p, &scene(4).1)
        };
        let report = pre_analysis(&plan).expect("pre-analysis");
        let relative = report.sigma_c_mm.unwrap() / p.c_mm;
        let warned = report
            .warnings
            .iter()
            .any(|w| w.contains("c is weakly determined"));
        assert_eq!(
            warned,
            relative > WEAK_C_RELATIVE_SIGMA,
            "{relative}: {:?}",
            report.warnings
        );
        if flat {
            assert!(warned, "{relative}");
        }
    }
}

/// A target seen by one station, and one behind every station, are reported as such (no σ, a
/// warning naming them); a station naming an unknown camera is an error naming it.
#[test]
fn plan_reports_targets_seen_by_fewer_than_two_stations() {
    let (p, truth) = scene(2);
    let mut plan = plan_of(&p, &truth);
    plan.targets.push(PlanTarget {
        point: "LONE".into(),
        xyz: [40.0, 1.5, 0.5],
        known: false,
        sigma_m: None,
    });
    plan.targets.push(PlanTarget {
        point: "BEHIND".into(),
        xyz: [0.0, 1.5, 400.0],
        known: false,
        sigma_m: None,
    });
    plan.stations.push(PlanStation {
        name: "S9".into(),
        camera: "cam".into(),
        position: [40.0, 1.5, 150.0],
        aim: [40.0, 1.5, 0.5],
        up: Some([0.0, 1.0, 0.0]),
        sees: None,
    });
    let report = pre_analysis(&plan).expect("pre-analysis");
    let lone = report.targets.iter().find(|t| t.point == "LONE").unwrap();
    assert_eq!(lone.cameras, 1);
    assert!(lone.sigma_mm.is_none() && lone.mdd_3d_mm.is_none());
    let behind = report.targets.iter().find(|t| t.point == "BEHIND").unwrap();
    assert_eq!(behind.cameras, 0);
    assert!(report.warnings.iter().any(|w| w.contains("LONE")));
    assert!(report.warnings.iter().any(|w| w.contains("BEHIND")));
    assert!(
        report
            .targets
            .iter()
            .filter(|t| t.sigma_mm.is_some())
            .count()
            == 16
    );

    plan.stations[0].camera = "nikon".into();
    let err = pre_analysis(&plan).unwrap_err();
    assert!(matches!(err, PlanError::UnknownCamera { .. }), "{err}");
    assert!(err.to_string().contains("nikon"));
}

/// The predicted σ of c at long range (4 stations at ≈ 150 m, σc ≈ 7 % of c): the adjustment's
/// weak prior on c (10 % of the given c) carries about half of c's information, and every epoch
/// gives the same c, so ĉ scatters from epoch to epoch by the predicted `sigma_c_repeat_mm`, not
/// by σc (which counts the prior as scatter). Over 4 geometries × 50 simulated epochs the rms of
/// (ĉ − c)/σc_repeat per geometry lies in [0.7, 1.3] (± 3 sampling σ of an rms of 50) and pooled
/// in [0.85, 1.2]; the rms over σc stays conservative by √(1 − share), in [0.55, 0.9] pooled.
#[test]
fn plan_sigma_c_repeat_matches_simulation_at_long_range() {
    let (mut all, mut pooled, mut pooled_c) = (Vec::new(), 0.0, 0.0);
    for seed in 1..=4u64 {
        let (p, truth) = scene(seed);
        let plan = plan_of(&p, &truth);
        let report = pre_analysis(&plan).expect("pre-analysis");
        let sigma_c = report.sigma_c_mm.unwrap();
        let repeat = report.interior[0].sigma_c_repeat_mm.unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(77 + seed);
        let (mut sum, mut sum_c) = (0.0, 0.0);
        for _ in 0..50 {
            let a = simulated_epoch(&plan, p.pixel_size_mm, &mut rng);
            let e = a.report.cameras[0].c_mm - p.c_mm;
            sum += (e / repeat).powi(2);
            sum_c += (e / sigma_c).powi(2);
        }
        pooled += sum;
        pooled_c += sum_c;
        all.push(((sum / 50.0).sqrt(), repeat, sigma_c));
    }
    let (pooled, pooled_c) = ((pooled / 200.0).sqrt(), (pooled_c / 200.0).sqrt());
    eprintln!(
        "plan: rms of (c error)/σc_repeat, σc_repeat and σc (mm) per geometry: {all:?}; pooled \
         {pooled:.3}, over σc {pooled_c:.3}"
    );
    for (rms, repeat, sigma_c) in all {
        assert!(
            (0.7..=1.3).contains(&rms),
            "rms {rms} at σc_repeat {repeat} mm (σc {sigma_c} mm)"
        );
    }
    assert!((0.85..=1.2).contains(&pooled), "{pooled}");
    assert!((0.55..=0.9).contains(&pooled_c), "{pooled_c}");
}

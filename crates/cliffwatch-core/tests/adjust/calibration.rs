//! Monte-Carlo calibration of the reported precision (issue 12): simulated long-range epochs of a
//! still cliff (cameras set up again every epoch, c drifting and self-calibrated), the a-priori σ
//! right, 30 % optimistic and 30 % pessimistic. Checks, per case:
//! - rms of (error / reported σ) per axis in the free-network datum, after a similarity onto the
//!   truth on all points, within 0.9–1.06 of its expected value `√mean((SΣSᵀ)_kk / Σ_kk)` from the
//!   reported joint covariance Σ (1 for the inner-constraint datum, where SΣSᵀ = Σ; √(1 − 7/(3n))
//!   would hold only for a covariance that still carried the 7 datum components);
//! - rms of (displacement / its σ) per axis in the stable-point datum of
//!   [`cliffwatch_core::analysis::analyse_epoch`] (points outside the datum, joint covariance of all
//!   points) within 0.9–1.06 of 1; the same with the joint covariance of the stable points only
//!   (today's service) is printed, not asserted: it is 8 % optimistic in depth (docs/accuracy.md);
//! - rms of (translation / its σ) per axis of the 6-point block (`analysis::rigid_body`, estimated
//!   with the joint covariance of its points) within 0.85–1.12 of 1 (180 block-epochs per case);
//!   the per-point weighting that ignores the cross-covariances is printed beside it (it is
//!   ~1.2 / 1.2 / 1.5: the datum's and the reference epoch's errors are common to the points);
//! - false drops at most 1.5 α per observed coordinate (no blunders are simulated);
//! - σ0 within ±5 % of the simulated noise.
//!
//! Run with `cargo test --release --test adjust calibration -- --nocapture` for the table.

use crate::support;

use chrono::{DateTime, Utc};
use cliffwatch_core::analysis::rigid_body::{estimate_block, BlockPoint};
use cliffwatch_core::analysis::{
    analyse_epoch, AnalysisConfig, EpochCoordinates, GroupConfig, GroupKind, History, PointConfig,
    PointRole,
};
use cliffwatch_core::photogrammetry::adjust::report::VarianceModel;
use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, Adjustment, JointCovariance};
use cliffwatch_sim::monitoring::FailureLaw;
use cliffwatch_sim::scenes::Truth;
use cliffwatch_sim::series::{image_series, ImageSeriesScenario};
use nalgebra::DMatrix;

/// Simulated image noise: 0.25 px of 10.5 µm, in mm.
const NOISE_MM: f64 = 0.25 * 0.0105;
/// Series (seeds) per case.
const SERIES: u64 = 60;
/// Epochs per series (the first is the displacement reference).
const EPOCHS: usize = 4;
/// Two-sided level of the snooping (|w| > 3.29).
const ALPHA: f64 = 0.001;

/// Sums of one case.
#[derive(Default)]
struct Tally {
    free: [Vec<f64>; 3],
    free_expected: [Vec<f64>; 3],
    disp: [Vec<f64>; 3],
    disp_stable_joint: [Vec<f64>; 3],
    block: [Vec<f64>; 3],
    block_per_point: [Vec<f64>; 3],
    coordinates: usize,
    false_drops: usize,
    sigma0: Vec<f64>,
    a_posteriori: usize,
    epochs: usize,
}

use crate::support::adjust::rms;

/// Errors of the adjusted points against the truth after a similarity on all points, divided by σ;
/// and, per coordinate, the expected square of that ratio from the reported joint covariance Σ of
/// all points: `(S Σ Sᵀ)_kk / Σ_kk` with `S = I − G (GᵀG)⁻¹ Gᵀ` the projection of the similarity
/// fit (7 columns: translations, rotations and scale about the centroid).
fn free_network(adj: &Adjustment, truth: &Truth, t: &mut Tally) {
    let e = support::adjust::normalized_errors(adj, truth);
    for (k, x) in e.iter().enumerate() {
        t.free[k % 3].push(*x);
    }
    let joint = adj.joint_covariance.as_ref().expect("joint covariance");
    let n = joint.points.len();
    let d = 3 * n;
    let xyz: Vec<[f64; 3]> = joint
        .points
        .iter()
        .map(|p| adj.point(p).expect("point").xyz)
        .collect();
    let mut c = [0.0; 3];
    for x in &xyz {
        for k in 0..3 {
            c[k] += x[k] / n as f64;
        }
    }
    let g = DMatrix::from_fn(d, 7, |r, col| {
        let (i, k) = (r / 3, r % 3);
        let x = [xyz[i][0] - c[0], xyz[i][1] - c[1], xyz[i][2] - c[2]];
        match col {
            0..=2 => f64::from(u8::from(col == k)),
            // Small rotations about X, Y, Z: ω × x.
            3 => [0.0, -x[2], x[1]][k],
            4 => [x[2], 0.0, -x[0]][k],
            5 => [-x[1], x[0], 0.0][k],
            _ => x[k],
        }
    });
    let gtg = (g.transpose() * &g).try_inverse().expect("regular GᵀG");
    let s = DMatrix::identity(d, d) - &g * gtg * g.transpose();
    let sigma = DMatrix::from_row_slice(d, d, &joint.matrix_m2);
    let projected = &s * &sigma * s.transpose();
    for r in 0..d {
        t.free_expected[r % 3].push(projected[(r, r)] / sigma[(r, r)]);
    }
}

/// The adjustment with its joint covariance cut down to `names`.
fn restrict(adj: &Adjustment, names: &[String]) -> Adjustment {
    let mut out = adj.clone();
    let full = adj.joint_covariance.as_ref().expect("joint covariance");
    let idx: Vec<usize> = names
        .iter()
        .filter_map(|n| full.points.iter().position(|p| p == n))
        .collect();
    let d = 3 * idx.len();
    let mut m = vec![0.0; d * d];
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            for r in 0..3 {
                for c in 0..3 {
                    m[(3 * a + r) * d + 3 * b + c] = full.get(3 * i + r, 3 * j + c);
                }
            }
        }
    }
    out.joint_covariance = Some(JointCovariance {
        points: idx.iter().map(|&i| full.points[i].clone()).collect(),
        matrix_m2: m,
    });
    out
}

fn run_case(sigma_factor: f64) -> Tally {
    let mut t = Tally::default();
    for seed in 1..=SERIES {
        let sc = ImageSeriesScenario {
            seed: 1000 + seed,
            epochs: EPOCHS,
            interval_hours: 24.0,
            law: FailureLaw {
                creep_mm_per_day: 0.0,
                acceleration_start_days: None,
                failure_days: 1000.0,
            },
            ..ImageSeriesScenario::default()
        };
        let series = image_series(&sc).expect("series");
        let points: Vec<PointConfig> = series.truth.point_configs(Some("block"), None);
        let stable: Vec<String> = points
            .iter()
            .filter(|p| p.role == PointRole::Stable)
            .map(|p| p.name.clone())
            .collect();
        let group = points
            .iter()
            .find_map(|p| p.group.clone())
            .expect("the scene declares a block");
        let config = AnalysisConfig {
            groups: vec![GroupConfig {
                name: group.clone(),
                kind: GroupKind::Block,
                direction: None,
                points: vec![],
                process_noise: None,
            }],
            ..AnalysisConfig::default()
        };
        let reference_xyz: std::collections::HashMap<String, [f64; 3]> = series
            .truth
            .points
            .iter()
            .map(|p| (p.name.clone(), p.xyz_m))
            .collect();
        let mut options = AdjustOptions {
            joint_covariance_of: points.iter().map(|p| p.name.clone()).collect(),
            ..AdjustOptions::default()
        };
        let mut reference = None;
        for (k, epoch) in series.epochs.iter().enumerate() {
            let mut epoch = epoch.clone();
            for c in epoch.cameras.iter_mut() {
                c.sigma_mm = Some(NOISE_MM * sigma_factor);
            }
            let adj = adjust(&epoch, &options).expect("adjustment");
            // Later epochs start from the latest coordinates, as the service does.
            options.prior = adj.points.iter().map(|p| (p.name.clone(), p.xyz)).collect();
            let truth = Truth {
                points: series
                    .truth
                    .points
                    .iter()
                    .map(|p| (p.name.clone(), p.xyz_m))
                    .collect(),
                cameras: Default::default(),
                c_mm: series.truth.epochs[k].c_mm,
                interior: None,
            };
            free_network(&adj, &truth, &mut t);
            t.coordinates += 2 * adj.report.residuals.len();
            t.false_drops += adj.report.dropped.len();
            t.sigma0.push(adj.report.sigma0_mm / NOISE_MM);
            t.a_posteriori += usize::from(adj.report.variance_model == VarianceModel::APosteriori);
            t.epochs += 1;
            let at: DateTime<Utc> = series.truth.epochs[k].observed_at;
            // With the joint covariance of all points, and of the stable points only (today's
            // service: the cross-covariances of the other points with the datum are then zero).
            let coords = [
                EpochCoordinates::from_adjustment(k as i64, at, &adj),
                EpochCoordinates::from_adjustment(k as i64, at, &restrict(&adj, &stable)),
            ];
            match &reference {
                None => reference = Some(coords),
                Some(r) => {
                    for (v, (r, c)) in r.iter().zip(&coords).enumerate() {
                        let a = analyse_epoch(r, c, &points, &History::new(), &config)
                            .expect("analysis");
                        if v == 0 {
                            block_errors(&a, &group, &reference_xyz, &mut t);
                        }
                        for p in a.points.iter().filter(|p| !p.in_datum) {
                            let d = [p.record.dx_mm, p.record.dy_mm, p.record.dz_mm];
                            for (i, x) in d.iter().enumerate() {
                                let z = x / p.covariance_mm2[i][i].sqrt();
                                if v == 0 {
                                    t.disp[i].push(z);
                                } else {
                                    t.disp_stable_joint[i].push(z);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    t
}

/// The still block's translation (its error) over its σ, per axis: as analysed (joint
/// covariance of the members) and re-estimated from the members' own covariances alone.
fn block_errors(
    a: &cliffwatch_core::analysis::EpochAnalysis,
    group: &str,
    xyz: &std::collections::HashMap<String, [f64; 3]>,
    t: &mut Tally,
) {
    let b = a
        .blocks
        .iter()
        .find(|b| b.group == group)
        .expect("block analysed");
    let m = b.motion.as_ref().expect("block motion");
    let members: Vec<BlockPoint> = b
        .points
        .iter()
        .map(|name| {
            let p = a.point(name).expect("member analysed");
            BlockPoint {
                name: name.clone(),
                xyz_m: xyz[name],
                d_mm: [p.record.dx_mm, p.record.dy_mm, p.record.dz_mm],
                cov_mm2: p.covariance_mm2,
            }
        })
        .collect();
    let naive = estimate_block(&members, 0.99).expect("per-point block");
    for i in 0..3 {
        t.block[i].push(m.translation_mm[i] / m.covariance_mm2[i][i].sqrt());
        t.block_per_point[i].push(naive.translation_mm[i] / naive.covariance_mm2[i][i].sqrt());
    }
}

#[test]
fn reported_precision_is_calibrated() {
    let started = std::time::Instant::now();
    let mut failures = Vec::new();
    println!(
        "| case | datum | X | Y | Z | expected | false drops (allowed) | σ0 / noise | τ test |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (name, f) in [
        ("σ right", 1.0),
        ("σ 30 % optimistic", 1.0 / 1.3),
        ("σ 30 % pessimistic", 1.3),
    ] {
        let t = run_case(f);
        let sigma0 = t.sigma0.iter().sum::<f64>() / t.sigma0.len() as f64;
        let allowed = 1.5 * ALPHA * t.coordinates as f64;
        let expected: Vec<f64> = t
            .free_expected
            .iter()
            .map(|v| (v.iter().sum::<f64>() / v.len() as f64).sqrt())
            .collect();
        let free: Vec<f64> = t.free.iter().map(|v| rms(v)).collect();
        let disp: Vec<f64> = t.disp.iter().map(|v| rms(v)).collect();
        let disp_stable: Vec<f64> = t.disp_stable_joint.iter().map(|v| rms(v)).collect();
        println!(
            "| {name} | free network ({} pt-epochs) | {:.3} | {:.3} | {:.3} | {:.3} / {:.3} / {:.3} | {} ({allowed:.1}) | {sigma0:.3} | {}/{} |",
            t.free[0].len(), free[0], free[1], free[2], expected[0], expected[1], expected[2], t.false_drops, t.a_posteriori, t.epochs
        );
        println!(
            "| {name} | stable-point displacements ({}) | {:.3} | {:.3} | {:.3} | 1.000 | | | |",
            t.disp[0].len(),
            disp[0],
            disp[1],
            disp[2]
        );
        println!(
            "| {name} | the same, joint covariance of the stable points only | {:.3} | {:.3} | {:.3} | 1.000 | | | |",
            disp_stable[0], disp_stable[1], disp_stable[2]
        );
        let block: Vec<f64> = t.block.iter().map(|v| rms(v)).collect();
        let per_point: Vec<f64> = t.block_per_point.iter().map(|v| rms(v)).collect();
        println!(
            "| {name} | block translation, joint covariance ({} epochs) | {:.3} | {:.3} | {:.3} | 1.000 | | | |",
            t.block[0].len(), block[0], block[1], block[2]
        );
        println!(
            "| {name} | the same, points taken as uncorrelated | {:.3} | {:.3} | {:.3} | 1.000 | | | |",
            per_point[0], per_point[1], per_point[2]
        );
        assert!(t.free[0].len() >= 1000 && t.disp[0].len() >= 1000 && t.block[0].len() >= 150);
        for (k, axis) in ["X", "Y", "Z"].iter().enumerate() {
            let r = free[k] / expected[k];
            if !(0.9..=1.06).contains(&r) {
                failures.push(format!("{name}: free network {axis} ratio {r:.3}"));
            }
            let r = disp[k];
            if !(0.9..=1.06).contains(&r) {
                failures.push(format!("{name}: displacement {axis} ratio {r:.3}"));
            }
            let r = block[k];
            if !(0.85..=1.12).contains(&r) {
                failures.push(format!("{name}: block translation {axis} ratio {r:.3}"));
            }
        }
        if t.false_drops as f64 > allowed {
            failures.push(format!(
                "{name}: {} false drops > {allowed:.1}",
                t.false_drops
            ));
        }
        if (sigma0 - 1.0).abs() > 0.05 {
            failures.push(format!("{name}: σ0 / noise = {sigma0:.3}"));
        }
    }
    println!("elapsed {:.1} s", started.elapsed().as_secs_f64());
    assert!(failures.is_empty(), "{failures:#?}");
}

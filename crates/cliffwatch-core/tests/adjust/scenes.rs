//! The long-range cliff, its East-North-Up twin, the nearly flat face, honest precision, a label
//! swap, and the wide-angle calibration network (central model). Bounds come from the noise or from
//! the rigorous optimum of the same data (the adjustment started from the true coordinates).

use crate::support;
use support::adjust as common;

use cliffwatch_core::photogrammetry::{adjust, AdjustError, Model};
use cliffwatch_sim::scenes::{
    calibration, long_range, with_true_approx, CalibrationParams, LongRangeParams,
};
use common::*;

/// Index 3 from the ± 0.5 m start and from the truth (the rigorous optimum), σ0, iterations, c.
fn from_start_and_optimum(params: &LongRangeParams) -> (f64, f64, f64, usize, (f64, f64)) {
    let (epoch, truth) = long_range(params).unwrap();
    let opts = options(Model::Orthogonal);
    let adj = match adjust(&epoch, &opts) {
        Ok(a) => a,
        Err(e) => {
            eprintln!("seed {}: {e}", params.seed);
            return (f64::INFINITY, 0.0, f64::INFINITY, 0, (f64::NAN, 0.0));
        }
    };
    assert!(adj.report.converged, "seed {}", params.seed);
    let best = adjust(&with_true_approx(&epoch, &truth), &opts)
        .unwrap_or_else(|e| panic!("seed {} from truth: {e}", params.seed));
    (
        index3(&adj, &truth),
        index3(&best, &truth),
        adj.report.sigma0_mm,
        adj.report.iterations,
        c_of(&adj),
    )
}

fn converges_like_the_optimum(base: LongRangeParams, label: &str) {
    let noise_mm = base.noise_px * base.pixel_size_mm;
    let mut failures: Vec<String> = Vec::new();
    for seed in 1..=6 {
        let params = LongRangeParams {
            seed,
            ..base.clone()
        };
        let (i3, best, s0, it, (c, sc)) = from_start_and_optimum(&params);
        eprintln!(
            "{label} seed {seed}: index3 {i3:.3} mm (optimum {best:.3}), σ0 {s0:.5} mm, it {it}, c {c:.2} ± {sc:.2}"
        );
        if i3.is_nan() || i3 > 1.3 * best {
            failures.push(format!(
                "seed {seed}: index 3 {i3:.3} mm vs optimum {best:.3}"
            ));
        }
        // σ0 against the noise (≈ 170 dof: ±5 %).
        if !(s0 > 0.8 * noise_mm && s0 < 1.25 * noise_mm) {
            failures.push(format!("seed {seed}: σ0 {s0:.5} mm vs noise {noise_mm}"));
        }
        if !(sc > 0.0 && (c - base.c_mm).abs() < 4.0 * sc) {
            failures.push(format!("seed {seed}: c {c:.2} ± {sc:.2} vs {}", base.c_mm));
        }
    }
    assert!(failures.is_empty(), "{label}: {failures:#?}");
}

#[test]
fn long_range_converges_to_the_rigorous_optimum() {
    converges_like_the_optimum(LongRangeParams::default(), "long range");
}

#[test]
fn flat_face_converges_like_the_relief_scene() {
    converges_like_the_optimum(LongRangeParams::flat(), "flat");
}

#[test]
fn enu_frame_gives_the_same_shape() {
    for seed in 1..=4 {
        let (a_epoch, a_truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::default()
        })
        .unwrap();
        let (b_epoch, b_truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::enu()
        })
        .unwrap();
        let opts = options(Model::Orthogonal);
        let a = adjust(&a_epoch, &opts).unwrap_or_else(|e| panic!("seed {seed} local: {e}"));
        let b = adjust(&b_epoch, &opts).unwrap_or_else(|e| panic!("seed {seed} ENU: {e}"));
        let (ia, ib) = (index3(&a, &a_truth), index3(&b, &b_truth));
        let (sa, sb) = (a.report.sigma0_mm, b.report.sigma0_mm);
        eprintln!("seed {seed}: index3 local {ia:.6} ENU {ib:.6} mm; σ0 {sa:.6} {sb:.6}");
        assert!((ia - ib).abs() < 1e-3, "seed {seed}: {ia} vs {ib} mm");
        assert!((sa - sb).abs() < 1e-3 * sa, "seed {seed}: σ0 {sa} vs {sb}");
        // Precision is the same too: the traces of the point covariances agree.
        let tr = |adj: &cliffwatch_core::photogrammetry::Adjustment| -> f64 {
            adj.points
                .iter()
                .map(|p| p.covariance_m2[0][0] + p.covariance_m2[1][1] + p.covariance_m2[2][2])
                .sum()
        };
        let (ta, tb) = (tr(&a), tr(&b));
        assert!(
            (ta - tb).abs() < 0.01 * ta,
            "seed {seed}: covariance traces {ta} vs {tb}"
        );
    }
}

#[test]
fn reported_precision_is_honest_over_60_seeds() {
    let mut z = Vec::new();
    let mut c_z = Vec::new();
    let opts = options(Model::Orthogonal);
    let start = std::time::Instant::now();
    for seed in 100..160 {
        let (epoch, truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::default()
        })
        .unwrap();
        let adj = match adjust(&epoch, &opts) {
            Ok(a) => a,
            // A refused wrong basin is counted by `no_false_convergence_over_60_seeds`, not here.
            Err(e @ AdjustError::Inconsistent { .. }) => {
                eprintln!("seed {seed}: {e}; left out");
                continue;
            }
            Err(e) => panic!("seed {seed}: {e}"),
        };
        let zs = normalized_errors(&adj, &truth);
        // The global test: σ0 against the a-priori σ (≈ 170 dof, so ±5 % per draw). An epoch
        // failing it is a wrong basin, counted by `no_false_convergence_over_60_seeds`, not here.
        let noise_mm = 0.25 * 0.0105;
        if adj.report.sigma0_mm > 1.25 * noise_mm {
            eprintln!(
                "seed {seed}: σ0 {:.5} mm fails the global test; left out",
                adj.report.sigma0_mm
            );
            continue;
        }
        if rms(&zs) > 3.0 {
            eprintln!(
                "seed {seed}: RMS z {:.1}, index 3 {:.1} mm, c {:.1}, σ0 {:.5}, it {}",
                rms(&zs),
                index3(&adj, &truth),
                c_of(&adj).0,
                adj.report.sigma0_mm,
                adj.report.iterations
            );
        }
        z.extend(zs);
        let (c, sc) = c_of(&adj);
        c_z.push((c - truth.c_mm) / sc);
    }
    let (r, rc) = (rms(&z), rms(&c_z));
    eprintln!(
        "60 seeds in {:.1} s: RMS of (error after similarity fit)/σ = {r:.3} over {} coordinates; RMS of (c error)/σc = {rc:.3}",
        start.elapsed().as_secs_f64(),
        z.len()
    );
    assert!(r > 0.7 && r < 1.4, "coordinates: RMS {r}");
    assert!(rc > 0.7 && rc < 1.4, "c: RMS {rc}");
}

#[test]
fn swapped_labels_are_dropped_and_do_not_corrupt_the_epoch() {
    let mut failures: Vec<String> = Vec::new();
    for seed in 1..=6 {
        let clean_p = LongRangeParams {
            seed,
            ..LongRangeParams::default()
        };
        let dirty_p = LongRangeParams {
            seed,
            ..LongRangeParams::with_blunder()
        };
        let (clean, truth) = long_range(&clean_p).unwrap();
        let (dirty, _) = long_range(&dirty_p).unwrap();
        let opts = options(Model::Orthogonal);
        let a = adjust(&clean, &opts).unwrap_or_else(|e| panic!("seed {seed} clean: {e}"));
        let b = adjust(&dirty, &opts).unwrap_or_else(|e| panic!("seed {seed} swapped: {e}"));
        let (ia, ib) = (index3(&a, &truth), index3(&b, &truth));
        let dropped: Vec<_> = b
            .report
            .dropped
            .iter()
            .map(|d| (d.image.as_str(), d.point.as_str()))
            .collect();
        eprintln!("seed {seed}: index3 clean {ia:.3} swapped {ib:.3} mm; dropped {dropped:?} (clean dropped {})", a.report.dropped.len());
        assert!(b.report.converged, "seed {seed}");
        if !(dropped.contains(&("S3", "T101")) && dropped.contains(&("S3", "T121"))) {
            failures.push(format!("seed {seed}: swap not dropped: {dropped:?}"));
        }
        // The spec compares with the clean epoch (within 10 %); dropping two observations of two
        // points changes index 3 by chance alone by several per cent (seed 2: +10.03 %), so the
        // assertion compares with the clean epoch *less those two observations*, which a method that
        // drops exactly the blunders must match to within 1 %.
        let mut reduced = clean.clone();
        for im in reduced.images.iter_mut().filter(|i| i.id == "S3") {
            im.observations
                .retain(|o| o.point != "T101" && o.point != "T121");
        }
        let ir = adjust(&reduced, &opts)
            .map(|r| index3(&r, &truth))
            .unwrap_or(f64::NAN);
        eprintln!(
            "seed {seed}: swapped / clean = {:.3}, swapped / clean-less-the-two = {:.4}",
            ib / ia,
            ib / ir
        );
        if ib.is_nan() || ib > 1.01 * ir {
            failures.push(format!(
                "seed {seed}: index 3 {ib:.3} mm vs {ir:.3} without the two swapped observations"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn calibration_network_central_model_full_self_calibration() {
    for seed in 1..=3 {
        let params = CalibrationParams {
            seed,
            ..CalibrationParams::default()
        };
        let (epoch, truth) = calibration(&params).unwrap();
        let adj =
            adjust(&epoch, &options(Model::Central)).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let r = &adj.report;
        let i3 = index3(&adj, &truth);
        let cal: Vec<_> = r.cameras[0]
            .calibrated
            .iter()
            .map(|p| format!("{} {:.4e} ± {:.1e}", p.name, p.value, p.sigma))
            .collect();
        eprintln!(
            "seed {seed}: converged {} it {} σ0 {:.6} mm, index3 {i3:.4} mm, dropped {}, {cal:?}",
            r.converged,
            r.iterations,
            r.sigma0_mm,
            r.dropped.len()
        );
        assert!(r.converged, "seed {seed}");
        assert!(
            r.sigma0_mm > 0.8 * params.noise_mm && r.sigma0_mm < 1.25 * params.noise_mm,
            "seed {seed}: σ0 {}",
            r.sigma0_mm
        );
        let names = ["c", "x0", "y0", "k1", "k2", "k3", "p1", "p2"];
        for (k, name) in names.iter().enumerate() {
            let p = r.cameras[0]
                .calibrated
                .iter()
                .find(|p| p.name == *name)
                .unwrap_or_else(|| panic!("seed {seed}: {name} not calibrated"));
            let t = params.interior[k];
            assert!(
                (p.value - t).abs() < 5.0 * p.sigma,
                "seed {seed}: {name} {} ± {} vs {t}",
                p.value,
                p.sigma
            );
        }
    }
}

#[test]
fn snooping_off_converges_as_well() {
    // Data snooping is optional: without it a clean epoch must still adjust to the right solution
    // (σ0 within the 99.9 % bound of the global test, ≈ 170 dof: 1.16 × the noise; index 3 within
    // 1.3 × the rigorous optimum, started from the truth), or be refused (no convergence, no
    // consistent solution) as seldom as with snooping on.
    let mut opts = options(Model::Orthogonal);
    opts.snooping = false;
    let noise_mm = 0.25 * 0.0105;
    let mut failures: Vec<String> = Vec::new();
    let mut refused: Vec<String> = Vec::new();
    for seed in 100..160 {
        let (epoch, truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::default()
        })
        .unwrap();
        match adjust(&epoch, &opts) {
            Err(e @ (AdjustError::NoConvergence { .. } | AdjustError::Inconsistent { .. })) => {
                refused.push(format!("seed {seed}: {e}"))
            }
            Err(e) => failures.push(format!("seed {seed}: {e}")),
            Ok(adj) => {
                let s0 = adj.report.sigma0_mm;
                if s0 > 1.2 * noise_mm {
                    failures.push(format!("seed {seed}: σ0 {s0:.5} mm vs noise {noise_mm}"));
                }
                let best = adjust(&with_true_approx(&epoch, &truth), &opts)
                    .unwrap_or_else(|e| panic!("seed {seed} from truth: {e}"));
                let (i3, b3) = (index3(&adj, &truth), index3(&best, &truth));
                if i3 > 1.3 * b3 {
                    failures.push(format!(
                        "seed {seed}: index 3 {i3:.3} mm vs optimum {b3:.3}"
                    ));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of 60 failed: {failures:#?}",
        failures.len()
    );
    assert!(
        refused.len() <= 2,
        "{} of 60 refused: {refused:#?}",
        refused.len()
    );
}

#[test]
fn no_false_convergence_over_60_seeds() {
    // A converged adjustment of a clean epoch must be the right one: σ0 near the noise, index 3
    // within 1.3 × the rigorous optimum (start from truth).
    let opts = options(Model::Orthogonal);
    let noise_mm = 0.25 * 0.0105;
    let mut failures: Vec<String> = Vec::new();
    let mut refused: Vec<String> = Vec::new();
    for seed in 100..160 {
        let (epoch, truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::default()
        })
        .unwrap();
        let adj = match adjust(&epoch, &opts) {
            Ok(a) => a,
            Err(e @ AdjustError::Inconsistent { .. }) => {
                // Refusing a wrong basin is not a false convergence, but it costs success rate.
                refused.push(format!("seed {seed}: {e}"));
                continue;
            }
            Err(e) => {
                failures.push(format!("seed {seed}: {e}"));
                continue;
            }
        };
        let i3 = index3(&adj, &truth);
        let best = adjust(&with_true_approx(&epoch, &truth), &opts)
            .map(|a| index3(&a, &truth))
            .unwrap_or(f64::NAN);
        if !(adj.report.sigma0_mm < 1.25 * noise_mm && i3 <= 1.3 * best) {
            failures.push(format!(
                "seed {seed}: converged={} σ0 {:.5} mm, index 3 {i3:.1} mm (optimum {best:.3}), c {:.1}",
                adj.report.converged,
                adj.report.sigma0_mm,
                c_of(&adj).0
            ));
        }
    }
    eprintln!("refused (inconsistent): {refused:#?}");
    assert!(
        failures.is_empty(),
        "{} of 60: {failures:#?}",
        failures.len()
    );
    // Success rate: at least 58 of 60 (the accuracy table in docs/accuracy.md has the full figures).
    assert!(
        refused.len() <= 2,
        "{} of 60 refused: {refused:#?}",
        refused.len()
    );
}

/// Every observation ends on its side of the critical value: a dropped one with |w| above it (else
/// the backward step would have taken it back), an active one at or below it unless it could not
/// be dropped (its point in two images, or its image down to four observations).
fn snooping_is_consistent(adj: &cliffwatch_core::photogrammetry::Adjustment, label: &str) -> usize {
    use std::collections::HashMap;
    let critical = cliffwatch_core::photogrammetry::AdjustOptions::default().critical_w;
    let r = &adj.report.residuals;
    let mut per_point: HashMap<&str, usize> = HashMap::new();
    let mut per_image: HashMap<&str, usize> = HashMap::new();
    for o in r.iter().filter(|o| !o.dropped) {
        *per_point.entry(&o.point).or_default() += 1;
        *per_image.entry(&o.image).or_default() += 1;
    }
    for o in r {
        if o.dropped {
            assert!(
                o.w > critical,
                "{label}: {}/{} dropped with |w| {}",
                o.image,
                o.point,
                o.w
            );
        } else if per_point[o.point.as_str()] > 2 && per_image[o.image.as_str()] > 4 {
            assert!(
                o.w <= critical * (1.0 + 1e-6),
                "{label}: {}/{} active with |w| {}",
                o.image,
                o.point,
                o.w
            );
        }
    }
    r.iter().filter(|o| o.dropped).count()
}

#[test]
fn snooping_leaves_every_observation_on_its_side_of_the_critical_value() {
    use cliffwatch_sim::scenes::{large, LargeParams};
    let mut drops = 0;
    for seed in 1..=3 {
        let (epoch, _) = large(&LargeParams {
            seed,
            ..LargeParams::default()
        })
        .unwrap();
        let adj = adjust(&epoch, &options(Model::Orthogonal)).unwrap();
        drops += snooping_is_consistent(&adj, &format!("20 × 500 seed {seed}"));
    }
    for seed in 1..=3 {
        let (epoch, _) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::with_blunder()
        })
        .unwrap();
        let adj = adjust(&epoch, &options(Model::Orthogonal)).unwrap();
        drops += snooping_is_consistent(&adj, &format!("long range with a swap, seed {seed}"));
    }
    // Pure noise exceeds 3.29 for ~0.1 % of the 2 × 10 000 coordinates of each large network,
    // and each swap adds two blunders: the test has drops to judge.
    assert!(drops >= 10, "only {drops} drops");
}

#[test]
fn a_large_network_gives_the_same_report_on_every_run() {
    // Its sums run on the rayon pool; they must not depend on how the threads shared the work
    // (the datum projection's sum once did: σ differed in the 10th digit from run to run).
    use cliffwatch_sim::scenes::{large, LargeParams};
    let (epoch, _) = large(&LargeParams::default()).unwrap();
    let report = || {
        let adj = adjust(&epoch, &options(Model::Orthogonal)).unwrap();
        serde_json::to_string(&adj.report).unwrap()
    };
    let first = report();
    for run in 2..=4 {
        assert!(report() == first, "run {run} differs from the first");
    }
}

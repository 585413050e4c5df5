//! The paper's Table 1 scene (Ono & Hattori §4): cases 1–3, on the shared epochs (seeds 101–103)
//! and on generated ones. Bounds follow `docs/model.md` and the noise (0.001 mm).

use crate::support;
use support::adjust as common;

use cliffwatch_core::photogrammetry::{adjust, Model};
use cliffwatch_sim::scenes::{paper_table1, with_true_approx, PaperCase, PaperParams, PAPER_C_MM};
use common::*;

const NOISE_MM: f64 = 0.001;

/// Shared seeds plus a few generated ones of one case.
fn epochs(
    case: u32,
) -> Vec<(
    String,
    cliffwatch_core::photogrammetry::EpochInput,
    cliffwatch_sim::scenes::Truth,
)> {
    let mut out = Vec::new();
    for seed in [101, 102, 103] {
        let (e, t) = shared(case, seed).expect("../shared/data lies beside the repository");
        out.push((format!("shared case {case} seed {seed}"), e, t));
    }
    let pc = match case {
        1 => PaperCase::Case1,
        2 => PaperCase::Case2,
        _ => PaperCase::Case3,
    };
    for seed in 1..=6 {
        let (e, t) = paper_table1(&PaperParams::case(pc, seed)).unwrap();
        out.push((format!("generated case {case} seed {seed}"), e, t));
    }
    out
}

#[test]
fn case2_three_images_c_fixed() {
    for (name, epoch, truth) in epochs(2) {
        let adj =
            adjust(&epoch, &options(Model::Orthogonal)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let r = &adj.report;
        let i3 = index3(&adj, &truth);
        eprintln!(
            "{name}: σ0 {:.5} mm, dof {}, it {}, index3 {i3:.4} mm",
            r.sigma0_mm, r.dof, r.iterations
        );
        assert!(r.converged, "{name}");
        // σ0 estimates the noise with ~25 dof: ±14 % per draw, so [0.55, 1.5] is beyond 3σ.
        assert!(
            r.sigma0_mm > 0.55 * NOISE_MM && r.sigma0_mm < 1.5 * NOISE_MM,
            "{name}: σ0 {}",
            r.sigma0_mm
        );
        // Rigorous adjustment: index 3 ≈ 0.05 mm (paper 0.0577).
        assert!(i3 < 0.1, "{name}: index 3 {i3} mm");
        assert!(r.dropped.is_empty(), "{name}: dropped {:?}", r.dropped);
    }
}

#[test]
fn case3_self_calibrated_c_recovers_300() {
    for (name, epoch, truth) in epochs(3) {
        assert_eq!(epoch.cameras[0].c_mm, 290.0);
        let free =
            adjust(&epoch, &options(Model::Orthogonal)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (c, sc) = c_of(&free);
        let i3 = index3(&free, &truth);
        eprintln!(
            "{name}: c {c:.3} ± {sc:.3}, σ0 {:.5}, index3 {i3:.4}, it {}",
            free.report.sigma0_mm, free.report.iterations
        );
        assert!(free.report.converged, "{name}");
        // The spec's ± 2 mm is stated for the shared epochs; on other draws c is held to its
        // reported σ (about 1.2 mm here, see `case3_c_scatter_matches_its_sigma`).
        if name.starts_with("shared") {
            assert!((c - PAPER_C_MM).abs() < 2.0, "{name}: c {c}");
        }
        assert!(sc > 0.0, "{name}: σ of c not reported");
        assert!(
            (c - PAPER_C_MM).abs() < 4.0 * sc,
            "{name}: c {c} ± {sc} is not honest"
        );
        // σ0 ≈ case 2 (24 dof): within the same band.
        assert!(
            free.report.sigma0_mm > 0.55 * NOISE_MM && free.report.sigma0_mm < 1.5 * NOISE_MM,
            "{name}: σ0 {}",
            free.report.sigma0_mm
        );
        // index 3 ≈ 0.05–0.09 mm (doc); 0.12 leaves room for the draw.
        assert!(i3 < 0.12, "{name}: index 3 {i3}");
    }
}

#[test]
fn case3_c_fixed_at_290_is_clearly_worse_than_c_free() {
    let mut failures: Vec<String> = Vec::new();
    for (name, epoch, truth) in epochs(3) {
        let free =
            adjust(&epoch, &options(Model::Orthogonal)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let mut fixed_epoch = epoch.clone();
        fixed_epoch.cameras[0].calibrate_c = false;
        let mut opts = options(Model::Orthogonal);
        // The wrong c leaves systematic residuals; do not let snooping hide them.
        opts.snooping = false;
        // The paper adjusts this case (σ0 0.00229 mm, index 3 0.1731 mm): it must give a result.
        let fixed = match adjust(&fixed_epoch, &opts) {
            Ok(a) => a,
            Err(e) => {
                failures.push(format!("{name}: c fixed at 290: {e}"));
                continue;
            }
        };
        let (i3f, i3x) = (index3(&free, &truth), index3(&fixed, &truth));
        eprintln!(
            "{name}: σ0 free {:.5} fixed {:.5}, index3 free {i3f:.4} fixed {i3x:.4}",
            free.report.sigma0_mm, fixed.report.sigma0_mm
        );
        if !(fixed.report.sigma0_mm > 1.5 * free.report.sigma0_mm && i3x > i3f) {
            failures.push(format!("{name}: fixed not clearly worse"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn case1_two_images_gives_a_result_and_a_warning() {
    for (name, epoch, truth) in epochs(1) {
        let adj =
            adjust(&epoch, &options(Model::Orthogonal)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let i3 = index3(&adj, &truth);
        eprintln!(
            "{name}: σ0 {:.5} dof {} index3 {i3:.4} warnings {:?}",
            adj.report.sigma0_mm, adj.report.dof, adj.report.warnings
        );
        assert!(adj.report.converged, "{name}");
        assert!(
            adj.report
                .warnings
                .iter()
                .any(|w| w.contains("2 images") || w.contains("two images")),
            "{name}: no two-image warning in {:?}",
            adj.report.warnings
        );
        assert_eq!(adj.points.len(), 12);
        // The paper's variant got 1.43 mm; the rigorous model keeps the perspective.
        assert!(i3.is_finite() && i3 < 0.5, "{name}: index 3 {i3}");
        // The rigorous optimum of the same data: start from the truth.
        let best = adjust(
            &with_true_approx(&epoch, &truth),
            &options(Model::Orthogonal),
        )
        .map(|a| index3(&a, &truth));
        eprintln!("{name}: index3 from truth start {best:?}");
    }
}

#[test]
fn paper_case2_index4_is_not_worse_than_index3() {
    let (epoch, truth) = paper_table1(&PaperParams::default()).unwrap();
    let adj = adjust(&epoch, &options(Model::Orthogonal)).unwrap();
    let i3 = truth.index3_rmse_mm(&adj.points).unwrap();
    let i4 = truth.index4_rmse_mm(&adj.points).unwrap();
    assert!(i4[3] <= i3[3] + 1e-12, "{i3:?} {i4:?}");
}

#[test]
fn case3_c_scatter_matches_its_sigma() {
    // Over 40 draws the errors of c divided by their reported σ have an RMS near 1 and the
    // spread of c itself is within ± 2 mm for most draws.
    let mut z = Vec::new();
    let mut within = 0;
    for seed in 1000..1040 {
        let (epoch, _) = paper_table1(&PaperParams::case(PaperCase::Case3, seed)).unwrap();
        let adj = adjust(&epoch, &options(Model::Orthogonal))
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        let (c, sc) = c_of(&adj);
        z.push((c - PAPER_C_MM) / sc);
        if (c - PAPER_C_MM).abs() < 2.0 {
            within += 1;
        }
    }
    let r = rms(&z);
    eprintln!("case 3 over 40 seeds: RMS of (c − 300)/σc = {r:.3}; {within}/40 within ± 2 mm");
    assert!(r > 0.7 && r < 1.4, "RMS {r}");
    assert!(within >= 30, "{within}/40 within ± 2 mm");
}

#[test]
fn case1_precision_is_honest_over_40_seeds() {
    // Two images: the depth is weak, but the reported σ must say so. Errors after a similarity
    // fit divided by the reported σ have an RMS near 1.
    let mut z = Vec::new();
    let mut i3 = Vec::new();
    let mut sig = Vec::new();
    for seed in 2000..2040 {
        let (epoch, truth) = paper_table1(&PaperParams::case(PaperCase::Case1, seed)).unwrap();
        let adj = adjust(&epoch, &options(Model::Orthogonal))
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        z.extend(normalized_errors(&adj, &truth));
        i3.push(index3(&adj, &truth));
        let s2: f64 = adj
            .points
            .iter()
            .map(|p| (0..3).map(|k| p.covariance_m2[k][k]).sum::<f64>())
            .sum::<f64>()
            / (3.0 * adj.points.len() as f64);
        sig.push(1000.0 * s2.sqrt());
    }
    let r = rms(&z);
    eprintln!(
        "case 1 over 40 seeds: RMS z {r:.3}; index 3 RMS {:.3} mm; reported σ RMS {:.3} mm",
        rms(&i3),
        rms(&sig)
    );
    assert!(r > 0.7 && r < 1.4, "RMS {r}");
}

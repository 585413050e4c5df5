//! The pre-analysis's reliability figures and its weak-geometry messages (`plan::quality`): each
//! message appears on a plan built to be weak in that way, and not on the sound long-range plan.

use cliffwatch_core::plan::quality::{
    delta0, FLAT_RELIEF, LOW_REDUNDANCY, PARALLEL_VIEWS_DEG, WEAK_INTERSECTION_DEG,
};
use cliffwatch_core::plan::{pre_analysis, PlanReport, PlanStation};

use super::plan::{plan_of, scene};

fn warned(report: &PlanReport, words: &str) -> bool {
    report.warnings.iter().any(|w| w.contains(words))
}

/// The sound long-range plan: redundancy numbers in (0, 1], their sum below the degrees of
/// freedom, each MDB Baarda's σ·δ0/√r, the strongest correlations listed strongest first, every
/// target intersected, and none of the weak-geometry messages.
#[test]
fn plan_reports_redundancy_mdb_and_correlations() {
    let (p, truth) = scene(1);
    let report = pre_analysis(&plan_of(&p, &truth)).expect("pre-analysis");
    let n = report.observations.len();
    assert!(n >= 50, "{n}");
    let d0 = delta0(0.95, 0.8);
    assert!((d0 - (1.959964 + 0.841621)).abs() < 1e-3, "{d0}");
    let sigma = 0.25 * p.pixel_size_mm;
    let mut sum = 0.0;
    for o in &report.observations {
        for c in 0..2 {
            let r = o.redundancy[c];
            assert!(r > 0.0 && r <= 1.0, "{o:?}");
            let mdb = o.mdb_mm[c].unwrap();
            assert!((mdb - sigma * d0 / r.sqrt()).abs() < 1e-9 * mdb, "{o:?}");
            sum += r;
        }
    }
    assert!(sum <= report.dof as f64 + 1e-6, "{sum} > {}", report.dof);
    assert!(sum > 0.5 * report.dof as f64, "{sum} vs {}", report.dof);
    assert!(report.min_redundancy.unwrap() > 0.0);
    assert!(!report.correlations.is_empty());
    for w in report.correlations.windows(2) {
        assert!(w[0].rho.abs() >= w[1].rho.abs());
    }
    assert!(report.correlations[0].parameter.ends_with(": c"));
    for t in &report.targets {
        assert!(t.intersection_deg.unwrap() > WEAK_INTERSECTION_DEG, "{t:?}");
    }
    for words in [
        "intersected at less",
        "not determinable",
        "redundancy number below",
    ] {
        assert!(!warned(&report, words), "{words}: {:?}", report.warnings);
    }
}

/// Stations bunched together (all within a few metres at 150 m): every target is intersected at
/// less than the threshold, and the message says so with the threshold and the angles.
#[test]
fn plan_warns_of_weak_intersections() {
    let (p, truth) = scene(2);
    let mut plan = plan_of(&p, &truth);
    let first = plan.stations[0].clone();
    for (k, s) in plan.stations.iter_mut().enumerate() {
        s.position = [
            first.position[0] + 2.0 * k as f64,
            first.position[1],
            first.position[2],
        ];
        s.aim = first.aim;
    }
    let report = pre_analysis(&plan).expect("pre-analysis");
    let message = report
        .warnings
        .iter()
        .find(|w| w.contains("intersected at less"))
        .unwrap_or_else(|| panic!("{:?}", report.warnings));
    assert!(
        message.contains(&format!("{WEAK_INTERSECTION_DEG}°")),
        "{message}"
    );
    assert!(message.contains("T101"), "{message}");
}

/// A target seen by exactly two of four stations has little redundancy in its image coordinates
/// against the rest; with two stations in all, the weakly controlled observations are named.
#[test]
fn plan_warns_of_weakly_controlled_observations() {
    let (p, truth) = scene(3);
    let mut plan = plan_of(&p, &truth);
    plan.stations.truncate(2);
    let report = pre_analysis(&plan).expect("pre-analysis");
    let low = report
        .observations
        .iter()
        .filter(|o| o.redundancy[0].min(o.redundancy[1]) < LOW_REDUNDANCY)
        .count();
    let message = report
        .warnings
        .iter()
        .find(|w| w.contains("redundancy number below"));
    assert_eq!(low > 0, message.is_some(), "{low}: {:?}", report.warnings);
    assert!(
        low > 0,
        "two stations leave some coordinates uncontrolled: {:?}",
        report.observations
    );
}

/// Four stations 150 m in front of the face (along +Z), 1–3 m apart, looking straight along −Z
/// (parallel axes), Y up.
fn square_stations(plan: &mut cliffwatch_core::plan::Plan) {
    let n = plan.targets.len() as f64;
    let c: Vec<f64> = (0..3)
        .map(|k| plan.targets.iter().map(|t| t.xyz[k]).sum::<f64>() / n)
        .collect();
    for (k, s) in plan.stations.iter_mut().enumerate() {
        s.position = [
            c[0] - 1.5 + k as f64,
            c[1] + 0.5 * (k % 2) as f64,
            c[2] + 150.0,
        ];
        s.aim = [s.position[0], s.position[1], c[2]];
        s.up = Some([0.0, 1.0, 0.0]);
    }
}

/// The orthogonal model's c: targets almost in one plane square to parallel views (2 cm of
/// relief at 150 m) make c not determinable, said with the threshold, and c's σ shows it (10 % of
/// c); stations with parallel axes are named as such (c then rests on the targets' relief
/// alone); with c held fixed neither is said.
#[test]
fn plan_says_when_c_is_not_determinable() {
    let (p, mut truth) = scene(4);
    for (k, (_, xyz)) in truth.points.iter_mut().enumerate() {
        xyz[2] = 0.02 * (k % 2) as f64;
    }
    let mut flat = plan_of(&p, &truth);
    square_stations(&mut flat);
    let report = pre_analysis(&flat).expect("pre-analysis");
    eprintln!(
        "flat, parallel: σc {:?} mm; {:?}",
        report.sigma_c_mm, report.warnings
    );
    let relief = report
        .warnings
        .iter()
        .find(|w| w.contains("depths") && w.contains("not determinable"))
        .unwrap_or_else(|| panic!("{:?}", report.warnings));
    assert!(
        relief.contains(&format!("{} %", 100.0 * FLAT_RELIEF)),
        "{relief}"
    );
    assert!(
        report.sigma_c_mm.unwrap() > 0.05 * p.c_mm,
        "{:?}",
        report.sigma_c_mm
    );
    let parallel = report
        .warnings
        .iter()
        .find(|w| w.contains("converge by only"))
        .unwrap_or_else(|| panic!("{:?}", report.warnings));
    assert!(
        parallel.contains(&format!("{PARALLEL_VIEWS_DEG}°")),
        "{parallel}"
    );

    // Exactly flat: the network may be singular; either way the reason is said, never a panic.
    let mut planar = flat.clone();
    for t in &mut planar.targets {
        t.xyz[2] = 0.0;
    }
    match pre_analysis(&planar) {
        Ok(r) => assert!(warned(&r, "not determinable"), "{:?}", r.warnings),
        Err(e) => assert!(e.to_string().contains("not determinable"), "{e}"),
    }

    flat.cameras[0].calibrate_c = false;
    let fixed = pre_analysis(&flat).expect("pre-analysis");
    assert!(!warned(&fixed, "not determinable"), "{:?}", fixed.warnings);

    // Parallel axes over the scene's own relief: c rests on the relief alone, said so.
    let (p, truth) = scene(4);
    let mut relief = plan_of(&p, &truth);
    square_stations(&mut relief);
    let r = pre_analysis(&relief).expect("pre-analysis");
    eprintln!(
        "relief, parallel: σc {:?} mm; {:?}",
        r.sigma_c_mm, r.warnings
    );
    assert!(warned(&r, "converge by only") && !warned(&r, "depths along"));
}

/// A station added on the other side of the targets (a convergent view) is seen in the
/// intersection angles: they grow.
#[test]
fn plan_intersection_angles_grow_with_a_convergent_station() {
    let (p, truth) = scene(5);
    let plan = plan_of(&p, &truth);
    let a = pre_analysis(&plan).expect("pre-analysis");
    let mut wider = plan.clone();
    let s = &plan.stations[0];
    let n = plan.targets.len() as f64;
    let centroid: [f64; 3] =
        std::array::from_fn(|k| plan.targets.iter().map(|t| t.xyz[k]).sum::<f64>() / n);
    wider.stations.push(PlanStation {
        name: "WIDE".into(),
        camera: s.camera.clone(),
        position: [centroid[0] + 60.0, centroid[1], centroid[2] + 140.0],
        aim: centroid,
        up: s.up,
        sees: None,
    });
    let b = pre_analysis(&wider).expect("pre-analysis");
    for (ta, tb) in a.targets.iter().zip(&b.targets) {
        if tb.cameras > ta.cameras {
            assert!(tb.intersection_deg.unwrap() >= ta.intersection_deg.unwrap());
        }
    }
}

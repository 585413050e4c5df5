//! Datum and robustness: IWST without stable points, bad input as typed errors (never a panic).

use crate::support;
use support::analysis as common;

use chrono::{TimeZone, Utc};
use cliffwatch_core::analysis::{
    analyse_epoch, AlertConfig, AnalysisConfig, AnalysisError, DatumMethod, EpochCoordinates,
    History, PointConfig, PointCoordinates, PointRole,
};
use cliffwatch_sim::monitoring::MonitoringScenario;
use proptest::prelude::*;

/// Without stable points, IWST keeps the moving block from dragging the datum: the block's displacement
/// error stays within 4.5σ (the 3-D test value below χ²(3) at 99.9 %… with margin), the fixed points' too.
#[test]
fn iwst_without_stable_points_is_not_dragged_by_the_block() {
    let sc = MonitoringScenario {
        seed: 5,
        ..Default::default()
    };
    let series = sc.generate();
    let points = all_monitored(&series.points);
    let steps = common::run(
        &series,
        &points,
        &AnalysisConfig::default(),
        &AlertConfig::new("s", vec![]),
    );
    let (mut n, mut below) = (0, 0);
    let mut worst: f64 = 0.0;
    for (k, s) in steps.iter().enumerate() {
        assert_eq!(s.analysis.datum.method, DatumMethod::Iwst);
        for (i, p) in s.analysis.points.iter().enumerate() {
            let t = series.epochs[k + 1].true_displacement_mm[i];
            let r = &p.record;
            let q = common::mahalanobis(
                [r.dx_mm - t[0], r.dy_mm - t[1], r.dz_mm - t[2]],
                p.covariance_mm2,
            )
            .expect("regular");
            n += 1;
            below += usize::from(q < 16.27);
            worst = worst.max(q);
        }
    }
    let share = below as f64 / n as f64;
    println!(
        "IWST: {below}/{n} = {:.2} % of point-epochs below χ²(3; 0.999) = 16.27; worst {worst:.1}",
        100.0 * share
    );
    // The block (4 of 20 points) moves up to ~45 mm; a dragged datum would shift every point by mm.
    assert!(share >= 0.97);
}

/// The same points, none of them stable (the datum then falls to IWST).
fn all_monitored(points: &[PointConfig]) -> Vec<PointConfig> {
    points
        .iter()
        .map(|p| PointConfig {
            role: PointRole::Monitored,
            ..p.clone()
        })
        .collect()
}

fn pt(name: &str, xyz: [f64; 3], s: f64) -> PointCoordinates {
    PointCoordinates {
        name: name.into(),
        xyz_m: xyz,
        covariance_m2: [[s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]],
    }
}

fn epoch(id: i64, pts: Vec<PointCoordinates>) -> EpochCoordinates {
    EpochCoordinates {
        epoch: id,
        observed_at: Utc
            .timestamp_opt(1_700_000_000 + id * 86_400, 0)
            .single()
            .expect("t"),
        points: pts,
        joint: None,
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let cfg = AnalysisConfig::default();
    let h = History::new();
    let a = epoch(
        1,
        vec![
            pt("A", [0.0, 0.0, 0.0], 1e-8),
            pt("B", [1.0, 0.0, 0.0], 1e-8),
        ],
    );
    assert!(matches!(
        analyse_epoch(&a, &a, &[], &h, &cfg),
        Err(AnalysisError::TooFewDatumPoints {
            found: 2,
            needed: 3
        })
    ));
    let mut b = epoch(
        2,
        vec![
            pt("A", [0.0, 0.0, 0.0], 1e-8),
            pt("B", [1.0, 0.0, 0.0], 1e-8),
            pt("C", [0.0, 1.0, 0.0], 1e-8),
        ],
    );
    let a3 = b.clone();
    b.points[1].xyz_m[0] = f64::NAN;
    assert!(matches!(
        analyse_epoch(&a3, &b, &[], &h, &cfg),
        Err(AnalysisError::NonFinite { .. })
    ));
    let bad_cfg = AnalysisConfig {
        confidence: 1.5,
        ..Default::default()
    };
    assert!(matches!(
        analyse_epoch(&a3, &a3, &[], &h, &bad_cfg),
        Err(AnalysisError::InvalidConfig(_))
    ));
    // Collinear stable points: the stable datum is impossible, IWST over all (also collinear) fails typed.
    let line = |id| {
        epoch(
            id,
            (0..4)
                .map(|i| pt(&format!("P{i}"), [i as f64, 0.0, 0.0], 1e-8))
                .collect(),
        )
    };
    let stable: Vec<PointConfig> = (0..4)
        .map(|i| PointConfig {
            name: format!("P{i}"),
            role: PointRole::Stable,
            group: None,
            direction: None,
        })
        .collect();
    assert!(matches!(
        analyse_epoch(&line(1), &line(2), &stable, &h, &cfg),
        Err(AnalysisError::Singular { .. })
    ));
    // Zero covariances everywhere: no panic, typed outcome.
    let z = |id| {
        epoch(
            id,
            (0..5)
                .map(|i| {
                    pt(
                        &format!("P{i}"),
                        [i as f64, (i * i) as f64, (i % 2) as f64],
                        0.0,
                    )
                })
                .collect(),
        )
    };
    let _ = analyse_epoch(&z(1), &z(2), &stable, &h, &cfg);
}

#[test]
fn the_reference_epoch_has_zero_displacement_and_new_points_are_listed() {
    let series = MonitoringScenario {
        seed: 3,
        epochs: 2,
        ..Default::default()
    }
    .generate();
    let e0 = &series.epochs[0].coordinates;
    let a = analyse_epoch(
        e0,
        e0,
        &series.points,
        &History::new(),
        &AnalysisConfig::default(),
    )
    .expect("ok");
    assert!(a
        .points
        .iter()
        .all(|p| p.record.d_mm == 0.0 && !p.record.significant));
    let mut e1 = series.epochs[1].coordinates.clone();
    e1.points.push(pt("NEW", [1.0, 2.0, 3.0], 1e-8));
    let a = analyse_epoch(
        e0,
        &e1,
        &series.points,
        &History::new(),
        &AnalysisConfig::default(),
    )
    .expect("ok");
    assert_eq!(a.new_points, vec!["NEW".to_string()]);
    assert!(
        a.points
            .iter()
            .all(|p| p.record.velocity_mm_per_day.is_none()),
        "no velocity without history"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Arbitrary finite coordinates and covariances (even indefinite ones): a result or a typed error.
    #[test]
    fn never_panics(coords in proptest::collection::vec((-100.0f64..100.0, -100.0f64..100.0, -100.0f64..100.0, -1e-6f64..1e-6), 0..8),
                    shift in -0.01f64..0.01, stable_mask in 0u8..=255) {
        let pts = |d: f64| coords.iter().enumerate().map(|(i, c)| pt(&format!("P{i}"), [c.0 + d, c.1, c.2], c.3)).collect();
        let roles: Vec<PointConfig> = (0..coords.len())
            .map(|i| PointConfig { name: format!("P{i}"), role: if stable_mask & (1 << i) != 0 { PointRole::Stable } else { PointRole::Monitored }, group: None, direction: Some([1.0, 0.0, 0.0]) })
            .collect();
        let _ = analyse_epoch(&epoch(1, pts(0.0)), &epoch(2, pts(shift)), &roles, &History::new(), &AnalysisConfig::default());
    }
}

/// A free network takes its datum from the approximate coordinates, so a blunder in one of them
/// rotates and scales a whole epoch (by degrees and percent) without changing its shape. The
/// analysis aligns such an epoch exactly: for every epoch of a series with a moving block, with the
/// stable-point datum and with IWST, its displacements equal those of the same epoch in the
/// ordinary datum, and two different gross datums give the same analysis. It says so in a warning,
/// which the ordinary epochs never get.
#[test]
fn a_grossly_different_datum_gives_the_same_displacements() {
    use nalgebra::{Matrix3, Rotation3, Vector3};
    let series = MonitoringScenario {
        seed: 11,
        ..Default::default()
    }
    .generate();
    let moved = |e: &EpochCoordinates, axis: Vector3<f64>, scale: f64, shift: Vector3<f64>| {
        let rotation = *Rotation3::new(axis).matrix();
        let mut out = e.clone();
        for p in &mut out.points {
            let x: Vector3<f64> = scale * rotation * Vector3::from(p.xyz_m) + shift;
            p.xyz_m = x.into();
            let c: Matrix3<f64> = Matrix3::from_fn(|i, j| p.covariance_m2[i][j]);
            let c: Matrix3<f64> = scale * scale * rotation * c * rotation.transpose();
            p.covariance_m2 = std::array::from_fn(|i| std::array::from_fn(|j| c[(i, j)]));
        }
        if let Some(j) = &mut out.joint {
            let dim = 3 * j.points.len();
            let m = nalgebra::DMatrix::from_row_slice(dim, dim, &j.matrix_m2);
            let r = nalgebra::DMatrix::from_fn(dim, dim, |a, b| {
                if a / 3 == b / 3 {
                    rotation[(a % 3, b % 3)]
                } else {
                    0.0
                }
            });
            let t = scale * scale * &r * m * r.transpose();
            j.matrix_m2 = t.transpose().as_slice().to_vec();
        }
        out
    };
    let monitored = all_monitored(&series.points);
    let reference = &series.epochs[0].coordinates;
    let config = AnalysisConfig::default();
    let history = History::new();
    for (points, method) in [
        (&series.points, DatumMethod::StablePoints),
        (&monitored, DatumMethod::Iwst),
    ] {
        let (mut to_plain, mut sigma_to_plain, mut between): (f64, f64, f64) = (0.0, 0.0, 0.0);
        for e in &series.epochs[1..] {
            let plain_epoch = e.coordinates.clone();
            assert!(plain_epoch.joint.is_some());
            let analyse = |c: &EpochCoordinates| {
                analyse_epoch(reference, c, points, &history, &config).expect("analysis")
            };
            let plain = analyse(&plain_epoch);
            let scale = 1.04;
            let gross = analyse(&moved(
                &plain_epoch,
                Vector3::new(0.05, -0.3, 0.2),
                scale,
                Vector3::new(20.0, -7.0, 3.0),
            ));
            let other = analyse(&moved(
                &plain_epoch,
                Vector3::new(-0.4, 0.1, 0.0),
                0.97,
                Vector3::new(-300.0, 5.0, 0.0),
            ));
            assert_eq!(plain.datum.method, method);
            assert_eq!(gross.datum.method, method);
            assert!(!plain.warnings.iter().any(|w| w.contains("aligned exactly")));
            for a in [&gross, &other] {
                assert!(
                    a.warnings.iter().any(|w| w.contains("aligned exactly")),
                    "{:?}",
                    a.warnings
                );
            }
            let expected_ppm = (scale * (1.0 + plain.datum.scale_ppm * 1e-6) - 1.0) * 1e6;
            assert!(
                (gross.datum.scale_ppm - expected_ppm).abs() < 1.0,
                "{} vs {expected_ppm}",
                gross.datum.scale_ppm
            );
            assert_eq!(plain.blocks.len(), gross.blocks.len());
            for (a, b) in plain.blocks.iter().zip(&gross.blocks) {
                let (Some(ma), Some(mb)) = (&a.motion, &b.motion) else {
                    assert_eq!(a.motion.is_some(), b.motion.is_some());
                    continue;
                };
                for k in 0..3 {
                    to_plain = to_plain.max((ma.translation_mm[k] - mb.translation_mm[k]).abs());
                    let (sa, sb) = (
                        ma.covariance_mm2[k][k].sqrt(),
                        mb.covariance_mm2[k][k].sqrt(),
                    );
                    if method == DatumMethod::StablePoints {
                        sigma_to_plain = sigma_to_plain.max((sa / sb - 1.0).abs());
                    }
                }
            }
            for ((a, b), c) in plain.points.iter().zip(&gross.points).zip(&other.points) {
                let (ra, rb, rc) = (&a.record, &b.record, &c.record);
                let d = |r: &cliffwatch_core::analysis::DisplacementRecord| {
                    [
                        r.dx_mm,
                        r.dy_mm,
                        r.dz_mm,
                        r.sigma_dx_mm,
                        r.sigma_dy_mm,
                        r.sigma_dz_mm,
                    ]
                };
                let (da, db, dc) = (d(ra), d(rb), d(rc));
                for k in 0..3 {
                    to_plain = to_plain.max((da[k] - db[k]).abs());
                    between = between.max((db[k] - dc[k]).abs());
                }
                for k in 3..6 {
                    sigma_to_plain = sigma_to_plain.max((da[k] / db[k] - 1.0).abs());
                    between = between.max((db[k] / dc[k] - 1.0).abs());
                }
            }
        }
        println!(
            "{method:?}: largest difference to the ordinary datum {to_plain:.2e} mm, its σ ratio − 1 \
             {sigma_to_plain:.2e}; between two gross datums {between:.2e}"
        );
        // The ordinary epochs' linear S-transformation leaves out the rotation of the displacement
        // itself (0.2 mrad × up to 12 mm ≈ 2.5 µm). Without the exact alignment the differences
        // reach metres.
        assert!(to_plain < 0.01, "{to_plain}");
        assert!(between < 1e-6, "{between}");
        // IWST's weights, 1/max(|d'|, ε σ), follow µm changes of d', and its σ with them.
        if method == DatumMethod::StablePoints {
            assert!(sigma_to_plain < 1e-3, "{sigma_to_plain}");
        }
    }
}

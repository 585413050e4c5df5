use super::*;
use cliffwatch_core::photogrammetry::adjust::result::AdjustedPoint;
use cliffwatch_core::photogrammetry::input::epoch::EpochInput;

fn shared(name: &str) -> Option<String> {
    std::fs::read_to_string(format!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/{}"),
        name
    ))
    .ok()
}

#[test]
fn paper_geometry_matches_the_shared_truth_files() {
    for (case, file, n) in [
        (PaperCase::Case1, "paper-case1-seed101.truth.json", 2),
        (PaperCase::Case2, "paper-case2-seed101.truth.json", 3),
        (PaperCase::Case3, "paper-case3-seed101.truth.json", 3),
    ] {
        let (input, truth) = paper_table1(&PaperParams::case(case, 101)).unwrap();
        assert_eq!(input.images.len(), n);
        let Some(text) = shared(file) else {
            eprintln!("shared data not available; skipping the comparison");
            return;
        };
        let theirs: Truth = serde_json::from_str(&text).unwrap();
        assert_eq!(theirs.points, truth.points);
        assert_eq!(theirs.c_mm, truth.c_mm);
        assert_eq!(theirs.cameras.len(), truth.cameras.len());
        for (id, cam) in &theirs.cameras {
            let mine = &truth.cameras[id];
            assert_eq!(cam.xo, mine.xo);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((cam.r[i][j] - mine.r[i][j]).abs() < 1e-12, "{id}");
                }
            }
        }
    }
}

#[test]
fn paper_epoch_has_the_form_of_the_shared_epochs() {
    let Some(text) = shared("paper-case3-seed101.epoch.json") else {
        return;
    };
    let theirs: EpochInput = serde_json::from_str(&text).unwrap();
    let (mine, truth) = paper_table1(&PaperParams::case(PaperCase::Case3, 7)).unwrap();
    assert_eq!(mine.cameras[0].c_mm, theirs.cameras[0].c_mm);
    assert_eq!(mine.cameras[0].calibrate_c, theirs.cameras[0].calibrate_c);
    assert_eq!(mine.images.len(), theirs.images.len());
    assert_eq!(mine.approx.len(), theirs.approx.len());
    // The observations agree with the shared ones to a few noise σ.
    for (a, b) in mine.images.iter().zip(&theirs.images) {
        for (o, q) in a.observations.iter().zip(&b.observations) {
            assert_eq!(o.point, q.point);
            assert!((o.x_mm.unwrap() - q.x_mm.unwrap()).abs() < 0.01);
            assert!((o.y_mm.unwrap() - q.y_mm.unwrap()).abs() < 0.01);
        }
    }
    mine.validate().unwrap();
    // Start errors of about 10 mm.
    let rms = (mine
        .approx
        .iter()
        .map(|a| {
            let t = truth.points[&a.point];
            (a.X - t[0]).powi(2) + (a.Y - t[1]).powi(2) + (a.Z - t[2]).powi(2)
        })
        .sum::<f64>()
        / (3.0 * mine.approx.len() as f64))
        .sqrt();
    assert!(rms > 0.004 && rms < 0.02, "{rms}");
}

#[test]
fn deterministic_by_seed() {
    let a = long_range(&LongRangeParams::default()).unwrap();
    let b = long_range(&LongRangeParams::default()).unwrap();
    assert_eq!(a, b);
    let c = long_range(&LongRangeParams {
        seed: 2,
        ..LongRangeParams::default()
    })
    .unwrap();
    assert_ne!(a.0, c.0);
}

fn noise_free_residuals(input: &EpochInput, truth: &Truth) -> f64 {
    // Re-project the truth with the true interior and compare with the (noise-free) observations.
    let problem = input.validate().unwrap();
    let interior = truth
        .interior
        .unwrap_or([truth.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let mut max: f64 = 0.0;
    for im in &problem.images {
        let cam = &truth.cameras[&im.id];
        for o in &im.observations {
            let x = truth.points[&problem.points[o.point]];
            let xy = project(&cam.r, cam.xo, &interior, x).unwrap();
            max = max
                .max((xy[0] - o.xy[0]).abs())
                .max((xy[1] - o.xy[1]).abs());
        }
    }
    max
}

#[test]
fn long_range_is_consistent_in_both_frames() {
    for params in [LongRangeParams::default(), LongRangeParams::enu()] {
        let (input, truth) = long_range(&LongRangeParams {
            noise_px: 0.0,
            ..params.clone()
        })
        .unwrap();
        input.validate().unwrap();
        assert_eq!(input.images.len(), 5);
        for im in &input.images {
            assert_eq!(im.observations.len(), 28, "image {} misses targets", im.id);
        }
        let worst = noise_free_residuals(&input, &truth);
        // UTM-sized coordinates round at ~4e-10 m: ~1e-9 mm in the image.
        assert!(worst < 1e-7, "{:?}: {worst} mm", params.frame);
        if params.frame != SiteFrame::TowardCameras {
            // Cameras look horizontally: r3 has no vertical component to speak of.
            for cam in truth.cameras.values() {
                assert!(cam.r[2][2].abs() < 0.03, "{:?}", cam.r);
                assert!(cam.xo[0] > 499_000.0 && cam.xo[1] > 3_899_000.0);
            }
        }
    }
    // The two frames differ by a rigid motion only: same distances between all points.
    let (a_in, a) = long_range(&LongRangeParams::default()).unwrap();
    let (b_in, b) = long_range(&LongRangeParams::enu()).unwrap();
    assert_eq!(a_in.images, b_in.images);
    let pa: Vec<_> = a.points.values().collect();
    let pb: Vec<_> = b.points.values().collect();
    for i in 0..pa.len() {
        for j in 0..i {
            let da = dot(sub(*pa[i], *pa[j]), sub(*pa[i], *pa[j])).sqrt();
            let db = dot(sub(*pb[i], *pb[j]), sub(*pb[i], *pb[j])).sqrt();
            assert!((da - db).abs() < 1e-8);
        }
    }
}

#[test]
fn calibration_network_sees_the_plate() {
    let params = CalibrationParams::default();
    let (input, truth) = calibration(&CalibrationParams {
        noise_mm: 0.0,
        ..params.clone()
    })
    .unwrap();
    input.validate().unwrap();
    assert_eq!(input.images.len(), 20);
    assert_eq!(input.control.len(), 4);
    assert!(noise_free_residuals(&input, &truth) < 1e-9);
    let mut max_r: f64 = 0.0;
    for im in &input.images {
        assert!(
            im.observations.len() >= 20,
            "{} sees {}",
            im.id,
            im.observations.len()
        );
        for o in &im.observations {
            max_r = max_r.max(o.x_mm.unwrap().hypot(o.y_mm.unwrap()));
        }
    }
    // The targets reach well into the field where the distortion is large.
    assert!(max_r > 14.0, "max radius {max_r} mm");
    let k1 = params.interior[3];
    let corner = (18.0f64).hypot(12.0);
    assert!((k1 * corner.powi(3) - 0.3).abs() < 1e-12);
}

#[test]
fn large_network_shapes() {
    let (input, _) = large(&LargeParams::default()).unwrap();
    let n: usize = input.images.iter().map(|i| i.observations.len()).sum();
    assert_eq!(n, 500 * 10);
    input.validate().unwrap();
    for im in &input.images {
        for o in &im.observations {
            assert!(o.x_mm.unwrap().abs() < 40.0 && o.y_mm.unwrap().abs() < 40.0);
        }
    }
}

#[test]
fn blunder_swaps_two_labels() {
    let (clean, _) = long_range(&LongRangeParams::default()).unwrap();
    let (dirty, _) = long_range(&LongRangeParams::with_blunder()).unwrap();
    let differing: Vec<_> = clean.images[2]
        .observations
        .iter()
        .zip(&dirty.images[2].observations)
        .filter(|(a, b)| a.point != b.point)
        .map(|(a, _)| a.point.clone())
        .collect();
    assert_eq!(differing, vec!["T101".to_string(), "T121".to_string()]);
    for i in [0, 1, 3, 4] {
        assert_eq!(clean.images[i], dirty.images[i]);
    }
    let mut e = clean.clone();
    assert!(matches!(
        swap_labels(&mut e, "nope", "T101", "T102"),
        Err(SceneError::UnknownImage(_))
    ));
    assert!(matches!(
        swap_labels(&mut e, "S1", "T101", "X"),
        Err(SceneError::UnknownPoint { .. })
    ));
}

#[test]
fn bad_parameters_are_typed_errors() {
    assert!(long_range(&LongRangeParams {
        n_stations: 1,
        ..LongRangeParams::default()
    })
    .is_err());
    assert!(long_range(&LongRangeParams {
        noise_px: f64::NAN,
        ..LongRangeParams::default()
    })
    .is_err());
    assert!(large(&LargeParams {
        images_per_point: 30,
        ..LargeParams::default()
    })
    .is_err());
    assert!(calibration(&CalibrationParams {
        grid: 1,
        ..CalibrationParams::default()
    })
    .is_err());
    assert!(paper_table1(&PaperParams {
        noise_mm: -1.0,
        ..PaperParams::default()
    })
    .is_err());
}

#[test]
fn truth_round_trips_and_gives_indexes() {
    let (_, truth) = paper_table1(&PaperParams::default()).unwrap();
    let text = serde_json::to_string(&truth).unwrap();
    assert!(text.contains("\"Xo\"") && text.contains("\"R\"") && !text.contains("interior"));
    let back: Truth = serde_json::from_str(&text).unwrap();
    assert_eq!(back.points, truth.points);
    for (id, cam) in &truth.cameras {
        let b = &back.cameras[id];
        assert_eq!(b.xo, cam.xo);
        for i in 0..3 {
            for j in 0..3 {
                assert!((b.r[i][j] - cam.r[i][j]).abs() < 1e-15);
            }
        }
    }
    let pts: Vec<AdjustedPoint> = truth
        .points
        .iter()
        .map(|(n, p)| AdjustedPoint {
            name: n.clone(),
            xyz: [p[0] + 1.0, p[1], p[2]],
            covariance_m2: [[0.0; 3]; 3],
        })
        .collect();
    assert!(truth.index3_rmse_mm(&pts).unwrap()[3] < 1e-9);
    assert!(truth.index4_rmse_mm(&pts).unwrap()[3] < 1e-9);
}

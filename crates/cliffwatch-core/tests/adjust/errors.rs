//! Bad input gives a typed error naming the image or point; malformed epochs never panic.

use cliffwatch_core::photogrammetry::input::epoch::ControlInput;
use cliffwatch_core::photogrammetry::{adjust, AdjustError, AdjustOptions, EpochError, EpochInput};
use cliffwatch_sim::scenes::{
    long_range, paper_table1, with_true_approx, LongRangeParams, PaperParams,
};
use proptest::prelude::*;

fn base() -> EpochInput {
    paper_table1(&PaperParams::default()).unwrap().0
}

fn run(e: &EpochInput) -> Result<(), AdjustError> {
    adjust(e, &AdjustOptions::default()).map(|_| ())
}

#[test]
fn fewer_than_four_known_points_names_the_image() {
    let mut e = base();
    // Image C alone sees the new points N1…N9; its only known points are 1, 2, 3.
    e.images[2]
        .observations
        .retain(|o| ["1", "2", "3"].contains(&o.point.as_str()));
    for (k, name) in ["N1", "N2", "N3", "N4", "N5"].iter().enumerate() {
        for im in 0..3 {
            e.images[im].observations.push(
                cliffwatch_core::photogrammetry::input::epoch::ObservationInput {
                    point: name.to_string(),
                    x_mm: Some(k as f64 * 0.7 - 1.0 + im as f64 * 0.1),
                    y_mm: Some(1.3 - k as f64 * 0.4),
                    col: None,
                    row: None,
                    sigma_mm: None,
                },
            );
        }
    }
    match run(&e) {
        Err(AdjustError::TooFewKnownPoints { image, known }) => {
            assert_eq!(image, "C");
            assert_eq!(known, 3);
        }
        other => panic!("expected TooFewKnownPoints for C, got {other:?}"),
    }
}

#[test]
fn point_in_one_image_only_names_the_point() {
    let mut e = base();
    e.images[0].observations.push(
        cliffwatch_core::photogrammetry::input::epoch::ObservationInput {
            point: "LONER".into(),
            x_mm: Some(1.0),
            y_mm: Some(2.0),
            col: None,
            row: None,
            sigma_mm: None,
        },
    );
    match run(&e) {
        Err(AdjustError::PointInTooFewImages { point, images }) => {
            assert_eq!(point, "LONER");
            assert_eq!(images, 1);
        }
        other => panic!("expected PointInTooFewImages, got {other:?}"),
    }
}

/// A point seen in two images from one station has no depth: the epoch is refused naming the
/// point and the station. The same two images from two stations adjust.
#[test]
fn point_seen_from_one_station_only_names_point_and_station() {
    let mut e = base();
    assert!(e.images.len() >= 3);
    let point = e.images[0].observations[0].point.clone();
    for im in &mut e.images[2..] {
        im.observations.retain(|o| o.point != point);
    }
    assert!(
        run(&e).is_ok(),
        "two stations (images '{}' and '{}') see '{point}'",
        e.images[0].id,
        e.images[1].id
    );

    e.images[0].station = Some("S1".into());
    e.images[1].station = Some("S1".into());
    match run(&e) {
        Err(AdjustError::PointFromOneStation {
            point: p,
            station,
            images,
        }) => {
            assert_eq!(p, point);
            assert_eq!(station, "S1");
            assert_eq!(images, 2);
        }
        other => panic!("expected PointFromOneStation, got {other:?}"),
    }
}

#[test]
fn nan_coordinates_name_the_image_and_point() {
    let mut e = base();
    e.images[1].observations[4].y_mm = Some(f64::NAN);
    match run(&e) {
        Err(AdjustError::Invalid(EpochError::NotFinite { item, field })) => {
            assert!(item.contains("'B'") && item.contains("'5'"), "{item}");
            assert_eq!(field, "y_mm");
        }
        other => panic!("expected NotFinite, got {other:?}"),
    }
    let mut e = base();
    e.approx[3].Z = f64::INFINITY;
    assert!(matches!(
        run(&e),
        Err(AdjustError::Invalid(EpochError::NotFinite { .. }))
    ));
}

#[test]
fn an_observation_off_the_sensor_names_the_image_and_point() {
    use cliffwatch_sim::scenes::{long_range, LongRangeParams};
    let (good, _) = long_range(&LongRangeParams::default()).unwrap();
    let (w, h) = (
        good.cameras[0].width_px.unwrap() as f64,
        good.cameras[0].height_px.unwrap() as f64,
    );
    // a column typed with one digit too many, then a target centred on the sensor's border
    for (col, row, refused) in [(10.0 * w, 0.5 * h, true), (w - 0.5, h - 0.5, false)] {
        let mut e = good.clone();
        let o = &mut e.images[1].observations[3];
        (o.col, o.row) = (Some(col), Some(row));
        let point = o.point.clone();
        match (e.validate(), refused) {
            (Err(EpochError::OutOfRange { item, reason, .. }), true) => {
                assert!(
                    item.contains(&format!("'{}'", e.images[1].id))
                        && item.contains(&format!("'{point}'")),
                    "{item}"
                );
                assert!(reason.contains("off the sensor"), "{reason}");
            }
            (Ok(_), false) => {}
            (other, _) => panic!("col {col}: {other:?}"),
        }
    }
}

#[test]
fn unknown_camera_names_the_image() {
    let mut e = base();
    e.images[2].camera = "nikon".into();
    assert_eq!(
        run(&e),
        Err(AdjustError::Invalid(EpochError::UnknownCamera {
            image: "C".into(),
            camera: "nikon".into()
        }))
    );
}

/// An observation's own σ: out of bounds it is refused naming the observation; every observation
/// at twice its camera's σ changes no coordinate and no σ0 (σ0 is expressed in the observations'
/// own σ) and quarters the variance factor; one image's observations at 10 × that σ weigh less.
#[test]
fn an_observations_own_sigma_weights_it() {
    let mut e = base();
    e.images[1].observations[2].sigma_mm = Some(1e-300);
    match run(&e) {
        Err(AdjustError::Invalid(EpochError::OutOfRange { item, field, .. })) => {
            let o = &e.images[1];
            let want = format!("image '{}' point '{}'", o.id, o.observations[2].point);
            assert_eq!((item, field.as_str()), (want, "sigma_mm"));
        }
        other => panic!("{other:?}"),
    }
    let plain = adjust(&base(), &AdjustOptions::default()).unwrap().report;
    let mut e = base();
    let s = e.cameras[0].sigma_mm.unwrap_or(0.002);
    for im in &mut e.images {
        for o in &mut im.observations {
            o.sigma_mm = Some(2.0 * s);
        }
    }
    let doubled = adjust(&e, &AdjustOptions::default()).unwrap().report;
    assert!((doubled.sigma0_mm / plain.sigma0_mm - 1.0).abs() < 1e-6);
    assert!((doubled.variance_factor / plain.variance_factor - 0.25).abs() < 1e-6);
    for (a, b) in plain.points.iter().zip(&doubled.points) {
        assert!((a.X - b.X).abs() + (a.Y - b.Y).abs() + (a.Z - b.Z).abs() < 1e-9);
    }
    let mut e = base();
    for o in &mut e.images[0].observations {
        o.sigma_mm = Some(10.0 * s);
    }
    let light = adjust(&e, &AdjustOptions::default()).unwrap().report;
    let rms = |r: &cliffwatch_core::photogrammetry::AdjustmentReport| r.images[0].rms_mm;
    assert!(
        rms(&light) > rms(&plain),
        "image 0 weighs less: its residuals grow ({} mm vs {} mm)",
        rms(&light),
        rms(&plain)
    );
}

/// A σ so small that its weight overflows is refused with its bounds, naming the camera or the
/// control point (it failed as "singular normal equations" before).
#[test]
fn a_vanishing_sigma_names_its_camera_or_control_point() {
    let mut e = base();
    e.cameras[0].sigma_mm = Some(1e-300);
    match run(&e) {
        Err(AdjustError::Invalid(EpochError::OutOfRange { item, field, .. })) => {
            assert_eq!(
                (item, field.as_str()),
                (format!("camera '{}'", e.cameras[0].id), "sigma_mm")
            );
        }
        other => panic!("{other:?}"),
    }
    let mut e = base();
    let a = e.approx[0].clone();
    e.control = vec![ControlInput {
        point: a.point.clone(),
        X: a.X,
        Y: a.Y,
        Z: a.Z,
        sigma_m: Some(1e-300),
    }];
    match run(&e) {
        Err(AdjustError::Invalid(EpochError::OutOfRange { item, field, .. })) => {
            assert_eq!(
                (item, field.as_str()),
                (format!("control point '{}'", a.point), "sigma_m")
            );
        }
        other => panic!("{other:?}"),
    }
}

/// Text PostgreSQL cannot store (NUL) or a log line should not hold: refused on both backends
/// alike, before the adjustment.
#[test]
fn a_label_with_control_characters_is_refused() {
    for label in ["a\u{0}b", "line\nbreak", "\u{1b}[31mred"] {
        let mut e = base();
        e.label = Some(label.into());
        assert_eq!(
            run(&e),
            Err(AdjustError::Invalid(EpochError::BadLabel)),
            "{label:?}"
        );
    }
    let mut e = base();
    e.label = Some("Kamo 2026-11 — campagne d'automne".into());
    assert_eq!(run(&e), Ok(()));
}

#[test]
fn a_station_outside_the_identifier_rule_names_its_image() {
    let mut e = base();
    e.images[1].station = Some("north\u{0}".into());
    let id = e.images[1].id.clone();
    assert_eq!(
        run(&e),
        Err(AdjustError::Invalid(EpochError::BadIdentifier(format!(
            "station 'north\u{0}' of image '{id}'"
        ))))
    );
}

#[test]
fn duplicate_observation_names_image_and_point() {
    let mut e = base();
    let dup = e.images[0].observations[6].clone();
    e.images[0].observations.push(dup);
    assert_eq!(
        run(&e),
        Err(AdjustError::Invalid(EpochError::DuplicateObservation {
            image: "A".into(),
            point: "7".into()
        }))
    );
}

#[test]
fn empty_epoch_is_an_error() {
    let mut e = base();
    e.images.clear();
    assert_eq!(run(&e), Err(AdjustError::Invalid(EpochError::Empty)));
    let e: EpochInput = serde_json::from_str(r#"{"observed_at": "2026-11-21T09:00:00Z"}"#).unwrap();
    assert_eq!(run(&e), Err(AdjustError::Invalid(EpochError::Empty)));
    // Images without observations.
    let mut e = base();
    for im in &mut e.images {
        im.observations.clear();
    }
    assert!(run(&e).is_err());
}

/// One way of breaking an epoch.
#[derive(Debug, Clone)]
enum Damage {
    DropObservation(usize, usize),
    DropApprox(usize),
    SetX(usize, usize, f64),
    SetApproxZ(usize, f64),
    Rename(usize, usize, String),
    DropImage(usize),
    DuplicateImage(usize),
    CameraC(f64),
    Pixel(usize, usize, f64, f64),
    Calibrate(Vec<String>),
    CollapseImage(usize),
}

fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(1e300),
        Just(-1e-300),
        -1e6..1e6f64,
        -50.0..50.0f64,
    ]
}

fn damage() -> impl Strategy<Value = Damage> {
    prop_oneof![
        (0..4usize, 0..14usize).prop_map(|(i, o)| Damage::DropObservation(i, o)),
        (0..14usize).prop_map(Damage::DropApprox),
        (0..4usize, 0..14usize, number()).prop_map(|(i, o, v)| Damage::SetX(i, o, v)),
        (0..14usize, number()).prop_map(|(a, v)| Damage::SetApproxZ(a, v)),
        (0..4usize, 0..14usize, "[A-Za-z0-9 ]{0,3}").prop_map(|(i, o, s)| Damage::Rename(i, o, s)),
        (0..4usize).prop_map(Damage::DropImage),
        (0..4usize).prop_map(Damage::DuplicateImage),
        number().prop_map(Damage::CameraC),
        (0..4usize, 0..14usize, number(), number())
            .prop_map(|(i, o, c, r)| Damage::Pixel(i, o, c, r)),
        prop::collection::vec(
            prop_oneof![Just("c"), Just("k1"), Just("x0"), Just("p2"), Just("zz")],
            0..4
        )
        .prop_map(|v| Damage::Calibrate(v.into_iter().map(String::from).collect())),
        (0..4usize).prop_map(Damage::CollapseImage),
    ]
}

fn apply(e: &mut EpochInput, d: &Damage) {
    let ni = e.images.len();
    match d {
        Damage::DropObservation(i, o) if *i < ni => {
            let obs = &mut e.images[*i].observations;
            if *o < obs.len() {
                obs.remove(*o);
            }
        }
        Damage::DropApprox(a) if *a < e.approx.len() => {
            e.approx.remove(*a);
        }
        Damage::SetX(i, o, v) if *i < ni => {
            if let Some(ob) = e.images[*i].observations.get_mut(*o) {
                ob.x_mm = Some(*v);
            }
        }
        Damage::SetApproxZ(a, v) => {
            if let Some(ap) = e.approx.get_mut(*a) {
                ap.Z = *v;
            }
        }
        Damage::Rename(i, o, s) if *i < ni => {
            if let Some(ob) = e.images[*i].observations.get_mut(*o) {
                ob.point = s.clone();
            }
        }
        Damage::DropImage(i) if *i < ni => {
            e.images.remove(*i);
        }
        Damage::DuplicateImage(i) if *i < ni => {
            let mut im = e.images[*i].clone();
            im.id.push('x');
            e.images.push(im);
        }
        Damage::CameraC(v) => e.cameras[0].c_mm = *v,
        Damage::Pixel(i, o, c, r) if *i < ni => {
            if let Some(ob) = e.images[*i].observations.get_mut(*o) {
                (ob.x_mm, ob.y_mm, ob.col, ob.row) = (None, None, Some(*c), Some(*r));
            }
            e.cameras[0].pixel_size_mm = Some(0.01);
            e.cameras[0].width_px = Some(2000);
            e.cameras[0].height_px = Some(1500);
        }
        Damage::Calibrate(v) => e.cameras[0].calibrate = Some(v.clone()),
        Damage::CollapseImage(i) if *i < ni => {
            // Every observation of the image at the same place: a degenerate resection.
            for ob in &mut e.images[*i].observations {
                ob.x_mm = Some(0.5);
                ob.y_mm = Some(0.5);
            }
        }
        _ => {}
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn malformed_epochs_never_panic(damages in prop::collection::vec(damage(), 1..5)) {
        let mut e = base();
        for d in &damages {
            apply(&mut e, d);
        }
        let opts = AdjustOptions { max_iterations: 30, ..AdjustOptions::default() };
        // Any Ok or Err is fine; a panic fails the property.
        let result = adjust(&e, &opts);
        if let Ok(a) = result {
            prop_assert!(a.report.sigma0_mm.is_finite());
        }
    }

    #[test]
    fn arbitrary_json_never_panics(text in "\\\\PC{0,200}") {
        if let Ok(e) = serde_json::from_str::<EpochInput>(&text) {
            let _ = adjust(&e, &AdjustOptions::default());
        }
    }
}

/// The orthogonal model estimates only c: asking it for more is said in a warning that names the
/// camera and the parameters held, and the central model gives no such warning.
#[test]
fn the_orthogonal_model_says_which_parameters_it_holds() {
    let mut e = base();
    e.cameras[0].calibrate = Some(vec!["c".into(), "k1".into(), "x0".into()]);
    let warned = |model| {
        let options = AdjustOptions {
            model,
            ..AdjustOptions::default()
        };
        adjust(&e, &options)
            .expect("adjusts")
            .report
            .warnings
            .into_iter()
            .find(|w| w.contains("estimates only c"))
    };
    let w = warned(cliffwatch_core::photogrammetry::Model::Orthogonal).expect("a warning");
    assert!(w.contains(&format!("camera '{}'", e.cameras[0].id)), "{w}");
    assert!(w.contains("x0, k1"), "{w}");
    assert!(warned(cliffwatch_core::photogrammetry::Model::Central).is_none());
}

/// A target that moved since its approximate coordinates were taken misfits every image's
/// resection at the start. With control points (no free-network prior to hold it), it once lost
/// all its observations and the epoch failed as "not positive definite", naming nothing. Now it
/// starts from the intersection of its rays and is adjusted like any other point.
#[test]
fn a_point_far_from_its_approximation_is_intersected_afresh() {
    for seed in 1..=5 {
        let (input, truth) = long_range(&LongRangeParams {
            seed,
            ..LongRangeParams::default()
        })
        .unwrap();
        let mut e = with_true_approx(&input, &truth);
        let names: Vec<&String> = truth.points.keys().collect();
        e.control = names[..4]
            .iter()
            .map(|n| {
                let x = truth.points[*n];
                ControlInput {
                    point: (*n).clone(),
                    X: x[0],
                    Y: x[1],
                    Z: x[2],
                    sigma_m: None,
                }
            })
            .collect();
        let moved = names[names.len() / 2].clone();
        let a = e.approx.iter_mut().find(|a| a.point == moved).unwrap();
        a.X += 0.3;
        a.Z -= 0.2;
        let adjusted = adjust(&e, &AdjustOptions::default())
            .unwrap_or_else(|err| panic!("seed {seed}, {moved} off by 0.36 m: {err}"));
        let p = adjusted.points.iter().find(|p| p.name == moved).unwrap();
        let t = truth.points[&moved];
        let error_mm =
            ((p.xyz[0] - t[0]).powi(2) + (p.xyz[1] - t[1]).powi(2) + (p.xyz[2] - t[2]).powi(2))
                .sqrt()
                * 1e3;
        assert!(
            error_mm < 20.0,
            "seed {seed}: {moved} {error_mm:.2} mm from the truth"
        );
    }
}

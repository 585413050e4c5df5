//! Units caught at the door (`photogrammetry::input::plausible`): every simulated scene, the shared
//! paper epochs and DBAT's real measurements are accepted; the same epochs with approximations or
//! control in millimetres, c in metres, or pixels given as mm are refused naming the field.

use cliffwatch_core::photogrammetry::input::epoch::{
    ApproxInput, CameraInput, ImageInput, ObservationInput,
};
use cliffwatch_core::photogrammetry::input::plausible::validate;
use cliffwatch_core::photogrammetry::{EpochError, EpochInput};
use cliffwatch_sim::scenes::{
    calibration, large, long_range, paper_table1, CalibrationParams, LargeParams, LongRangeParams,
    PaperCase, PaperParams,
};

use crate::support::adjust::shared;
use crate::support::dbat::{marks, pm_points, C_MM, PIXEL_MM, SIZE_PX};

/// The simulated epochs, named: three paper cases × three seeds, the long-range cliff (in its own
/// frame, in ENU with UTM-sized coordinates, flat), the calibration plate, a large network.
fn simulated() -> Vec<(String, EpochInput)> {
    let mut out = Vec::new();
    for (case, name) in [
        (PaperCase::Case1, "paper-1"),
        (PaperCase::Case2, "paper-2"),
        (PaperCase::Case3, "paper-3"),
    ] {
        for seed in [101, 102, 103] {
            let (e, _) = paper_table1(&PaperParams::case(case, seed)).expect("paper scene");
            out.push((format!("{name} seed {seed}"), e));
        }
    }
    for (name, p) in [
        ("long-range", LongRangeParams::default()),
        ("long-range-enu", LongRangeParams::enu()),
        ("flat", LongRangeParams::flat()),
        (
            "long-range in mm",
            LongRangeParams {
                pixel_observations: false,
                seed: 7,
                ..LongRangeParams::default()
            },
        ),
    ] {
        out.push((name.into(), long_range(&p).expect("long-range scene").0));
    }
    let cal = calibration(&CalibrationParams::default()).expect("calibration scene");
    out.push(("calibration".into(), cal.0));
    out.push((
        "large".into(),
        large(&LargeParams::default()).expect("large").0,
    ));
    out
}

/// DBAT's real photographs as PhotoModeler measured them (pixels), its points as approximations.
fn dbat() -> EpochInput {
    let mut images: Vec<ImageInput> = marks()
        .into_iter()
        .map(|(name, m)| ImageInput {
            id: name.trim_end_matches(".JPG").into(),
            camera: "olympus".into(),
            station: None,
            observations: m
                .into_iter()
                .map(|(id, col, row)| ObservationInput {
                    point: format!("P{id}"),
                    x_mm: None,
                    y_mm: None,
                    col: Some(col),
                    row: Some(row),
                    sigma_mm: None,
                })
                .collect(),
        })
        .collect();
    images.sort_by(|a, b| a.id.cmp(&b.id));
    EpochInput {
        observed_at: "2004-08-25T12:00:00Z".into(),
        label: None,
        cameras: vec![CameraInput {
            id: "olympus".into(),
            c_mm: C_MM,
            calibrate_c: true,
            calibrate: None,
            pixel_size_mm: Some(PIXEL_MM),
            width_px: Some(SIZE_PX.0),
            height_px: Some(SIZE_PX.1),
            x0_mm: 0.0,
            y0_mm: 0.0,
            k1: 0.0,
            k2: 0.0,
            k3: 0.0,
            p1: 0.0,
            p2: 0.0,
            sigma_mm: None,
        }],
        images,
        control: Vec::new(),
        approx: pm_points()
            .into_iter()
            .map(|(id, p)| ApproxInput {
                point: format!("P{id}"),
                X: p[0],
                Y: p[1],
                Z: p[2],
            })
            .collect(),
    }
}

/// The refusal's field and message, or a failure saying what was accepted.
fn implausible(name: &str, e: &EpochInput) -> (String, String) {
    match validate(e) {
        Err(err @ EpochError::Implausible { .. }) => {
            let EpochError::Implausible { ref field, .. } = err else {
                unreachable!()
            };
            (field.clone(), err.to_string())
        }
        other => panic!("{name}: expected an implausible-units refusal, got {other:?}"),
    }
}

#[test]
fn every_simulated_shared_and_real_epoch_is_plausible() {
    let mut all = simulated();
    for case in 1..=3 {
        for seed in [101, 102, 103] {
            if let Some((e, _)) = shared(case, seed) {
                all.push((format!("shared paper-case{case}-seed{seed}"), e));
            }
        }
    }
    all.push(("dbat-camcal".into(), dbat()));
    assert!(all.len() >= 15, "{} epochs", all.len());
    for (name, e) in &all {
        if let Err(err) = validate(e) {
            panic!("{name} refused: {err}");
        }
    }
}

#[test]
fn approximations_in_millimetres_are_refused_naming_approx() {
    let mut checked = 0;
    for (name, mut e) in simulated() {
        // The calibration plate is 1.4 m from its cameras: in mm it would stand 1.4 km away,
        // which a cliff may; the check does not claim it.
        if name == "calibration" || e.approx.is_empty() {
            continue;
        }
        for a in &mut e.approx {
            (a.X, a.Y, a.Z) = (a.X * 1000.0, a.Y * 1000.0, a.Z * 1000.0);
        }
        checked += 1;
        if name == "long-range-enu" {
            // UTM-sized coordinates in mm pass the bound of any coordinate, 10⁸ m.
            let message = validate(&e).unwrap_err().to_string();
            assert!(
                message.starts_with("approx point 'T101': X ")
                    && message.contains("looks like millimetres")
                    && message.ends_with("expected metres"),
                "{message}"
            );
            continue;
        }
        let (field, message) = implausible(&name, &e);
        assert_eq!(field, "approx", "{name}: {message}");
        assert!(message.contains("millimetres"), "{name}: {message}");
        assert!(
            message.contains("expected coordinates in metres"),
            "{name}: {message}"
        );
    }
    assert!(checked >= 12, "{checked} scenes");
}

#[test]
fn control_in_millimetres_is_refused_naming_control() {
    // The long-range scene's approximations (in m) become control in mm for four points.
    let (mut e, _) = long_range(&LongRangeParams::default()).expect("scene");
    let mut control = Vec::new();
    for a in e.approx.iter().take(6) {
        control.push(
            cliffwatch_core::photogrammetry::input::epoch::ControlInput {
                point: a.point.clone(),
                X: a.X * 1000.0,
                Y: a.Y * 1000.0,
                Z: a.Z * 1000.0,
                sigma_m: None,
            },
        );
    }
    e.control = control;
    let (field, message) = implausible("long-range", &e);
    assert_eq!(field, "control", "{message}");
    // The same control in metres is accepted.
    for c in &mut e.control {
        (c.X, c.Y, c.Z) = (c.X / 1000.0, c.Y / 1000.0, c.Z / 1000.0);
    }
    assert!(validate(&e).is_ok(), "{:?}", validate(&e));
}

#[test]
fn c_in_metres_is_refused_naming_c_mm_of_the_camera() {
    let mut all = simulated();
    all.push(("dbat-camcal".into(), dbat()));
    for (name, mut e) in all {
        let last = e.cameras.len() - 1;
        let c = e.cameras[last].c_mm;
        e.cameras[last].c_mm = c / 1000.0;
        let (field, message) = implausible(&name, &e);
        assert!(
            field.starts_with(&format!("cameras[{last}].c_mm")),
            "{name}: {message}"
        );
        assert!(message.contains("looks like metres"), "{name}: {message}");
        assert!(
            message.contains("expected the principal distance in millimetres"),
            "{name}: {message}"
        );
    }
}

#[test]
fn pixels_given_as_mm_are_refused_naming_the_observation() {
    for (name, pixel_mm) in [("paper-1 seed 101", 0.005), ("paper-3 seed 102", 0.0105)] {
        let (_, mut e) = simulated()
            .into_iter()
            .find(|(n, _)| n == name)
            .expect("scene");
        for o in e.images.iter_mut().flat_map(|i| i.observations.iter_mut()) {
            o.x_mm = o.x_mm.map(|x| x / pixel_mm);
            o.y_mm = o.y_mm.map(|y| y / pixel_mm);
        }
        let (field, message) = implausible(name, &e);
        assert!(
            field.starts_with("images[") && field.ends_with("x_mm, y_mm"),
            "{name}: {message}"
        );
        assert!(message.contains("look like pixels"), "{name}: {message}");
    }
}

/// One grossly wrong control point among six (the long-range scene's first target mirrored
/// through the cameras' mean centre) is not taken for a unit error: each image's distance is the
/// median over pairs of points, most of which it is not in.
#[test]
fn one_gross_control_point_is_not_a_unit_error() {
    use cliffwatch_core::photogrammetry::input::epoch::ControlInput;
    let (mut e, truth) = long_range(&LongRangeParams::default()).expect("scene");
    let n = truth.cameras.len() as f64;
    let mut centre = [0.0; 3];
    for cam in truth.cameras.values() {
        for k in 0..3 {
            centre[k] += cam.xo[k] / n;
        }
    }
    e.control = e
        .approx
        .iter()
        .take(6)
        .map(|a| {
            let p = truth.points[&a.point];
            ControlInput {
                point: a.point.clone(),
                X: p[0],
                Y: p[1],
                Z: p[2],
                sigma_m: None,
            }
        })
        .collect();
    let c = &mut e.control[0];
    (c.X, c.Y, c.Z) = (
        2.0 * centre[0] - c.X,
        2.0 * centre[1] - c.Y,
        2.0 * centre[2] - c.Z,
    );
    assert!(validate(&e).is_ok(), "{:?}", validate(&e));
    // All six in mm is still a unit error.
    for c in &mut e.control {
        (c.X, c.Y, c.Z) = (c.X * 1000.0, c.Y * 1000.0, c.Z * 1000.0);
    }
    assert_eq!(implausible("control in mm", &e).0, "control");
}

//! `cliffwatch plan PLAN.json` as a user runs it: one object per target with its σ, σ along the
//! face normal and MDDs, the network's figures, and a larger σ once a station is removed.

use serde_json::{json, Value};

/// A small plan: four stations 150 m in front of a 4 m × 3 m face (site frame X east, Y toward
/// the cameras, Z up), 400 mm lens, 12 targets with up to 0.8 m of relief, four known.
fn plan(stations: usize) -> Value {
    let targets: Vec<Value> = (0..12)
        .map(|k| {
            let (i, j) = ((k % 4) as f64, (k / 4) as f64);
            let known = [0, 3, 8, 11].contains(&k);
            json!({
                "point": format!("T{k:02}"),
                "xyz": [-2.0 + 4.0 * i / 3.0, 0.8 * ((1.3 * i + 0.7 * j).sin().abs()), 0.2 + 1.3 * j],
                "known": known,
            })
        })
        .collect();
    let stations: Vec<Value> = [-30.0, -10.0, 10.0, 30.0]
        .iter()
        .take(stations)
        .enumerate()
        .map(|(n, x)| {
            json!({
                "name": format!("S{}", n + 1),
                "camera": "cam",
                "position": [x, 150.0, 1.0],
                "aim": [0.0, 0.4, 1.5],
            })
        })
        .collect();
    json!({
        "sigma_px": 0.25,
        "cameras": [{"id": "cam", "c_mm": 400.0, "pixel_size_mm": 0.0105,
                     "width_px": 2160, "height_px": 1440}],
        "stations": stations,
        "targets": targets,
    })
}

/// Runs `cliffwatch plan` on `plan` and returns its output.
fn run_plan(plan: &Value) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    std::fs::write(&path, plan.to_string()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .arg("plan")
        .arg(&path)
        .output()
        .expect("run cliffwatch");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

#[test]
fn the_plan_command_reports_every_target_and_a_dropped_station_weakens_it() {
    let four = run_plan(&plan(4));
    assert_eq!(four["confidence"], json!(0.95));
    assert_eq!(four["power"], json!(0.8));
    assert!(four["sigma_c_mm"].as_f64().unwrap() > 0.0);
    // 0.8 m of relief at 150 m: c is weakly determined, and nothing else is wrong.
    let warnings = four["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0]
        .as_str()
        .unwrap()
        .contains("c is weakly determined"));
    let targets = four["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 12);
    for t in targets {
        assert_eq!(t["cameras"], json!(4), "{t}");
        for axis in ["x", "y", "z"] {
            let s = t["sigma_mm"][axis].as_f64().unwrap();
            // About 0.25 px × 10.5 µm × 150 m / 0.4 m ≈ 1 mm in the image plane.
            assert!(s > 0.05 && s < 20.0, "{t}");
        }
        let normal = t["sigma_normal_mm"].as_f64().unwrap();
        let mdd_normal = t["mdd_normal_mm"].as_f64().unwrap();
        let mdd_3d = t["mdd_3d_mm"].as_f64().unwrap();
        // The MDD of two epochs exceeds the σ of one and the worst direction bounds the normal.
        assert!(
            mdd_normal > 2.0 * normal && mdd_3d >= mdd_normal * (1.0 - 1e-9),
            "{t}"
        );
    }

    let three = run_plan(&plan(3));
    for (a, b) in targets.iter().zip(three["targets"].as_array().unwrap()) {
        assert_eq!(b["cameras"], json!(3));
        let trace = |t: &Value| {
            ["x", "y", "z"]
                .iter()
                .map(|k| t["sigma_mm"][k].as_f64().unwrap().powi(2))
                .sum::<f64>()
        };
        assert!(trace(b) > trace(a), "{} → {}", a, b);
        assert!(b["mdd_3d_mm"].as_f64().unwrap() > a["mdd_3d_mm"].as_f64().unwrap());
    }
}

/// A station naming a camera the plan lacks fails with a message naming both.
#[test]
fn the_plan_command_names_a_bad_station() {
    let mut bad = plan(4);
    bad["stations"][2]["camera"] = json!("nikon");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    std::fs::write(&path, bad.to_string()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .arg("plan")
        .arg(&path)
        .output()
        .expect("run cliffwatch");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("S3") && err.contains("nikon"), "{err}");
}

//! Bad image files through `cliffwatch detect`: each is named on standard error with why, the
//! good images are still measured (one JSON line each), and the exit status is 1.

use std::collections::BTreeMap;
use std::process::Command;

use cliffwatch_core::detect::GreyImage;
use cliffwatch_sim::images::{encode_png, render, scatter_targets, ImageSpec, TargetTruth};

use crate::support::bad_images::{
    giant_file, odd_tiff16, one_pixel_png, png_claiming, truncated_jpeg,
};

/// A rendered 16-bit image of 4 targets of 10 px and the targets.
fn rendered(w: u32, h: u32, seed: u64) -> (GreyImage, Vec<TargetTruth>) {
    let mut spec = ImageSpec::new(w, h, 16);
    spec.targets = scatter_targets(w, h, 4, 10.0, 50.0 * spec.noise_sigma, 1.2, seed);
    let r = render(&spec, seed).unwrap();
    (r.image, r.targets)
}

fn to_8bit(img: &GreyImage) -> GreyImage {
    let d = img.data().iter().map(|&v| v / 257).collect();
    GreyImage::new(img.width(), img.height(), 8, d).unwrap()
}

#[test]
fn detect_names_each_bad_file_measures_the_rest_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let (good, good_truth) = rendered(201, 157, 1);
    std::fs::write(p("good.png"), encode_png(&to_8bit(&good)).unwrap()).unwrap();
    std::fs::write(p("truncated.jpg"), truncated_jpeg(&to_8bit(&good))).unwrap();
    std::fs::write(p("one_pixel.png"), one_pixel_png()).unwrap();
    let (odd, odd_truth) = rendered(123, 97, 2);
    std::fs::write(p("odd16.tif"), odd_tiff16(&odd)).unwrap();
    std::fs::write(p("huge.png"), png_claiming(100_000, 100_000)).unwrap();
    giant_file(&p("giant.jpg"));
    let names = [
        "good.png",
        "truncated.jpg",
        "one_pixel.png",
        "odd16.tif",
        "huge.png",
        "giant.jpg",
    ];
    let out = Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .arg("detect")
        .args(names.iter().map(|n| p(n)))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!("stdout:\n{stdout}\nstderr:\n{stderr}");
    assert_eq!(out.status.code(), Some(1), "exit status");
    let lines: BTreeMap<String, serde_json::Value> = stdout
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            let image = v["image"].as_str().unwrap().to_string();
            let name = image.rsplit('/').next().unwrap().to_string();
            (name, v)
        })
        .collect();
    // each bad file named with its reason, none in the output
    for (name, reason) in [
        ("truncated.jpg", "truncated JPEG"),
        ("one_pixel.png", "too small"),
        ("huge.png", "too large"),
        ("giant.jpg", "exceeds the limit"),
    ] {
        let line = stderr
            .lines()
            .find(|l| l.contains(name))
            .unwrap_or_else(|| panic!("{name} not named on stderr"));
        assert!(line.contains(reason), "{name}: {line}");
        assert!(!lines.contains_key(name), "{name} measured");
    }
    // the good ones measured: every target found where it was rendered
    let mut measured = vec![("good.png", &good_truth)];
    // The odd TIFF is measured right or named with a clear reason, never misread.
    match lines.get("odd16.tif") {
        Some(_) => measured.push(("odd16.tif", &odd_truth)),
        None => {
            let line = stderr.lines().find(|l| l.contains("odd16.tif")).unwrap();
            assert!(line.contains("cannot decode"), "{line}");
        }
    }
    for (name, truth) in measured {
        let v = &lines[name];
        let targets = v["targets"].as_array().unwrap();
        assert_eq!(targets.len(), truth.len(), "{name}: {v}");
        for t in truth {
            let e = targets
                .iter()
                .map(|x| {
                    (x["col"].as_f64().unwrap() - t.col).hypot(x["row"].as_f64().unwrap() - t.row)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                e < 0.1,
                "{name}: target at ({}, {}) off by {e} px",
                t.col,
                t.row
            );
        }
    }
    assert!(
        stderr.contains("4 of 6 images could not be measured")
            || stderr.contains("5 of 6 images could not be measured"),
        "{stderr}"
    );
}

//! `cliffwatch adjust FILE --truth TRUTH` as a user runs it: the report it prints is the
//! in-process adjustment of the same file, written as one compact JSON line into a pipe.

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, EpochInput};
use serde_json::Value;

fn cliffwatch(args: &[&std::ffi::OsStr]) -> std::process::Output {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .args(args)
        .output()
        .expect("run cliffwatch");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

#[test]
fn the_adjust_command_prints_the_in_process_report() {
    let dir = tempfile::tempdir().unwrap();
    for seed in 1..=3u64 {
        let seed_text = seed.to_string();
        cliffwatch(&[
            "simulate".as_ref(),
            "--scene".as_ref(),
            "long-range".as_ref(),
            "--seed".as_ref(),
            seed_text.as_ref(),
            "--out-dir".as_ref(),
            dir.path().as_os_str(),
        ]);
        let epoch = dir.path().join(format!("long-range-seed{seed}.epoch.json"));
        let truth = dir.path().join(format!("long-range-seed{seed}.truth.json"));
        let out = cliffwatch(&[
            "adjust".as_ref(),
            epoch.as_os_str(),
            "--truth".as_ref(),
            truth.as_os_str(),
        ]);
        let text = String::from_utf8(out.stdout).unwrap();
        assert_eq!(text.lines().count(), 1, "compact into a pipe");
        let printed: Value = serde_json::from_str(&text).unwrap();

        let input: EpochInput =
            serde_json::from_str(&std::fs::read_to_string(&epoch).unwrap()).unwrap();
        let direct = adjust(&input, &AdjustOptions::default()).unwrap().report;
        let direct = serde_json::to_value(&direct).unwrap();
        assert_eq!(printed["converged"], Value::Bool(true));
        let close = |a: &Value, b: &Value, what: &str| {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(
                (a - b).abs() <= 1e-9 * b.abs().max(1.0),
                "{what}: {a} vs {b}"
            );
        };
        close(&printed["sigma0_mm"], &direct["sigma0_mm"], "σ0");
        close(
            &printed["cameras"][0]["c_mm"],
            &direct["cameras"][0]["c_mm"],
            "c",
        );
        let (p, d) = (
            printed["points"].as_array().unwrap(),
            direct["points"].as_array().unwrap(),
        );
        assert_eq!(p.len(), d.len());
        for (a, b) in p.iter().zip(d) {
            assert_eq!(a["point"], b["point"]);
            for k in ["X", "Y", "Z", "sigma_X_mm", "sigma_Y_mm", "sigma_Z_mm"] {
                close(&a[k], &b[k], k);
            }
        }
        // Against the truth (seeds 1–3: depth 1.3–1.5 mm rms, 0.81–0.94 mm over the three axes);
        // a wrong frame or scale would be metres off.
        let rmse = printed["index3_rmse_mm"]
            .as_array()
            .expect("index 3 with --truth");
        let total = rmse[3].as_f64().unwrap();
        assert!(
            total > 0.0 && total < 2.0,
            "seed {seed}: index 3 {total} mm"
        );
    }
}

/// `cliffwatch adjust FILE | head -c 1`: the reader goes away after its first byte; the command
/// ends quietly with success, as Unix tools do, instead of printing an error.
#[test]
fn a_reader_that_goes_away_ends_the_command_quietly() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    cliffwatch(&[
        "simulate".as_ref(),
        "--scene".as_ref(),
        "large".as_ref(),
        "--seed".as_ref(),
        "1".as_ref(),
        "--out-dir".as_ref(),
        dir.path().as_os_str(),
    ]);
    let epoch = dir.path().join("large-seed1.epoch.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
        .arg("adjust")
        .arg(&epoch)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut first = [0u8; 1];
    stdout.read_exact(&mut first).unwrap();
    assert_eq!(&first, b"{");
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

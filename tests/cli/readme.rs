//! The README's quick start, run as written (extracted from the README, only the address and
//! the `cargo run --release --` prefix replaced by the test's daemon and binary) against a fresh
//! daemon: every command succeeds, every later epoch is answered 201, and the incidents it ends
//! with hold one alarm for block B1 with a forecast.

use crate::support;

use support::alerts::write_config;
use support::server::Daemon;

/// The indented command block of the README's "Quick start" section.
fn quick_start(readme: &str) -> String {
    let section = readme
        .split("\n## Quick start")
        .nth(1)
        .expect("the README has a Quick start section");
    let mut out = vec![];
    let mut started = false;
    for line in section.lines() {
        if let Some(cmd) = line.strip_prefix("    ") {
            started = true;
            out.push(cmd.to_string());
        } else if started && !line.trim().is_empty() {
            break;
        }
    }
    out.join("\n")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_readme_quick_start_runs_to_the_end() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let script = quick_start(&readme);
    assert!(
        script.contains("simulate --scene monitoring-series"),
        "{script}"
    );
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let address = d.base.trim_start_matches("http://").to_string();
    let script = script
        .replace("localhost:8080", &address)
        .replace("127.0.0.1:8080", &address)
        .replace(
            "cargo run --release -- ",
            &format!("{} ", env!("CARGO_BIN_EXE_cliffwatch")),
        );
    let work = dir.path().join("work");
    std::fs::create_dir(&work).unwrap();
    let out = tokio::task::spawn_blocking(move || {
        std::process::Command::new("bash")
            .args(["-euo", "pipefail", "-c", &script])
            .current_dir(&work)
            .output()
            .expect("bash runs")
    })
    .await
    .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{stdout}\n{stderr}");
    // Step 5: the 39 later epochs, each 201 (`FILE CODE` after the previous answer's JSON).
    let answered: Vec<&str> = stdout
        .split("demo/monitoring-series-seed1-0")
        .skip(1)
        .filter_map(|l| l.split_once(".epoch.json ").map(|(_, rest)| rest))
        .map(|rest| rest.get(..3).unwrap_or(rest))
        .collect();
    assert_eq!(answered.len(), 39, "{stdout}");
    assert!(answered.iter().all(|code| *code == "201"), "{answered:?}");
    // Step 6: one incident for the block, at alarm, with its forecast.
    let incidents = &stdout[stdout.rfind("{\"items\"").expect("the incidents")..];
    let incidents: serde_json::Value = serde_json::from_str(incidents.trim()).unwrap();
    let first = &incidents["items"][0];
    assert_eq!(first["id"], "block:B1", "{incidents:#}");
    assert_eq!(first["level"], "alarm", "{first:#}");
    assert!(first["forecast"]["likely_before"].is_string(), "{first:#}");
}

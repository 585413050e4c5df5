//! Every upload's work is bounded and ends with it (issue 79, item 1): an epoch larger than the
//! node takes is refused before any computation, naming the limit; an upload that computes past
//! its request's time limit is answered 408, stops computing and frees its slot at once, so the
//! next upload gets its 201 and the CPU is idle again; SIGTERM ends the process within its grace
//! period whatever it was computing. The last two run the real binary, whose CPU time is read
//! from `/proc`.

use crate::support;

use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::server::{paper, Daemon, TestServer, PAPER};

/// A paper epoch with `extra` more points seen in each of its images at random places, with
/// start values: valid for the schema, and a long computation (its adjustment chases thousands
/// of observations that fit nothing).
fn oversized_epoch(extra: usize) -> Value {
    let mut e = paper(PAPER[6]);
    let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut uniform = move |lo: f64, hi: f64| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (state >> 11) as f64 / (1u64 << 53) as f64;
        ((lo + u * (hi - lo)) * 1000.0).round() / 1000.0
    };
    for image in e["images"].as_array_mut().unwrap() {
        let obs = image["observations"].as_array_mut().unwrap();
        for k in 0..extra {
            let (x, y) = (uniform(-10.0, 10.0), uniform(-7.0, 7.0));
            obs.push(json!({"point": format!("X{k}"), "x_mm": x, "y_mm": y}));
        }
    }
    let approx = e["approx"]
        .as_array_mut()
        .expect("the paper epoch has approx");
    for k in 0..extra {
        let (x, y, z) = (
            uniform(-20.0, 20.0),
            uniform(-20.0, 20.0),
            uniform(-5.0, 5.0),
        );
        approx.push(json!({"point": format!("X{k}"), "X": x, "Y": y, "Z": z}));
    }
    e
}

/// Seconds of CPU the process has used (user + system), from `/proc/PID/stat`.
fn cpu_seconds(pid: u32) -> f64 {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).expect("/proc/PID/stat");
    // the fields after the command's closing parenthesis; utime and stime are the 14th and 15th
    let after = &stat[stat.rfind(')').unwrap() + 2..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks: f64 = fields[11].parse::<f64>().unwrap() + fields[12].parse::<f64>().unwrap();
    // SAFETY: sysconf only reads a system constant.
    let per_second = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    assert!(per_second > 0, "clock ticks per second");
    ticks / per_second as f64
}

/// A configuration file for the binary: one upload slot, short time limits, and epoch limits
/// large enough for [`oversized_epoch`] to be computed.
fn config(dir: &std::path::Path, request_timeout_secs: u64, grace_secs: u64) -> std::path::PathBuf {
    let path = dir.join("cliffwatch.toml");
    std::fs::write(
        &path,
        format!(
            "max_concurrent_uploads = 1\nrequest_timeout_secs = {request_timeout_secs}\n\
             upload_queue_secs = 4.0\nshutdown_grace_secs = {grace_secs}\n\
             max_epoch_points = 100000\nmax_epoch_observations = 1000000\n"
        ),
    )
    .unwrap();
    path
}

async fn create_site(d: &Daemon, id: &str) {
    let (status, body) = d
        .send(
            reqwest::Method::POST,
            "/api/v1/sites",
            Some(&json!({"id": id})),
        )
        .await;
    assert_eq!(status, 201, "{body}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_timed_out_upload_stops_computing_and_the_next_upload_gets_its_slot() {
    let dir = tempfile::tempdir().unwrap();
    let timeout = Duration::from_secs(5);
    let grace = Duration::from_secs(5);
    let mut d = Daemon::start(
        &dir.path().join("data"),
        &config(dir.path(), timeout.as_secs(), grace.as_secs()),
    )
    .await;
    create_site(&d, "big").await;
    create_site(&d, "ordinary").await;
    let big = serde_json::to_vec(&oversized_epoch(20_000)).unwrap();
    assert!(
        big.len() < 16 << 20,
        "under the body limit: {} bytes",
        big.len()
    );

    let started = Instant::now();
    let answer = d
        .client
        .post(d.url("/api/v1/sites/big/epochs"))
        .header("content-type", "application/json")
        .body(big)
        .send()
        .await
        .unwrap();
    let answered = Instant::now();
    assert_eq!(answer.status(), 408, "the request time limit answers it");
    assert!(
        answered - started <= timeout + Duration::from_secs(1),
        "answered after {:?}",
        answered - started
    );

    // The slot is free again within a second of the answer (the metric of busy slots reads 0).
    let freed = loop {
        let metrics = d.client.get(d.url("/metrics")).send().await.unwrap();
        let text = metrics.text().await.unwrap();
        let busy = text
            .lines()
            .find(|l| l.starts_with("cliffwatch_upload_slots_busy"))
            .and_then(|l| l.split_whitespace().last())
            .and_then(|v| v.parse::<f64>().ok());
        if busy == Some(0.0) {
            break answered.elapsed();
        }
        assert!(
            answered.elapsed() < Duration::from_secs(5),
            "slot still busy: {busy:?}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    assert!(
        freed <= Duration::from_secs(1),
        "slot freed {freed:?} after the answer"
    );

    // The one slot is free again: an ordinary upload to another site is stored in its own time.
    let t = Instant::now();
    let (status, body) = d
        .send(
            reqwest::Method::POST,
            "/api/v1/sites/ordinary/epochs",
            Some(&paper(PAPER[7])),
        )
        .await;
    assert_eq!(status, 201, "{body}");
    let ordinary_took = t.elapsed();
    assert!(ordinary_took < timeout, "took {ordinary_took:?}");

    // Idle again within 2 s of the first answer: under 0.2 s of CPU over the next second.
    tokio::time::sleep_until((answered + Duration::from_secs(2)).into()).await;
    let before = cpu_seconds(d.pid());
    tokio::time::sleep(Duration::from_secs(1)).await;
    let used = cpu_seconds(d.pid()) - before;
    println!(
        "answered {:?} after sending; slot free {freed:?} after the answer; the ordinary upload \
         took {:?}; CPU 2–3 s after: {used:.2} s",
        answered - started,
        ordinary_took
    );
    assert!(used < 0.2, "{used:.2} s of CPU in the second after");
    let (_, big_epochs) = d.get("/api/v1/sites/big/epochs").await;
    assert_eq!(
        big_epochs["items"].as_array().map(Vec::len),
        Some(0),
        "nothing stored"
    );

    let took = d.terminate(grace + Duration::from_secs(2));
    assert!(
        took.is_some_and(|t| t <= grace),
        "SIGTERM: exited after {took:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_during_a_long_computation_exits_within_the_grace_period() {
    let dir = tempfile::tempdir().unwrap();
    let grace = Duration::from_secs(3);
    let mut d = Daemon::start(
        &dir.path().join("data"),
        &config(dir.path(), 120, grace.as_secs()),
    )
    .await;
    create_site(&d, "big").await;
    let big = serde_json::to_vec(&oversized_epoch(20_000)).unwrap();
    let request = d
        .client
        .post(d.url("/api/v1/sites/big/epochs"))
        .header("content-type", "application/json")
        .body(big)
        .send();
    let before = cpu_seconds(d.pid());
    let upload = tokio::spawn(request);
    // computing: two seconds of CPU since it was sent (parsing takes a tenth of that)
    let sent = Instant::now();
    while cpu_seconds(d.pid()) - before < 2.0 {
        assert!(
            sent.elapsed() < Duration::from_secs(30),
            "the upload is not computing"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert!(!upload.is_finished(), "the upload is still computing");

    let took = d.terminate(grace + Duration::from_secs(5));
    println!("SIGTERM while computing: exited after {took:?} (grace {grace:?})");
    // within the grace period (and the polling of the exit, on a loaded machine)
    assert!(
        took.is_some_and(|t| t <= grace + Duration::from_millis(250)),
        "SIGTERM: exited after {took:?} (grace {grace:?})"
    );
    // The client was answered or its connection closed; it is not left hanging.
    let outcome = tokio::time::timeout(Duration::from_secs(2), upload).await;
    assert!(outcome.is_ok(), "the upload's client still waits");
}

#[tokio::test]
async fn an_epoch_over_the_limits_is_refused_before_computing_naming_the_limit() {
    let s = TestServer::start(|c| {
        c.max_epoch_points = 10;
        c.max_epoch_observations = 1_000;
    })
    .await;
    s.create_site("small").await;
    let before = s.snapshot().await;
    let epoch = paper(PAPER[6]);
    let points = epoch["approx"].as_array().unwrap().len();
    assert!(points > 10, "the paper epoch has {points} points");
    let (status, e) = s.upload("small", &epoch).await;
    assert_eq!(status, 413, "{e}");
    assert_eq!(e["error"]["code"], "epoch_too_large");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(
        msg.contains(&format!(
            "has {points} points; this server takes at most 10 per epoch (max_epoch_points)"
        )),
        "{msg}"
    );
    assert_eq!(s.snapshot().await, before, "nothing stored");

    let s = TestServer::start(|c| c.max_epoch_observations = 30).await;
    s.create_site("few").await;
    let (status, e) = s.upload("few", &epoch).await;
    assert_eq!(status, 413, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(
        msg.contains(
            "image observations; this server takes at most 30 per epoch (max_epoch_observations)"
        ),
        "{msg}"
    );
}

//! Repeats the service benchmark's upload for profiling: `cargo run --release --example
//! upload_repeat -- [N] [WARM] [postgres]` starts an in-process server on a temporary SQLite
//! database (or a throwaway PostgreSQL cluster), uploads
//! WARM 5 × 28 epochs (default 45, so that the analysis reads a full 40-epoch history), then N more
//! (default 50) and prints the median, mean, minimum and maximum of those N. Under
//! `valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*upload_inner*'` it counts the
//! server's instructions per upload, which the machine's load does not move. It also prints the
//! CPU time per upload of itself and of the `postgres` processes. `CLIFFWATCH_HOLD_SECONDS=S`
//! keeps the database S seconds after the uploads (and prints how to reach a cluster with
//! `psql`, for `EXPLAIN ANALYZE`).

#[path = "../tests/support/mod.rs"]
mod support;

use std::time::Instant;

use support::server::{synthetic_epoch, TestServer};

fn observed_at(k: usize) -> String {
    let t = chrono::DateTime::parse_from_rfc3339("2020-01-01T00:00:00Z").unwrap()
        + chrono::Duration::hours(k as i64);
    t.to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

/// CPU time (user + system, ms) of processes whose name is `postgres`, or of this process when
/// `name` is `None`, from `/proc` (Linux; 0 elsewhere).
fn cpu_ms(name: Option<&str>) -> f64 {
    let ticks = |stat: &str| -> f64 {
        // fields after the ")" of the command: state is field 3, utime 14, stime 15
        let rest = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
        let f: Vec<&str> = rest.split_whitespace().collect();
        let get = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
        get(11) + get(12)
    };
    let per_tick = 10.0; // USER_HZ = 100 on Linux
    let Some(name) = name else {
        return std::fs::read_to_string("/proc/self/stat")
            .map(|s| ticks(&s) * per_tick)
            .unwrap_or(0.0);
    };
    let mut total = 0.0;
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let stat = entry.path().join("stat");
        if let Ok(s) = std::fs::read_to_string(stat) {
            if s.contains(&format!("({name})")) {
                total += ticks(&s) * per_tick;
            }
        }
    }
    total
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(50);
    let warm: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(45);
    // `postgres`: a throwaway cluster (tests/support/pg.rs) instead of SQLite.
    let cluster = (args.next().as_deref() == Some("postgres")).then(support::pg::PgCluster::start);
    let url = cluster.as_ref().map(|c| c.create_database("upload"));
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    rt.block_on(async {
        let server = TestServer::start(move |c| c.database_url = url).await;
        server.create_site("bench").await;
        let mut times = Vec::with_capacity(n);
        let mut cpu_start = (0.0, 0.0);
        for k in 1..=warm + n {
            let body =
                serde_json::to_vec(&synthetic_epoch(5, 28, &observed_at(k), k as u64, 0.0, 28))
                    .expect("JSON");
            if k == warm + 1 {
                cpu_start = (cpu_ms(None), cpu_ms(Some("postgres")));
            }
            let t = Instant::now();
            let (status, _) = server.upload_bytes("bench", body).await;
            assert_eq!(status, 201, "upload {k}");
            if k > warm {
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        if let Some(secs) = std::env::var("CLIFFWATCH_HOLD_SECONDS")
            .ok()
            .and_then(|s| s.parse().ok())
        {
            if let Some(c) = &cluster {
                eprintln!(
                    "holding for {secs} s: psql -h 127.0.0.1 -p {} -U cliffwatch upload",
                    c.port()
                );
            }
            tokio::time::sleep(std::time::Duration::from_secs(secs)).await;
        }
        let cpu = (
            (cpu_ms(None) - cpu_start.0) / n.max(1) as f64,
            (cpu_ms(Some("postgres")) - cpu_start.1) / n.max(1) as f64,
        );
        let mean = times.iter().sum::<f64>() / n.max(1) as f64;
        times.sort_by(f64::total_cmp);
        if !times.is_empty() {
            println!(
                "upload 5 × 28 after {warm}: median {:.2} ms, mean {mean:.2} ms over {n} (min {:.2}, max {:.2}; {} over twice the median)",
                times[n / 2],
                times[0],
                times[n - 1],
                times.iter().filter(|&&t| t > 2.0 * times[n / 2]).count()
            );
            match &cluster {
                Some(_) => println!(
                    "CPU per upload: this process {:.2} ms, PostgreSQL processes {:.2} ms",
                    cpu.0, cpu.1
                ),
                None => println!("CPU per upload: this process {:.2} ms", cpu.0),
            }
        }
        let _ = server.stop().await;
    });
}

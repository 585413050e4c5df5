//! Repeats one adjustment for profiling (`perf record`): `cargo run --release --example adjust_repeat
//! -- small|large|huge N` runs the benchmark network N times and prints the median time, and that
//! of the first run (cold: fresh heap, thread pool starting).

use std::time::Instant;

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions};
use cliffwatch_sim::scenes::{large, long_range, LargeParams, LongRangeParams};

fn main() {
    let mut args = std::env::args().skip(1);
    let scene = args.next().unwrap_or_else(|| "small".into());
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(100);
    let epoch = match scene.as_str() {
        "small" => long_range(&LongRangeParams::default()).expect("scene").0,
        "large" => large(&LargeParams::default()).expect("scene").0,
        _ => large(&LargeParams::huge()).expect("scene").0,
    };
    let options = AdjustOptions::default();
    let mut times = Vec::with_capacity(n);
    let mut last = None;
    for _ in 0..n {
        let t = Instant::now();
        last = Some(adjust(&epoch, &options).expect("adjusts"));
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let first = times[0];
    times.sort_by(f64::total_cmp);
    let a = last.expect("ran");
    println!(
        "{scene}: median {:.3} ms over {n} runs (min {:.3}, first {first:.3}); σ0 {:.6} mm, iterations {}, dropped {}",
        times[n / 2],
        times[0],
        a.report.sigma0_mm,
        a.report.iterations,
        a.report.dropped.len()
    );
}

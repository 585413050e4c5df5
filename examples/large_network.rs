//! Times the adjustment of the benchmark networks of `simulate::scenes::large`.
//!
//! `cargo run --release --example large_network [-- huge]` — default 20 images × 500 points (each in
//! 10 images); `huge`: 100 images × 10 000 points. Then the cost of the cameras' variance
//! components (the fastest of three adjustments without and with them).

use std::time::Instant;

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions};
use cliffwatch_sim::scenes::{large, LargeParams};

fn main() {
    let params = if std::env::args().nth(1).as_deref() == Some("huge") {
        LargeParams::huge()
    } else {
        LargeParams::default()
    };
    let t0 = Instant::now();
    let (epoch, truth) = large(&params).expect("scene");
    let generated = t0.elapsed();
    let observations: usize = epoch.images.iter().map(|i| i.observations.len()).sum();
    let t1 = Instant::now();
    let result = adjust(&epoch, &AdjustOptions::default());
    let adjusted = t1.elapsed();
    println!(
        "{} images × {} points ({observations} observations): generated in {:.2} s, adjusted in {:.2} s",
        params.n_images,
        params.n_points,
        generated.as_secs_f64(),
        adjusted.as_secs_f64()
    );
    match result {
        Ok(a) => println!(
            "converged {} in {} iterations, σ0 {:.5} mm (noise {} mm), index 3 {:?} mm, dropped {}",
            a.report.converged,
            a.report.iterations,
            a.report.sigma0_mm,
            params.noise_mm,
            truth.index3_rmse_mm(&a.points).map(|v| v[3]),
            a.report.dropped.len()
        ),
        Err(e) => println!("error: {e}"),
    }
    // The service asks every adjustment for the cameras' variance components (issue 61,
    // item 8): the same network again with them, three times each, the fastest kept.
    let time = |components: bool| {
        let options = AdjustOptions {
            variance_components: components,
            ..AdjustOptions::default()
        };
        (0..3)
            .map(|_| {
                let t = Instant::now();
                let _ = adjust(&epoch, &options);
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    let (without, with) = (time(false), time(true));
    println!(
        "variance components: {without:.3} s without, {with:.3} s with (+{:.1} %)",
        100.0 * (with / without - 1.0)
    );
}

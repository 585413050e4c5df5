//! Times the adjustment of the benchmark networks of `simulate::scenes::large`.
//!
//! `cargo run --release --example large_network [-- huge]` — default 20 images × 500 points (each in
//! 10 images); `huge`: 100 images × 10 000 points.

use std::time::Instant;

use cliffwatch::photogrammetry::{adjust, AdjustOptions};
use cliffwatch::simulate::scenes::{large, LargeParams};

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
}

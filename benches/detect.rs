//! Benchmark of target detection: a 6000 × 4000 8-bit JPEG (quality 90) with 100 targets of about
//! 10 px, rendered by `simulate::images` (contrast-to-noise 50, blur 0.7 px, gradient, a few glints) and
//! encoded in memory. Times `detect_bytes` (decode included) and prints the median of each stage,
//! and the dashboard's preview of the same image.
//!
//! `cargo bench --bench detect`.

use criterion::{criterion_group, criterion_main, Criterion};
use std::time::Duration;

use cliffwatch_core::detect::{detect_bytes, DetectOptions, StageTimings};
use cliffwatch_sim::images::{encode_jpeg, random_clutter, render, scatter_targets, ImageSpec};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn bench(c: &mut Criterion) {
    let (w, h) = (6000, 4000);
    let mut spec = ImageSpec::new(w, h, 8);
    spec.targets = scatter_targets(w, h, 100, 10.0, 150.0, 1.3, 42);
    spec.clutter = random_clutter(w, h, 20, 0, 150.0, 42);
    let img = render(&spec, 42).expect("renders").image;
    let jpeg = encode_jpeg(&img, 90).expect("encodes");
    let opts = DetectOptions::default();
    let d = detect_bytes(&jpeg, &opts).expect("detects");
    let found = spec
        .targets
        .iter()
        .filter(|t| {
            d.targets
                .iter()
                .any(|x| (x.col - t.col).hypot(x.row - t.row) < 0.5)
        })
        .count();
    eprintln!(
        "image {w}×{h} JPEG {:.1} MB, {} targets rendered, {found} found, {} detections",
        jpeg.len() as f64 / 1e6,
        spec.targets.len(),
        d.targets.len()
    );
    let mut stages: Vec<StageTimings> = Vec::new();
    let mut group = c.benchmark_group("detect");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(15));
    group.bench_function("6000x4000 JPEG, 100 targets (decode included)", |b| {
        b.iter(|| {
            let d = detect_bytes(&jpeg, &opts).expect("detects");
            stages.push(d.timings);
            d.targets.len()
        })
    });
    // The epoch page's preview of the same image (decode, box average to ≤ 1280 px, stretch,
    // JPEG), made on request by the dashboard.
    group.bench_function("6000x4000 JPEG preview for the epoch page", |b| {
        b.iter(|| {
            cliffwatch::dashboard::image_preview::preview(
                &jpeg,
                cliffwatch::dashboard::image_preview::PREVIEW_MAX_SIDE,
            )
            .expect("preview")
            .jpeg
            .len()
        })
    });
    group.finish();
    let ms = |f: fn(&StageTimings) -> Duration| {
        median(stages.iter().map(|s| f(s).as_secs_f64() * 1e3).collect())
    };
    eprintln!(
        "median stages over {} runs: decode {:.1} ms, threshold {:.1} ms, components {:.1} ms, centring {:.1} ms, total {:.1} ms",
        stages.len(),
        ms(|s| s.decode),
        ms(|s| s.threshold),
        ms(|s| s.components),
        ms(|s| s.centring),
        ms(|s| s.decode + s.threshold + s.components + s.centring),
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Benchmarks of the bundle adjustment (orthogonal model, c self-calibrated, precision included):
//! the long-range monitoring epoch (5 images × 28 points) and the large networks of the issue
//! (20 images × 500 points and 100 images × 10 000 points, each point in 10 images).
//!
//! The 20 × 500 network also as `cliffwatch adjust FILE` does it: read and parse the file, adjust,
//! write the report, in this process and as a whole process of the binary.
//!
//! `cargo bench --bench adjust` (the 100 × 10 000 case only with `CLIFFWATCH_BENCH_HUGE=1`).

use criterion::{criterion_group, criterion_main, Criterion};

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, EpochInput};
use cliffwatch_sim::scenes::{large, long_range, LargeParams, LongRangeParams};

fn bench(c: &mut Criterion) {
    let options = AdjustOptions::default();
    let (epoch, _) = long_range(&LongRangeParams::default()).expect("scene");
    c.bench_function("adjust 5 images x 28 points", |b| {
        b.iter(|| adjust(&epoch, &options).expect("adjusts"))
    });
    let (epoch, _) = large(&LargeParams::default()).expect("scene");
    let mut group = c.benchmark_group("large");
    group.sample_size(10);
    group.bench_function("adjust 20 images x 500 points", |b| {
        b.iter(|| adjust(&epoch, &options).expect("adjusts"))
    });
    let dir = tempfile::tempdir().expect("temporary directory");
    let file = dir.path().join("large.epoch.json");
    std::fs::write(&file, serde_json::to_vec_pretty(&epoch).expect("json")).expect("write");
    group.bench_function("read, adjust, write 20 images x 500 points", |b| {
        b.iter(|| {
            let text = std::fs::read_to_string(&file).expect("read");
            let input: EpochInput = serde_json::from_str(&text).expect("parse");
            let a = adjust(&input, &options).expect("adjusts");
            serde_json::to_vec(&a.report).expect("report").len()
        })
    });
    group.bench_function("cliffwatch adjust process 20 images x 500 points", |b| {
        b.iter(|| {
            let status = std::process::Command::new(env!("CARGO_BIN_EXE_cliffwatch"))
                .arg("adjust")
                .arg(&file)
                .stdout(std::process::Stdio::null())
                .status()
                .expect("runs");
            assert!(status.success());
        })
    });
    if std::env::var_os("CLIFFWATCH_BENCH_HUGE").is_some() {
        let (epoch, _) = large(&LargeParams::huge()).expect("scene");
        group.bench_function("adjust 100 images x 10000 points", |b| {
            b.iter(|| adjust(&epoch, &options).expect("adjusts"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

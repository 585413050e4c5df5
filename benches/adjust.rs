//! Benchmarks of the bundle adjustment (orthogonal model, c self-calibrated, precision included):
//! the long-range monitoring epoch (5 images × 28 points) and the large networks of the issue
//! (20 images × 500 points and 100 images × 10 000 points, each point in 10 images).
//!
//! `cargo bench --bench adjust` (the 100 × 10 000 case only with `CLIFFWATCH_BENCH_HUGE=1`).

use criterion::{criterion_group, criterion_main, Criterion};

use cliffwatch::photogrammetry::{adjust, AdjustOptions};
use cliffwatch::simulate::scenes::{large, long_range, LargeParams, LongRangeParams};

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

//! Benchmark of first-epoch identification across stations: the long-range scene widened to 100
//! targets on a 10 m × 6 m face (about 0.75 m apart), 5 stations about 105 m away with a 4000 × 2700
//! sensor, the true points projected with σ 0.25 px plus 10 clutter detections per station, the same
//! 4 corner targets seeded everywhere, approximations off by a common σ 0.45 m and σ 0.10 m per point.
//! Times `identify_first_epoch` (matching, cameras, naming) on top of detection.
//!
//! `cargo bench --bench identify`.

use std::collections::BTreeMap;
use std::time::Duration;

use cliffwatch_core::detect::first_epoch::{identify_first_epoch, FirstEpochOptions, StationView};
use cliffwatch_core::detect::identify::Seed;
use cliffwatch_sim::scenes::{long_range, project, LongRangeParams};
use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

fn bench(c: &mut Criterion) {
    let p = LongRangeParams {
        n_points: 100,
        face_width_m: 10.0,
        face_height_m: 6.0,
        width_px: 4000,
        height_px: 2700,
        ..LongRangeParams::default()
    };
    let (_, truth) = long_range(&p).expect("scene");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut g = move || -> f64 { rng.sample(StandardNormal) };
    let px = p.pixel_size_mm;
    let (hx, hy) = (0.5 * p.width_px as f64 * px, 0.5 * p.height_px as f64 * px);
    let interior = [truth.c_mm, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let corners: Vec<String> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|(sx, sy)| {
            truth
                .points
                .iter()
                .max_by(|a, b| (sx * a.1[0] + sy * a.1[1]).total_cmp(&(sx * b.1[0] + sy * b.1[1])))
                .expect("points")
                .0
                .clone()
        })
        .collect();
    let mut stations = Vec::new();
    for (name, cam) in &truth.cameras {
        let mut blobs = Vec::new();
        let mut seeds = Vec::new();
        for (point, x) in &truth.points {
            let Some(q) = project(&cam.r, cam.xo, &interior, *x) else {
                continue;
            };
            let q = [q[0] + 0.25 * px * g(), q[1] + 0.25 * px * g()];
            if q[0].abs() < hx && q[1].abs() < hy {
                if corners.contains(point) {
                    seeds.push(Seed {
                        point: point.clone(),
                        xy_mm: [q[0] + px * g(), q[1] + px * g()],
                    });
                }
                blobs.push(q);
            }
        }
        for _ in 0..10 {
            blobs.push([
                hx * (2.0 * g().abs().fract() - 1.0),
                hy * (2.0 * g().abs().fract() - 1.0),
            ]);
        }
        stations.push((name.clone(), blobs, seeds));
    }
    let (off, each) = ([0.45 * g(), 0.45 * g(), 0.45 * g()], 0.10);
    let known: BTreeMap<String, [f64; 3]> = truth
        .points
        .iter()
        .map(|(n, x)| {
            (
                n.clone(),
                [
                    x[0] + off[0] + each * g(),
                    x[1] + off[1] + each * g(),
                    x[2] + off[2] + each * g(),
                ],
            )
        })
        .collect();
    let views: Vec<StationView> = stations
        .iter()
        .map(|(s, b, seeds)| StationView {
            station: s,
            blobs_mm: b,
            seeds,
        })
        .collect();
    let opts = FirstEpochOptions::default();
    let r = identify_first_epoch(&views, &known, &opts).expect("identifies");
    eprintln!(
        "{} targets matched, {} named; {}",
        r.tracks,
        r.named.len(),
        r.summary()
    );
    let mut group = c.benchmark_group("identify");
    group.sample_size(20);
    group.measurement_time(Duration::from_secs(10));
    group.bench_function("first epoch, 5 stations x 100 targets", |b| {
        b.iter(|| {
            identify_first_epoch(&views, &known, &opts)
                .expect("identifies")
                .named
                .len()
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Benchmarks of campaign design (`cliffwatch_core::plan`, issue 78): the pre-analysis of a
//! 10-station × 500-target plan (goal ≤ 200 ms) and the what-if on a 5-station, 30-target site
//! (goal ≤ 20 ms: the core call of `POST /api/v1/sites/{site}/plan`, i.e. the site's network
//! rebuilt from its epoch, a station dropped and the pre-analysis).
//!
//! `cargo bench --bench plan`

use criterion::{criterion_group, criterion_main, Criterion};

use cliffwatch_core::photogrammetry::input::epoch::ApproxInput;
use cliffwatch_core::photogrammetry::{Cancel, Model};
use cliffwatch_core::plan::{
    apply_changes, planned_epoch, pre_analysis, site_plan, Plan, PlanCamera, PlanChange,
    PlanStation, PlanTarget, SiteNetwork,
};

/// A face 40 m wide and 25 m high (Y up, Z towards the cameras, 3 m of relief) with a grid of
/// `targets` targets, the four corners known, seen by `stations` stations 120 m away spread over
/// 80 m, 200 mm lens on a 24 MP sensor.
fn plan(stations: usize, targets: usize) -> Plan {
    let cols = (targets as f64 * 40.0 / 25.0).sqrt().ceil() as usize;
    let rows = targets.div_ceil(cols);
    let targets: Vec<PlanTarget> = (0..targets)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let corner = (r == 0 || r == rows - 1) && (c == 0 || c == cols - 1);
            PlanTarget {
                point: format!("T{i:04}"),
                xyz: [
                    -20.0 + 40.0 * c as f64 / (cols - 1) as f64,
                    25.0 * r as f64 / (rows - 1).max(1) as f64,
                    3.0 * ((i * 7919) % 13) as f64 / 13.0,
                ],
                known: corner || i < 2,
                sigma_m: None,
            }
        })
        .collect();
    let stations = (0..stations)
        .map(|k| PlanStation {
            name: format!("S{}", k + 1),
            camera: "cam".into(),
            position: [
                -40.0 + 80.0 * k as f64 / (stations - 1) as f64,
                5.0 + 3.0 * (k % 2) as f64,
                120.0,
            ],
            aim: [0.0, 12.5, 1.5],
            up: Some([0.0, 1.0, 0.0]),
            sees: None,
        })
        .collect();
    Plan {
        model: Model::Orthogonal,
        sigma_px: 0.25,
        confidence: 0.95,
        power: 0.8,
        known_sigma_m: 0.001,
        datum: Default::default(),
        face_normal: Some([0.0, 0.0, 1.0]),
        cameras: vec![PlanCamera {
            id: "cam".into(),
            c_mm: 100.0,
            calibrate_c: true,
            pixel_size_mm: 0.006,
            width_px: 6000,
            height_px: 4000,
            sigma_px: None,
        }],
        stations,
        targets,
    }
}

fn bench(c: &mut Criterion) {
    let big = plan(10, 500);
    let report = pre_analysis(&big).expect("pre-analysis");
    assert!(report.targets.iter().all(|t| t.sigma_mm.is_some()));
    let mut group = c.benchmark_group("plan");
    group.sample_size(10);
    group.bench_function("pre-analysis 10 stations x 500 targets", |b| {
        b.iter(|| pre_analysis(&big).expect("pre-analysis"))
    });
    group.finish();

    // A site of 5 stations × 30 targets: its epoch as stored (all targets approximated, free
    // network), the what-if as the service runs it.
    let small = plan(5, 30);
    let mut epoch = planned_epoch(&small).expect("planned").epoch;
    epoch
        .approx
        .extend(epoch.control.drain(..).map(|c| ApproxInput {
            point: c.point,
            X: c.X,
            Y: c.Y,
            Z: c.Z,
        }));
    let network = SiteNetwork {
        model: Model::Orthogonal,
        epoch,
        stable: small
            .targets
            .iter()
            .filter(|t| t.known)
            .map(|t| t.point.clone())
            .collect(),
        control_datum: false,
        confidence: 0.95,
        face_normal: None,
    };
    let changes = [PlanChange::DropStation {
        station: "S3".into(),
    }];
    c.bench_function(
        "what-if 5 stations x 30 targets (rebuild, drop one, analyse)",
        |b| {
            b.iter(|| {
                let own = site_plan(&network, Cancel::default()).expect("site plan");
                let changed = apply_changes(&own, &changes).expect("changes");
                pre_analysis(&changed).expect("pre-analysis")
            })
        },
    );
    c.bench_function("pre-analysis 5 stations x 30 targets", |b| {
        b.iter(|| pre_analysis(&small).expect("pre-analysis"))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);

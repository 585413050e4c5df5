//! Identification on the long-range scene (28 targets, 5 stations): true points projected through the
//! true cameras and perturbed; first epoch from seeds, second epoch (targets moved by a few cm) from
//! the first epoch's orientations; ambiguity reported, never guessed.

use crate::support;

use std::collections::BTreeMap;

use cliffwatch_core::detect::identify::{
    identify, Identification, IdentifyError, IdentifyOptions, Prior, Seed,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use support::identify::{scene, true_orientation, Scene};

/// Observations (point, mm) of the points inside the sensor, with noise σ 0.25 px, shuffled.
fn observe(
    s: &Scene,
    station: &str,
    points: &BTreeMap<String, [f64; 3]>,
    rng: &mut ChaCha8Rng,
) -> Vec<(String, [f64; 2])> {
    let o = true_orientation(s, station);
    let px = s.cam.pixel_size_mm.unwrap();
    let (w, h) = s.cam.size_px.unwrap();
    let n = Normal::new(0.0, 0.25 * px).unwrap();
    let mut out: Vec<(String, [f64; 2])> = points
        .iter()
        .filter_map(|(name, x)| {
            let q = o.project(&s.cam_true, *x)?;
            let q = [q[0] + n.sample(rng), q[1] + n.sample(rng)];
            (q[0].abs() < 0.5 * w as f64 * px && q[1].abs() < 0.5 * h as f64 * px)
                .then(|| (name.clone(), q))
        })
        .collect();
    for i in (1..out.len()).rev() {
        out.swap(i, rng.gen_range(0..=i));
    }
    out
}

/// Blobs = observations + `n_clutter` blobs at least 1 mm from every target image.
fn blobs_with_clutter(
    s: &Scene,
    obs: &[(String, [f64; 2])],
    n_clutter: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<[f64; 2]> {
    let px = s.cam.pixel_size_mm.unwrap();
    let (w, h) = s.cam.size_px.unwrap();
    let (hx, hy) = (0.5 * w as f64 * px, 0.5 * h as f64 * px);
    let mut b: Vec<[f64; 2]> = obs.iter().map(|o| o.1).collect();
    while b.len() < obs.len() + n_clutter {
        let q = [rng.gen_range(-hx..hx), rng.gen_range(-hy..hy)];
        if obs
            .iter()
            .all(|o| (o.1[0] - q[0]).hypot(o.1[1] - q[1]) > 1.0)
        {
            b.push(q);
        }
    }
    b
}

/// Four seeds: the observed points nearest to the image corners.
fn corner_seeds(obs: &[(String, [f64; 2])]) -> Vec<Seed> {
    let mut seeds: Vec<Seed> = Vec::new();
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        let best = obs
            .iter()
            .filter(|o| !seeds.iter().any(|s| s.point == o.0))
            .max_by(|a, b| (sx * a.1[0] + sy * a.1[1]).total_cmp(&(sx * b.1[0] + sy * b.1[1])))
            .unwrap();
        seeds.push(Seed {
            point: best.0.clone(),
            xy_mm: best.1,
        });
    }
    seeds
}

/// Every observed target identified as itself, clutter unmatched, nothing ambiguous.
fn assert_all_correct(id: &Identification, obs: &[(String, [f64; 2])], n_blobs: usize, what: &str) {
    for m in &id.matched {
        assert!(
            m.blob < obs.len(),
            "{what}: clutter blob {} taken as {}",
            m.blob,
            m.point
        );
        assert_eq!(
            m.point, obs[m.blob].0,
            "{what}: blob {} misidentified",
            m.blob
        );
    }
    assert_eq!(id.matched.len(), obs.len(), "{what}: {id:?}");
    assert!(
        id.ambiguous_blobs.is_empty() && id.ambiguous_points.is_empty(),
        "{what}"
    );
    assert_eq!(id.unmatched_blobs.len(), n_blobs - obs.len(), "{what}");
}

#[test]
fn first_epoch_from_seeds_then_second_epoch_from_orientation() {
    let opts = IdentifyOptions::default();
    for seed in [1u64, 2, 3] {
        let s = scene(seed);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut orientations = BTreeMap::new();
        for station in s.truth.cameras.keys() {
            let obs = observe(&s, station, &s.truth.points, &mut rng);
            assert!(
                obs.len() >= 20,
                "scene {seed} {station}: {} visible",
                obs.len()
            );
            let blobs = blobs_with_clutter(&s, &obs, 15, &mut rng);
            let seeds = corner_seeds(&obs);
            let id =
                identify(&blobs, &s.truth.points, &s.cam, Prior::Seeds(&seeds), &opts).unwrap();
            assert_all_correct(
                &id,
                &obs,
                blobs.len(),
                &format!("scene {seed} {station} epoch 1"),
            );
            orientations.insert(station.clone(), id.orientation);
        }
        // epoch 2: every target moved by 1–4 cm in a random direction
        let moved: BTreeMap<String, [f64; 3]> = s
            .truth
            .points
            .iter()
            .map(|(n, x)| {
                let d: f64 = rng.gen_range(0.01..0.04);
                let v: [f64; 3] = std::array::from_fn(|_| rng.gen_range(-1.0..1.0));
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-9);
                (n.clone(), std::array::from_fn(|k| x[k] + d * v[k] / l))
            })
            .collect();
        for station in s.truth.cameras.keys() {
            let obs = observe(&s, station, &moved, &mut rng);
            let blobs = blobs_with_clutter(&s, &obs, 15, &mut rng);
            let prior = &orientations[station];
            // the known points are the previous epoch's coordinates, not the moved ones
            let id = identify(
                &blobs,
                &s.truth.points,
                &s.cam,
                Prior::Orientation(prior),
                &opts,
            )
            .unwrap();
            assert_all_correct(
                &id,
                &obs,
                blobs.len(),
                &format!("scene {seed} {station} epoch 2"),
            );
        }
    }
}

#[test]
fn ambiguity_is_reported_not_guessed() {
    let opts = IdentifyOptions::default();
    let s = scene(4);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let station = s.truth.cameras.keys().next().unwrap().clone();
    let prior = true_orientation(&s, &station);
    let obs = observe(&s, &station, &s.truth.points, &mut rng);
    // (a) a second blob inside one point's gate
    let base = identify(
        &obs.iter().map(|o| o.1).collect::<Vec<_>>(),
        &s.truth.points,
        &s.cam,
        Prior::Orientation(&prior),
        &opts,
    )
    .unwrap();
    let (name, q) = obs[0].clone();
    let g = base.gates_mm[&name];
    let mut blobs: Vec<[f64; 2]> = obs.iter().map(|o| o.1).collect();
    blobs.push([q[0] + 0.4 * g, q[1]]);
    let id = identify(
        &blobs,
        &s.truth.points,
        &s.cam,
        Prior::Orientation(&prior),
        &opts,
    )
    .unwrap();
    assert!(id.ambiguous_points.contains(&name), "{id:?}");
    assert!(id.ambiguous_blobs.contains(&0) && id.ambiguous_blobs.contains(&(blobs.len() - 1)));
    assert!(id.matched.iter().all(|m| m.point != name && m.blob != 0));
    for m in &id.matched {
        assert_eq!(m.point, obs[m.blob].0);
    }
    assert_eq!(id.matched.len(), obs.len() - 1);
    // (b) two known points whose images fall within one gate of the same blob
    let mut known = s.truth.points.clone();
    let x = known[&name];
    known.insert("X_near".into(), [x[0] + 0.01, x[1], x[2]]);
    let blobs: Vec<[f64; 2]> = obs.iter().map(|o| o.1).collect();
    let id = identify(&blobs, &known, &s.cam, Prior::Orientation(&prior), &opts).unwrap();
    assert!(id.ambiguous_blobs.contains(&0), "{id:?}");
    assert!(
        id.ambiguous_points.contains(&name) && id.ambiguous_points.contains(&"X_near".to_string())
    );
    assert!(id
        .matched
        .iter()
        .all(|m| m.blob != 0 && m.point != "X_near"));
    for m in &id.matched {
        assert_eq!(m.point, obs[m.blob].0);
    }
}

#[test]
fn missing_targets_are_listed() {
    let s = scene(5);
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let station = s.truth.cameras.keys().next().unwrap().clone();
    let prior = true_orientation(&s, &station);
    let obs = observe(&s, &station, &s.truth.points, &mut rng);
    let blobs: Vec<[f64; 2]> = obs[1..].iter().map(|o| o.1).collect();
    let id = identify(
        &blobs,
        &s.truth.points,
        &s.cam,
        Prior::Orientation(&prior),
        &IdentifyOptions::default(),
    )
    .unwrap();
    assert_eq!(id.missing_points, vec![obs[0].0.clone()]);
    for m in &id.matched {
        assert_eq!(m.point, obs[m.blob + 1].0);
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let s = scene(6);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let station = s.truth.cameras.keys().next().unwrap().clone();
    let obs = observe(&s, &station, &s.truth.points, &mut rng);
    let blobs: Vec<[f64; 2]> = obs.iter().map(|o| o.1).collect();
    let opts = IdentifyOptions::default();
    let seeds = corner_seeds(&obs);
    let r = identify(
        &blobs,
        &s.truth.points,
        &s.cam,
        Prior::Seeds(&seeds[..3]),
        &opts,
    );
    assert!(matches!(r, Err(IdentifyError::TooFewSeeds(3))));
    let mut dup = seeds[..3].to_vec();
    dup.push(seeds[0].clone());
    let r = identify(&blobs, &s.truth.points, &s.cam, Prior::Seeds(&dup), &opts);
    assert!(matches!(r, Err(IdentifyError::TooFewSeeds(3))));
    let mut bad = seeds.clone();
    bad[0].point = "nope".into();
    let r = identify(&blobs, &s.truth.points, &s.cam, Prior::Seeds(&bad), &opts);
    assert!(matches!(r, Err(IdentifyError::UnknownSeedPoint(_))));
    let mut nan = blobs.clone();
    nan.push([f64::NAN, 0.0]);
    let r = identify(&nan, &s.truth.points, &s.cam, Prior::Seeds(&seeds), &opts);
    assert!(matches!(r, Err(IdentifyError::Invalid(_))));
    let r = identify(
        &blobs,
        &s.truth.points,
        &s.cam,
        Prior::Seeds(&seeds),
        &IdentifyOptions {
            max_motion_m: -1.0,
            ..opts
        },
    );
    assert!(matches!(r, Err(IdentifyError::Invalid(_))));
}

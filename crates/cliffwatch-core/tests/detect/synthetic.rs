//! Detection on images of the crate's renderer: centring accuracy against truth over several seeds
//! (8- and 16-bit, 3–12 px), no false target on clutter, typed errors on bad input.

use cliffwatch_core::detect::{
    decode, decode_with_limit, detect, detect_bytes, DetectError, DetectOptions, GreyImage,
};
use cliffwatch_sim::images::{
    encode_jpeg, encode_png, random_clutter, render, scatter_targets, Clutter, ImageSpec,
    RenderError,
};

const SEEDS: [u64; 4] = [1, 2, 3, 4];

/// Renders 16 targets of `diameter` px at contrast-to-noise 50 with a few glints on a 384 × 384
/// image; returns the squared radial errors of all targets (each must be found within 1 px) and the
/// count of detections that match no target.
fn run(diameter: f64, bit_depth: u8, seed: u64) -> (Vec<f64>, usize) {
    let mut spec = ImageSpec::new(384, 384, bit_depth);
    spec.targets = scatter_targets(384, 384, 16, diameter, 50.0 * spec.noise_sigma, 1.3, seed);
    // glints apart from the targets (a glint across a target is a different test)
    spec.clutter = random_clutter(384, 384, 3, 0, 50.0 * spec.noise_sigma, seed)
        .into_iter()
        .filter(|c| match *c {
            Clutter::Glint { col, row, .. } => spec
                .targets
                .iter()
                .all(|t| (t.col - col).hypot(t.row - row) > 25.0 + 2.0 * diameter),
            Clutter::Band { .. } => true,
        })
        .collect();
    let r = render(&spec, seed).unwrap();
    let d = detect(&r.image, &DetectOptions::default()).unwrap();
    let mut errs = Vec::new();
    for t in &r.targets {
        let best = d
            .targets
            .iter()
            .map(|x| (x.col - t.col).hypot(x.row - t.row))
            .fold(f64::INFINITY, f64::min);
        assert!(
            best < 1.0,
            "{diameter} px {bit_depth}-bit seed {seed}: target at ({:.2}, {:.2}) missed",
            t.col,
            t.row
        );
        if best > 0.05 {
            eprintln!("  {diameter} px {bit_depth}-bit seed {seed}: {t:?} off by {best:.3}");
        }
        errs.push(best * best);
    }
    let unmatched = d
        .targets
        .iter()
        .filter(|x| {
            r.targets
                .iter()
                .all(|t| (x.col - t.col).hypot(x.row - t.row) > 2.0)
        })
        .count();
    (errs, unmatched)
}

fn rms(diameter: f64, bit_depth: u8) -> f64 {
    let mut all = Vec::new();
    for s in SEEDS {
        let (e, f) = run(diameter, bit_depth, s);
        assert_eq!(
            f, 0,
            "{diameter} px {bit_depth}-bit seed {s}: false targets"
        );
        all.extend(e);
    }
    let r = (all.iter().sum::<f64>() / all.len() as f64).sqrt();
    eprintln!(
        "{diameter} px {bit_depth}-bit: {} targets, radial RMS {r:.4} px",
        all.len()
    );
    r
}

#[test]
fn centring_8bit_large_targets() {
    for d in [6.0, 9.0, 12.0] {
        let r = rms(d, 8);
        assert!(r <= 0.02, "{d} px 8-bit: radial RMS {r}");
    }
}

#[test]
fn centring_8bit_3px() {
    let r = rms(3.0, 8);
    assert!(r <= 0.05, "3 px 8-bit: radial RMS {r}");
}

#[test]
fn centring_16bit_no_worse() {
    for (d, bound) in [(3.0, 0.05), (6.0, 0.02), (12.0, 0.02)] {
        let r8 = rms(d, 8);
        let r16 = rms(d, 16);
        assert!(r16 <= bound, "{d} px 16-bit: radial RMS {r16}");
        // same seeds → the same noise draws scaled by 257: only quantisation differs
        assert!(
            r16 <= 1.05 * r8 + 0.001,
            "{d} px: 16-bit {r16} vs 8-bit {r8}"
        );
    }
}

#[test]
fn no_false_targets_on_100_clutter_images() {
    let mut total = 0;
    for seed in 0..100u64 {
        let mut spec = ImageSpec::new(256, 256, if seed % 4 == 3 { 16 } else { 8 });
        let c = 50.0 * spec.noise_sigma;
        spec.clutter = random_clutter(
            256,
            256,
            2 + (seed % 5) as usize,
            (seed % 3 == 0) as usize,
            c,
            seed,
        );
        let r = render(&spec, seed).unwrap();
        let d = detect(&r.image, &DetectOptions::default()).unwrap();
        if !d.targets.is_empty() {
            eprintln!("seed {seed}: {:?}", d.targets);
        }
        total += d.targets.len();
    }
    assert_eq!(total, 0, "false targets on clutter");
}

#[test]
fn encoded_round_trip_png_and_jpeg() {
    let mut spec = ImageSpec::new(320, 256, 8);
    spec.targets = scatter_targets(320, 256, 6, 8.0, 150.0, 1.2, 9);
    let r = render(&spec, 9).unwrap();
    let png = encode_png(&r.image).unwrap();
    assert_eq!(decode(&png).unwrap(), r.image);
    let jpg = encode_jpeg(&r.image, 95).unwrap();
    let d = detect_bytes(&jpg, &DetectOptions::default()).unwrap();
    assert_eq!(d.targets.len(), r.targets.len());
    for t in &r.targets {
        let best = d
            .targets
            .iter()
            .map(|x| (x.col - t.col).hypot(x.row - t.row))
            .fold(f64::INFINITY, f64::min);
        assert!(best < 0.1, "JPEG: target off by {best} px");
    }
}

use crate::support::bad_images::png_claiming;

#[test]
fn bad_input_gives_typed_errors() {
    let opts = DetectOptions::default();
    assert!(matches!(
        detect_bytes(&[], &opts),
        Err(DetectError::Decode(_))
    ));
    assert!(matches!(
        detect_bytes(b"not an image at all", &opts),
        Err(DetectError::Decode(_))
    ));
    let good = encode_png(&GreyImage::new(16, 16, 8, vec![9; 256]).unwrap()).unwrap();
    for cut in [8, 20, 40, good.len() - 5] {
        assert!(
            detect_bytes(&good[..cut], &opts).is_err(),
            "truncated at {cut}"
        );
    }
    let mut flipped = good.clone();
    let n = flipped.len();
    flipped[n / 2] ^= 0xff;
    assert!(detect_bytes(&flipped, &opts).is_err());
    assert!(matches!(
        detect_bytes(&png_claiming(100_000, 100_000), &opts),
        Err(DetectError::TooLarge { .. })
    ));
    assert!(matches!(
        decode_with_limit(&good, 100),
        Err(DetectError::TooLarge { .. })
    ));
    assert!(detect_bytes(&png_claiming(0, 16), &opts).is_err());
    assert!(matches!(
        GreyImage::new(0, 5, 8, vec![]),
        Err(DetectError::Empty { .. })
    ));
    assert!(matches!(
        GreyImage::new(3, 3, 8, vec![0; 8]),
        Err(DetectError::BadBuffer { .. })
    ));
    let bad_opts = DetectOptions {
        min_diameter_px: f64::NAN,
        ..DetectOptions::default()
    };
    let img = GreyImage::new(16, 16, 8, vec![9; 256]).unwrap();
    assert!(matches!(
        detect(&img, &bad_opts),
        Err(DetectError::InvalidOptions(_))
    ));
    // renderer
    assert!(matches!(
        render(&ImageSpec::new(0, 10, 8), 1),
        Err(RenderError::InvalidSpec(_))
    ));
    assert!(matches!(
        render(&ImageSpec::new(200_000, 200_000, 8), 1),
        Err(RenderError::InvalidSpec(_))
    ));
    assert!(matches!(
        render(&ImageSpec::new(10, 10, 12), 1),
        Err(RenderError::InvalidSpec(_))
    ));
}

#[test]
fn tiny_images_are_refused_and_flat_ones_give_no_targets() {
    let opts = DetectOptions::default();
    for (w, h) in [(1, 1), (1, 50), (7, 3), (50, 7)] {
        let img = GreyImage::new(w, h, 8, vec![100; (w * h) as usize]).unwrap();
        assert!(
            matches!(detect(&img, &opts), Err(DetectError::TooSmall { .. })),
            "{w}×{h}"
        );
    }
    for (w, h) in [(8, 8), (9, 40), (40, 40)] {
        let img = GreyImage::new(w, h, 8, vec![100; (w * h) as usize]).unwrap();
        assert!(detect(&img, &opts).unwrap().targets.is_empty());
    }
    let mut v = vec![0u16; 40 * 40];
    v[20 * 40 + 20] = 255;
    v[0] = 255;
    v[40 * 40 - 1] = 65535;
    let img = GreyImage::new(40, 40, 16, v).unwrap();
    let _ = detect(&img, &opts).unwrap();
}

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = detect_bytes(&bytes, &DetectOptions::default());
        }

        #[test]
        fn corrupted_png_never_panics(pos in 0usize..2000, val in any::<u8>()) {
            let img = GreyImage::new(24, 24, 8, (0..576).map(|i| (i % 251) as u16).collect()).unwrap();
            let mut png = encode_png(&img).unwrap();
            let n = png.len();
            png[pos % n] = val;
            let _ = detect_bytes(&png, &DetectOptions::default());
        }
    }
}

/// Each of 12 targets of `diameter` px gets a small glint (a capsule `len` × 2.5 px as bright as the
/// target) touching its edge, radially or tangentially; returns the squared radial errors (each
/// target must be found within 1 px).
fn glint_touching(diameter: f64, len: f64, seed: u64) -> Vec<f64> {
    let mut spec = ImageSpec::new(384, 384, 8);
    let c = 50.0 * spec.noise_sigma;
    spec.targets = scatter_targets(384, 384, 12, diameter, c, 1.0, seed);
    let wid = 2.5;
    spec.clutter = spec
        .targets
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let phi = (seed * 7 + k as u64) as f64 * 2.399; // golden-angle spread of the contact side
            let (u, v) = (phi.cos(), phi.sin());
            let r = t.semi_minor_px.min(t.semi_major_px) + 0.5 * wid;
            let (col, row, angle) = if k % 2 == 0 {
                // radial: the near end of the capsule's axis at r + width/2 from the centre
                let d = r + 0.5 * (len - wid);
                (t.col + d * u, t.row + d * v, phi)
            } else {
                // tangential: the capsule's middle touches the edge
                (
                    t.col + r * u,
                    t.row + r * v,
                    phi + std::f64::consts::FRAC_PI_2,
                )
            };
            Clutter::Glint {
                col,
                row,
                length_px: len,
                width_px: wid,
                angle_rad: angle,
                contrast: c,
            }
        })
        .collect();
    let r = render(&spec, seed).unwrap();
    let d = detect(&r.image, &DetectOptions::default()).unwrap();
    r.targets
        .iter()
        .map(|t| {
            let best = d
                .targets
                .iter()
                .map(|x| (x.col - t.col).hypot(x.row - t.row))
                .fold(f64::INFINITY, f64::min);
            assert!(
                best < 1.0,
                "{diameter} px seed {seed}: target at ({:.2}, {:.2}) with a touching glint missed",
                t.col,
                t.row
            );
            best * best
        })
        .collect()
}

/// 12 px targets meet the bound (0.02 px) with a glint touching each; 8 px ones reach
/// 0.028 px (measured: the glint's fringe still pulls a little), so their bound here is 0.03 px. Before
/// the symmetric start mask, such targets were lost or pulled by up to 1 px.
#[test]
fn glint_touching_a_target_does_not_pull_its_centre() {
    for (d, bound) in [(8.0, 0.03), (12.0, 0.02)] {
        let all: Vec<f64> = SEEDS
            .iter()
            .flat_map(|&s| glint_touching(d, 0.75 * d, s))
            .collect();
        let r = (all.iter().sum::<f64>() / all.len() as f64).sqrt();
        eprintln!(
            "{d} px with touching glints: {} targets, radial RMS {r:.4} px",
            all.len()
        );
        assert!(r <= bound, "{d} px with touching glints: radial RMS {r}");
    }
}

/// An image of a dense grid of bright specks (noise, texture or a crafted file) is refused with
/// a typed error before the work and memory grow with the specks' number; a photograph of
/// targets stays far below the limits.
#[test]
fn an_image_of_countless_specks_is_refused() {
    let opts = DetectOptions::default();
    // 2 × 2 px squares on a 6 px grid: ~110 000 blobs, ~220 000 runs in 2000 × 2000 px.
    let (w, h) = (2000u32, 2000u32);
    let data: Vec<u16> = (0..h)
        .flat_map(|r| (0..w).map(move |c| if r % 6 < 2 && c % 6 < 2 { 255 } else { 10 }))
        .collect();
    let img = GreyImage::new(w, h, 8, data).expect("image");
    match detect(&img, &opts) {
        Err(DetectError::TooManyBlobs { found, limit, .. }) => {
            assert!(found > limit, "{found} ≤ {limit}")
        }
        other => panic!("countless specks: {:?}", other.map(|d| d.targets.len())),
    }
    // single bright pixels on every other row: over the limit of runs
    let (w, h) = (8000u32, 2200u32);
    let data: Vec<u16> = (0..h)
        .flat_map(|r| (0..w).map(move |c| if r % 2 == 1 && c % 4 == 2 { 255 } else { 10 }))
        .collect();
    let img = GreyImage::new(w, h, 8, data).expect("image");
    assert!(matches!(
        detect(&img, &opts),
        Err(DetectError::TooManyBlobs { what: "runs", .. })
    ));
}

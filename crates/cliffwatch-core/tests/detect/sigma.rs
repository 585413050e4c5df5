//! The per-target σ against truth on rendered images: rms of (error / σ) per coordinate, per
//! centring method, over several seeds and sizes, without the floor for what real images add
//! (`DetectOptions::sigma_floor_px` 0).

use cliffwatch_core::detect::{detect, CentreMethod, DetectOptions};
use cliffwatch_sim::images::{render, scatter_targets, ImageSpec};

/// rms of (error / σ) over col and row, and the rms error (px), of every target of `diameter` px
/// over `seeds` (8-bit, noise σ 3, contrast-to-noise `cnr`), with the method that centred them.
fn honesty(
    diameter: f64,
    cnr: f64,
    seeds: std::ops::Range<u64>,
) -> (f64, f64, f64, CentreMethod, usize) {
    let (mut zc, mut zr, mut ee, mut n) = (0.0, 0.0, 0.0, 0usize);
    let mut method = None;
    for seed in seeds {
        let size = 640;
        let mut spec = ImageSpec::new(size, size, 8);
        spec.targets = scatter_targets(size, size, 25, diameter, cnr * spec.noise_sigma, 1.3, seed);
        let r = render(&spec, seed).unwrap();
        // the centring's own σ: no floor for what rendered images do not hold
        let opts = DetectOptions {
            sigma_floor_px: 0.0,
            ..DetectOptions::default()
        };
        let d = detect(&r.image, &opts).unwrap();
        for t in &r.targets {
            let Some(x) = d
                .targets
                .iter()
                .find(|x| (x.col - t.col).hypot(x.row - t.row) < 1.0)
            else {
                eprintln!(
                    "{diameter} px seed {seed}: target at ({:.1}, {:.1}) missed",
                    t.col, t.row
                );
                continue;
            };
            method.get_or_insert(x.method);
            assert_eq!(Some(x.method), method, "{diameter} px: one method");
            zc += ((x.col - t.col) / x.sigma_col_px).powi(2);
            zr += ((x.row - t.row) / x.sigma_row_px).powi(2);
            ee += (x.col - t.col).powi(2) + (x.row - t.row).powi(2);
            n += 1;
        }
    }
    let n_f = n as f64;
    (
        (zc / n_f).sqrt(),
        (zr / n_f).sqrt(),
        (ee / (2.0 * n_f)).sqrt(),
        method.unwrap(),
        n,
    )
}

#[test]
fn synthetic_sigma_agrees_with_the_error() {
    // (diameter px, contrast-to-noise, seeds): every method, two contrasts for the dual conic
    let cases: [(f64, f64, std::ops::Range<u64>); 8] = [
        (3.0, 50.0, 1..5),
        (4.0, 50.0, 1..5),
        (8.0, 50.0, 1..5),
        (12.0, 50.0, 1..5),
        (20.0, 50.0, 1..5),
        (20.0, 35.0, 1..5),
        (30.0, 50.0, 1..5),
        (45.0, 50.0, 1..10),
    ];
    for (d, cnr, seeds) in cases {
        let (zc, zr, e, m, n) = honesty(d, cnr, seeds);
        eprintln!(
            "{d} px, contrast/noise {cnr}, {}: {n} targets, rms error {e:.4} px, rms error/σ col \
             {zc:.3} row {zr:.3}",
            m.name()
        );
        assert!(n >= 80, "{d} px: {n} targets found");
        // ≥ 80 targets: the rms of error/σ is within ±8 % of its value at 1σ of its sampling
        for z in [zc, zr] {
            assert!(
                (0.75..=1.33).contains(&z),
                "{d} px, {cnr}: rms error/σ {zc}, {zr}"
            );
        }
    }
}

//! σ0 in image mm when the cameras' a-priori σ differ: expressed in the observations'
//! quadratic-mean a-priori σ, so it does not depend on which camera is listed first.

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, EpochInput};
use cliffwatch_sim::scenes::{paper_table1, PaperParams};

/// Paper case 2 (c held) with image C on a second camera of the same c and twice the σ;
/// `swap` lists the second camera first.
fn two_cameras(seed: u64, swap: bool) -> EpochInput {
    let params = PaperParams {
        seed,
        ..PaperParams::default()
    };
    let mut e = paper_table1(&params).unwrap().0;
    e.cameras[0].sigma_mm = Some(0.001);
    let mut second = e.cameras[0].clone();
    second.id = "cam2".into();
    second.sigma_mm = Some(0.002);
    e.images[2].camera = "cam2".into();
    e.cameras.push(second);
    if swap {
        e.cameras.reverse();
    }
    e
}

#[test]
fn sigma0_does_not_depend_on_the_order_of_the_cameras() {
    for seed in [1, 2, 3] {
        let e = two_cameras(seed, false);
        let first = adjust(&e, &AdjustOptions::default()).unwrap().report;
        let swapped = adjust(&two_cameras(seed, true), &AdjustOptions::default())
            .unwrap()
            .report;
        assert!(
            (first.sigma0_mm - swapped.sigma0_mm).abs() <= 1e-9 * first.sigma0_mm,
            "seed {seed}: σ0 {} mm with cam first, {} mm with cam2 first",
            first.sigma0_mm,
            swapped.sigma0_mm
        );
        // the quadratic mean of the observations' σ, times √(vᵀPv/dof)
        let n: Vec<f64> = e
            .images
            .iter()
            .map(|i| i.observations.len() as f64)
            .collect();
        let reference = ((n[0] + n[1]) * 1e-6 + n[2] * 4e-6) / (n[0] + n[1] + n[2]);
        let want = reference.sqrt() * first.variance_factor.sqrt();
        assert!(
            (first.sigma0_mm - want).abs() <= 1e-9 * want,
            "seed {seed}: σ0 {} mm, want {want} mm",
            first.sigma0_mm
        );
    }
}

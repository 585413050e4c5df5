//! The minimum detectable displacement against a Monte-Carlo run of the single-point test: with a
//! true displacement of MDD · u added to Gaussian noise of covariance Σ, the test
//! `dᵀ Σ⁻¹ d > χ²(3; confidence)` must fire with the stated power; 10 % less motion must be
//! detected less often than that and 10 % more motion more often, so the Monte-Carlo MDD lies
//! within 10 % of the computed one. Over 6 random covariances (1:1 to 1:6 anisotropy, as the
//! face-plane against depth σ of a long-range network) and both the direction of interest and the
//! worst direction.

use cliffwatch_core::analysis::sensitivity::{minimum_detectable, DEFAULT_POWER};
use cliffwatch_core::analysis::stats::chi2_quantile;
use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, Uniform};

const TRIALS: usize = 20_000;

/// Detection rate of the test over `TRIALS` noisy displacements around `truth`.
fn detection_rate(
    truth: Vector3<f64>,
    cov: &Matrix3<f64>,
    critical: f64,
    rng: &mut ChaCha8Rng,
) -> f64 {
    let chol = cov.cholesky().expect("positive definite").l();
    let inv = cov.try_inverse().expect("invertible");
    let mut hits = 0;
    for _ in 0..TRIALS {
        let z = Vector3::from_fn(|_, _| StandardNormal.sample(rng));
        let d = truth + chol * z;
        if (d.transpose() * inv * d)[(0, 0)] > critical {
            hits += 1;
        }
    }
    hits as f64 / TRIALS as f64
}

#[test]
fn the_minimum_detectable_displacement_matches_monte_carlo_within_ten_percent() {
    let confidence = 0.99;
    let critical = chi2_quantile(confidence, 3.0);
    for seed in 0..6u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let angle = Uniform::new(-3.1, 3.1);
        let rotation = Rotation3::from_euler_angles(
            angle.sample(&mut rng),
            angle.sample(&mut rng),
            angle.sample(&mut rng),
        );
        let sigma_face = Uniform::new(0.3, 0.7).sample(&mut rng);
        let ratio = 1.0 + seed as f64;
        let sigmas = Vector3::new(sigma_face, sigma_face * 1.2, sigma_face * ratio);
        let cov = rotation.matrix()
            * Matrix3::from_diagonal(&sigmas.component_mul(&sigmas))
            * rotation.matrix().transpose();
        let direction = Vector3::new(0.0, -0.6, 0.8);
        let mdd = minimum_detectable(&cov, critical, 3, DEFAULT_POWER, Some(&direction))
            .expect("a regular covariance has an MDD");
        let worst = SymmetricEigen::new(cov)
            .eigenvectors
            .column(SymmetricEigen::new(cov).eigenvalues.imax())
            .into_owned();
        let along = mdd.along_mm.expect("a direction was given");
        assert!(
            along <= mdd.worst_mm + 1e-9,
            "along {along} > worst {}",
            mdd.worst_mm
        );
        for (what, u, size) in [("along", direction, along), ("worst", worst, mdd.worst_mm)] {
            let at = detection_rate(u * size, &cov, critical, &mut rng);
            let below = detection_rate(u * size * 0.9, &cov, critical, &mut rng);
            let above = detection_rate(u * size * 1.1, &cov, critical, &mut rng);
            println!(
                "seed {seed} {what}: MDD {size:.3} mm, detected {at:.3} (0.9×: {below:.3}, 1.1×: {above:.3})"
            );
            assert!(
                (at - DEFAULT_POWER).abs() < 0.02,
                "seed {seed} {what}: power {at} at the MDD"
            );
            assert!(
                below < DEFAULT_POWER && above > DEFAULT_POWER,
                "seed {seed} {what}: {below} / {above}"
            );
        }
    }
}

//! The failure time from the onset model over the long window, with a burst allowed for.
//!
//! The onset test ([`super::onset`]) fits creep, then the inverse-velocity law continuing the
//! creep's velocity (`v = v₀ (t_f − t_a)/(t_f − t)`, Fukuzono 1985), to the last 40 epochs.
//! Because the creep before the onset pins `v₀`, and through it the law's amplitude, that model
//! knows far more about `t_f` than the law alone on a short window. But real records carry
//! bursts: a few days of fast motion that slow down again. Left in the window, a burst reads as part of the
//! acceleration and pulls the failure time late. Here the model may add one forward step `δ ≥ 0`
//! at any epoch with at least [`MIN_EPOCHS_AFTER_STEP`] epochs after it: a burst's displacement,
//! or a target knocked forward, is taken out, and the law fits the rest.
//!
//! For fixed `(t_f, t_a)` the model is linear in `(a, v₀)`, and the step at epoch `j` reduces
//! χ² by `R_j² / h_j` (the residual's weighted sum from `j` on over the step's own norm once
//! the line is projected out), so every step costs O(1) after a suffix sum.

use super::failure::{line_fit, min_over_failure_time, profile_law, LawFit};

/// Epochs that must follow a step for it to be fitted: a step at the last epochs would take the
/// acceleration itself out.
pub const MIN_EPOCHS_AFTER_STEP: usize = 4;

/// Latest onset of the acceleration, days before the current epoch: an onset in the last few
/// epochs would let the law take scatter for the start of a failure.
pub const MIN_ACCELERATION_DAYS: f64 = 5.0;

/// A step is kept only if it lowers χ² by more than this many times the step-free fit's
/// variance factor: the gain of a 3σ jump, so scatter alone rarely buys one.
pub const STEP_PENALTY: f64 = 9.0;

/// Parameters of the model: a, v₀, t_a, t_f, the step and its epoch.
const PARAMETERS: usize = 6;

/// χ² of the onset model with at most one forward step at the failure time `tf` (days after the
/// origin of `t`), minimised over the onset and the step; infinite when no forward creep fits.
fn chi2_at(
    t: &[f64],
    d: &[f64],
    w: &[f64],
    tf: f64,
    step_penalty: f64,
    scratch: &mut Vec<f64>,
) -> f64 {
    let n = t.len();
    let latest_onset = t[n - 1] - MIN_ACCELERATION_DAYS;
    let sw: f64 = w.iter().sum();
    let ln_rest: Vec<f64> = t.iter().map(|&ti| (tf - ti).ln()).collect();
    let mut best = f64::INFINITY;
    scratch.resize(n, 0.0);
    for k in 0..n - 1 {
        let mid = 0.5 * (t[k] + t[k + 1]);
        for (ta, ln_beta) in [(t[k], ln_rest[k]), (mid, (tf - mid).ln())] {
            if ta > latest_onset {
                continue;
            }
            let beta = tf - ta;
            let alpha = ta + beta * ln_beta;
            let g = scratch.as_mut_slice();
            for i in 0..n {
                g[i] = if t[i] <= ta {
                    t[i]
                } else {
                    alpha - beta * ln_rest[i]
                };
            }
            let gm = g.iter().zip(w).map(|(g, w)| w * g).sum::<f64>() / sw;
            let dm = d.iter().zip(w).map(|(d, w)| w * d).sum::<f64>() / sw;
            let (mut sgg, mut sgd, mut sdd) = (0.0, 0.0, 0.0);
            for i in 0..n {
                let (gc, dc) = (g[i] - gm, d[i] - dm);
                sgg += w[i] * gc * gc;
                sgd += w[i] * gc * dc;
                sdd += w[i] * dc * dc;
            }
            if !(sgg > 0.0) {
                continue;
            }
            let v0 = sgd / sgg;
            let chi0 = (sdd - sgd * sgd / sgg).max(0.0);
            if v0 > 0.0 && chi0 < best {
                best = chi0;
            }
            // Suffix sums for a step at epoch j (H = 1 from j on).
            let (mut a, mut b, mut r) = (0.0, 0.0, 0.0);
            for j in (2..n).rev() {
                let gc = g[j] - gm;
                a += w[j];
                b += w[j] * gc;
                r += w[j] * ((d[j] - dm) - v0 * gc);
                if j + MIN_EPOCHS_AFTER_STEP > n {
                    continue;
                }
                let hh = a - a * a / sw - b * b / sgg;
                if !(hh > 1e-12 * sw) {
                    continue;
                }
                let delta = r / hh;
                let v0j = v0 - delta * b / sgg;
                let chi = chi0 - r * r / hh + step_penalty;
                if delta > 0.0 && v0j > 0.0 && chi < best {
                    best = chi.max(0.0);
                }
            }
        }
    }
    best
}

/// The failure time of the onset model with at most one forward step, fitted to `d_mm` (along
/// the direction of motion, σ `sigma_mm`) at `t_days` (≤ 0, oldest first, the current epoch
/// last): σ and 90 % interval from its χ² profile, scaled by the variance factor over
/// `n − 6` degrees of freedom when that exceeds 1 ([`profile_law`]). None for fewer than 12
/// usable epochs or when no forward creep fits.
pub fn fit_onset_law(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64]) -> Option<LawFit> {
    fit(t_days, d_mm, sigma_mm, Some(STEP_PENALTY))
}

/// [`fit_onset_law`] with the step's penalty `step_penalty` (times the step-free variance
/// factor; None: no step).
fn fit(
    t_days: &[f64],
    d_mm: &[f64],
    sigma_mm: &[f64],
    step_penalty: Option<f64>,
) -> Option<LawFit> {
    let rows = super::stats::weighted_rows(t_days, d_mm, sigma_mm);
    let n = rows.len();
    if n < 12 {
        return None;
    }
    let t: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let d: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let w: Vec<f64> = rows.iter().map(|r| r.2).collect();
    let t_last = t[n - 1];
    let (chi2_line, _, _) = line_fit(&t, &d, &w)?;
    let scratch = std::cell::RefCell::new(Vec::new());
    let plain = |tf: f64| {
        chi2_at(
            &t,
            &d,
            &w,
            t_last + tf,
            f64::INFINITY,
            &mut scratch.borrow_mut(),
        )
    };
    let tf0 = min_over_failure_time(60, 30, plain)?;
    let s2 = (plain(tf0) / (n - 4) as f64).max(1.0);
    let penalty = step_penalty.map_or(f64::INFINITY, |p| p * s2);
    let chi = |tf: f64| chi2_at(&t, &d, &w, t_last + tf, penalty, &mut scratch.borrow_mut());
    let advances = |tf: f64| chi(tf).is_finite();
    let misfit = |tf: f64| chi(tf) / (n - PARAMETERS) as f64;
    profile_law(t_last, chi2_line, n, chi, advances, misfit)
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    use std::f64::consts::{PI, TAU};

    use super::*;
    use crate::analysis::onset::tests::creep_then_law;

    fn hours(fit: &LawFit) -> f64 {
        fit.forecast.time_to_failure_hours
    }

    #[test]
    fn recovers_the_failure_time_without_noise() {
        for tf in [1.5, 3.0, 5.0] {
            let (t, d) = creep_then_law(tf);
            let f = fit_onset_law(&t, &d, &[0.2; 40]).expect("fit");
            assert!((hours(&f) - 24.0 * tf).abs() < 2.0, "tf {tf}: {f:?}");
            let (lo, hi) = (f.forecast.lower_hours, f.forecast.upper_hours);
            assert!(lo.is_some_and(|lo| lo <= 24.0 * tf), "tf {tf}: {f:?}");
            assert!(hi.is_some_and(|hi| hi >= 24.0 * tf), "tf {tf}: {f:?}");
        }
    }

    #[test]
    fn refuses_short_or_still_series() {
        let (t, d) = creep_then_law(3.0);
        assert!(fit_onset_law(&t[..11], &d[..11], &[0.2; 11]).is_none());
        let still = vec![0.0; 40];
        assert!(fit_onset_law(&t, &still, &[0.2; 40]).is_none());
    }

    /// Coverage of the truth by the 90 % interval and median error (h) of the fits with the
    /// step and without it, over 20 seeds: creep at 0.5 mm/day, onset `onset` days before the
    /// failure, the failure `lead` days after the last of 40 daily epochs, σ 0.3 mm, and a burst
    /// (the benchmark's shape, `v₀ (1 + factor sin²)`) starting `start` days before the failure
    /// and lasting `days`.
    struct Outcome {
        covered_with: usize,
        median_with: f64,
        covered_without: usize,
        fits_with: usize,
    }

    fn outcome(onset: f64, (start, days, factor): (f64, f64, f64), lead: f64) -> Outcome {
        let noise = Normal::new(0.0, 0.3).expect("normal");
        let (tf, ta) = (lead, lead - onset);
        let t: Vec<f64> = (0..40).map(|k| k as f64 - 39.0).collect();
        let truth = 24.0 * tf;
        let (mut errors, mut covered_with, mut covered_without) = (vec![], 0, 0);
        for seed in 0..20u64 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let d: Vec<f64> = t
                .iter()
                .map(|&ti| {
                    let base = if ti <= ta {
                        0.5 * ti
                    } else {
                        0.5 * (ta + (tf - ta) * ((tf - ta) / (tf - ti)).ln())
                    };
                    let x = (ti - (tf - start)).clamp(0.0, days);
                    let burst =
                        0.5 * factor * (0.5 * x - days / (4.0 * PI) * (TAU * x / days).sin());
                    base + burst + noise.sample(&mut rng)
                })
                .collect();
            let s = [0.3; 40];
            if let Some(f) = fit_onset_law(&t, &d, &s) {
                errors.push((hours(&f) - truth).abs());
                covered_with += usize::from(covered(truth, &f));
            }
            if let Some(f) = fit(&t, &d, &s, None) {
                covered_without += usize::from(covered(truth, &f));
            }
        }
        Outcome {
            fits_with: errors.len(),
            median_with: median(errors),
            covered_with,
            covered_without,
        }
    }

    fn covered(truth: f64, f: &LawFit) -> bool {
        let lo = f.forecast.lower_hours.unwrap_or(0.0);
        let hi = f.forecast.upper_hours.unwrap_or(f64::INFINITY);
        (lo..=hi).contains(&truth)
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::INFINITY)
    }

    /// Bursts 12–13 days before failure, onsets 18 and 24 days before it, 2 and 3 days' lead:
    /// with the step the interval holds the truth in at least 15 of 20 seeds in every case and
    /// the median error is under 25 h (measured 17–20 covered, 3–17 h); without it the burst
    /// reads as acceleration and the intervals miss (measured 49 covered in all 160 fits against
    /// 151 with the step). An onset 12 days before failure with the burst at its start is the
    /// limit: there the step helps less (12–16 of 20 covered at 2–3 days' lead).
    #[test]
    fn a_burst_is_taken_out_by_the_step() {
        let (mut with, mut without) = (0, 0);
        for onset in [18.0, 24.0] {
            for burst in [(13.0, 3.0, 5.0), (12.0, 2.0, 8.0)] {
                for lead in [2.0, 3.0] {
                    let o = outcome(onset, burst, lead);
                    let case = format!("onset {onset} burst {burst:?} lead {lead}");
                    println!(
                        "{case}: {} covered ({} without the step), median error {:.1} h",
                        o.covered_with, o.covered_without, o.median_with
                    );
                    assert_eq!(o.fits_with, 20, "{case}");
                    assert!(o.covered_with >= 15, "{case}: {} covered", o.covered_with);
                    assert!(o.median_with < 25.0, "{case}: {:.1} h", o.median_with);
                    with += o.covered_with;
                    without += o.covered_without;
                }
            }
        }
        assert!(
            with >= without + 60,
            "{with} covered with the step, {without} without"
        );
    }

    /// Without a burst the step is rarely bought: coverage and error as without it (onset 12
    /// and 18 days before failure, 3 days' lead; measured 18 of 20 covered, 16 h).
    #[test]
    fn without_a_burst_the_step_costs_little() {
        for onset in [12.0, 18.0] {
            let o = outcome(onset, (10.0, 3.0, 0.0), 3.0);
            println!(
                "onset {onset}, no burst: {} covered ({} without the step), median error {:.1} h",
                o.covered_with, o.covered_without, o.median_with
            );
            assert!(
                o.covered_with >= 16,
                "onset {onset}: {} covered",
                o.covered_with
            );
            assert!(o.covered_with + 2 >= o.covered_without, "onset {onset}");
            assert!(
                o.median_with < 30.0,
                "onset {onset}: {:.1} h",
                o.median_with
            );
        }
    }
}

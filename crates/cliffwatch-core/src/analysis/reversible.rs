//! Evidence that a motion the onset law fits is reversible (a seasonal or thermal cycle) rather
//! than a failure on its way (issue 75): the rising half of a cycle reads as an onset of
//! acceleration with a failure a few hours ahead. A block that creeps and then accelerates by
//! the inverse-velocity law never moves backward along its direction, and its velocity never
//! falls; a cycle does both every half period, and a creep plus a sinusoid fits it.
//!
//! Each test reads the onset law's window along the direction of motion (`t_days` ≤ 0, oldest
//! first, the current epoch last; `d_mm` and its σ `sigma_mm`), and is switched on by its own
//! [`super::epoch::FailureConfig`] setting.

use super::failure::line_fit;
use super::stats::weighted_rows;

/// Days over which local velocities are fitted: one, two and three weeks of daily epochs (a
/// slow cycle's backward half shows over the longer stretches only).
pub const STRETCH_DAYS: [f64; 3] = [7.0, 14.0, 21.0];

/// Fewest epochs a stretch needs for its velocity.
const MIN_STRETCH_EPOCHS: usize = 4;

/// Shortest period of the cycle the alternative scans (days).
pub const MIN_PERIOD_DAYS: f64 = 10.0;

/// Longest period scanned, as a multiple of the window's span: a longer cycle is a parabola
/// over the window and would take the acceleration of a failure for one.
pub const MAX_PERIOD_SPANS: f64 = 3.0;

/// Periods scanned (log-spaced).
const PERIOD_NODES: usize = 80;

/// A velocity over one stretch of the window (start and end, days): its mid time (days), value and σ (mm/day, σ from
/// the epochs' σ alone), and the stretch's χ² about its line with its degrees of freedom.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stretch {
    start: f64,
    end: f64,
    v: f64,
    sigma_v: f64,
    chi2: f64,
    dof: usize,
}

/// The velocity of each stretch of `days` starting at each epoch (stretches overlap).
fn stretches(rows: &[(f64, f64, f64)], days: f64) -> Vec<Stretch> {
    let mut out = vec![];
    for (i, first) in rows.iter().enumerate() {
        let end = first.0 + days;
        let seg: Vec<&(f64, f64, f64)> = rows[i..].iter().take_while(|r| r.0 < end).collect();
        if seg.len() < MIN_STRETCH_EPOCHS || seg.last().is_some_and(|r| r.0 - first.0 < 0.5 * days)
        {
            continue;
        }
        let t: Vec<f64> = seg.iter().map(|r| r.0).collect();
        let d: Vec<f64> = seg.iter().map(|r| r.1).collect();
        let w: Vec<f64> = seg.iter().map(|r| r.2).collect();
        let sw: f64 = w.iter().sum();
        let tm = t.iter().zip(&w).map(|(t, w)| w * t).sum::<f64>() / sw;
        let stt: f64 = t.iter().zip(&w).map(|(t, w)| w * (t - tm).powi(2)).sum();
        let Some((chi2, _, v)) = line_fit(&t, &d, &w) else {
            continue;
        };
        if !(stt > 0.0) {
            continue;
        }
        out.push(Stretch {
            start: first.0,
            end: t[t.len() - 1],
            v,
            sigma_v: stt.recip().sqrt(),
            chi2,
            dof: seg.len() - 2,
        });
    }
    out
}

/// The motion's scatter beyond its σ (≥ 1): χ² about local lines over disjoint stretches per
/// degree of freedom, whatever the motion's shape over the whole window.
fn local_factor(all: &[Stretch]) -> f64 {
    let (mut chi2, mut dof, mut after) = (0.0, 0usize, f64::NEG_INFINITY);
    for s in all {
        if s.start > after {
            chi2 += s.chi2;
            dof += s.dof;
            after = s.end;
        }
    }
    if dof == 0 {
        1.0
    } else {
        (chi2 / dof as f64).max(1.0)
    }
}

/// Whether the motion went significantly backward over some stretch of the window (of each
/// length of [`STRETCH_DAYS`]): a stretch's velocity plus `z` of its σ (scaled by the local
/// scatter over the shortest stretches) below zero.
pub fn moves_backward(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64], z: f64) -> bool {
    let r = weighted_rows(t_days, d_mm, sigma_mm);
    let f = local_factor(&stretches(&r, STRETCH_DAYS[0])).sqrt();
    STRETCH_DAYS.iter().any(|&days| {
        stretches(&r, days)
            .iter()
            .any(|s| s.v + z * f * s.sigma_v < 0.0)
    })
}

/// Whether the motion slowed significantly somewhere in the window: a stretch's velocity below
/// that of an earlier stretch it does not overlap by more than `z` σ of the difference (scaled
/// by the local scatter).
pub fn slows_down(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64], z: f64) -> bool {
    let all = stretches(&weighted_rows(t_days, d_mm, sigma_mm), STRETCH_DAYS[0]);
    let f = local_factor(&all).sqrt();
    all.iter().any(|a| {
        all.iter().any(|b| {
            b.start > a.end && a.v - b.v > z * f * (a.sigma_v.powi(2) + b.sigma_v.powi(2)).sqrt()
        })
    })
}

/// χ² of creep plus a cycle, `d = a + v t + A sin(2πt/P) + B cos(2πt/P)`, minimised over the
/// period P (log-spaced from [`MIN_PERIOD_DAYS`] to [`MAX_PERIOD_SPANS`] × the window's span).
/// None for fewer than 8 usable epochs or a singular fit at every period.
pub fn cycle_chi2(t_days: &[f64], d_mm: &[f64], sigma_mm: &[f64]) -> Option<f64> {
    let r = weighted_rows(t_days, d_mm, sigma_mm);
    if r.len() < 8 {
        return None;
    }
    let span = r[r.len() - 1].0 - r[0].0;
    let p_max = (MAX_PERIOD_SPANS * span).max(MIN_PERIOD_DAYS * 1.01);
    let ratio = p_max / MIN_PERIOD_DAYS;
    let t0 = r[0].0;
    (0..=PERIOD_NODES)
        .filter_map(|k| {
            let p = MIN_PERIOD_DAYS * ratio.powf(k as f64 / PERIOD_NODES as f64);
            fit4(&r, t0, std::f64::consts::TAU / p)
        })
        .min_by(f64::total_cmp)
}

/// Weighted least squares of `d = a + v t + A sin(ωt) + B cos(ωt)` (t from `t0`): χ².
fn fit4(rows: &[(f64, f64, f64)], t0: f64, omega: f64) -> Option<f64> {
    use nalgebra::{Matrix4, Vector4};
    let mut n = Matrix4::<f64>::zeros();
    let mut b = Vector4::<f64>::zeros();
    let x = |t: f64| {
        let s = t - t0;
        Vector4::new(1.0, s, (omega * s).sin(), (omega * s).cos())
    };
    for &(t, d, w) in rows {
        let xi = x(t);
        n += xi * xi.transpose() * w;
        b += xi * (w * d);
    }
    let p = n.cholesky()?.solve(&b);
    let chi2: f64 = rows
        .iter()
        .map(|&(t, d, w)| w * (d - x(t).dot(&p)).powi(2))
        .sum();
    chi2.is_finite().then_some(chi2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn window() -> Vec<f64> {
        (0..40).map(|k| k as f64 - 39.0).collect()
    }

    #[test]
    fn a_cycle_reverses_slows_and_fits_a_sinusoid() {
        let t = window();
        let d: Vec<f64> = t
            .iter()
            .map(|&t| 0.2 * t + 4.0 * (TAU * t / 30.0).sin())
            .collect();
        let s = vec![0.3; 40];
        assert!(moves_backward(&t, &d, &s, 3.0));
        assert!(slows_down(&t, &d, &s, 3.0));
        // The scan's periods are log-spaced (3 % apart), so a cycle between two nodes keeps
        // some χ²; the law fits the cycle far worse, when at all.
        let cycle = cycle_chi2(&t, &d, &s).expect("cycle");
        let (chi2_line, _, _) = line_fit(&t, &d, &[1.0 / 0.09; 40]).expect("line");
        let chi2_law = crate::analysis::onset_law::fit_onset_law(&t, &d, &s)
            .map_or(f64::INFINITY, |law| (1.0 - law.forecast.r2) * chi2_line);
        println!("cycle χ² {cycle:.3}, law χ² {chi2_law:.3}");
        assert!(
            cycle < 2.0 && cycle < chi2_law,
            "cycle {cycle}, law {chi2_law}"
        );
    }

    #[test]
    fn creep_then_the_law_neither_reverses_nor_slows() {
        let t = window();
        let (tf, ta, v0) = (3.0, -15.0, 0.5);
        let d: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t <= ta {
                    v0 * t
                } else {
                    v0 * ta + v0 * (tf - ta) * ((tf - ta) / (tf - t)).ln()
                }
            })
            .collect();
        let s = vec![0.3; 40];
        assert!(!moves_backward(&t, &d, &s, 3.0));
        assert!(!slows_down(&t, &d, &s, 3.0));
        // The law fits its own shape exactly; no cycle follows 1/(t_f − t).
        let law = crate::analysis::onset_law::fit_onset_law(&t, &d, &s).expect("law");
        let (chi2_line, _, _) = line_fit(&t, &d, &[1.0 / 0.09; 40]).expect("line");
        let chi2_law = (1.0 - law.forecast.r2) * chi2_line;
        let cycle = cycle_chi2(&t, &d, &s).expect("cycle");
        println!("law χ² {chi2_law:.3}, cycle χ² {cycle:.3}");
        assert!(cycle > chi2_law + 9.0, "law {chi2_law}, cycle {cycle}");
    }

    #[test]
    fn too_few_epochs_give_no_cycle() {
        let t = window();
        let d = vec![0.0; 40];
        assert!(cycle_chi2(&t[..7], &d[..7], &[0.3; 7]).is_none());
        assert!(cycle_chi2(&t, &d, &[f64::NAN; 40]).is_none());
    }
}

//! Prints the success rate and iterations of the orthogonal and the central model from the same
//! start on the long-range cliff (like the paper's Tables 6–7), as a Markdown table.
//!
//! `cargo run --example accuracy_table [-- SEEDS]` (default 20 seeds per start error).
//!
//! Success: the adjustment returns converged, σ0 passes the global test (< 1.25 × the image noise,
//! ≈ 170 degrees of freedom) and index 3 is within 1.3 × that of the same data and model started
//! from the true coordinates (the rigorous optimum).

use cliffwatch_core::photogrammetry::{adjust, AdjustError, AdjustOptions, Model};
use cliffwatch_sim::scenes::{long_range, with_true_approx, LongRangeParams};

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let start_errors = [0.1, 0.5, 1.0, 2.0, 5.0];
    println!("| start error σ (m) | model | success | iterations mean (min–max) | index 3 median (mm) | failures |");
    println!("|---|---|---|---|---|---|");
    for &err in &start_errors {
        for model in [Model::Orthogonal, Model::Central] {
            // The same start for both models: collinearity starts from the start values, not from
            // the orthogonal solution.
            let opts = AdjustOptions {
                model,
                central_from_orthogonal: false,
                ..AdjustOptions::default()
            };
            let mut ok = 0;
            let mut its = Vec::new();
            let mut i3s = Vec::new();
            let mut failures = Vec::new();
            for seed in 1..=seeds {
                let params = LongRangeParams {
                    seed,
                    approx_sigma_m: err,
                    ..LongRangeParams::default()
                };
                let noise_mm = params.noise_px * params.pixel_size_mm;
                let (epoch, truth) = long_range(&params).expect("scene");
                let best = adjust(&with_true_approx(&epoch, &truth), &opts)
                    .ok()
                    .and_then(|a| truth.index3_rmse_mm(&a.points).ok())
                    .map(|v| v[3]);
                match adjust(&epoch, &opts) {
                    Ok(a) => {
                        let i3 = truth
                            .index3_rmse_mm(&a.points)
                            .map(|v| v[3])
                            .unwrap_or(f64::NAN);
                        let good = a.report.converged
                            && a.report.sigma0_mm < 1.25 * noise_mm
                            && best.is_some_and(|b| i3 <= 1.3 * b);
                        if good {
                            ok += 1;
                            its.push(a.report.iterations);
                            i3s.push(i3);
                        } else {
                            failures.push(format!(
                                "{seed}: {} (σ0 {:.4} mm, index 3 {i3:.2} mm, optimum {})",
                                if a.report.converged {
                                    "accepted"
                                } else {
                                    "not converged"
                                },
                                a.report.sigma0_mm,
                                best.map_or("–".into(), |b| format!("{b:.2}"))
                            ));
                        }
                    }
                    Err(e) => failures.push(format!("{seed}: {}", short(&e))),
                }
            }
            i3s.sort_by(f64::total_cmp);
            let mean = if its.is_empty() {
                f64::NAN
            } else {
                its.iter().sum::<usize>() as f64 / its.len() as f64
            };
            let range = match (its.iter().min(), its.iter().max()) {
                (Some(a), Some(b)) => format!("{mean:.1} ({a}–{b})"),
                _ => "–".into(),
            };
            let median = i3s
                .get(i3s.len() / 2)
                .map_or("–".into(), |v| format!("{v:.3}"));
            let shown: Vec<_> = failures.iter().take(4).cloned().collect();
            println!(
                "| {err} | {} | {ok}/{seeds} | {range} | {median} | {} |",
                model.as_str(),
                if shown.is_empty() {
                    "".into()
                } else {
                    shown.join("; ").replace('|', "/")
                }
            );
        }
    }
}

/// The kind of a failure, short enough for a table cell.
fn short(e: &AdjustError) -> String {
    match e {
        AdjustError::NoConvergence { iterations, .. } => format!("not converged in {iterations}"),
        AdjustError::Inconsistent {
            sigma0_mm,
            outliers,
        } => {
            format!("refused (σ0 {sigma0_mm:.4} mm, {outliers} beyond |w|)")
        }
        AdjustError::Singular(_) => "singular".into(),
        other => format!("error: {other}"),
    }
}

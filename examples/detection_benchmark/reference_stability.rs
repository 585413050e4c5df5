//! The detection benchmark's count of `reference_unstable` on its still series.

use cliffwatch_core::analysis::{evaluate_alerts, AlertConfig, AlertState};

use super::Processed;

/// `reference_unstable` on the still series at the default confidence: the stable point-epochs
/// (stable points × the epochs after the first), those the congruence test excluded from the
/// datum, those the change test also found moved (`datum.moved`), and the point-epochs the alert
/// named, with the series it was raised in; the last two also for the rule before the change
/// test (every exclusion counts). Returns (point-epochs, excluded, moved, named, series, named
/// by the old rule, series by the old rule).
pub(super) fn reference_stability(processed: &[Processed]) -> [usize; 7] {
    let mut out = [0; 7];
    let cfg = AlertConfig::new("bench", vec![]);
    for p in processed.iter().filter(|p| !p.failing) {
        for old_rule in [false, true] {
            let mut st = AlertState::default();
            let (mut named, mut any) = (0, false);
            for a in p.analyses.iter().skip(1) {
                let mut a = a.clone();
                if old_rule {
                    a.datum.moved = None;
                } else {
                    out[0] += a.datum.points.len() + a.datum.excluded.len();
                    out[1] += a.datum.excluded.len();
                    out[2] += a.datum.moved.as_ref().map_or(0, Vec::len);
                }
                let (n, _) = evaluate_alerts(&cfg, &st, &a, a.observed_at);
                st = n;
                let now = st
                    .find(
                        None,
                        cliffwatch_core::analysis::AlertKind::ReferenceUnstable,
                    )
                    .map_or(0, |x| x.points.len());
                named += now;
                any |= now > 0;
            }
            let k = if old_rule { 5 } else { 3 };
            out[k] += named;
            out[k + 1] += usize::from(any);
        }
    }
    out
}

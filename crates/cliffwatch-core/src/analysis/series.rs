//! A whole series analysed again against one reference, with the alert rules replayed over it
//! from an empty state: what a recompute (new reference, epoch out of order, changed settings)
//! derives. Pure: the service loads the epochs and stores the outcome.

use std::collections::HashMap;

use crate::analysis::{
    self, AlertConfig, AlertEvent, AlertState, AnalysisConfig, DisplacementRecord,
    EpochCoordinates, History, PointConfig,
};

/// A series analysed again against one reference, with the alert rules replayed over it.
#[derive(Debug, Default)]
pub struct SeriesAnalysis {
    /// Every displacement record, epoch by epoch in time order.
    pub records: Vec<DisplacementRecord>,
    /// Every block motion record (`point` names the group), epoch by epoch.
    pub block_records: Vec<DisplacementRecord>,
    /// The alert state the rules reach over the series, replayed from an empty state.
    pub replayed: AlertState,
    /// Epochs whose analysis failed, with the reason.
    pub failures: Vec<(i64, String)>,
    /// Epochs analysed.
    pub analysed: Vec<i64>,
    /// Every alert event of the replay, in order, with the epoch that caused it.
    pub events: Vec<(i64, AlertEvent)>,
    /// Every pooled forecast, epoch by epoch: the epoch, the point and the other targets of
    /// the mean series that gave its forecast ([`analysis::EpochAnalysis::pooled`]).
    pub pooled: Vec<(i64, String, Vec<String>)>,
}

/// Analyses a whole series against one reference (pure; the analysis part of
/// `service::recompute`): `epochs` oldest first; each epoch's history is the records computed
/// before it, and the site's rules are replayed epoch by epoch from an empty state (each epoch
/// stamped with its observation time). Epochs whose analysis fails are listed with the reason and
/// replayed as [`analysis::analysis_failed`].
pub fn analyse_series(
    reference: &EpochCoordinates,
    epochs: &[EpochCoordinates],
    points: &[PointConfig],
    config: &AnalysisConfig,
    alerts: &AlertConfig,
) -> SeriesAnalysis {
    let keep = config.history_epochs().max(1);
    let mut history: History = HashMap::new();
    let mut out = SeriesAnalysis::default();
    for e in epochs {
        match analysis::analyse_epoch(reference, e, points, &history, config) {
            Ok(a) => {
                for r in a.records() {
                    let h = history.entry(r.point.clone()).or_default();
                    h.push(r.clone());
                    trim_history(h, keep, config);
                    out.records.push(r);
                }
                out.block_records.extend(a.block_records());
                out.pooled
                    .extend(a.pooled().into_iter().map(|(p, with)| (e.epoch, p, with)));
                let (state, events) =
                    analysis::evaluate_alerts(alerts, &out.replayed, &a, e.observed_at);
                out.replayed = state;
                out.events
                    .extend(events.into_iter().map(|ev| (e.epoch, ev)));
                out.analysed.push(e.epoch);
            }
            Err(err) => {
                let reason = format!(
                    "analysis against reference epoch {}: {err}",
                    reference.epoch
                );
                let (state, events) = analysis::analysis_failed(
                    alerts,
                    &out.replayed,
                    e.epoch,
                    e.observed_at,
                    &reason,
                    e.observed_at,
                );
                out.replayed = state;
                out.events
                    .extend(events.into_iter().map(|ev| (e.epoch, ev)));
                out.failures.push((e.epoch, reason));
            }
        }
    }
    out
}

/// Drops the oldest of a point's records (oldest first) that no later epoch reads: beyond the
/// last `keep` and the last [`AnalysisConfig::history_span_days`] before the newest, or beyond
/// [`analysis::MAX_FILTER_EPOCHS`].
fn trim_history(h: &mut Vec<DisplacementRecord>, keep: usize, config: &AnalysisConfig) {
    let Some(newest) = h.last().map(|r| r.observed_at) else {
        return;
    };
    let cap = keep.max(analysis::MAX_FILTER_EPOCHS);
    let span = config.history_span_days();
    let old = |r: &DisplacementRecord| super::velocity::days_between(r.observed_at, newest) > span;
    let drop = h
        .iter()
        .take(h.len().saturating_sub(keep))
        .take_while(|r| old(r))
        .count()
        .max(h.len().saturating_sub(cap));
    h.drain(..drop);
}

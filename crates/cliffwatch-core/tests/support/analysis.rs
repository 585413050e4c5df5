//! Shared helpers of the analysis tests: run a simulated series through the analysis and the alerts.
#![allow(dead_code)]

use cliffwatch_core::analysis::{
    analyse_epoch, evaluate_alerts, AlertConfig, AlertEvent, AlertState, AnalysisConfig,
    EpochAnalysis, History, PointConfig,
};
use cliffwatch_sim::monitoring::MonitoringSeries;

/// One analysed epoch with the alert events it produced.
pub struct Step {
    pub analysis: EpochAnalysis,
    pub events: Vec<AlertEvent>,
}

/// Analyses every epoch after the first against the first, feeding the history and alert state forward.
pub fn run(
    series: &MonitoringSeries,
    points: &[PointConfig],
    config: &AnalysisConfig,
    alerts: &AlertConfig,
) -> Vec<Step> {
    let reference = &series.epochs[0].coordinates;
    let mut history = History::new();
    let mut state = AlertState::default();
    let mut out = vec![];
    for e in &series.epochs[1..] {
        let analysis =
            analyse_epoch(reference, &e.coordinates, points, &history, config).expect("analysis");
        for r in analysis.records() {
            history.entry(r.point.clone()).or_default().push(r);
        }
        let (s, events) = evaluate_alerts(alerts, &state, &analysis, analysis.observed_at);
        state = s;
        out.push(Step { analysis, events });
    }
    out
}

/// eᵀΣ⁻¹e of a 3-vector error with a 3 × 3 covariance (None if singular).
pub fn mahalanobis(e: [f64; 3], cov: [[f64; 3]; 3]) -> Option<f64> {
    let m = nalgebra::Matrix3::from_fn(|r, c| cov[r][c]);
    let inv = m.try_inverse()?;
    let v = nalgebra::Vector3::from(e);
    Some((v.transpose() * inv * v)[(0, 0)])
}

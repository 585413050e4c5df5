//! Input types of the analysis: adjusted coordinates of one epoch with covariances, the points'
//! configuration (role, group, direction of interest) and the analysis configuration.

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use super::error::AnalysisError;
use crate::photogrammetry::Adjustment;

/// Default of [`FailureConfig::forecast_bin_hours`] (hours): daily means.
pub const DEFAULT_FORECAST_BIN_HOURS: f64 = 24.0;

/// Most epochs the filter and the forecast read of one subject (an hourly site's 40 daily bins
/// hold 948; a site sampled more often reads its last 1 000 epochs).
pub const MAX_FILTER_EPOCHS: usize = 1000;

/// Adjusted coordinates of one point in one epoch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointCoordinates {
    /// Point name.
    pub name: String,
    /// X, Y, Z in m, site frame.
    pub xyz_m: [f64; 3],
    /// 3 × 3 covariance of X, Y, Z in m² (σ0²·Qxx of the adjustment).
    pub covariance_m2: [[f64; 3]; 3],
}

/// Joint covariance of a set of points of one epoch (usually the stable points): row-major 3n × 3n in m²,
/// ordered X, Y, Z per point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointCovarianceM2 {
    /// Point names in matrix order.
    pub points: Vec<String>,
    /// Row-major 3n × 3n matrix in m².
    pub matrix_m2: Vec<f64>,
}

/// The adjusted coordinates of one epoch, as the analysis needs them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpochCoordinates {
    /// Epoch id (integer, unique within the site).
    pub epoch: i64,
    /// When the epoch was observed (UTC).
    pub observed_at: DateTime<Utc>,
    /// Every adjusted point.
    pub points: Vec<PointCoordinates>,
    /// Joint covariance of chosen points (the stable ones), when the adjustment provided it. Without it the
    /// points are taken as uncorrelated.
    pub joint: Option<JointCovarianceM2>,
}

impl EpochCoordinates {
    /// Builds the analysis input from an adjustment result (coordinates in m, covariances in m²).
    pub fn from_adjustment(
        epoch: i64,
        observed_at: DateTime<Utc>,
        adjustment: &Adjustment,
    ) -> Self {
        EpochCoordinates {
            epoch,
            observed_at,
            points: adjustment
                .points
                .iter()
                .map(|p| PointCoordinates {
                    name: p.name.clone(),
                    xyz_m: p.xyz,
                    covariance_m2: p.covariance_m2,
                })
                .collect(),
            joint: adjustment
                .joint_covariance
                .as_ref()
                .map(|j| JointCovarianceM2 {
                    points: j.points.clone(),
                    matrix_m2: j.matrix_m2.clone(),
                }),
        }
    }
}

/// Role of a point (contract: `stable` or `monitored`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum PointRole {
    /// Assumed not to move: defines the datum, checked by the congruence test.
    Stable,
    /// Watched for movement.
    #[default]
    Monitored,
}

crate::contract_names!(PointRole, "point role" {
    Stable => "stable",
    Monitored => "monitored",
});

/// Per-point configuration set through `PUT .../points/{point}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointConfig {
    /// Point name.
    pub name: String,
    /// Role.
    #[serde(default)]
    pub role: PointRole,
    /// Point group (alert rules can be restricted to a group).
    #[serde(default)]
    pub group: Option<String>,
    /// Direction of interest in the site frame (e.g. the cliff normal); need not be normalised.
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
}

/// What a point group is (contract: `"kind": "block"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GroupKind {
    /// A rigid block: its motion is estimated from all its points, and rules naming the group
    /// apply to that motion.
    #[default]
    Block,
}

/// A point group declared through `PUT .../groups/{group}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupConfig {
    /// Group name (`[A-Za-z0-9._-]{1,64}`).
    pub name: String,
    /// Kind of group.
    #[serde(default)]
    pub kind: GroupKind,
    /// Direction of interest of the block in the site frame (need not be normalised).
    #[serde(default)]
    pub direction: Option<[f64; 3]>,
    /// Member points; empty: the points whose `group` names this group.
    #[serde(default)]
    pub points: Vec<String>,
    /// Process noise of the block's Kalman filter (see [`super::kalman`]); None: the site's.
    #[serde(default)]
    pub process_noise: Option<f64>,
}

impl GroupConfig {
    /// The member points: the explicit list, else the points whose `group` names this group.
    pub fn members(&self, points: &[PointConfig]) -> Vec<String> {
        if !self.points.is_empty() {
            return self.points.clone();
        }
        points
            .iter()
            .filter(|p| p.group.as_deref() == Some(self.name.as_str()))
            .map(|p| p.name.clone())
            .collect()
    }
}

/// The similarity-transformation model of the datum (parameters estimated per epoch).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DatumTransformation {
    /// 3 translations.
    Translation,
    /// 3 translations and 3 small rotations.
    Rigid,
    /// 3 translations, 3 small rotations and a scale (7-parameter Helmert): the datum defect of a free
    /// photogrammetric network.
    #[default]
    Similarity,
}

impl DatumTransformation {
    /// Number of parameters (3, 6 or 7).
    pub fn parameters(self) -> usize {
        match self {
            DatumTransformation::Translation => 3,
            DatumTransformation::Rigid => 6,
            DatumTransformation::Similarity => 7,
        }
    }

    /// Fewest points that determine the transformation (1 or 3, not collinear).
    pub fn min_points(self) -> usize {
        match self {
            DatumTransformation::Translation => 1,
            _ => 3,
        }
    }
}

/// A time window over the history: the last `n` epochs, or the epochs of the last `days` days (both
/// counting the current epoch).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Window {
    /// The last n epochs including the current one.
    Epochs(usize),
    /// The epochs observed within this many days before the current one (inclusive).
    Days(f64),
}

/// How the filtered time to failure is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ForecastMethod {
    /// Once the displacements along the direction of motion show an onset of acceleration: the
    /// onset model (creep, then the inverse-velocity law continuing the creep's velocity) with
    /// at most one forward step for a burst, fitted to the displacements over
    /// `acceleration_window` ([`super::onset_law`]). The creep before the onset pins the law's
    /// amplitude, so the failure time is known days earlier than from the law alone.
    #[default]
    OnsetLaw,
    /// The inverse-velocity law alone integrated and fitted to the displacement vectors of the
    /// last `law_window` epochs in three dimensions (no differentiation of noisy data), once the
    /// displacements along the direction of motion show an onset of acceleration.
    Displacement,
    /// Fukuzono's line through the inverse of the Kalman smoother's velocities.
    SmoothedVelocity,
}

/// The default of [`FailureConfig::pool_radius_m`]: targets this close (m) may be pooled.
pub const DEFAULT_POOL_RADIUS_M: f64 = 15.0;

/// Time-to-failure (inverse velocity) settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FailureConfig {
    /// Epochs whose velocities enter the 1/v fit; also the window of the acceleration (parabola) fit.
    pub window: Window,
    /// Smoothing: each velocity is the least-squares slope over this many consecutive epochs, placed at
    /// their mean time (≥ 2).
    pub smoothing_epochs: usize,
    /// One-sided confidence that the acceleration is positive before a forecast is made.
    pub acceleration_confidence: f64,
    /// Minimum coefficient of determination R² of the 1/v fit for a forecast.
    pub min_r2: f64,
    /// How the filtered forecast is fitted.
    pub method: ForecastMethod,
    /// Epochs whose displacements enter the fit of the integrated law
    /// (`ForecastMethod::Displacement`): short enough that the creep before the acceleration
    /// does not pull the failure time late (12 epochs measured best on the detection benchmark).
    pub law_window: Window,
    /// Hours over which a forecast must converge before it is published (0: no confirmation):
    /// the series is refitted without the current epoch, and without each earlier epoch observed
    /// within this many hours of it (at least the previous one), and every such forecast must
    /// exist and hold the current failure time inside its 90 % interval. One epoch's scatter or
    /// the first epochs of a burst or a step cannot raise a time-to-failure alarm alone (72 h,
    /// chosen by the trade-off table of `docs/accuracy.md`).
    pub confirm_hours: f64,
    /// Whether the confirmation also asks each earlier failure time to lie inside the current
    /// forecast's 90 % interval (the two agree both ways).
    pub confirm_both_ways: bool,
    /// Epochs whose displacements enter the test for an onset of acceleration
    /// (`super::onset`, creep then the law, against a straight line) that must pass before the
    /// law is fitted (`ForecastMethod::Displacement`): long, so the creep before the onset pins
    /// the line (40 epochs measured best on the detection benchmark; capped by `filter_epochs`).
    pub acceleration_window: Window,
    /// Targets not in a declared block that lie within this distance (m) of each other and move
    /// together (displacements and filtered velocities equal within their σ) have their mean
    /// series forecast, and each takes that forecast when it is tighter than its own
    /// (`super::pooling`; 0: never pooled).
    pub pool_radius_m: f64,
    /// Whether the spread of the failure times forecast over `confirm_hours` (the current one
    /// and each refit the confirmation makes) is added to the forecast's σ in quadrature. It
    /// removes most alarms more than 120 h early and most intervals that miss the truth, but
    /// more alarms then come less than 24 h before failure (`docs/accuracy.md`), so it is off.
    pub confirm_spread: bool,
    /// Whether a forecast is withheld when the motion went significantly backward along its
    /// direction over a stretch of one to three weeks of the onset law's window (its velocity
    /// 3 σ below zero, σ scaled by the local scatter; `super::reversible::moves_backward`): a
    /// cycle's falling half; a block that creeps and then accelerates never reverses (issue 75).
    /// Off: it stopped 1 of 5 cyclic alarms, the cycle alternative all (`docs/accuracy.md`).
    pub refuse_backward: bool,
    /// Whether a forecast is withheld when the motion slowed significantly within the onset
    /// law's window (a week's velocity 3 σ below an earlier week's;
    /// `super::reversible::slows_down`): a cycle slows every half period, but so does a burst
    /// inside a real failure's acceleration. Off: it stopped 1 of 5 cyclic alarms and delayed
    /// a failing series' alarm (`docs/accuracy.md`).
    pub refuse_slowing: bool,
    /// Margin of the creep-plus-cycle alternative, in units of the law's variance factor
    /// (dimensionless; None: not asked): a forecast is withheld when creep plus a sinusoid
    /// (`super::reversible::cycle_chi2`, periods 10 days to 3 × the window) fits the onset law's
    /// window with a χ² below the law's plus this margin. 0 by default: a forecast is published
    /// only when the law fits better than a cycle (issue 75: cyclic series alarmed 5 of 20 →
    /// 0, failing series' alarms kept; `docs/accuracy.md`).
    pub cycle_margin: Option<f64>,
    /// Hours over which epochs are averaged before the forecast's fits (the onset test, the
    /// law, the cycle alternative and the confirmation's refits; 0: every epoch on its own).
    /// Bins are counted back from the current epoch (epoch k hours back falls in bin
    /// `round(k / bin)`), so epochs this far apart or farther stay one per bin and windows
    /// counted in epochs count bins; the filter's history reaches back
    /// `AnalysisConfig::filter_epochs` bins ([`AnalysisConfig::filter_start`]). 24 by default:
    /// a daily site's epochs stay as they are, an hourly, 6-hourly or 12-hourly site's are
    /// fitted as daily means, each better known, at a daily series' cost (hourly failures: 12
    /// of 16 alarmed 24–120 h before with daily bins, none without; `docs/accuracy.md`).
    pub forecast_bin_hours: f64,
}

impl Default for FailureConfig {
    fn default() -> Self {
        FailureConfig {
            window: Window::Epochs(16),
            smoothing_epochs: 6,
            acceleration_confidence: 0.99,
            min_r2: 0.5,
            method: ForecastMethod::OnsetLaw,
            law_window: Window::Epochs(12),
            confirm_hours: 72.0,
            confirm_both_ways: false,
            acceleration_window: Window::Epochs(40),
            pool_radius_m: DEFAULT_POOL_RADIUS_M,
            confirm_spread: false,
            refuse_backward: false,
            refuse_slowing: false,
            cycle_margin: Some(0.0),
            forecast_bin_hours: DEFAULT_FORECAST_BIN_HOURS,
        }
    }
}

/// The kinematic model of the filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MotionModel {
    /// Position and velocity; process noise is white acceleration (q in mm²/day³).
    ConstantVelocity,
    /// Position, velocity and acceleration; process noise is white jerk (q in mm²/day⁵).
    #[default]
    ConstantAcceleration,
}

impl MotionModel {
    /// Derivatives per axis in the state (2 or 3).
    pub fn order(self) -> usize {
        match self {
            MotionModel::ConstantVelocity => 2,
            MotionModel::ConstantAcceleration => 3,
        }
    }
}

/// Settings of the filter (per site, or per block group).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct KalmanConfig {
    /// The kinematic model.
    pub model: MotionModel,
    /// Spectral density of the process noise: mm²/day³ (constant velocity) or mm²/day⁵
    /// (constant acceleration). Larger follows sudden changes faster and smooths less.
    pub process_noise: f64,
}

impl Default for KalmanConfig {
    /// Constant acceleration with q = 0.05 mm²/day⁵: over one day the jerk noise moves the
    /// acceleration by √q ≈ 0.22 mm/day², enough to follow a block accelerating to failure
    /// by the inverse-velocity law from about five days before failure on (its jerk there is
    /// ≈ 0.4 mm/day³ for a creep of 2 mm/day), while a still point's filtered velocity stays
    /// within a few tenths of a mm/day (measured by `tests/analysis/kalman.rs`).
    fn default() -> Self {
        KalmanConfig {
            model: MotionModel::ConstantAcceleration,
            process_noise: 0.05,
        }
    }
}

impl KalmanConfig {
    /// Checks the process noise (> 0 and finite).
    pub fn validate(&self) -> Result<(), AnalysisError> {
        if !(self.process_noise > 0.0 && self.process_noise.is_finite()) {
            return Err(AnalysisError::InvalidConfig(
                "process_noise must be a finite number > 0".into(),
            ));
        }
        Ok(())
    }
}

/// Settings of the displacement analysis (per site).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AnalysisConfig {
    /// Confidence of the per-point significance test (default 0.99).
    pub confidence: f64,
    /// Confidence of the global congruence test of the stable points (default 0.99).
    pub congruence_confidence: f64,
    /// Degrees of freedom of the variance factor the covariances were scaled with; `None` (default) treats
    /// it as known, so tests use χ² (F with infinite denominator degrees of freedom).
    pub variance_dof: Option<f64>,
    /// The datum transformation.
    pub transformation: DatumTransformation,
    /// Iterations of the robust (IWST) datum when no point is stable.
    pub iwst_max_iterations: usize,
    /// Window of the velocity and acceleration fit.
    pub velocity_window: Window,
    /// Time-to-failure settings.
    pub failure: FailureConfig,
    /// The Kalman filter of the points' (and blocks') kinematics (model and process noise).
    pub kalman: KalmanConfig,
    /// Epochs the filter runs over at each analysis (the current one and the ones before it),
    /// or forecast bins when the epochs come more often than one per bin
    /// ([`AnalysisConfig::filter_start`]).
    pub filter_epochs: usize,
    /// Declared point groups (blocks).
    pub groups: Vec<GroupConfig>,
}

impl Default for AnalysisConfig {
    fn default() -> Self {
        AnalysisConfig {
            confidence: 0.99,
            congruence_confidence: 0.99,
            variance_dof: None,
            transformation: DatumTransformation::Similarity,
            iwst_max_iterations: 100,
            velocity_window: Window::Epochs(5),
            failure: FailureConfig::default(),
            kalman: KalmanConfig::default(),
            filter_epochs: 40,
            groups: vec![],
        }
    }
}

impl AnalysisConfig {
    /// Checks ranges; every analysis calls it.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        let p = |x: f64| x > 0.0 && x < 1.0;
        if !p(self.confidence)
            || !p(self.congruence_confidence)
            || !p(self.failure.acceleration_confidence)
        {
            return Err(AnalysisError::InvalidConfig(
                "confidences must lie in (0, 1)".into(),
            ));
        }
        if let Some(f) = self.variance_dof {
            if !(f > 0.0) {
                return Err(AnalysisError::InvalidConfig(
                    "variance_dof must be > 0".into(),
                ));
            }
        }
        for w in [
            self.velocity_window,
            self.failure.window,
            self.failure.law_window,
            self.failure.acceleration_window,
        ] {
            match w {
                Window::Epochs(n) if n < 2 => {
                    return Err(AnalysisError::InvalidConfig(
                        "a window needs ≥ 2 epochs".into(),
                    ))
                }
                Window::Days(d) if !(d > 0.0) => {
                    return Err(AnalysisError::InvalidConfig(
                        "a window needs > 0 days".into(),
                    ))
                }
                _ => {}
            }
        }
        self.kalman.validate()?;
        if self.filter_epochs < 2 {
            return Err(AnalysisError::InvalidConfig(
                "filter_epochs must be ≥ 2".into(),
            ));
        }
        for g in &self.groups {
            if let Some(q) = g.process_noise {
                if !(q > 0.0 && q.is_finite()) {
                    return Err(AnalysisError::InvalidConfig(format!(
                        "group {}: process_noise must be a finite number > 0",
                        g.name
                    )));
                }
            }
        }
        if !(self.failure.forecast_bin_hours >= 0.0 && self.failure.forecast_bin_hours.is_finite())
        {
            return Err(AnalysisError::InvalidConfig(
                "forecast_bin_hours must be a finite number ≥ 0".into(),
            ));
        }
        if self.failure.smoothing_epochs < 2 {
            return Err(AnalysisError::InvalidConfig(
                "smoothing_epochs must be ≥ 2".into(),
            ));
        }
        Ok(())
    }

    /// How many days of history the store must load at least when windows are in days (`None` when both
    /// windows count epochs: then load the last [`AnalysisConfig::history_epochs`] records per point).
    pub fn history_days(&self) -> Option<f64> {
        match (self.velocity_window, self.failure.window) {
            (Window::Days(a), Window::Days(b)) => Some(a.max(b)),
            (Window::Days(a), _) | (_, Window::Days(a)) => Some(a),
            _ => None,
        }
    }

    /// Index of the first of `len` epochs (oldest first; `days_back(k)`: epoch k's days before
    /// the current epoch, ≥ 0) that the filter and the forecast read: the last `keep` of them
    /// (`filter_epochs` with the current epoch, `filter_epochs − 1` of a history before it), or
    /// every epoch of the last `filter_epochs` forecast bins when those reach further back (an
    /// hourly site's last 40 days with the defaults), never more than [`MAX_FILTER_EPOCHS`].
    /// A series with one epoch per bin or fewer reads its last `keep` epochs, as without bins.
    pub fn filter_start(&self, len: usize, keep: usize, days_back: impl Fn(usize) -> f64) -> usize {
        let by_count = len.saturating_sub(keep);
        let bin = self.failure.forecast_bin_hours;
        if !(bin > 0.0) || by_count == 0 {
            return by_count;
        }
        let in_bins =
            |k: usize| ((days_back(k) * 24.0 / bin).round() as usize) < self.filter_epochs;
        // The epochs are oldest first, so `in_bins` is false up to some index, then true:
        // bisection (a daily site's ten years of history are 3 650 records per point).
        let (mut lo, mut hi) = (0, len);
        while lo < hi {
            let mid = lo + (hi - lo) / 2;
            if in_bins(mid) {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        let by_bins = lo;
        by_count
            .min(by_bins)
            .max(len.saturating_sub(MAX_FILTER_EPOCHS))
    }

    /// Days of history the filter may read beyond its last `filter_epochs` records
    /// ([`AnalysisConfig::filter_start`]: `filter_epochs` forecast bins; 0 without bins). The
    /// store loads every record of these days as well as the last
    /// [`AnalysisConfig::history_epochs`], at most [`MAX_FILTER_EPOCHS`] per point.
    pub fn history_span_days(&self) -> f64 {
        let bin = self.failure.forecast_bin_hours.max(0.0);
        (self.filter_epochs as f64 - 0.5) * bin / 24.0
    }

    /// How many past records per point the windows counted in epochs need.
    pub fn history_epochs(&self) -> usize {
        let n = |w: Window| match w {
            Window::Epochs(n) => n,
            Window::Days(_) => 0,
        };
        n(self.velocity_window)
            .max(n(self.failure.window) + self.failure.smoothing_epochs)
            .max(n(self.failure.law_window))
            .max(n(self.failure.acceleration_window))
            .max(self.filter_epochs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Where the filter starts in `n` epochs `spacing_hours` apart (the last one current, or,
    /// with `keep` < 40, a spacing before it: a history), each late or early by up to 0.9 h
    /// (daily; less in proportion for shorter spacings) at set phases (a schedule slips).
    fn start(config: &AnalysisConfig, n: usize, spacing_hours: f64, keep: usize) -> usize {
        let slip = |k: usize| [0.0, 0.9, -0.7, 0.4][k % 4] * spacing_hours.min(24.0) / 24.0;
        let last = if keep < config.filter_epochs {
            n
        } else {
            n - 1
        };
        config.filter_start(n, keep, |k| {
            ((last - k) as f64 * spacing_hours + slip(k)).max(0.0) / 24.0
        })
    }

    /// Daily epochs read the last 40 however late or early each was taken; with a day
    /// missing too. Hourly ones read the last 40 daily bins (948 epochs: bins 0–39, bin 39
    /// ending 39.5 days back); 10-minute ones the last 1 000; and without bins every site
    /// reads its last 40 epochs.
    #[test]
    fn the_filter_reads_forty_epochs_or_forty_daily_bins() {
        let c = AnalysisConfig::default();
        assert_eq!(100 - start(&c, 100, 24.0, 40), 40);
        assert_eq!(100 - start(&c, 100, 24.0, 39), 39);
        assert_eq!(2000 - start(&c, 2000, 1.0, 40), 948);
        assert_eq!(20 - start(&c, 20, 1.0, 40), 20);
        assert_eq!(10_000 - start(&c, 10_000, 1.0 / 6.0, 40), MAX_FILTER_EPOCHS);
        assert_eq!(200 - start(&c, 200, 6.0, 40), 158);
        let mut unbinned = AnalysisConfig::default();
        unbinned.failure.forecast_bin_hours = 0.0;
        assert_eq!(2000 - start(&unbinned, 2000, 1.0, 40), 40);
        assert_eq!(unbinned.history_span_days(), 0.0);
        assert_eq!(c.history_span_days(), 39.5);
    }
}

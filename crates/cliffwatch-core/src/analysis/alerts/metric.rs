//! What a rule thresholds ([`Metric`]), which estimate it reads ([`Source`]), and what an alert
//! is about ([`AlertKind`]: a metric or a site-level kind).

use serde::{Deserialize, Serialize};

/// A point metric rules can threshold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Metric {
    /// 3-D displacement `d_mm`, mm.
    DisplacementMm,
    /// Displacement along the direction of interest `d_along_mm`, mm (signed).
    DisplacementAlongMm,
    /// `velocity_mm_per_day`, mm/day.
    VelocityMmPerDay,
    /// `time_to_failure_hours`, hours (use `below`).
    TimeToFailureHours,
}

crate::contract_names!(Metric, "metric" {
    DisplacementMm => "displacement_mm",
    DisplacementAlongMm => "displacement_along_mm",
    VelocityMmPerDay => "velocity_mm_per_day",
    TimeToFailureHours => "time_to_failure_hours",
});

impl Metric {
    /// Unit of the metric.
    pub fn unit(self) -> &'static str {
        match self {
            Metric::DisplacementMm | Metric::DisplacementAlongMm => "mm",
            Metric::VelocityMmPerDay => "mm/day",
            Metric::TimeToFailureHours => "hours",
        }
    }

    /// Where the metric is read by default: either estimate for displacements (the filter sees a
    /// steady creep over the threshold a few epochs earlier, the raw value a sudden step one
    /// epoch later, once the next epoch confirms it; `docs/accuracy.md` measures both), the
    /// Kalman-filtered state for velocity and time to failure (a raw velocity of noisy epochs
    /// flickers).
    pub fn default_source(self) -> Source {
        match self {
            Metric::DisplacementMm | Metric::DisplacementAlongMm => Source::Either,
            Metric::VelocityMmPerDay | Metric::TimeToFailureHours => Source::Filtered,
        }
    }

    pub(super) fn index(self) -> usize {
        match self {
            Metric::DisplacementMm => 0,
            Metric::DisplacementAlongMm => 1,
            Metric::VelocityMmPerDay => 2,
            Metric::TimeToFailureHours => 3,
        }
    }
}

/// Which estimate of a metric a rule reads (contract: `"source": "raw" | "filtered"`, and
/// `"either"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// The epoch's own value (displacement against the reference; velocity and time to failure
    /// from least-squares fits over the last epochs).
    Raw,
    /// The Kalman filter's estimate at the epoch (see [`crate::analysis::kalman`]).
    Filtered,
    /// Both: the rule triggers when either estimate exceeds the threshold at the confidence, and
    /// clears when both are back. A raw exceedance the filtered value does not share raises the
    /// alert only when the next epoch exceeds too, so one noisy epoch never alerts alone.
    Either,
}

crate::contract_names!(Source, "source" {
    Raw => "raw",
    Filtered => "filtered",
    Either => "either",
});

/// What an alert is about: a point metric or a site-level kind (the webhook's `rule`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlertKind {
    /// See [`Metric::DisplacementMm`].
    DisplacementMm,
    /// See [`Metric::DisplacementAlongMm`].
    DisplacementAlongMm,
    /// See [`Metric::VelocityMmPerDay`].
    VelocityMmPerDay,
    /// See [`Metric::TimeToFailureHours`].
    TimeToFailureHours,
    /// A site with a schedule has no new epoch in time.
    CampaignOverdue,
    /// The congruence test found moving stable points.
    ReferenceUnstable,
    /// An epoch was stored without displacements because its analysis failed (e.g. too few
    /// points in common with the reference).
    AnalysisFailed,
}

impl AlertKind {
    /// Contract name.
    pub fn as_str(self) -> &'static str {
        match self {
            AlertKind::DisplacementMm => "displacement_mm",
            AlertKind::DisplacementAlongMm => "displacement_along_mm",
            AlertKind::VelocityMmPerDay => "velocity_mm_per_day",
            AlertKind::TimeToFailureHours => "time_to_failure_hours",
            AlertKind::CampaignOverdue => "campaign_overdue",
            AlertKind::ReferenceUnstable => "reference_unstable",
            AlertKind::AnalysisFailed => "analysis_failed",
        }
    }
}

impl From<Metric> for AlertKind {
    fn from(m: Metric) -> Self {
        match m {
            Metric::DisplacementMm => AlertKind::DisplacementMm,
            Metric::DisplacementAlongMm => AlertKind::DisplacementAlongMm,
            Metric::VelocityMmPerDay => AlertKind::VelocityMmPerDay,
            Metric::TimeToFailureHours => AlertKind::TimeToFailureHours,
        }
    }
}

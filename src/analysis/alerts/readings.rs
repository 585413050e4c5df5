//! The values the rules read for one subject (a point or a block), raw and filtered.

use serde::{Deserialize, Serialize};

use super::metric::{Metric, Source};
use crate::analysis::displacement::PointAnalysis;
use crate::analysis::failure::FailureForecast;

/// One value of a metric with its σ (unit of the metric) and whether it is significant.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Reading {
    /// The value (None when not available, e.g. no forecast).
    pub value: Option<f64>,
    /// Its σ (0 when unknown).
    pub sigma: f64,
    /// Whether the value differs significantly from zero (the raw displacement test; filtered
    /// values carry their own σ and count as significant).
    pub significant: bool,
}

impl Reading {
    /// A value with σ, significant.
    pub fn new(value: Option<f64>, sigma: Option<f64>) -> Self {
        Reading {
            value,
            sigma: sigma.filter(|s| s.is_finite() && *s >= 0.0).unwrap_or(0.0),
            significant: value.is_some(),
        }
    }

    /// The time to failure (hours) of a forecast with its σ; no value without one, nor for a
    /// forecast whose 90 % interval is wider than its horizon ("no reliable forecast",
    /// [`FailureForecast::is_reliable`]): time-to-failure rules do not read it.
    pub fn forecast(f: Option<FailureForecast>) -> Self {
        let f = f.filter(FailureForecast::is_reliable);
        Reading::new(f.map(|f| f.time_to_failure_hours), f.map(|f| f.sigma_hours))
    }
}

/// The values the rules can read for one subject (a point or a block): per [`Source`], one
/// [`Reading`] per [`Metric`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Readings {
    /// Raw readings, indexed like [`Metric`] (displacement, along, velocity, time to failure).
    pub raw: [Reading; 4],
    /// Filtered readings, same order.
    pub filtered: [Reading; 4],
}

impl Readings {
    /// The reading of `metric` from `source` ([`Source::Either`]: the raw one, as shown).
    pub fn get(&self, metric: Metric, source: Source) -> Reading {
        match source {
            Source::Raw | Source::Either => self.raw[metric.index()],
            Source::Filtered => self.filtered[metric.index()],
        }
    }

    /// Sets the reading of `metric` from `source`.
    pub fn set(&mut self, metric: Metric, source: Source, reading: Reading) {
        match source {
            Source::Raw | Source::Either => self.raw[metric.index()] = reading,
            Source::Filtered => self.filtered[metric.index()] = reading,
        }
    }

    /// The readings of a point's analysis.
    pub fn of_point(p: &PointAnalysis) -> Self {
        let r = &p.record;
        let mut out = Readings::default();
        out.set(
            Metric::DisplacementMm,
            Source::Raw,
            Reading {
                value: Some(r.d_mm),
                sigma: r.sigma_mm,
                significant: r.significant,
            },
        );
        out.set(
            Metric::DisplacementAlongMm,
            Source::Raw,
            Reading {
                value: r.d_along_mm,
                sigma: p.sigma_along_mm.unwrap_or(0.0),
                significant: r.significant,
            },
        );
        out.set(
            Metric::VelocityMmPerDay,
            Source::Raw,
            Reading {
                value: r.velocity_mm_per_day,
                sigma: p.kinematics.map_or(0.0, |k| k.sigma_velocity_mm_per_day),
                significant: r.significant && p.kinematics.is_some_and(|k| k.velocity_significant),
            },
        );
        // A forecast exists only for a significant, accelerating point.
        out.set(
            Metric::TimeToFailureHours,
            Source::Raw,
            Reading::forecast(p.failure),
        );
        if let Some(f) = &r.filtered {
            out.set(
                Metric::DisplacementMm,
                Source::Filtered,
                Reading::new(Some(f.f_d_mm), Some(f.sigma_f_d_mm)),
            );
            out.set(
                Metric::VelocityMmPerDay,
                Source::Filtered,
                Reading::new(
                    Some(f.f_velocity_mm_per_day),
                    Some(f.sigma_f_velocity_mm_per_day),
                ),
            );
        }
        if let Some((d, s)) = p.filtered_along_mm {
            out.set(
                Metric::DisplacementAlongMm,
                Source::Filtered,
                Reading::new(Some(d), Some(s)),
            );
        }
        out.set(
            Metric::TimeToFailureHours,
            Source::Filtered,
            Reading::forecast(p.filtered_failure),
        );
        out
    }
}

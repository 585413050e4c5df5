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

    /// The time to failure (hours) of a forecast with its σ; no value without one. However
    /// wide its interval, a rule reads it through its one-sided upper bound (`v + z·σ < below`):
    /// 26 ± 35 h under a 96 h rule alarms at 95 %.
    pub fn forecast(f: Option<FailureForecast>) -> Self {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::alerts::rule::AlertRule;

    fn forecast(hours: f64, sigma_hours: f64) -> Option<FailureForecast> {
        Some(FailureForecast {
            time_to_failure_hours: hours,
            sigma_hours,
            r2: 0.9,
            velocities: 40,
            lower_hours: None,
            upper_hours: None,
        })
    }

    /// "Alarm when time to failure < 96 h" reads the one-sided upper bound at the rule's
    /// confidence (0.95 under a site at 0.99): 26 ± 35 h (bound 83.6 h) alarms, however wide its
    /// two-sided interval; 26 ± 45 h (bound 100 h) does not; neither does no forecast.
    #[test]
    fn a_wide_forecast_whose_upper_bound_is_near_alarms() {
        let rule: AlertRule = serde_json::from_str(
            r#"{"level": "alarm", "metric": "time_to_failure_hours", "below": 96}"#,
        )
        .expect("rule");
        let z = rule.z(0.99);
        assert!((z - 1.6449).abs() < 1e-3, "{z}");
        let fires = |f: Option<FailureForecast>| {
            let r = Reading::forecast(f);
            r.value.is_some_and(|v| rule.triggers(v, r.sigma, z))
        };
        assert!(fires(forecast(26.0, 35.0)));
        assert!(!fires(forecast(26.0, 45.0)));
        assert!(fires(forecast(90.0, 3.0)));
        assert!(!fires(forecast(95.0, 3.0)));
        assert!(!fires(None));
    }
}

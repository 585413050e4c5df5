//! One row of a displacement series (a point's, or a block's motion) as stored and served, its
//! conversion from and to the analysis' record, and its column lists.

use serde::Serialize;
use sqlx::FromRow;
use utoipa::ToSchema;

use super::series::record::{Filtered, Record};
use super::{parse_timestamp, timestamp};
use cliffwatch_core::analysis::{DisplacementRecord, FilteredValues};

/// The displacement of one point in one epoch against the reference epoch. Lengths in mm.
#[derive(Debug, Clone, Default, PartialEq, Serialize, FromRow, ToSchema)]
pub struct Displacement {
    /// Point name.
    pub point: String,
    /// Epoch id.
    #[sqlx(rename = "epoch_id")]
    pub epoch: i64,
    /// Observation time of the epoch (RFC 3339).
    pub observed_at: String,
    /// The reference epoch's id.
    pub reference_epoch: i64,
    /// ΔX in mm.
    pub dx_mm: f64,
    /// ΔY in mm.
    pub dy_mm: f64,
    /// ΔZ in mm.
    pub dz_mm: f64,
    /// 3-D length in mm.
    pub d_mm: f64,
    /// σ of ΔX in mm.
    pub sigma_dx_mm: f64,
    /// σ of ΔY in mm.
    pub sigma_dy_mm: f64,
    /// σ of ΔZ in mm.
    pub sigma_dz_mm: f64,
    /// σ of `d_mm` in mm.
    pub sigma_mm: f64,
    /// Covariance of ΔX and ΔY in mm² (null for rows stored before schema version 4).
    pub cov_dxdy_mm2: Option<f64>,
    /// Covariance of ΔX and ΔZ in mm².
    pub cov_dxdz_mm2: Option<f64>,
    /// Covariance of ΔY and ΔZ in mm².
    pub cov_dydz_mm2: Option<f64>,
    /// Component along the point's direction of interest in mm (when set).
    pub d_along_mm: Option<f64>,
    /// Significant at the site's confidence.
    #[sqlx(try_from = "super::Flag")]
    pub significant: bool,
    /// Rate of `d_mm` in mm/day against the previous epoch.
    pub velocity_mm_per_day: Option<f64>,
    /// Time to failure in hours (null unless accelerating).
    pub time_to_failure_hours: Option<f64>,
    /// σ of `time_to_failure_hours` in hours.
    #[sqlx(default)]
    pub time_to_failure_sigma_hours: Option<f64>,
    /// Kalman-filtered ΔX in mm (the filter over the epochs up to this one).
    #[sqlx(default)]
    pub f_dx_mm: Option<f64>,
    /// Filtered ΔY in mm.
    #[sqlx(default)]
    pub f_dy_mm: Option<f64>,
    /// Filtered ΔZ in mm.
    #[sqlx(default)]
    pub f_dz_mm: Option<f64>,
    /// 3-D length of the filtered displacement in mm.
    #[sqlx(default)]
    pub f_d_mm: Option<f64>,
    /// σ of `f_dx_mm` in mm.
    #[sqlx(default)]
    pub sigma_f_dx_mm: Option<f64>,
    /// σ of `f_dy_mm` in mm.
    #[sqlx(default)]
    pub sigma_f_dy_mm: Option<f64>,
    /// σ of `f_dz_mm` in mm.
    #[sqlx(default)]
    pub sigma_f_dz_mm: Option<f64>,
    /// σ of `f_d_mm` in mm.
    #[sqlx(default)]
    pub sigma_f_d_mm: Option<f64>,
    /// Filtered velocity in mm/day, along the direction of interest (else along the filtered displacement).
    #[sqlx(default)]
    pub f_velocity_mm_per_day: Option<f64>,
    /// σ of `f_velocity_mm_per_day` in mm/day.
    #[sqlx(default)]
    pub sigma_f_velocity_mm_per_day: Option<f64>,
    /// Filtered acceleration along the same direction in mm/day².
    #[sqlx(default)]
    pub f_acceleration_mm_per_day2: Option<f64>,
    /// σ of `f_acceleration_mm_per_day2` in mm/day².
    #[sqlx(default)]
    pub sigma_f_acceleration_mm_per_day2: Option<f64>,
    /// Time to failure in hours from the filtered analysis (null unless moving and the inverse-velocity law fits).
    #[sqlx(default)]
    pub f_time_to_failure_hours: Option<f64>,
    /// σ of `f_time_to_failure_hours` in hours.
    #[sqlx(default)]
    pub sigma_f_time_to_failure_hours: Option<f64>,
}

impl Displacement {
    /// The stored row of an analysis record against `reference_epoch` (observed_at in the store's
    /// form): the two types carry the same contract fields; the store adds the reference epoch.
    pub fn from_record(r: &DisplacementRecord, reference_epoch: i64) -> Displacement {
        let f = r.filtered.as_ref();
        Displacement {
            point: r.point.clone(),
            epoch: r.epoch,
            observed_at: timestamp(r.observed_at),
            reference_epoch,
            dx_mm: r.dx_mm,
            dy_mm: r.dy_mm,
            dz_mm: r.dz_mm,
            d_mm: r.d_mm,
            sigma_dx_mm: r.sigma_dx_mm,
            sigma_dy_mm: r.sigma_dy_mm,
            sigma_dz_mm: r.sigma_dz_mm,
            sigma_mm: r.sigma_mm,
            cov_dxdy_mm2: r.cov_dxdy_mm2,
            cov_dxdz_mm2: r.cov_dxdz_mm2,
            cov_dydz_mm2: r.cov_dydz_mm2,
            d_along_mm: r.d_along_mm,
            significant: r.significant,
            velocity_mm_per_day: r.velocity_mm_per_day,
            time_to_failure_hours: r.time_to_failure_hours,
            time_to_failure_sigma_hours: r.time_to_failure_sigma_hours,
            f_dx_mm: f.map(|f| f.f_dx_mm),
            f_dy_mm: f.map(|f| f.f_dy_mm),
            f_dz_mm: f.map(|f| f.f_dz_mm),
            f_d_mm: f.map(|f| f.f_d_mm),
            sigma_f_dx_mm: f.map(|f| f.sigma_f_dx_mm),
            sigma_f_dy_mm: f.map(|f| f.sigma_f_dy_mm),
            sigma_f_dz_mm: f.map(|f| f.sigma_f_dz_mm),
            sigma_f_d_mm: f.map(|f| f.sigma_f_d_mm),
            f_velocity_mm_per_day: f.map(|f| f.f_velocity_mm_per_day),
            sigma_f_velocity_mm_per_day: f.map(|f| f.sigma_f_velocity_mm_per_day),
            f_acceleration_mm_per_day2: f.and_then(|f| f.f_acceleration_mm_per_day2),
            sigma_f_acceleration_mm_per_day2: f.and_then(|f| f.sigma_f_acceleration_mm_per_day2),
            f_time_to_failure_hours: f.and_then(|f| f.f_time_to_failure_hours),
            sigma_f_time_to_failure_hours: f.and_then(|f| f.sigma_f_time_to_failure_hours),
        }
    }

    /// The row in the packed form of the series ([`super::series::record`]), as stored.
    pub(super) fn record(&self) -> Record<'_> {
        Record {
            epoch: self.epoch,
            observed_at: self.observed_at.as_bytes(),
            reference: self.reference_epoch,
            v: [
                self.dx_mm,
                self.dy_mm,
                self.dz_mm,
                self.d_mm,
                self.sigma_dx_mm,
                self.sigma_dy_mm,
                self.sigma_dz_mm,
                self.sigma_mm,
            ],
            significant: self.significant,
            velocity: self.velocity_mm_per_day,
            ttf: self.time_to_failure_hours,
            cov: [self.cov_dxdy_mm2, self.cov_dxdz_mm2, self.cov_dydz_mm2],
            ttf_sigma: self.time_to_failure_sigma_hours,
            filtered: self.filtered().map(|f| Filtered {
                v: [
                    f.f_dx_mm,
                    f.f_dy_mm,
                    f.f_dz_mm,
                    f.f_d_mm,
                    f.sigma_f_dx_mm,
                    f.sigma_f_dy_mm,
                    f.sigma_f_dz_mm,
                    f.sigma_f_d_mm,
                    f.f_velocity_mm_per_day,
                    f.sigma_f_velocity_mm_per_day,
                ],
                opt: [
                    f.f_acceleration_mm_per_day2,
                    f.sigma_f_acceleration_mm_per_day2,
                    f.f_time_to_failure_hours,
                    f.sigma_f_time_to_failure_hours,
                ],
            }),
        }
    }

    /// The filtered values of the row (`None` unless all the required ones are stored).
    pub fn filtered(&self) -> Option<FilteredValues> {
        Some(FilteredValues {
            f_dx_mm: self.f_dx_mm?,
            f_dy_mm: self.f_dy_mm?,
            f_dz_mm: self.f_dz_mm?,
            f_d_mm: self.f_d_mm?,
            sigma_f_dx_mm: self.sigma_f_dx_mm?,
            sigma_f_dy_mm: self.sigma_f_dy_mm?,
            sigma_f_dz_mm: self.sigma_f_dz_mm?,
            sigma_f_d_mm: self.sigma_f_d_mm?,
            f_velocity_mm_per_day: self.f_velocity_mm_per_day?,
            sigma_f_velocity_mm_per_day: self.sigma_f_velocity_mm_per_day?,
            f_acceleration_mm_per_day2: self.f_acceleration_mm_per_day2,
            sigma_f_acceleration_mm_per_day2: self.sigma_f_acceleration_mm_per_day2,
            f_time_to_failure_hours: self.f_time_to_failure_hours,
            sigma_f_time_to_failure_hours: self.sigma_f_time_to_failure_hours,
        })
    }

    /// The analysis record of a row read back (`None` when observed_at does not parse).
    pub fn to_record(&self) -> Option<DisplacementRecord> {
        Some(DisplacementRecord {
            point: self.point.clone(),
            epoch: self.epoch,
            observed_at: parse_timestamp(&self.observed_at)?,
            dx_mm: self.dx_mm,
            dy_mm: self.dy_mm,
            dz_mm: self.dz_mm,
            d_mm: self.d_mm,
            sigma_dx_mm: self.sigma_dx_mm,
            sigma_dy_mm: self.sigma_dy_mm,
            sigma_dz_mm: self.sigma_dz_mm,
            sigma_mm: self.sigma_mm,
            cov_dxdy_mm2: self.cov_dxdy_mm2,
            cov_dxdz_mm2: self.cov_dxdz_mm2,
            cov_dydz_mm2: self.cov_dydz_mm2,
            d_along_mm: self.d_along_mm,
            significant: self.significant,
            velocity_mm_per_day: self.velocity_mm_per_day,
            time_to_failure_hours: self.time_to_failure_hours,
            time_to_failure_sigma_hours: self.time_to_failure_sigma_hours,
            filtered: self.filtered(),
        })
    }
}

/// The columns of a row the analysis reads back as history (all but the forecast's σ and the
/// filtered values, which it recomputes). SQLite's fast read of the history
/// (`displacements::history_row`) takes them by position, in this order.
macro_rules! history_columns {
    () => {
        "point, epoch_id, observed_at, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
         sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, d_along_mm, significant, \
         velocity_mm_per_day, time_to_failure_hours, cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2"
    };
}

/// `columns` (a list of [`COLUMNS`]) as a select list: each column prefixed with `prefix` (a
/// table alias and a dot, or nothing), `significant` read through [`super::Flag`]'s cast.
pub(super) fn select_list(columns: &str, prefix: &str) -> String {
    columns
        .split(',')
        .map(|c| match c.trim() {
            "significant" => format!("CAST({prefix}significant AS INTEGER) AS significant"),
            c => format!("{prefix}{c}"),
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The columns the analysis reads back as history.
pub(super) const HISTORY_COLUMNS: &str = history_columns!();

/// Every served column of a row.
pub(super) const COLUMNS: &str = concat!(
    history_columns!(),
    ", time_to_failure_sigma_hours, f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, \
     sigma_f_dy_mm, sigma_f_dz_mm, sigma_f_d_mm, f_velocity_mm_per_day, \
     sigma_f_velocity_mm_per_day, f_acceleration_mm_per_day2, sigma_f_acceleration_mm_per_day2, \
     f_time_to_failure_hours, sigma_f_time_to_failure_hours"
);

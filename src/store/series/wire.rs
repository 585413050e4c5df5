//! The wire writer: a series' rows formatted straight into the bytes the API serves (the CSV
//! with its header, or the items of a JSON page), numbers through `zmij`/`itoa`, stored
//! timestamps shortened in place. The API's JSON field names and CSV columns are fixed here and
//! must stay those of `Displacement`'s serialization.

use std::io::Write;

use super::record::Record;
use crate::store::display_timestamp;
use crate::store::time::shortened;

/// Columns of the CSV time series (the contract's order).
/// The contract's fourteen first, then the forecast's σ and the Kalman filter's values.
pub const CSV_HEADER: &str = "epoch,observed_at,dx_mm,dy_mm,dz_mm,d_mm,sigma_dx_mm,sigma_dy_mm,sigma_dz_mm,sigma_mm,d_along_mm,significant,velocity_mm_per_day,time_to_failure_hours,time_to_failure_sigma_hours,f_dx_mm,f_dy_mm,f_dz_mm,f_d_mm,sigma_f_dx_mm,sigma_f_dy_mm,sigma_f_dz_mm,sigma_f_d_mm,f_velocity_mm_per_day,sigma_f_velocity_mm_per_day,f_acceleration_mm_per_day2,sigma_f_acceleration_mm_per_day2,f_time_to_failure_hours,sigma_f_time_to_failure_hours";

/// Names of the optional values after `time_to_failure_hours`, in the order of the CSV columns
/// and of the JSON fields (that of `Displacement`).
const EXTRA_NAMES: [&str; 15] = [
    "time_to_failure_sigma_hours",
    "f_dx_mm",
    "f_dy_mm",
    "f_dz_mm",
    "f_d_mm",
    "sigma_f_dx_mm",
    "sigma_f_dy_mm",
    "sigma_f_dz_mm",
    "sigma_f_d_mm",
    "f_velocity_mm_per_day",
    "sigma_f_velocity_mm_per_day",
    "f_acceleration_mm_per_day2",
    "sigma_f_acceleration_mm_per_day2",
    "f_time_to_failure_hours",
    "sigma_f_time_to_failure_hours",
];

/// The values named by [`EXTRA_NAMES`] of a record.
fn extra_values(r: &Record<'_>) -> [Option<f64>; 15] {
    let mut out = [None; 15];
    out[0] = r.ttf_sigma;
    if let Some(f) = &r.filtered {
        for (k, v) in f.v.iter().enumerate() {
            out[1 + k] = Some(*v);
        }
        for (k, v) in f.opt.iter().enumerate() {
            out[11 + k] = *v;
        }
    }
    out
}

/// The served form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesFormat {
    /// `text/csv`: the header line, then one line per epoch.
    Csv,
    /// The JSON array of a page's `items`: each object as `Displacement` serializes.
    JsonItems,
}

/// Formats rows already read (e.g. a block's motion series) as the point series is served:
/// CSV with its header, or the JSON array of a page's items; `d_along_mm` along `direction`.
pub fn format_rows(
    rows: &[crate::store::displacements::Displacement],
    format: SeriesFormat,
    direction: Option<[f64; 3]>,
    name: &str,
) -> Vec<u8> {
    let mut w = Writer::new(
        format,
        direction,
        name,
        Vec::with_capacity(rows.len() * 600 + 256),
    );
    w.start();
    for r in rows {
        w.row(&r.record());
    }
    w.finish();
    w.out
}

/// `d_along_mm` as the API computes it: (d · n) / |n|.
pub fn along(d: [f64; 3], direction: Option<[f64; 3]>) -> Option<f64> {
    let n = direction?;
    let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    (norm > 0.0).then(|| (d[0] * n[0] + d[1] * n[1] + d[2] * n[2]) / norm)
}

fn json_string(s: &str) -> Vec<u8> {
    serde_json::to_vec(s).unwrap_or_else(|_| b"\"\"".to_vec())
}

pub(super) struct Writer {
    pub(super) out: Vec<u8>,
    pub(super) format: SeriesFormat,
    pub(super) direction: Option<[f64; 3]>,
    /// The point name as a JSON string (quoted, escaped).
    pub(super) point: Vec<u8>,
    pub(super) rows: usize,
    pub(super) float: zmij::Buffer,
    pub(super) int: itoa::Buffer,
}

impl Writer {
    pub(super) fn new(
        format: SeriesFormat,
        direction: Option<[f64; 3]>,
        point: &str,
        out: Vec<u8>,
    ) -> Writer {
        Writer {
            out,
            format,
            direction,
            point: json_string(point),
            rows: 0,
            float: zmij::Buffer::new(),
            int: itoa::Buffer::new(),
        }
    }

    pub(super) fn start(&mut self) {
        match self.format {
            SeriesFormat::Csv => {
                self.out.extend_from_slice(CSV_HEADER.as_bytes());
                self.out.push(b'\n');
            }
            SeriesFormat::JsonItems => self.out.push(b'['),
        }
    }

    pub(super) fn finish(&mut self) {
        if self.format == SeriesFormat::JsonItems {
            self.out.push(b']');
        }
    }

    fn int(&mut self, v: i64) {
        self.out.extend_from_slice(self.int.format(v).as_bytes());
    }

    /// A float as serde_json writes it (its own formatter, `zmij`: shortest round trip);
    /// non-finite: `null` in JSON,
    /// empty in CSV (SQLite stores NaN as NULL, so these do not come from the table).
    fn float(&mut self, v: f64) {
        if v.is_finite() {
            self.out
                .extend_from_slice(self.float.format_finite(v).as_bytes());
        } else if self.format == SeriesFormat::JsonItems {
            self.out.extend_from_slice(b"null");
        }
    }

    fn opt_float(&mut self, v: Option<f64>) {
        match v {
            Some(v) => self.float(v),
            None if self.format == SeriesFormat::JsonItems => self.out.extend_from_slice(b"null"),
            None => {}
        }
    }

    fn bool(&mut self, v: bool) {
        self.out
            .extend_from_slice(if v { b"true" as &[u8] } else { b"false" });
    }

    /// The stored time in the API form ([`display_timestamp`]), quoted in JSON.
    fn timestamp(&mut self, stored: &[u8]) {
        let json = self.format == SeriesFormat::JsonItems;
        match shortened(stored) {
            Some(short) => {
                if json {
                    self.out.push(b'"');
                }
                self.out.extend_from_slice(short);
                self.out.push(b'Z');
                if json {
                    self.out.push(b'"');
                }
            }
            None => {
                let shown = display_timestamp(&String::from_utf8_lossy(stored));
                if json {
                    self.out.extend_from_slice(&json_string(&shown));
                } else {
                    self.out.extend_from_slice(shown.as_bytes());
                }
            }
        }
    }

    pub(super) fn row(&mut self, r: &Record<'_>) {
        let epoch = r.epoch;
        let observed_at = r.observed_at;
        let reference = r.reference;
        let d = [r.v[0], r.v[1], r.v[2]];
        let length = r.v[3];
        let sigma = [r.v[4], r.v[5], r.v[6], r.v[7]];
        let significant = r.significant;
        let velocity = r.velocity;
        let ttf = r.ttf;
        let d_along = along(d, self.direction);
        match self.format {
            SeriesFormat::Csv => {
                self.int(epoch);
                self.out.push(b',');
                self.timestamp(observed_at);
                for v in [
                    d[0], d[1], d[2], length, sigma[0], sigma[1], sigma[2], sigma[3],
                ] {
                    self.out.push(b',');
                    self.float(v);
                }
                self.out.push(b',');
                self.opt_float(d_along);
                self.out.push(b',');
                self.bool(significant);
                self.out.push(b',');
                self.opt_float(velocity);
                self.out.push(b',');
                self.opt_float(ttf);
                for v in extra_values(r) {
                    self.out.push(b',');
                    self.opt_float(v);
                }
                self.out.push(b'\n');
            }
            SeriesFormat::JsonItems => {
                if self.rows > 0 {
                    self.out.push(b',');
                }
                self.out.extend_from_slice(b"{\"point\":");
                self.out.extend_from_slice(&self.point);
                self.out.extend_from_slice(b",\"epoch\":");
                self.int(epoch);
                self.out.extend_from_slice(b",\"observed_at\":");
                self.timestamp(observed_at);
                self.out.extend_from_slice(b",\"reference_epoch\":");
                self.int(reference);
                let named = [
                    ("dx_mm", d[0]),
                    ("dy_mm", d[1]),
                    ("dz_mm", d[2]),
                    ("d_mm", length),
                    ("sigma_dx_mm", sigma[0]),
                    ("sigma_dy_mm", sigma[1]),
                    ("sigma_dz_mm", sigma[2]),
                    ("sigma_mm", sigma[3]),
                ];
                for (name, v) in named {
                    let _ = write!(self.out, ",\"{name}\":");
                    self.float(v);
                }
                let cov = ["cov_dxdy_mm2", "cov_dxdz_mm2", "cov_dydz_mm2"];
                for (name, v) in cov.iter().zip(r.cov) {
                    let _ = write!(self.out, ",\"{name}\":");
                    self.opt_float(v);
                }
                self.out.extend_from_slice(b",\"d_along_mm\":");
                self.opt_float(d_along);
                self.out.extend_from_slice(b",\"significant\":");
                self.bool(significant);
                self.out.extend_from_slice(b",\"velocity_mm_per_day\":");
                self.opt_float(velocity);
                self.out.extend_from_slice(b",\"time_to_failure_hours\":");
                self.opt_float(ttf);
                for (name, v) in EXTRA_NAMES.iter().zip(extra_values(r)) {
                    self.out.extend_from_slice(b",\"");
                    self.out.extend_from_slice(name.as_bytes());
                    self.out.extend_from_slice(b"\":");
                    self.opt_float(v);
                }
                self.out.push(b'}');
            }
        }
        self.rows += 1;
    }
}

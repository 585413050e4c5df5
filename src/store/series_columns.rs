//! A point's whole displacement series as columns (one vector per quantity), read through the
//! same fast path as the served series ([`super::series`]): the dashboard's plots downsample it
//! on the server.

use super::series::{each_record, SeriesQuery, Source};
use super::series_record;
use super::{Store, StoreError};

/// The series, oldest first; NaN where a value is missing. Lengths in mm, velocities in mm/day,
/// times to failure in hours, times in seconds since 1970 (UTC).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SeriesColumns {
    /// Epoch ids.
    pub epoch: Vec<i64>,
    /// Observation times, seconds since 1970-01-01T00:00:00Z.
    pub t: Vec<f64>,
    /// dx, dy, dz, d (3-D length), in mm.
    pub d: [Vec<f64>; 4],
    /// σ of dx, dy, dz, d, in mm.
    pub sigma: [Vec<f64>; 4],
    /// Displacement along the point's direction of interest, mm (NaN without a direction).
    pub along: Vec<f64>,
    /// Rate of d in mm/day.
    pub velocity: Vec<f64>,
    /// Time to failure in hours (raw forecast).
    pub ttf: Vec<f64>,
    /// Filtered dx, dy, dz, d in mm.
    pub f_d: [Vec<f64>; 4],
    /// σ of the filtered dx, dy, dz, d in mm.
    pub sigma_f_d: [Vec<f64>; 4],
    /// Filtered velocity along the direction of motion (mm/day) and its σ.
    pub f_velocity: [Vec<f64>; 2],
    /// Filtered time to failure (h) and its σ.
    pub f_ttf: [Vec<f64>; 2],
}

/// Seconds since 1970 of a stored time `YYYY-MM-DDTHH:MM:SS[.ffffff]Z`; NaN when malformed.
pub fn unix_seconds(stored: &[u8]) -> f64 {
    let num = |a: usize, b: usize| -> Option<i64> {
        let s = stored.get(a..b)?;
        s.iter().try_fold(0i64, |acc, &c| {
            c.is_ascii_digit().then(|| acc * 10 + i64::from(c - b'0'))
        })
    };
    let parts = (
        num(0, 4),
        num(5, 7),
        num(8, 10),
        num(11, 13),
        num(14, 16),
        num(17, 19),
    );
    let (Some(y), Some(m), Some(d), Some(hh), Some(mm), Some(ss)) = parts else {
        return f64::NAN;
    };
    // Days from civil (Howard Hinnant's algorithm).
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = era * 146_097 + doe - 719_468;
    let mut frac = 0.0;
    if stored.get(19) == Some(&b'.') {
        let mut scale = 0.1;
        for &c in stored[20..].iter().take_while(|c| c.is_ascii_digit()) {
            frac += f64::from(c - b'0') * scale;
            scale *= 0.1;
        }
    }
    (days * 86_400 + hh * 3600 + mm * 60 + ss) as f64 + frac
}

/// Reads the whole series of `q` (its range and direction; no limit) as columns, on a blocking
/// thread.
pub async fn read(store: &Store, q: SeriesQuery) -> Result<SeriesColumns, StoreError> {
    let mut source = Source::of(store, &q).await?;
    tokio::task::spawn_blocking(move || {
        let mut c = SeriesColumns::default();
        let nan = f64::NAN;
        each_record(&mut source, &q, |bytes| {
            let Some((r, _)) = series_record::decode(bytes) else {
                return false;
            };
            c.epoch.push(r.epoch);
            c.t.push(unix_seconds(r.observed_at));
            for k in 0..4 {
                c.d[k].push(r.v[k]);
                c.sigma[k].push(r.v[4 + k]);
            }
            c.along
                .push(super::series::along([r.v[0], r.v[1], r.v[2]], q.direction).unwrap_or(nan));
            c.velocity.push(r.velocity.unwrap_or(nan));
            c.ttf.push(r.ttf.unwrap_or(nan));
            let f = r.filtered;
            for k in 0..4 {
                c.f_d[k].push(f.map_or(nan, |f| f.v[k]));
                c.sigma_f_d[k].push(f.map_or(nan, |f| f.v[4 + k]));
            }
            c.f_velocity[0].push(f.map_or(nan, |f| f.v[8]));
            c.f_velocity[1].push(f.map_or(nan, |f| f.v[9]));
            c.f_ttf[0].push(f.and_then(|f| f.opt[2]).unwrap_or(nan));
            c.f_ttf[1].push(f.and_then(|f| f.opt[3]).unwrap_or(nan));
            true
        })?;
        Ok(c)
    })
    .await
    .map_err(super::series::reader_failed)?
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stored_times_to_unix_seconds() {
        assert_eq!(unix_seconds(b"1970-01-01T00:00:00Z"), 0.0);
        assert_eq!(unix_seconds(b"2000-03-01T00:00:00.000000Z"), 951_868_800.0);
        assert_eq!(
            unix_seconds(b"2026-11-24T12:30:15.250000Z"),
            chrono::DateTime::parse_from_rfc3339("2026-11-24T12:30:15.25Z")
                .unwrap()
                .timestamp_millis() as f64
                / 1000.0
        );
        assert!(unix_seconds(b"garbage").is_nan());
    }
}

//! A point's whole displacement series as columns (one vector per quantity), read through the
//! same fast path as the served series ([`super`]): the dashboard's plots downsample it
//! on the server.

use super::query::SeriesQuery;
use super::read::{count_records, each_record, reader_failed, reads_extremes, Source};
use super::record::{self, Record};
use super::wire::along;
use crate::store::displacement_row::{select_list, Displacement, COLUMNS};
use crate::store::{Store, StoreError};

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

/// One record's values, in the units of [`SeriesColumns`] (NaN where missing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesRow {
    /// Epoch id.
    pub epoch: i64,
    /// Observation time, seconds since 1970 (UTC).
    pub t: f64,
    /// dx, dy, dz, d in mm.
    pub d: [f64; 4],
    /// σ of dx, dy, dz, d in mm.
    pub sigma: [f64; 4],
    /// Displacement along the direction of interest, mm.
    pub along: f64,
    /// Rate of d, mm/day.
    pub velocity: f64,
    /// Raw time to failure, h.
    pub ttf: f64,
    /// Filtered dx, dy, dz, d in mm.
    pub f_d: [f64; 4],
    /// σ of the filtered dx, dy, dz, d in mm.
    pub sigma_f_d: [f64; 4],
    /// Filtered velocity (mm/day) and its σ.
    pub f_velocity: [f64; 2],
    /// Filtered time to failure (h) and its σ.
    pub f_ttf: [f64; 2],
}

impl SeriesRow {
    /// The values of record `r`; `along` with the point's `direction`.
    pub fn of(r: &Record<'_>, direction: Option<[f64; 3]>) -> SeriesRow {
        let nan = f64::NAN;
        let f = r.filtered;
        SeriesRow {
            epoch: r.epoch,
            t: unix_seconds(r.observed_at),
            d: [r.v[0], r.v[1], r.v[2], r.v[3]],
            sigma: [r.v[4], r.v[5], r.v[6], r.v[7]],
            along: along([r.v[0], r.v[1], r.v[2]], direction).unwrap_or(nan),
            velocity: r.velocity.unwrap_or(nan),
            ttf: r.ttf.unwrap_or(nan),
            f_d: std::array::from_fn(|k| f.map_or(nan, |f| f.v[k])),
            sigma_f_d: std::array::from_fn(|k| f.map_or(nan, |f| f.v[4 + k])),
            f_velocity: [f.map_or(nan, |f| f.v[8]), f.map_or(nan, |f| f.v[9])],
            f_ttf: [
                f.and_then(|f| f.opt[2]).unwrap_or(nan),
                f.and_then(|f| f.opt[3]).unwrap_or(nan),
            ],
        }
    }
}

impl SeriesColumns {
    /// Appends one row.
    pub fn push(&mut self, r: &SeriesRow) {
        self.epoch.push(r.epoch);
        self.t.push(r.t);
        for k in 0..4 {
            self.d[k].push(r.d[k]);
            self.sigma[k].push(r.sigma[k]);
            self.f_d[k].push(r.f_d[k]);
            self.sigma_f_d[k].push(r.sigma_f_d[k]);
        }
        self.along.push(r.along);
        self.velocity.push(r.velocity);
        self.ttf.push(r.ttf);
        for k in 0..2 {
            self.f_velocity[k].push(r.f_velocity[k]);
            self.f_ttf[k].push(r.f_ttf[k]);
        }
    }
}

/// Reads the whole series of `q` (its range and direction; no limit) as columns, on a blocking
/// thread.
pub async fn read(store: &Store, q: SeriesQuery) -> Result<SeriesColumns, StoreError> {
    let direction = q.direction;
    fold(
        store,
        q,
        |_: SeriesSize| SeriesColumns::default(),
        move |c, r| {
            c.push(&SeriesRow::of(r, direction));
            true
        },
    )
    .await
}

/// The size of a series [`fold`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SeriesSize {
    /// Records of the whole series, counted just before the read (rows written meanwhile may
    /// add a few).
    pub records: usize,
    /// The read gives each packed block's extremes, not all its rows
    /// ([`SeriesQuery::extremes_above`]): the first and last rows, and the minimum and maximum of
    /// dx, dy, dz and d, of every block but the last; the last block and the tail whole.
    pub extremes: bool,
}

/// Streams the series of `q` through a state of the caller's, on a blocking thread: `start`
/// gets the series' size and makes the state, `each` is called with every record read in time
/// order and returns `false` to stop. Hands the state back. Nothing but the state is kept, so a
/// long series costs no memory of its length.
pub async fn fold<T, S, E>(
    store: &Store,
    q: SeriesQuery,
    start: S,
    mut each: E,
) -> Result<T, StoreError>
where
    T: Send + 'static,
    S: FnOnce(SeriesSize) -> T + Send + 'static,
    E: FnMut(&mut T, &Record<'_>) -> bool + Send + 'static,
{
    let mut source = Source::of(store, &q).await?;
    tokio::task::spawn_blocking(move || {
        let records = count_records(&mut source, &q)?;
        let extremes = reads_extremes(&q, records);
        let mut state = start(SeriesSize { records, extremes });
        each_record(&mut source, &q, extremes, |bytes| {
            match record::decode(bytes) {
                Some((r, _)) => each(&mut state, &r),
                None => false,
            }
        })?;
        Ok(state)
    })
    .await
    .map_err(reader_failed)?
}

/// The rows of `site`/`point` at the epochs `epochs` (ids; those without a row are left out), in
/// time order: the alert epochs a read of the blocks' extremes may not hold.
pub async fn rows_at_epochs(
    store: &Store,
    site: &str,
    point: &str,
    epochs: &[i64],
    direction: Option<[f64; 3]>,
) -> Result<Vec<SeriesRow>, StoreError> {
    let columns = select_list(COLUMNS, "");
    let sql = format!(
        "SELECT {columns} FROM displacements WHERE site_id = $1 AND epoch_id = $2 AND point = $3"
    );
    let mut out = Vec::with_capacity(epochs.len());
    for &epoch in epochs {
        let row: Option<Displacement> = sqlx::query_as(&sql)
            .bind(site)
            .bind(epoch)
            .bind(point)
            .fetch_optional(store.reader())
            .await?;
        out.extend(row.map(|r| SeriesRow::of(&r.record(), direction)));
    }
    out.sort_by(|a, b| a.t.total_cmp(&b.t));
    Ok(out)
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

//! Where a series' rows come from ([`Source`]: SQLite's C API or PostgreSQL's packed records)
//! and the walk over them as packed records, in time order.

use sqlx::pool::PoolConnection;
use sqlx::Sqlite;

use super::query::{count_params, params, SeriesQuery, COUNT_SQL, EXTREMES_SQL, SQL};
use super::record::{self, Record};
use super::sqlite_raw::{self, Row};
use crate::store::{Store, StoreError};

/// Where the rows of a series come from.
pub(super) enum Source {
    /// SQLite: a native read connection for [`sqlite_raw`].
    Sqlite(PoolConnection<Sqlite>),
    /// PostgreSQL: the rows already read, as packed records ([`postgres`]), and
    /// the whole series' record count when it was read first (for [`SeriesQuery::extremes_above`]).
    Packed {
        /// The records, one after the other.
        bytes: Vec<u8>,
        /// [`COUNT_SQL`]'s answer, when asked.
        whole: Option<usize>,
    },
}

impl Source {
    /// The source of `q` in `store`.
    pub(super) async fn of(store: &Store, q: &SeriesQuery) -> Result<Source, StoreError> {
        Ok(match store.sqlite_reader() {
            Some(pool) => Source::Sqlite(pool.acquire().await?),
            None => {
                let pool = store.reader();
                let whole = match q.extremes_above {
                    Some(_) => Some(super::postgres::count(pool, q).await?),
                    None => None,
                };
                let extremes = reads_extremes(q, whole.unwrap_or(0));
                let bytes = super::postgres::packed_records(pool, q, extremes).await?;
                Source::Packed { bytes, whole }
            }
        })
    }
}

/// Whether a read of `q`, whose whole series holds `records` records, takes the blocks'
/// extremes ([`SeriesQuery::extremes_above`]).
pub(super) fn reads_extremes(q: &SeriesQuery, records: usize) -> bool {
    q.extremes_above.is_some_and(|m| records > m)
}

/// Calls `each` with every row of `q` in time order as a packed record
/// ([`series_record`]). `each` returns `false` to stop.
///
/// `extremes`: read each block's extremes ([`EXTREMES_SQL`]; a PostgreSQL source was read so
/// by [`Source::of`]).
pub(super) fn each_record(
    source: &mut Source,
    q: &SeriesQuery,
    extremes: bool,
    mut each: impl FnMut(&[u8]) -> bool,
) -> Result<(), StoreError> {
    match source {
        Source::Sqlite(conn) => each_sqlite_record(conn, q, extremes, each),
        Source::Packed { bytes, .. } => {
            let mut rest = &bytes[..];
            while let Some((_, n)) = record::peek(rest) {
                let (record, later) = rest.split_at(n);
                rest = later;
                if !each(record) {
                    break;
                }
            }
            Ok(())
        }
    }
}

/// How many records the whole series of `q` holds (without its range), read before the
/// records themselves: rows written in between may add a few.
pub(super) fn count_records(source: &mut Source, q: &SeriesQuery) -> Result<usize, StoreError> {
    match source {
        Source::Sqlite(conn) => {
            let mut n = 0;
            sqlite_raw::query(conn, COUNT_SQL, &count_params(q), |row| {
                n = usize::try_from(row.int(0)).unwrap_or(0);
                false
            })?;
            Ok(n)
        }
        Source::Packed { whole: Some(n), .. } => Ok(*n),
        Source::Packed { bytes, whole: None } => {
            let (mut rest, mut n) = (&bytes[..], 0);
            while let Some((_, len)) = record::peek(rest) {
                rest = &rest[len..];
                n += 1;
            }
            Ok(n)
        }
    }
}

/// [`each_record`] of SQLite: a block's records in the range as they are stored, a tail row
/// packed first.
fn each_sqlite_record(
    conn: &mut PoolConnection<Sqlite>,
    q: &SeriesQuery,
    extremes: bool,
    mut each: impl FnMut(&[u8]) -> bool,
) -> Result<(), StoreError> {
    let from = q.from.as_deref().unwrap_or("").as_bytes();
    let to = q.to.as_deref().unwrap_or(crate::store::TEXT_MAX).as_bytes();
    let after = q.after.as_deref().unwrap_or("").as_bytes();
    let mut packed = Vec::with_capacity(256);
    let mut failed = None;
    let sql = if extremes { EXTREMES_SQL } else { SQL };
    sqlite_raw::query(conn, sql, &params(q), |row| {
        if row.is_null(1) {
            // a tail row, in the range (the SQL's condition)
            packed.clear();
            if !record::encode(&tail_record(row), &mut packed) {
                failed = Some("observed_at too long");
                return false;
            }
            return each(&packed);
        }
        let Some((format, mut rest)) = row.blob(1).split_first() else {
            failed = Some("empty block");
            return false;
        };
        if !record::readable(*format) {
            failed = Some("unknown block format");
            return false;
        }
        while !rest.is_empty() {
            let Some((t, n)) = record::peek(rest) else {
                failed = Some("cut block");
                return false;
            };
            let (record, later) = rest.split_at(n);
            rest = later;
            if t > to {
                return false; // rows are in time order: none later is in the range
            }
            if t >= from && t > after && !each(record) {
                return false;
            }
        }
        true
    })?;
    match failed {
        Some(what) => Err(StoreError::Block(format!(
            "series of {}/{}: {what}",
            q.site, q.point
        ))),
        None => Ok(()),
    }
}

pub(crate) fn reader_failed(e: tokio::task::JoinError) -> StoreError {
    StoreError::Sqlite {
        code: 0,
        message: format!("series reader: {e}"),
    }
}

/// A tail row of [`SQL`] (columns 0 and 2–32) as a record, borrowed until the next step.
fn tail_record(r: &Row) -> Record<'_> {
    Record {
        epoch: r.int(2),
        observed_at: r.text(0),
        reference: r.int(3),
        v: std::array::from_fn(|k| r.double(4 + k)),
        significant: r.int(12) != 0,
        velocity: r.opt_double(13),
        ttf: r.opt_double(14),
        cov: std::array::from_fn(|k| r.opt_double(15 + k)),
        ttf_sigma: r.opt_double(18),
        filtered: (0..10)
            .all(|k| !r.is_null(19 + k))
            .then(|| record::Filtered {
                v: std::array::from_fn(|k| r.double(19 + k)),
                opt: std::array::from_fn(|k| r.opt_double(29 + k)),
            }),
    }
}

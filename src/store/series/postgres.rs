//! The series read of a PostgreSQL store: the same statement as SQLite's fast path
//! ([`super`]: the point's packed blocks that overlap the range, then its unpacked tail
//! rows; ~128 rows per block, so a 10-year hourly series is ~700 rows) through sqlx, into one buffer of packed records ([`super::record`])
//! that the series writers then format on a blocking thread as they do SQLite's rows.

use sqlx::{AnyPool, Row};

use super::query::{
    count_params, params, SeriesQuery, COUNT_SQL, EXTREMES_SQL_LIMITED, SQL_LIMITED,
};
use super::record::{self, Filtered, Record};
use super::sqlite_raw::Param;
use crate::store::StoreError;

/// How many records the whole series of `q.site`/`q.point` holds (its range is not applied).
pub async fn count(pool: &AnyPool, q: &SeriesQuery) -> Result<usize, StoreError> {
    let mut query = sqlx::query_scalar(COUNT_SQL);
    for p in count_params(q) {
        query = match p {
            Param::Text(t) => query.bind(t),
            Param::Int(i) => query.bind(i),
        };
    }
    let n: i64 = query.fetch_one(pool).await?;
    Ok(usize::try_from(n).unwrap_or(0))
}

/// The rows of `q` in time order as packed records, one after the other: all of them, or with
/// `q.limit` the rows and blocks that hold the first `limit + 1` records (the writers stop at
/// theirs and tell by the one more whether more follow; [`SQL_LIMITED`]); with `extremes`, each
/// block's extremes but the last block's ([`EXTREMES_SQL_LIMITED`]).
pub async fn packed_records(
    pool: &AnyPool,
    q: &SeriesQuery,
    extremes: bool,
) -> Result<Vec<u8>, StoreError> {
    let from = q.from.as_deref().unwrap_or("");
    let to = q.to.as_deref().unwrap_or(crate::store::TEXT_MAX);
    let after = q.after.as_deref().unwrap_or("");
    let mut query = sqlx::query(if extremes {
        EXTREMES_SQL_LIMITED
    } else {
        SQL_LIMITED
    });
    for p in params(q) {
        query = match p {
            Param::Text(t) => query.bind(t),
            Param::Int(i) => query.bind(i),
        };
    }
    // limit + 1 records: at most that many rows, from blocks with fewer records before them
    // than that plus one block (the first block may hold records before the range)
    let records = q.limit.map_or(i64::MAX, |l| l.max(0).saturating_add(1));
    let block_records = super::blocks::BLOCK_EPOCHS as i64;
    query = query
        .bind(records)
        .bind(records.saturating_add(block_records));
    let rows = query.fetch_all(pool).await?;
    let mut out = Vec::new();
    let cut = |what: &str| StoreError::Block(format!("series of {}/{}: {what}", q.site, q.point));
    for row in rows {
        let block: Option<Vec<u8>> = row.try_get(1)?;
        let Some(block) = block else {
            let t: String = row.try_get(0)?;
            let d = |k: usize| row.try_get::<f64, _>(k);
            let o = |k: usize| row.try_get::<Option<f64>, _>(k);
            let filtered: [Option<f64>; 10] = [
                o(19)?,
                o(20)?,
                o(21)?,
                o(22)?,
                o(23)?,
                o(24)?,
                o(25)?,
                o(26)?,
                o(27)?,
                o(28)?,
            ];
            let opt = [o(29)?, o(30)?, o(31)?, o(32)?];
            let record = Record {
                epoch: row.try_get(2)?,
                observed_at: t.as_bytes(),
                reference: row.try_get(3)?,
                v: [d(4)?, d(5)?, d(6)?, d(7)?, d(8)?, d(9)?, d(10)?, d(11)?],
                significant: row.try_get(12)?,
                velocity: o(13)?,
                ttf: o(14)?,
                cov: [o(15)?, o(16)?, o(17)?],
                ttf_sigma: o(18)?,
                filtered: filtered.iter().all(Option::is_some).then(|| Filtered {
                    v: filtered.map(Option::unwrap_or_default),
                    opt,
                }),
            };
            if !record::encode(&record, &mut out) {
                return Err(cut("observed_at too long"));
            }
            continue;
        };
        let Some((format, mut rest)) = block.split_first() else {
            return Err(cut("empty block"));
        };
        if !record::readable(*format) {
            return Err(cut("unknown block format"));
        }
        while !rest.is_empty() {
            let Some((t, n)) = record::peek(rest) else {
                return Err(cut("cut block"));
            };
            let (record, later) = rest.split_at(n);
            rest = later;
            if t > to.as_bytes() {
                return Ok(out); // rows are in time order: none later is in the range
            }
            if t >= from.as_bytes() && t > after.as_bytes() {
                out.extend_from_slice(record);
            }
        }
    }
    Ok(out)
}

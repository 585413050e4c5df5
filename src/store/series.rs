//! A point's displacement time series written straight from the database into the bytes the API
//! serves (CSV, or the items of a JSON page), on a blocking thread: no row structs, no per-value
//! allocation, numbers through `zmij`/`itoa`, stored timestamps shortened in place.
//!
//! Ten years of hourly epochs is 87 600 rows a point (`docs/performance.md`, section "Service").
//! One statement reads the point's packed blocks that overlap the range
//! ([`super::series_blocks`]: ~128 rows each, decoded by [`super::series_record`]) followed by its
//! unpacked tail rows, through [`super::sqlite_raw`] (SQLite C API); a PostgreSQL store reads the
//! same statement through sqlx into packed records first ([`super::series_postgres`]) and feeds
//! the same writers. [`super::displacements::series`] is the portable
//! sqlx read of the displacements table, and the reference the tests compare this output with.

use std::io::Write;

use bytes::Bytes;
use sqlx::pool::PoolConnection;
use sqlx::Sqlite;
use tokio::sync::mpsc;

use super::series_record::{self, Record};
use super::sqlite_raw::{self, Param, Row};
use super::{display_timestamp, Store, StoreError};

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

/// What to read: one point, `from ≤ observed_at ≤ to`, after the cursor `after` (store format),
/// at most `limit` rows.
#[derive(Debug, Clone, Default)]
pub struct SeriesQuery {
    /// Site id.
    pub site: String,
    /// Point name.
    pub point: String,
    /// Earliest observed_at, inclusive (store format).
    pub from: Option<String>,
    /// Latest observed_at, inclusive (store format).
    pub to: Option<String>,
    /// Only rows after this observed_at (store format): the page cursor.
    pub after: Option<String>,
    /// At most this many rows (`None`: all); one more is read to tell whether there are more.
    pub limit: Option<i64>,
    /// The point's direction of interest (site frame, any length): gives `d_along_mm`.
    pub direction: Option<[f64; 3]>,
    /// Read each packed block's extremes instead of all its rows ([`EXTREMES_SQL`]) when the
    /// whole series holds more than this many records: for a plot whose buckets span a block or
    /// more ([`series_columns::fold`](super::series_columns::fold)). `None`: every row.
    pub extremes_above: Option<usize>,
}

/// The served form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeriesFormat {
    /// `text/csv`: the header line, then one line per epoch.
    Csv,
    /// The JSON array of a page's `items`: each object as `Displacement` serializes.
    JsonItems,
}

/// What [`write`] wrote.
#[derive(Debug)]
pub struct Written {
    /// The buffer given, with the series appended.
    pub out: Vec<u8>,
    /// Rows written.
    pub rows: usize,
    /// observed_at of the last row written (store format): the next page's cursor.
    pub last_observed_at: Option<String>,
    /// More rows follow the `limit` written.
    pub more: bool,
}

/// The 31 empty columns of a block row (where a tail row has its values).
macro_rules! block_row_nulls {
    () => {
        "NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, \
         NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL"
    };
}

/// The point's packed blocks that overlap the range, with their column `$col`: a block row has
/// its last time and `$col`.
macro_rules! blocks_in_range {
    ($($col:tt)+) => {
        concat!(
            "SELECT last_at, ", $($col)+, ", ", block_row_nulls!(), " FROM series_blocks \
             WHERE site_id = $1 AND point = $2 AND last_at >= $3 AND last_at > $4 AND first_at <= $5"
        )
    };
}

/// [`blocks_in_range`] but only the blocks that can hold the first `$13` records: those with
/// fewer than `$13` records in the blocks before them (PostgreSQL: a window over the blocks' row
/// counts, read from the index and the small heap rows, not from the blocks' data).
macro_rules! blocks_in_range_cut {
    ($($col:tt)+) => {
        concat!(
            "SELECT last_at, ", $($col)+, ", ", block_row_nulls!(), " FROM (SELECT last_at, extremes, data, \
             SUM(n_rows) OVER (ORDER BY last_at) - n_rows AS records_before FROM series_blocks \
             WHERE site_id = $1 AND point = $2 AND last_at >= $3 AND last_at > $4 AND first_at <= $5) AS blocks \
             WHERE records_before < $13"
        )
    };
}

/// The series: the block rows of `$blocks`, then the tail rows in the range, in time order (one
/// statement: one snapshot). A tail row has its time and values. The union is merged on the two
/// primary keys (`EXPLAIN QUERY PLAN`: `MERGE (UNION ALL)`, no sort).
macro_rules! series_sql {
    ($($blocks:tt)+) => {
        concat!(
            $($blocks)+,
            " UNION ALL \
            SELECT observed_at, NULL, epoch_id, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
            sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, significant, velocity_mm_per_day, \
            time_to_failure_hours, cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2, time_to_failure_sigma_hours, \
            f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, sigma_f_dy_mm, sigma_f_dz_mm, sigma_f_d_mm, \
            f_velocity_mm_per_day, sigma_f_velocity_mm_per_day, f_acceleration_mm_per_day2, \
            sigma_f_acceleration_mm_per_day2, f_time_to_failure_hours, sigma_f_time_to_failure_hours \
            FROM displacements \
            WHERE site_id = $6 AND point = $7 \
            AND observed_at > COALESCE((SELECT sealed_until FROM series_seals WHERE site_id = $8), '') \
            AND observed_at >= $9 AND observed_at <= $10 AND observed_at > $11 ORDER BY 1"
        )
    };
}

/// The blocks' column of [`EXTREMES_SQL`]: each block's extremes, the point's last block whole.
macro_rules! extremes_column {
    () => {
        "CASE WHEN last_at = (SELECT MAX(b.last_at) FROM series_blocks b \
         WHERE b.site_id = $1 AND b.point = $2) THEN data ELSE extremes END"
    };
}

/// Every row of the series: each block's packed rows, then the tail rows.
pub(super) const SQL: &str = series_sql!(blocks_in_range!("data"));

/// The series as a coarse plot reads it: each block's extremes
/// ([`series_record::extremes`]) but the point's last block whole, then the tail rows, so the
/// last epochs are all there.
pub(super) const EXTREMES_SQL: &str = series_sql!(blocks_in_range!(extremes_column!()));

/// [`SQL`] for a page, on PostgreSQL, which sends every row of a statement before the writers
/// see one ([`super::series_postgres`]): the blocks that can hold the first `$13` records
/// ([`blocks_in_range_cut`]), and at most `$12` rows. Each row gives at least one record in the
/// range (a block is read only when its last record is after the cursor and `from`), and only
/// the first block can hold records before them, so a page of `limit` records needs `limit + 1`
/// rows and the blocks before which fewer than `limit + 1 + BLOCK_EPOCHS` records lie, however
/// long the rest of the series.
pub(super) const SQL_LIMITED: &str =
    concat!(series_sql!(blocks_in_range_cut!("data")), " LIMIT $12");

/// [`EXTREMES_SQL`] for a page (see [`SQL_LIMITED`]).
pub(super) const EXTREMES_SQL_LIMITED: &str = concat!(
    series_sql!(blocks_in_range_cut!(extremes_column!())),
    " LIMIT $12"
);

/// Where the rows of a series come from.
pub(super) enum Source {
    /// SQLite: a native read connection for [`sqlite_raw`].
    Sqlite(PoolConnection<Sqlite>),
    /// PostgreSQL: the rows already read, as packed records ([`super::series_postgres`]), and
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
                    Some(_) => Some(super::series_postgres::count(pool, q).await?),
                    None => None,
                };
                let extremes = reads_extremes(q, whole.unwrap_or(0));
                let bytes = super::series_postgres::packed_records(pool, q, extremes).await?;
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

/// Reads the series of `q` and appends it to `out` in `format` (oldest first), on a blocking
/// thread.
pub async fn write(
    store: &Store,
    q: SeriesQuery,
    format: SeriesFormat,
    out: Vec<u8>,
) -> Result<Written, StoreError> {
    let mut source = Source::of(store, &q).await?;
    tokio::task::spawn_blocking(move || run(&mut source, &q, format, out))
        .await
        .map_err(reader_failed)?
}

/// Rows per formatting batch of a streamed CSV series.
pub const BATCH_ROWS: usize = 8192;

/// Reads the CSV series of `q` on a blocking thread and sends it in chunks of [`BATCH_ROWS`] rows
/// as they are ready, so the answer goes out while later rows are still read. The reader only
/// copies the packed records out (a block's as they are, a tail row packed); each batch is
/// formatted on the rayon pool (in order), so reading and formatting use both cores. The first message is the first chunk (the header with the first
/// rows) or the error that stopped the read before any row; a later error ends the stream with
/// it. Dropping the receiver stops the read.
pub async fn stream_csv(
    store: &Store,
    q: SeriesQuery,
) -> Result<mpsc::Receiver<Result<Bytes, StoreError>>, StoreError> {
    let mut source = Source::of(store, &q).await?;
    let (tx, rx) = mpsc::channel(4);
    tokio::task::spawn_blocking(move || {
        if let Err(e) = run_csv_batched(&mut source, &q, &tx) {
            let _ = tx.blocking_send(Err(e));
        }
    });
    Ok(rx)
}

type Pending = std::collections::VecDeque<std::sync::mpsc::Receiver<Vec<u8>>>;

/// Formats `batch` (`rows` packed records) on the rayon pool; its bytes arrive on the receiver
/// queued in `pending`.
fn format_batch(
    batch: Vec<u8>,
    rows: usize,
    header: bool,
    direction: Option<[f64; 3]>,
    pending: &mut Pending,
) {
    let (done, result) = std::sync::mpsc::sync_channel(1);
    rayon::spawn(move || {
        let mut w = Writer::new(
            SeriesFormat::Csv,
            direction,
            "",
            Vec::with_capacity(rows * 300 + 256),
        );
        if header {
            w.start();
        }
        for r in series_record::records(&batch) {
            w.row(&r);
        }
        let _ = done.send(w.out);
    });
    pending.push_back(result);
}

/// Sends the formatted batches in order until at most `keep` are left; `false` when the
/// receiver is gone.
fn send_ready(
    pending: &mut Pending,
    keep: usize,
    tx: &mpsc::Sender<Result<Bytes, StoreError>>,
) -> bool {
    while pending.len() > keep {
        let Some(next) = pending.pop_front() else {
            break;
        };
        let bytes = next.recv().unwrap_or_default();
        if tx.blocking_send(Ok(Bytes::from(bytes))).is_err() {
            return false;
        }
    }
    true
}

fn run_csv_batched(
    source: &mut Source,
    q: &SeriesQuery,
    tx: &mpsc::Sender<Result<Bytes, StoreError>>,
) -> Result<(), StoreError> {
    let limit = q.limit.map_or(usize::MAX, |l| l.max(0) as usize);
    let mut pending = Pending::new();
    let mut batch = Vec::with_capacity(BATCH_ROWS * 150);
    let mut in_batch = 0usize;
    let mut rows = 0usize;
    let mut open = true;
    each_record(source, q, false, |record| {
        if rows == limit {
            return false;
        }
        batch.extend_from_slice(record);
        in_batch += 1;
        rows += 1;
        if in_batch == BATCH_ROWS {
            let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH_ROWS * 150));
            format_batch(
                full,
                in_batch,
                rows == BATCH_ROWS,
                q.direction,
                &mut pending,
            );
            in_batch = 0;
            open = send_ready(&mut pending, 2, tx);
        }
        open
    })?;
    if in_batch > 0 || rows == 0 {
        format_batch(
            batch,
            in_batch,
            rows <= BATCH_ROWS,
            q.direction,
            &mut pending,
        );
    }
    send_ready(&mut pending, 0, tx);
    Ok(())
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
            while let Some((_, n)) = series_record::peek(rest) {
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

/// The number of records of the whole series of `q.site`/`q.point` (its range is not applied):
/// the packed blocks' row counts and the tail rows.
/// (PostgreSQL's SUM of a BIGINT is a NUMERIC: cast back.)
pub(super) const COUNT_SQL: &str = "SELECT CAST(COALESCE((SELECT SUM(n_rows) FROM series_blocks WHERE site_id = $1 AND point = $2), 0) \
    + (SELECT COUNT(*) FROM displacements WHERE site_id = $3 AND point = $4 \
    AND observed_at > COALESCE((SELECT sealed_until FROM series_seals WHERE site_id = $5), '')) AS BIGINT)";

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
            while let Some((_, len)) = series_record::peek(rest) {
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
    let to = q.to.as_deref().unwrap_or(super::TEXT_MAX).as_bytes();
    let after = q.after.as_deref().unwrap_or("").as_bytes();
    let mut packed = Vec::with_capacity(256);
    let mut failed = None;
    let sql = if extremes { EXTREMES_SQL } else { SQL };
    sqlite_raw::query(conn, sql, &params(q), |row| {
        if row.is_null(1) {
            // a tail row, in the range (the SQL's condition)
            packed.clear();
            if !series_record::encode(&tail_record(row), &mut packed) {
                failed = Some("observed_at too long");
                return false;
            }
            return each(&packed);
        }
        let Some((format, mut rest)) = row.blob(1).split_first() else {
            failed = Some("empty block");
            return false;
        };
        if !series_record::readable(*format) {
            failed = Some("unknown block format");
            return false;
        }
        while !rest.is_empty() {
            let Some((t, n)) = series_record::peek(rest) else {
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

/// Formats rows already read (e.g. a block's motion series) as the point series is served:
/// CSV with its header, or the JSON array of a page's items; `d_along_mm` along `direction`.
pub fn format_rows(
    rows: &[super::displacements::Displacement],
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

pub(super) fn reader_failed(e: tokio::task::JoinError) -> StoreError {
    StoreError::Sqlite {
        code: 0,
        message: format!("series reader: {e}"),
    }
}

/// The read: rows of `q` through one writer into `out`, on the calling thread.
fn run(
    source: &mut Source,
    q: &SeriesQuery,
    format: SeriesFormat,
    out: Vec<u8>,
) -> Result<Written, StoreError> {
    let mut w = Writer::new(format, q.direction, &q.point, out);
    w.start();
    let mut last = Vec::new();
    let limit = q.limit.map_or(usize::MAX, |l| l.max(0) as usize);
    let mut more = false;
    each_record(source, q, false, |record| {
        if w.rows == limit {
            more = true;
            return false;
        }
        if let Some((r, _)) = series_record::decode(record) {
            w.row(&r);
            last.clear();
            last.extend_from_slice(r.observed_at);
        }
        true
    })?;
    w.finish();
    Ok(Written {
        rows: w.rows,
        last_observed_at: (w.rows > 0).then(|| String::from_utf8_lossy(&last).into_owned()),
        out: w.out,
        more,
    })
}

/// The parameters of [`COUNT_SQL`] for `q` (site, point, site, point, site; both backends bind
/// these).
pub(super) fn count_params(q: &SeriesQuery) -> [Param<'_>; 5] {
    let (site, point) = (Param::Text(&q.site), Param::Text(&q.point));
    [site, point, site, point, site]
}

/// The parameters of [`SQL`] for `q`, in order (both backends bind these).
pub(super) fn params(q: &SeriesQuery) -> [Param<'_>; 11] {
    let from = Param::Text(q.from.as_deref().unwrap_or(""));
    let to = Param::Text(q.to.as_deref().unwrap_or(super::TEXT_MAX));
    let after = Param::Text(q.after.as_deref().unwrap_or(""));
    let site = Param::Text(&q.site);
    let point = Param::Text(&q.point);
    [
        site, point, from, after, to, site, point, site, from, to, after,
    ]
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
            .then(|| series_record::Filtered {
                v: std::array::from_fn(|k| r.double(19 + k)),
                opt: std::array::from_fn(|k| r.opt_double(29 + k)),
            }),
    }
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

struct Writer {
    out: Vec<u8>,
    format: SeriesFormat,
    direction: Option<[f64; 3]>,
    /// The point name as a JSON string (quoted, escaped).
    point: Vec<u8>,
    rows: usize,
    float: zmij::Buffer,
    int: itoa::Buffer,
}

impl Writer {
    fn new(format: SeriesFormat, direction: Option<[f64; 3]>, point: &str, out: Vec<u8>) -> Writer {
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

    fn start(&mut self) {
        match self.format {
            SeriesFormat::Csv => {
                self.out.extend_from_slice(CSV_HEADER.as_bytes());
                self.out.push(b'\n');
            }
            SeriesFormat::JsonItems => self.out.push(b'['),
        }
    }

    fn finish(&mut self) {
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

    fn row(&mut self, r: &Record<'_>) {
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

/// The API form of a time kept in the store's own form (`YYYY-MM-DDTHH:MM:SS.ffffffZ`, as
/// [`super::timestamp`] writes it), without its final `Z`: the fraction dropped when zero, cut to
/// milliseconds when whole, as chrono's `AutoSi` prints it. `None` for any other text.
pub fn shortened(stored: &[u8]) -> Option<&[u8]> {
    let digits = |r: std::ops::Range<usize>| stored[r].iter().all(u8::is_ascii_digit);
    let store_form = stored.len() == 27
        && digits(0..4)
        && stored[4] == b'-'
        && digits(5..7)
        && stored[7] == b'-'
        && digits(8..10)
        && stored[10] == b'T'
        && digits(11..13)
        && stored[13] == b':'
        && digits(14..16)
        && stored[16] == b':'
        && digits(17..19)
        && stored[19] == b'.'
        && digits(20..26)
        && stored[26] == b'Z';
    if !store_form {
        return None;
    }
    let end = if &stored[20..26] == b"000000" {
        19
    } else if &stored[23..26] == b"000" {
        23
    } else {
        26
    };
    Some(&stored[..end])
}

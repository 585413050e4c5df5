//! A point's displacement time series written straight from the database into the bytes the API
//! serves (CSV, or the items of a JSON page), on a blocking thread: no row structs, no per-value
//! allocation, numbers through `zmij`/`itoa`, stored timestamps shortened in place.
//!
//! Ten years of hourly epochs is 87 600 rows a point (`docs/performance.md`, section "Service").
//! One statement reads the point's packed blocks that overlap the range
//! ([`blocks`]: ~128 rows each, decoded by [`record`]) followed by its
//! unpacked tail rows, through [`sqlite_raw`] (SQLite C API); a PostgreSQL store reads the
//! same statement through sqlx into packed records first ([`postgres`]) and feeds
//! the same writers. [`crate::store::displacements::series`] is the portable
//! sqlx read of the displacements table, and the reference the tests compare this output with.

pub mod blocks;
pub mod columns;
mod postgres;
mod query;
mod read;
pub(crate) mod record;
pub(crate) mod sqlite_raw;
mod wire;

use bytes::Bytes;
use tokio::sync::mpsc;

pub use query::SeriesQuery;
pub(crate) use read::reader_failed;
use read::{each_record, Source};
pub use wire::{along, format_rows, SeriesFormat, CSV_HEADER};

use crate::store::{Store, StoreError};
use wire::Writer;

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
        for r in record::records(&batch) {
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
        if let Some((r, _)) = record::decode(record) {
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

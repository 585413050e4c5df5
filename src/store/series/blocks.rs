//! Each point's displacement series packed into immutable blocks (tables `series_blocks` and
//! `series_seals`, migration 20261122000700), so that [`super`] reads ten years of hourly
//! rows as ~700 blobs instead of 87 600 rows of 17 columns.
//!
//! The displacements table stays the truth; the blocks are derived from it inside the caller's
//! write transaction. Per site, the rows observed up to `sealed_until` are in the blocks, exactly
//! once, each block holding one point's rows of up to [`BLOCK_EPOCHS`] consecutive epochs in
//! [`super::record`]'s layout; later rows (the tail, fewer than [`BLOCK_EPOCHS`] epochs
//! after a seal) are read as rows. A site without a `series_seals` row is all tail: correct,
//! only slower. Blocks are packed from the rows as the table returns them, so the served values
//! are the table's, bit for bit. Each block also keeps its extremes
//! ([`record::extremes`], migration 20261125001300), which a plot whose buckets span a
//! block reads instead of the block's rows.
//!
//! Write paths: [`added`] after every insert of displacements ([`crate::store::displacements::insert`]),
//! [`delete_site`] with [`crate::store::displacements::delete_site`], [`backfill`] at open for databases
//! that had displacements before the migrations (20261125001300 drops the blocks without
//! extremes, so they are packed again).

use std::collections::BTreeSet;

use sqlx::AnyConnection;

use super::record;
use crate::store::displacement_row::{select_list, Displacement, COLUMNS};
use crate::store::{Store, StoreError};

/// Epochs per block: a block holds one point's rows of this many consecutive epochs of its site
/// (≈ 17 kB). Also the most epochs a site's tail holds after a seal.
pub const BLOCK_EPOCHS: usize = 128;

/// Keeps the blocks of `site` consistent after `rows` were inserted into displacements (same
/// transaction): counts the new epochs, seals the next blocks when [`BLOCK_EPOCHS`] epochs are
/// pending, and re-packs the site when a row is older than its sealed part.
pub async fn added(
    db: &mut AnyConnection,
    site: &str,
    rows: &[Displacement],
) -> Result<(), StoreError> {
    let times: BTreeSet<&str> = rows.iter().map(|d| d.observed_at.as_str()).collect();
    let Some(earliest) = times.first() else {
        return Ok(());
    };
    let (sealed_until, pending): (String, i64) = sqlx::query_as(
        "INSERT INTO series_seals (site_id, sealed_until, pending) VALUES ($1, '', $2) \
         ON CONFLICT (site_id) DO UPDATE SET pending = series_seals.pending + excluded.pending \
         RETURNING sealed_until, pending",
    )
    .bind(site)
    .bind(times.len() as i64)
    .fetch_one(&mut *db)
    .await?;
    if *earliest <= sealed_until.as_str() {
        return rebuild(db, site).await;
    }
    if pending >= BLOCK_EPOCHS as i64 {
        seal(db, site, &sealed_until).await?;
    }
    Ok(())
}

/// Removes the blocks of `site` (with its displacements; same transaction).
pub async fn delete_site(db: &mut AnyConnection, site: &str) -> Result<(), StoreError> {
    sqlx::query("DELETE FROM series_blocks WHERE site_id = $1")
        .bind(site)
        .execute(&mut *db)
        .await?;
    sqlx::query("DELETE FROM series_seals WHERE site_id = $1")
        .bind(site)
        .execute(&mut *db)
        .await?;
    Ok(())
}

/// Packs the whole series of `site` anew from its displacements (inside a write transaction):
/// after an insert into its sealed past, at [`backfill`], or after rows were written by other
/// means (benchmarks, tests).
pub async fn rebuild(db: &mut AnyConnection, site: &str) -> Result<(), StoreError> {
    delete_site(db, site).await?;
    sqlx::query("INSERT INTO series_seals (site_id, sealed_until, pending) VALUES ($1, '', 0)")
        .bind(site)
        .execute(&mut *db)
        .await?;
    seal(db, site, "").await
}

/// Packs every site that has displacements but no `series_seals` row (databases from before
/// migration 20261122000700 on SQLite, 20261125000300 on PostgreSQL, which dropped the blocks), one
/// write transaction per site; returns how many it packed. Called when a store is opened; a no-op
/// afterwards (two index probes per site).
pub async fn backfill(store: &Store) -> Result<usize, StoreError> {
    let sites: Vec<String> = sqlx::query_scalar(
        "SELECT s.id FROM sites s WHERE NOT EXISTS (SELECT 1 FROM series_seals x WHERE x.site_id = s.id) \
         AND EXISTS (SELECT 1 FROM displacements d WHERE d.site_id = s.id) ORDER BY s.id",
    )
    .fetch_all(store.reader())
    .await?;
    let mut packed = 0;
    for site in &sites {
        let mut tx = store.begin_write_site(site).await?;
        // Asked again under the site's lock: another node opening the same PostgreSQL database
        // may have packed it meanwhile.
        let sealed: Option<String> =
            sqlx::query_scalar("SELECT site_id FROM series_seals WHERE site_id = $1")
                .bind(site)
                .fetch_optional(&mut *tx)
                .await?;
        if sealed.is_some() {
            continue;
        }
        rebuild(&mut tx, site).await?;
        tx.commit().await?;
        packed += 1;
    }
    Ok(packed)
}

/// Seals the site's epochs after `sealed_until` in groups of [`BLOCK_EPOCHS`]: every point's rows
/// of each full group become one block; the rest stays tail.
async fn seal(db: &mut AnyConnection, site: &str, sealed_until: &str) -> Result<(), StoreError> {
    let times: Vec<String> = sqlx::query_scalar(
        "SELECT observed_at FROM epochs WHERE site_id = $1 AND observed_at > $2 ORDER BY observed_at",
    )
    .bind(site)
    .bind(sealed_until)
    .fetch_all(&mut *db)
    .await?;
    let full = times.len() / BLOCK_EPOCHS * BLOCK_EPOCHS;
    // the last epoch of each full group
    let cuts: Vec<&str> = times[..full]
        .iter()
        .skip(BLOCK_EPOCHS - 1)
        .step_by(BLOCK_EPOCHS)
        .map(String::as_str)
        .collect();
    if let Some(until) = cuts.last() {
        // the series endpoint serves the points of the points table only
        let points: Vec<String> =
            sqlx::query_scalar("SELECT name FROM points WHERE site_id = $1 ORDER BY name")
                .bind(site)
                .fetch_all(&mut *db)
                .await?;
        for point in &points {
            let columns = select_list(COLUMNS, "");
            let rows: Vec<Displacement> = sqlx::query_as(&format!(
                "SELECT {columns} FROM displacements \
                 WHERE site_id = $1 AND point = $2 AND observed_at > $3 AND observed_at <= $4 \
                 ORDER BY observed_at"
            ))
            .bind(site)
            .bind(point)
            .bind(sealed_until)
            .bind(*until)
            .fetch_all(&mut *db)
            .await?;
            let mut rest = rows.as_slice();
            for cut in &cuts {
                let n = rest.partition_point(|r| r.observed_at.as_str() <= *cut);
                let (block, later) = rest.split_at(n);
                rest = later;
                insert_block(db, site, point, block).await?;
            }
        }
    }
    let until = cuts.last().copied().unwrap_or(sealed_until);
    sqlx::query("UPDATE series_seals SET sealed_until = $1, pending = $2 WHERE site_id = $3")
        .bind(until)
        .bind((times.len() - full) as i64)
        .bind(site)
        .execute(&mut *db)
        .await?;
    Ok(())
}

async fn insert_block(
    db: &mut AnyConnection,
    site: &str,
    point: &str,
    rows: &[Displacement],
) -> Result<(), StoreError> {
    let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
        return Ok(());
    };
    let mut data = Vec::with_capacity(1 + rows.len() * 150);
    data.push(record::FORMAT);
    for r in rows {
        if !record::encode(&r.record(), &mut data) {
            return Err(StoreError::Block(format!(
                "observed_at of {site}/{point} too long to pack"
            )));
        }
    }
    let extremes = record::extremes(&data)
        .ok_or_else(|| StoreError::Block(format!("block of {site}/{point} unreadable")))?;
    sqlx::query(
        "INSERT INTO series_blocks (site_id, point, last_at, first_at, n_rows, data, extremes) \
         VALUES ($1, $2, $3, $4, $5, $6, $7)",
    )
    .bind(site)
    .bind(point)
    .bind(&last.observed_at)
    .bind(&first.observed_at)
    .bind(rows.len() as i64)
    .bind(data)
    .bind(extremes)
    .execute(&mut *db)
    .await?;
    Ok(())
}

//! The motion series of declared blocks, one row per block and epoch in the form of a point's
//! displacement row ([`Displacement`], `point` naming the group): translation in mm with its
//! covariance in mm², velocity in mm/day, time to failure in hours, the filtered values.

use sqlx::{AnyConnection, AnyExecutor};

use super::displacements::{insert_into, latest_of, series_of, Displacement};
use super::StoreError;

/// Stores block motion rows (observed_at in store format); inside the epoch's write transaction.
pub async fn insert(
    db: &mut AnyConnection,
    site: &str,
    rows: &[Displacement],
) -> Result<(), StoreError> {
    insert_into(db, "block_motions", "block", site, rows).await
}

/// Deletes every block motion of a site (before a recompute).
pub async fn delete_site(db: &mut AnyConnection, site: &str) -> Result<(), StoreError> {
    sqlx::query("DELETE FROM block_motions WHERE site_id = $1")
        .bind(site)
        .execute(&mut *db)
        .await?;
    Ok(())
}

/// The motion series of `block`, oldest first, with `from ≤ observed_at ≤ to` and after the
/// cursor `after` (store format); at most `limit` rows (`None`: all).
pub async fn series(
    db: impl AnyExecutor<'_>,
    site: &str,
    block: &str,
    from: Option<&str>,
    to: Option<&str>,
    after: Option<&str>,
    limit: Option<i64>,
) -> Result<Vec<Displacement>, StoreError> {
    series_of(
        db,
        "block_motions",
        "block",
        site,
        block,
        from,
        to,
        after,
        limit,
    )
    .await
}

/// The newest motion row of `block` (None before its first), read alone.
pub async fn latest(
    db: impl AnyExecutor<'_>,
    site: &str,
    block: &str,
) -> Result<Option<Displacement>, StoreError> {
    latest_of(db, "block_motions", "block", site, block).await
}

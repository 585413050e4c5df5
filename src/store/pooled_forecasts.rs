//! Which targets a point's filtered forecast was pooled with (not declared as a block, they move
//! together: the forecast is their mean series', `cliffwatch_core::analysis::pooling`), one row
//! per point and epoch where it was.

use sqlx::{AnyConnection, AnyExecutor};

use super::StoreError;

/// One point's pooled forecast at one epoch: the other targets of its mean series.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PooledForecast {
    /// The epoch (id) of the forecast.
    pub epoch: i64,
    /// The point whose forecast was pooled.
    pub point: String,
    /// The other targets of the mean series, by name.
    pub pooled_with: Vec<String>,
}

/// Separates the stored names (names may hold commas; they hold no newline).
const SEPARATOR: char = '\n';

/// Stores pooled forecasts, as few statements as the backend's bound parameters allow; inside
/// the epoch's (or the recompute's) write transaction.
pub async fn insert(
    db: &mut AnyConnection,
    site: &str,
    rows: &[PooledForecast],
) -> Result<(), StoreError> {
    const COLS: usize = 4;
    for chunk in rows.chunks(super::rows_per_insert(COLS)) {
        let sql = format!(
            "INSERT INTO pooled_forecasts (site_id, epoch_id, point, pooled_with) VALUES {}",
            super::values_list(db, chunk.len(), COLS)
        );
        let mut q = sqlx::query(&sql);
        for r in chunk {
            q = q
                .bind(site)
                .bind(r.epoch)
                .bind(&r.point)
                .bind(r.pooled_with.join(&SEPARATOR.to_string()));
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// Deletes every pooled forecast of a site (before a recompute).
pub async fn delete_site(db: &mut AnyConnection, site: &str) -> Result<(), StoreError> {
    sqlx::query("DELETE FROM pooled_forecasts WHERE site_id = $1")
        .bind(site)
        .execute(&mut *db)
        .await?;
    Ok(())
}

/// The targets `point`'s forecast was pooled with at `epoch` (empty: its own forecast).
pub async fn of_point(
    db: impl AnyExecutor<'_>,
    site: &str,
    point: &str,
    epoch: i64,
) -> Result<Vec<String>, StoreError> {
    let row: Option<(String,)> = sqlx::query_as(
        "SELECT pooled_with FROM pooled_forecasts \
         WHERE site_id = $1 AND point = $2 AND epoch_id = $3",
    )
    .bind(site)
    .bind(point)
    .bind(epoch)
    .fetch_optional(db)
    .await?;
    Ok(row.map_or_else(Vec::new, |(names,)| {
        names.split(SEPARATOR).map(str::to_string).collect()
    }))
}

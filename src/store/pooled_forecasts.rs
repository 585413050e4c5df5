//! Which targets a point's filtered forecast was pooled with (not declared as a block, they move
//! together: the forecast is their mean series', `cliffwatch_core::analysis::pooling`), one row
//! per point and epoch where it was.

use sqlx::{AnyConnection, AnyExecutor};

use super::StoreError;

/// One point's pooled forecast at one epoch: the other targets of its mean series.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PooledForecast {
    /// The point whose forecast was pooled.
    pub point: String,
    /// The other targets of the mean series, by name.
    pub pooled_with: Vec<String>,
}

/// Separates the stored names (names may hold commas; they hold no newline).
const SEPARATOR: char = '\n';

/// Stores an epoch's pooled forecasts; inside the epoch's write transaction.
pub async fn insert(
    db: &mut AnyConnection,
    site: &str,
    epoch: i64,
    rows: &[PooledForecast],
) -> Result<(), StoreError> {
    for r in rows {
        let names = r.pooled_with.join(&SEPARATOR.to_string());
        sqlx::query(
            "INSERT INTO pooled_forecasts (site_id, epoch_id, point, pooled_with) \
             VALUES ($1, $2, $3, $4)",
        )
        .bind(site)
        .bind(epoch)
        .bind(&r.point)
        .bind(names)
        .execute(&mut *db)
        .await?;
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

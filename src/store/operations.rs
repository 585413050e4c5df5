//! What operations read of the store at every scrape of `/metrics`: open alerts per site and
//! level, and each site's schedule and last epoch.

use sqlx::AnyExecutor;

use super::StoreError;

/// The open and acknowledged alerts of every site, counted per level: `(site, level, count)`.
pub async fn open_alert_counts(
    db: impl AnyExecutor<'_>,
) -> Result<Vec<(String, String, i64)>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT site_id, level, COUNT(*) FROM alerts WHERE state <> 'resolved' \
         GROUP BY site_id, level",
    )
    .fetch_all(db)
    .await?)
}

/// Every site with its schedule (hours between epochs, when set) and the observation time of
/// its last epoch (store format, none before its first): `(site, schedule_hours, last)`.
pub async fn site_freshness(
    db: impl AnyExecutor<'_>,
) -> Result<Vec<(String, Option<f64>, Option<String>)>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT s.id, s.schedule_hours, MAX(e.observed_at) FROM sites s \
         LEFT JOIN epochs e ON e.site_id = s.id GROUP BY s.id, s.schedule_hours",
    )
    .fetch_all(db)
    .await?)
}

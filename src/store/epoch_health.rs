//! The adjustments' health as the campaign report reads it: the epochs' reports that used an
//! estimated a-priori σ.

use sqlx::AnyExecutor;

use super::epoch_report::EpochReport;
use super::StoreError;
use crate::photogrammetry::statistics::variance_components::PooledSigma;

/// The epochs observed between `from` and `to` (store format, inclusive; `None`: open) whose
/// adjustment used cameras' σ estimated from earlier epochs, oldest first, with those σ.
pub async fn estimated_sigma_epochs(
    db: impl AnyExecutor<'_>,
    site: &str,
    from: Option<&str>,
    to: Option<&str>,
) -> Result<Vec<(i64, Vec<PooledSigma>)>, StoreError> {
    let rows: Vec<(i64, String)> = sqlx::query_as(
        "SELECT id, report FROM epochs WHERE site_id = $1 AND observed_at >= $2 \
         AND observed_at <= $3 AND report LIKE '%\"apriori_sigma_estimated\"%' ORDER BY observed_at",
    )
    .bind(site)
    .bind(from.unwrap_or(""))
    .bind(to.unwrap_or(super::TEXT_MAX))
    .fetch_all(db)
    .await?;
    let mut out = Vec::with_capacity(rows.len());
    for (id, r) in rows {
        let report: EpochReport = serde_json::from_str(&r)?;
        if let Some(used) = report.apriori_sigma_estimated {
            out.push((id, used));
        }
    }
    Ok(out)
}

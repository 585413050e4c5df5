//! The adjustments' health: the epochs' variance components, which the a-priori σ estimate pools,
//! and the epochs whose adjustment used an estimated a-priori σ, as the campaign report reads them.

use sqlx::AnyExecutor;

use super::epoch_report::EpochReport;
use super::StoreError;
use cliffwatch_core::photogrammetry::statistics::variance_components::{
    PooledSigma, VarianceComponent,
};

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

/// The variance components of the `n` newest epochs observed before `before` (store format;
/// `None`: all), newest first, each as its adjustment reported it (the epochs' column, not their
/// reports; epochs stored without components are skipped, so fewer may come back; the read is
/// bounded by `n` either way).
pub async fn recent_variance_components(
    db: impl AnyExecutor<'_>,
    site: &str,
    before: Option<&str>,
    n: usize,
) -> Result<Vec<Vec<VarianceComponent>>, StoreError> {
    let rows: Vec<String> = sqlx::query_scalar(
        "SELECT variance_components FROM (SELECT variance_components, observed_at FROM epochs \
         WHERE site_id = $1 AND observed_at < $2 ORDER BY observed_at DESC LIMIT $3) newest \
         WHERE variance_components IS NOT NULL ORDER BY observed_at DESC",
    )
    .bind(site)
    .bind(before.unwrap_or(super::TEXT_MAX))
    .bind(n as i64)
    .fetch_all(db)
    .await?;
    rows.iter()
        .map(|r| Ok(serde_json::from_str::<Vec<VarianceComponent>>(r)?))
        .collect()
}

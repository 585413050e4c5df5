//! Changes of a site's settings that the derived series depend on: the reference epoch and the
//! declared block groups. Each change and the recompute it causes commit in one transaction.

use crate::analysis::GroupConfig;
use crate::store::{epochs, groups, sites, Store, StoreError};

use super::recompute::recompute_site;
use super::ServiceError;

/// Sets the reference epoch of `site` (`None`: back to the earliest epoch) and recomputes its
/// displacements and alerts.
pub async fn set_reference(
    store: &Store,
    site: &str,
    epoch: Option<i64>,
) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let s = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    if let Some(e) = epoch {
        if epochs::observed_at_raw(&mut *tx, site, e).await?.is_none() {
            return Err(ServiceError::UnknownEpoch {
                site: site.to_string(),
                epoch: e,
            });
        }
    }
    sites::set_reference(&mut *tx, site, epoch).await?;
    recompute_site(&mut tx, &s).await?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(())
}

/// Declares (or replaces) a block group of `site` and recomputes the site's series and alerts.
pub async fn declare_group(
    store: &Store,
    site: &str,
    group: &GroupConfig,
) -> Result<(), ServiceError> {
    let mut tx = store.begin_write_site(site).await?;
    let s = sites::get(&mut *tx, site)
        .await?
        .ok_or_else(|| ServiceError::UnknownSite(site.to_string()))?;
    groups::put(&mut tx, site, group).await?;
    recompute_site(&mut tx, &s).await?;
    tx.commit().await.map_err(StoreError::from)?;
    Ok(())
}

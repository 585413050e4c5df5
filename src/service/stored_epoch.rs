//! An epoch as stored, with the rows the upload answer and the epoch's page show.

use crate::store::alerts::{self, Alert};
use crate::store::displacements::{self, Displacement};
use crate::store::epoch_report::EpochReport;
use crate::store::epochs::{self, EpochListItem, StoredResidual};
use crate::store::Store;

use super::ServiceError;

/// An epoch as stored, with the rows the upload answer and the epoch's page show.
#[derive(Debug)]
pub struct StoredEpoch {
    /// The list fields.
    pub item: EpochListItem,
    /// The adjustment report.
    pub report: EpochReport,
    /// Residuals per observation, when asked for.
    pub residuals: Option<Vec<StoredResidual>>,
    /// Displacements of this epoch against the reference epoch.
    pub displacements: Vec<Displacement>,
    /// Alerts this epoch raised or escalated, in their current state.
    pub alerts: Vec<Alert>,
}

/// Epoch `id` of `site` as stored (`None`: no such epoch), with its residuals when `residuals`,
/// read on one connection.
pub async fn stored_epoch(
    store: &Store,
    site: &str,
    id: i64,
    residuals: bool,
) -> Result<Option<StoredEpoch>, ServiceError> {
    let mut conn = store.read().await?;
    let db = &mut *conn;
    let Some((item, report)) = epochs::get(&mut *db, site, id).await? else {
        return Ok(None);
    };
    let residuals = if residuals {
        Some(epochs::residuals(&mut *db, site, id).await?)
    } else {
        None
    };
    Ok(Some(StoredEpoch {
        item,
        report,
        residuals,
        displacements: displacements::of_epoch(&mut *db, site, id).await?,
        alerts: alerts::of_epoch(&mut *db, site, id).await?,
    }))
}

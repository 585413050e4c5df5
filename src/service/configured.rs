//! The configuration file's sites and webhooks, applied when the daemon starts.

use thiserror::Error;

use crate::config::Config;
use crate::store::webhooks::{self, NewWebhook};
use crate::store::{sites, Store, StoreError};

/// Why the configuration could not be applied; nothing of it was stored.
#[derive(Debug, Error)]
pub enum ConfiguredError {
    /// A configured site or webhook is refused: its id or URL, and why.
    #[error("configured '{0}': {1}")]
    Item(String, String),
    /// The database failed.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Stores the configuration's sites (checked as the API checks them, recomputing a site whose
/// analysis settings or rules changed) and replaces the configured webhooks, in one
/// transaction: nothing is applied when one item is refused.
pub async fn apply_configured(store: &Store, config: &Config) -> Result<(), ConfiguredError> {
    let mut tx = store.begin_write().await?;
    let mut raised = 0;
    for site in &config.sites {
        super::sites::validate_site(site)
            .map_err(|e| ConfiguredError::Item(site.id.clone(), e.to_string()))?;
        let before = sites::get(&mut *tx, &site.id).await?;
        sites::upsert(&mut tx, site).await?;
        // Settings the analysis or the alert rules depend on changed: the series and alerts are
        // recomputed (like a new reference epoch through the API), so that an alert of a rule
        // that is gone or no longer met resolves now instead of staying open.
        if let (Some(b), Some(a)) = (before, sites::get(&mut *tx, &site.id).await?) {
            if super::site_admin::analysis_changed(&b, &a) {
                tracing::info!(site = %site.id, "analysis settings or alert rules changed in the \
                    configuration file: the site's series and alerts are recomputed");
                let cause = super::recompute::RecomputeCause::Settings;
                raised += super::recompute::recompute_site(
                    &mut tx,
                    &a.id,
                    &cause,
                    config.public_url.as_deref(),
                )
                .await
                .map_err(|e| ConfiguredError::Item(site.id.clone(), e.to_string()))?;
            }
        }
    }
    let hooks: Vec<NewWebhook> = config
        .webhooks
        .iter()
        .map(|w| NewWebhook {
            url: w.url.clone(),
            secret: w.secret.clone(),
            min_level: Some(w.min_level),
            format: w.format,
        })
        .collect();
    for h in &hooks {
        super::webhooks::validate_webhook(h)
            .map_err(|e| ConfiguredError::Item(h.url.clone(), e.to_string()))?;
    }
    webhooks::replace_configured(&mut tx, &hooks).await?;
    tx.commit().await.map_err(StoreError::from)?;
    super::alert_outcome::count_raised(raised);
    Ok(())
}

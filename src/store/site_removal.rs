//! A retired site's rows deleted, every table of it, children before parents (the foreign
//! keys), inside the caller's transaction. The audit trail is not deleted: its rows have no
//! foreign key to the site and outlive it, ending with the deletion's own row.

use sqlx::AnyConnection;

use super::StoreError;

/// The tables of a site, each with the condition that selects the site's rows (`$1`: the site's
/// id), in an order the foreign keys allow.
const SITE_TABLES: &[(&str, &str)] = &[
    (
        "webhook_deliveries",
        "outbox_id IN (SELECT o.id FROM webhook_outbox o JOIN alerts a ON a.id = o.alert_id \
         WHERE a.site_id = $1)",
    ),
    (
        "webhook_outbox",
        "alert_id IN (SELECT a.id FROM alerts a WHERE a.site_id = $1)",
    ),
    ("alerts", "site_id = $1"),
    ("alert_states", "site_id = $1"),
    ("watch_folders", "site_id = $1"),
    ("watch_orientations", "site_id = $1"),
    ("series_blocks", "site_id = $1"),
    ("series_seals", "site_id = $1"),
    ("pooled_forecasts", "site_id = $1"),
    ("block_motions", "site_id = $1"),
    ("displacements", "site_id = $1"),
    ("joint_covariances", "site_id = $1"),
    ("coordinates", "site_id = $1"),
    ("observations", "site_id = $1"),
    ("images", "site_id = $1"),
    ("epochs", "site_id = $1"),
    ("points", "site_id = $1"),
    ("groups", "site_id = $1"),
    ("stations", "site_id = $1"),
    ("cameras", "site_id = $1"),
    ("sites", "id = $1"),
];

/// Deletes every row of `site` but its audit trail, in `tx`; returns how many rows each table
/// lost (tables that lost none left out).
pub async fn delete_site(
    tx: &mut AnyConnection,
    site: &str,
) -> Result<Vec<(&'static str, u64)>, StoreError> {
    let mut deleted = Vec::new();
    for (table, condition) in SITE_TABLES {
        let done = sqlx::query(&format!("DELETE FROM {table} WHERE {condition}"))
            .bind(site)
            .execute(&mut *tx)
            .await?;
        if done.rows_affected() > 0 {
            deleted.push((*table, done.rows_affected()));
        }
    }
    Ok(deleted)
}

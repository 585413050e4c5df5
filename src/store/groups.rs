//! Point groups declared as rigid blocks (`PUT /api/v1/sites/{site}/groups/{group}`).

use sqlx::{AnyConnection, AnyExecutor};

use super::{now, StoreError};
use cliffwatch_core::analysis::{GroupConfig, GroupKind};

type Row = (String, String, Option<String>, String, Option<f64>);

fn from_row(
    (name, kind, direction, points, process_noise): Row,
) -> Result<GroupConfig, StoreError> {
    let kind = match kind.as_str() {
        "block" => GroupKind::Block,
        other => {
            return Err(StoreError::Corrupt(format!(
                "group {name}: unknown kind '{other}'"
            )))
        }
    };
    Ok(GroupConfig {
        name,
        kind,
        direction: direction.map(|d| serde_json::from_str(&d)).transpose()?,
        points: serde_json::from_str(&points)?,
        process_noise,
    })
}

/// The groups of a site, by name.
pub async fn list(db: impl AnyExecutor<'_>, site: &str) -> Result<Vec<GroupConfig>, StoreError> {
    let rows: Vec<Row> = sqlx::query_as(
        "SELECT name, kind, direction, points, process_noise FROM groups WHERE site_id = $1 ORDER BY name",
    )
    .bind(site)
    .fetch_all(db)
    .await?;
    rows.into_iter().map(from_row).collect()
}

/// One group of a site.
pub async fn get(
    db: impl AnyExecutor<'_>,
    site: &str,
    name: &str,
) -> Result<Option<GroupConfig>, StoreError> {
    let row: Option<Row> = sqlx::query_as(
        "SELECT name, kind, direction, points, process_noise FROM groups WHERE site_id = $1 AND name = $2",
    )
    .bind(site)
    .bind(name)
    .fetch_optional(db)
    .await?;
    row.map(from_row).transpose()
}

/// Creates or replaces a group.
pub async fn put(db: &mut AnyConnection, site: &str, g: &GroupConfig) -> Result<(), StoreError> {
    let kind = match g.kind {
        GroupKind::Block => "block",
    };
    let at = now(&mut *db).await?;
    sqlx::query(
        "INSERT INTO groups (site_id, name, kind, direction, points, process_noise, updated_at) \
         VALUES ($1, $2, $3, $4, $5, $6, $7) ON CONFLICT (site_id, name) DO UPDATE SET kind = excluded.kind, \
         direction = excluded.direction, points = excluded.points, \
         process_noise = excluded.process_noise, updated_at = excluded.updated_at",
    )
    .bind(site)
    .bind(&g.name)
    .bind(kind)
    .bind(g.direction.map(|d| serde_json::to_string(&d)).transpose()?)
    .bind(serde_json::to_string(&g.points)?)
    .bind(g.process_noise)
    .bind(&at)
    .execute(db)
    .await?;
    Ok(())
}

/// Deletes group `name` of `site`; false when there was none.
pub async fn delete(db: impl AnyExecutor<'_>, site: &str, name: &str) -> Result<bool, StoreError> {
    let done = sqlx::query("DELETE FROM groups WHERE site_id = $1 AND name = $2")
        .bind(site)
        .bind(name)
        .execute(db)
        .await?;
    Ok(done.rows_affected() > 0)
}

//! Points (role, group, direction of interest) and their adjusted coordinates per epoch.

use serde::{Deserialize, Serialize};
use sqlx::{AnyConnection, AnyExecutor, FromRow};
use utoipa::ToSchema;

use super::StoreError;
use cliffwatch_core::analysis::PointRole;

/// Settings of a point (`PUT /api/v1/sites/{site}/points/{point}`): a member left out keeps its
/// value, `null` clears a group or a direction.
#[derive(Debug, Clone, Default, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PointSettings {
    /// `stable` or `monitored`.
    #[serde(default)]
    pub role: Option<PointRole>,
    /// Group name (e.g. a block of the cliff); `null` takes the point out of its group.
    #[serde(default, deserialize_with = "present")]
    #[schema(value_type = Option<String>, pattern = "^[A-Za-z0-9._-]{1,64}$")]
    pub group: Option<Option<String>>,
    /// Direction of interest in the site frame (e.g. the cliff normal); any length but zero;
    /// `null` clears it.
    #[serde(default, deserialize_with = "present")]
    #[schema(value_type = Option<[f64; 3]>, min_items = 3, max_items = 3)]
    pub direction: Option<Option<[f64; 3]>>,
    /// Declares a point no epoch has measured yet (a target about to be set up): without it,
    /// settings for a point the site has never measured are refused once the site has epochs
    /// (a misspelt name would otherwise appear as a new point). Not stored.
    #[serde(default)]
    pub planned: bool,
}

/// A member that is present: `Some(None)` for `null`, `Some(Some(v))` for a value (an absent
/// member stays `None` through `#[serde(default)]`).
fn present<'de, T, D>(d: D) -> Result<Option<Option<T>>, D::Error>
where
    T: Deserialize<'de>,
    D: serde::Deserializer<'de>,
{
    Option::<T>::deserialize(d).map(Some)
}

/// A stored point.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct Point {
    /// Point name.
    pub name: String,
    /// Its role.
    pub role: PointRole,
    /// Group name.
    pub group: Option<String>,
    /// Direction of interest, site frame.
    pub direction: Option<[f64; 3]>,
}

#[derive(FromRow)]
struct PointRow {
    name: String,
    #[sqlx(try_from = "String")]
    role: PointRole,
    grp: Option<String>,
    dir_x: Option<f64>,
    dir_y: Option<f64>,
    dir_z: Option<f64>,
}

impl TryFrom<PointRow> for Point {
    type Error = StoreError;
    fn try_from(r: PointRow) -> Result<Point, StoreError> {
        let direction = match (r.dir_x, r.dir_y, r.dir_z) {
            (Some(x), Some(y), Some(z)) => Some([x, y, z]),
            _ => None,
        };
        Ok(Point {
            name: r.name,
            role: r.role,
            group: r.grp,
            direction,
        })
    }
}

/// Every point of a site, by name, after `after` (cursor), at most `limit`.
pub async fn list(
    db: impl AnyExecutor<'_>,
    site: &str,
    after: Option<&str>,
    limit: i64,
) -> Result<Vec<Point>, StoreError> {
    let rows: Vec<PointRow> = sqlx::query_as(
        "SELECT name, role, grp, dir_x, dir_y, dir_z FROM points WHERE site_id = $1 \
         AND name > $2 ORDER BY name LIMIT $3",
    )
    .bind(site)
    // A range from the cursor that the primary key reads directly; every name is longer than "".
    .bind(after.unwrap_or(""))
    .bind(limit)
    .fetch_all(db)
    .await?;
    rows.into_iter().map(Point::try_from).collect()
}

/// One point.
pub async fn get(
    db: impl AnyExecutor<'_>,
    site: &str,
    name: &str,
) -> Result<Option<Point>, StoreError> {
    let row: Option<PointRow> = sqlx::query_as(
        "SELECT name, role, grp, dir_x, dir_y, dir_z FROM points WHERE site_id = $1 AND name = $2",
    )
    .bind(site)
    .bind(name)
    .fetch_optional(db)
    .await?;
    row.map(Point::try_from).transpose()
}

/// Names of the site's stable points.
pub async fn stable(db: impl AnyExecutor<'_>, site: &str) -> Result<Vec<String>, StoreError> {
    Ok(sqlx::query_scalar(
        "SELECT name FROM points WHERE site_id = $1 AND role = 'stable' ORDER BY name",
    )
    .bind(site)
    .fetch_all(db)
    .await?)
}

/// Creates the point or changes the given settings (others stay; a group or direction given as
/// `null` is cleared).
pub async fn upsert(
    db: impl AnyExecutor<'_>,
    site: &str,
    name: &str,
    s: &PointSettings,
) -> Result<(), StoreError> {
    let group = s.group.clone().flatten();
    let d = s.direction.flatten();
    sqlx::query(
        "INSERT INTO points (site_id, name, role, grp, dir_x, dir_y, dir_z) VALUES ($1, $2, COALESCE($3, 'monitored'), $4, $5, $6, $7) \
         ON CONFLICT (site_id, name) DO UPDATE SET role = COALESCE($3, points.role), \
         grp = CASE WHEN $8 THEN $4 ELSE points.grp END, \
         dir_x = CASE WHEN $9 THEN $5 ELSE points.dir_x END, \
         dir_y = CASE WHEN $9 THEN $6 ELSE points.dir_y END, \
         dir_z = CASE WHEN $9 THEN $7 ELSE points.dir_z END",
    )
    .bind(site)
    .bind(name)
    .bind(s.role.map(PointRole::as_str))
    .bind(group)
    .bind(d.map(|d| d[0]))
    .bind(d.map(|d| d[1]))
    .bind(d.map(|d| d[2]))
    .bind(s.group.is_some())
    .bind(s.direction.is_some())
    .execute(db)
    .await?;
    Ok(())
}

/// Adjusted coordinates of one point in one epoch: m and covariance m².
#[derive(Debug, Clone, PartialEq)]
pub struct StoredCoordinate {
    /// Point name.
    pub point: String,
    /// Epoch id.
    pub epoch: i64,
    /// Observation time (store format).
    pub observed_at: String,
    /// X, Y, Z in m.
    pub xyz: [f64; 3],
    /// 3 × 3 covariance in m².
    pub covariance_m2: [[f64; 3]; 3],
}

#[derive(FromRow)]
struct CoordRow {
    point: String,
    epoch_id: i64,
    observed_at: String,
    x_m: f64,
    y_m: f64,
    z_m: f64,
    cxx_m2: f64,
    cxy_m2: f64,
    cxz_m2: f64,
    cyy_m2: f64,
    cyz_m2: f64,
    czz_m2: f64,
}

impl From<CoordRow> for StoredCoordinate {
    fn from(r: CoordRow) -> Self {
        StoredCoordinate {
            point: r.point,
            epoch: r.epoch_id,
            observed_at: r.observed_at,
            xyz: [r.x_m, r.y_m, r.z_m],
            covariance_m2: [
                [r.cxx_m2, r.cxy_m2, r.cxz_m2],
                [r.cxy_m2, r.cyy_m2, r.cyz_m2],
                [r.cxz_m2, r.cyz_m2, r.czz_m2],
            ],
        }
    }
}

const COORD_COLUMNS: &str = "c.point, c.epoch_id, c.observed_at, c.x_m, c.y_m, c.z_m, \
    c.cxx_m2, c.cxy_m2, c.cxz_m2, c.cyy_m2, c.cyz_m2, c.czz_m2";

/// The latest coordinates (by observation time) of every point of the site. Each point costs
/// one index seek however long the history: SQLite keeps the points as the outer loop of the
/// `CROSS JOIN`; PostgreSQL, whose planner joined all the site's coordinates by hash (its
/// statistics of a young table), reads each point's newest row `LATERAL`ly.
pub async fn latest_coordinates(
    db: &mut AnyConnection,
    site: &str,
) -> Result<Vec<StoredCoordinate>, StoreError> {
    let sql = if super::is_postgres(db) {
        format!(
            "SELECT {COORD_COLUMNS} FROM points p CROSS JOIN LATERAL (SELECT * FROM coordinates c2 \
             WHERE c2.site_id = p.site_id AND c2.point = p.name ORDER BY c2.observed_at DESC LIMIT 1) c \
             WHERE p.site_id = $1 ORDER BY p.name"
        )
    } else {
        format!(
            "SELECT {COORD_COLUMNS} FROM points p CROSS JOIN coordinates c \
             WHERE p.site_id = $1 AND c.site_id = p.site_id AND c.point = p.name AND c.observed_at = \
             (SELECT MAX(c2.observed_at) FROM coordinates c2 WHERE c2.site_id = p.site_id AND c2.point = p.name) \
             ORDER BY p.name"
        )
    };
    let rows: Vec<CoordRow> = sqlx::query_as(&sql).bind(site).fetch_all(db).await?;
    Ok(rows.into_iter().map(StoredCoordinate::from).collect())
}

/// The coordinates of every point of one epoch.
pub async fn epoch_coordinates(
    db: impl AnyExecutor<'_>,
    site: &str,
    epoch: i64,
) -> Result<Vec<StoredCoordinate>, StoreError> {
    let rows: Vec<CoordRow> = sqlx::query_as(&format!(
        "SELECT {COORD_COLUMNS} FROM coordinates c WHERE c.site_id = $1 AND c.epoch_id = $2 ORDER BY c.point"
    ))
    .bind(site)
    .bind(epoch)
    .fetch_all(db)
    .await?;
    Ok(rows.into_iter().map(StoredCoordinate::from).collect())
}

/// Every coordinate of the site, oldest epoch first (recomputing displacements).
pub async fn all_coordinates(
    db: impl AnyExecutor<'_>,
    site: &str,
) -> Result<Vec<StoredCoordinate>, StoreError> {
    let rows: Vec<CoordRow> = sqlx::query_as(&format!(
        "SELECT {COORD_COLUMNS} FROM coordinates c WHERE c.site_id = $1 ORDER BY c.observed_at, c.point"
    ))
    .bind(site)
    .fetch_all(db)
    .await?;
    Ok(rows.into_iter().map(StoredCoordinate::from).collect())
}

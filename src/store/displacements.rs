//! Displacements of points per epoch against the site's reference epoch (mm).

use sqlx::{AnyConnection, AnyExecutor};

use super::series::sqlite_raw::{self, Param};
use super::{display_timestamp, Store, StoreError};

pub use super::displacement_row::Displacement;
use super::displacement_row::{select_list, COLUMNS, HISTORY_COLUMNS};

fn display(mut rows: Vec<Displacement>) -> Vec<Displacement> {
    for r in &mut rows {
        r.observed_at = display_timestamp(&r.observed_at);
    }
    rows
}

/// Stores displacements (observed_at in store format) and keeps the site's packed series
/// consistent ([`super::series::blocks::added`]). Call inside the epoch's write transaction.
pub async fn insert(
    db: &mut AnyConnection,
    site: &str,
    rows: &[Displacement],
) -> Result<(), StoreError> {
    insert_into(db, "displacements", "point", site, rows).await?;
    super::series::blocks::added(db, site, rows).await
}

/// The column list of `table`, whose name column (`point` in [`COLUMNS`]) is `name_column`.
pub(super) fn columns_of(name_column: &str) -> String {
    COLUMNS.replacen("point", name_column, 1)
}

/// Inserts `rows` into `table` (`displacements`, or a table of the same columns whose name
/// column is `name_column`).
pub(super) async fn insert_into(
    db: &mut AnyConnection,
    table: &str,
    name_column: &str,
    site: &str,
    rows: &[Displacement],
) -> Result<(), StoreError> {
    let cols = COLUMNS.split(',').count() + 1;
    for chunk in rows.chunks(super::rows_per_insert(cols)) {
        let sql = format!(
            "INSERT INTO {table} (site_id, {}) VALUES {}",
            columns_of(name_column),
            super::values_list(db, chunk.len(), cols)
        );
        let mut q = sqlx::query(&sql);
        for d in chunk {
            q = q
                .bind(site)
                .bind(&d.point)
                .bind(d.epoch)
                .bind(&d.observed_at)
                .bind(d.reference_epoch)
                .bind(d.dx_mm)
                .bind(d.dy_mm)
                .bind(d.dz_mm)
                .bind(d.d_mm)
                .bind(d.sigma_dx_mm)
                .bind(d.sigma_dy_mm)
                .bind(d.sigma_dz_mm)
                .bind(d.sigma_mm)
                .bind(d.d_along_mm)
                .bind(d.significant)
                .bind(d.velocity_mm_per_day)
                .bind(d.time_to_failure_hours)
                .bind(d.cov_dxdy_mm2)
                .bind(d.cov_dxdz_mm2)
                .bind(d.cov_dydz_mm2)
                .bind(d.time_to_failure_sigma_hours)
                .bind(d.f_dx_mm)
                .bind(d.f_dy_mm)
                .bind(d.f_dz_mm)
                .bind(d.f_d_mm)
                .bind(d.sigma_f_dx_mm)
                .bind(d.sigma_f_dy_mm)
                .bind(d.sigma_f_dz_mm)
                .bind(d.sigma_f_d_mm)
                .bind(d.f_velocity_mm_per_day)
                .bind(d.sigma_f_velocity_mm_per_day)
                .bind(d.f_acceleration_mm_per_day2)
                .bind(d.sigma_f_acceleration_mm_per_day2)
                .bind(d.f_time_to_failure_hours)
                .bind(d.sigma_f_time_to_failure_hours);
        }
        q.execute(&mut *db).await?;
    }
    Ok(())
}

/// Deletes every displacement of a site (before recomputing against a new reference), with its
/// packed series.
pub async fn delete_site(db: &mut AnyConnection, site: &str) -> Result<(), StoreError> {
    sqlx::query("DELETE FROM displacements WHERE site_id = $1")
        .bind(site)
        .execute(&mut *db)
        .await?;
    super::series::blocks::delete_site(db, site).await
}

/// The time series of one point, oldest first, with `from ≤ observed_at ≤ to` and after the
/// cursor `after` (all in store format); at most `limit` rows (`None`: all).
pub async fn series(
    db: impl AnyExecutor<'_>,
    site: &str,
    point: &str,
    from: Option<&str>,
    to: Option<&str>,
    after: Option<&str>,
    limit: Option<i64>,
) -> Result<Vec<Displacement>, StoreError> {
    series_of(
        db,
        "displacements",
        "point",
        site,
        point,
        from,
        to,
        after,
        limit,
    )
    .await
}

/// [`series`] from `table`, whose name column is `name_column`.
#[allow(clippy::too_many_arguments)]
pub(super) async fn series_of(
    db: impl AnyExecutor<'_>,
    table: &str,
    name_column: &str,
    site: &str,
    name: &str,
    from: Option<&str>,
    to: Option<&str>,
    after: Option<&str>,
    limit: Option<i64>,
) -> Result<Vec<Displacement>, StoreError> {
    let columns = select_list(COLUMNS, "").replacen(
        "point",
        &format!("{name_column} AS point"),
        usize::from(name_column != "point"),
    );
    let rows: Vec<Displacement> = sqlx::query_as(&format!(
        "SELECT {columns} FROM {table} WHERE site_id = $1 AND {name_column} = $2 \
         AND observed_at >= $3 AND observed_at <= $4 AND observed_at > $5 ORDER BY observed_at LIMIT $6"
    ))
    .bind(site)
    .bind(name)
    .bind(from.unwrap_or(""))
    .bind(to.unwrap_or(super::TEXT_MAX))
    .bind(after.unwrap_or(""))
    .bind(limit.unwrap_or(i64::MAX))
    .fetch_all(db)
    .await?;
    Ok(display(rows))
}

/// The newest row of `name` in `table` (`name_column` naming it), or None: one indexed read
/// where [`series_of`] would read the whole series to keep its last row.
pub(super) async fn latest_of(
    db: impl AnyExecutor<'_>,
    table: &str,
    name_column: &str,
    site: &str,
    name: &str,
) -> Result<Option<Displacement>, StoreError> {
    let columns = select_list(COLUMNS, "").replacen(
        "point",
        &format!("{name_column} AS point"),
        usize::from(name_column != "point"),
    );
    let rows: Vec<Displacement> = sqlx::query_as(&format!(
        "SELECT {columns} FROM {table} WHERE site_id = $1 AND {name_column} = $2 \
         ORDER BY observed_at DESC LIMIT 1"
    ))
    .bind(site)
    .bind(name)
    .fetch_all(db)
    .await?;
    Ok(display(rows).pop())
}

/// How far back a point's history reaches: its last `records` rows, and every row observed at
/// or after `since` (store format; an hourly site's last 40 days), at most `cap` rows.
#[derive(Debug, Clone)]
pub struct Reach {
    /// Rows read whatever their age.
    pub records: usize,
    /// Rows observed at or after this time (store format) are read too.
    pub since: String,
    /// Most rows read per point.
    pub cap: usize,
}

/// The rows of each point of `site` observed before `before` (store format) that `reach`
/// covers, newest first, one entry per point with rows, times in store format: the analysis'
/// history of a new epoch (without the filtered values, which the analysis recomputes).
///
/// Both backends read on their native read pool, not through sqlx's `Any` driver, whose copies
/// of each value made this read most of an upload's time (28 points × 40 rows × 19 columns):
/// SQLite through the C API ([`sqlite_raw`], one range scan of the primary key per point),
/// PostgreSQL in one statement. That connection sees the last committed state, not the epoch's
/// write transaction: call it once that transaction holds the site's write lock (SQLite's
/// `BEGIN IMMEDIATE`, PostgreSQL's advisory lock: no other writer of the site commits in
/// between), and before it commits; it may run while the transaction writes.
pub async fn recent(
    store: &Store,
    site: &str,
    before: &str,
    reach: &Reach,
) -> Result<Vec<(String, Vec<Displacement>)>, StoreError> {
    let Some(pool) = store.sqlite_reader() else {
        return recent_postgres(store, site, before, reach).await;
    };
    let mut conn = pool.acquire().await?;
    let (site, before) = (site.to_string(), before.to_string());
    // From the older of `since` and the point's `records`-th newest row ('' when it has fewer).
    let sql = format!(
        "SELECT {} FROM displacements WHERE site_id = ?1 AND point = ?2 \
         AND observed_at < ?3 AND observed_at >= MIN(?4, COALESCE((SELECT observed_at \
         FROM displacements WHERE site_id = ?1 AND point = ?2 AND observed_at < ?3 \
         ORDER BY observed_at DESC LIMIT 1 OFFSET ?5), '')) \
         ORDER BY observed_at DESC LIMIT ?6",
        select_list(HISTORY_COLUMNS, "")
    );
    let n = reach.records.max(1);
    let offset = i64::try_from(n - 1).unwrap_or(i64::MAX);
    let limit = i64::try_from(reach.cap.max(n)).unwrap_or(i64::MAX);
    let since = reach.since.clone();
    tokio::task::spawn_blocking(move || {
        let mut points = Vec::new();
        sqlite_raw::query(
            &mut conn,
            "SELECT name FROM points WHERE site_id = $1 ORDER BY name",
            &[Param::Text(&site)],
            |row| {
                points.push(String::from_utf8_lossy(row.text(0)).into_owned());
                true
            },
        )?;
        let params: Vec<[Param<'_>; 6]> = points
            .iter()
            .map(|p| {
                [
                    Param::Text(&site),
                    Param::Text(p),
                    Param::Text(&before),
                    Param::Text(&since),
                    Param::Int(offset),
                    Param::Int(limit),
                ]
            })
            .collect();
        let sets: Vec<&[Param<'_>]> = params.iter().map(|p| &p[..]).collect();
        let mut rows: Vec<Vec<Displacement>> = vec![Vec::with_capacity(n); points.len()];
        sqlite_raw::query_each(&mut conn, &sql, &sets, |k, row| {
            rows[k].push(history_row(row));
            true
        })?;
        // the parameters borrow `points`, which the answer takes
        drop(sets);
        drop(params);
        Ok(points
            .into_iter()
            .zip(rows)
            .filter(|(_, r)| !r.is_empty())
            .collect())
    })
    .await
    .map_err(super::series::reader_failed)?
}

/// PostgreSQL's [`recent`]: one statement for all points (a `LATERAL` read of each point's last
/// `n` rows by the primary key) instead of one round trip per point, on the native pool
/// ([`Store::postgres_reader`]). No `ORDER BY`: sorting the 1 120 rows of a 40-epoch history
/// took PostgreSQL a third of the statement; the rows are grouped and ordered here.
async fn recent_postgres(
    store: &Store,
    site: &str,
    before: &str,
    reach: &Reach,
) -> Result<Vec<(String, Vec<Displacement>)>, StoreError> {
    let Some(pool) = store.postgres_reader() else {
        let missing = "the history read needs the store's native read pool";
        return Err(StoreError::Sql(sqlx::Error::Configuration(missing.into())));
    };
    let sql = format!(
        "SELECT {HISTORY_COLUMNS} FROM points p CROSS JOIN LATERAL (SELECT * FROM displacements d \
         WHERE d.site_id = p.site_id AND d.point = p.name AND d.observed_at < $2 \
         AND d.observed_at >= LEAST($4, COALESCE((SELECT e.observed_at FROM displacements e \
         WHERE e.site_id = p.site_id AND e.point = p.name AND e.observed_at < $2 \
         ORDER BY e.observed_at DESC LIMIT 1 OFFSET $5), '')) \
         ORDER BY d.observed_at DESC LIMIT $3) d WHERE p.site_id = $1"
    );
    let n = reach.records.max(1);
    let rows = sqlx::query(&sql)
        .bind(site)
        .bind(before)
        .bind(i64::try_from(reach.cap.max(n)).unwrap_or(i64::MAX))
        .bind(reach.since.as_str())
        .bind(i64::try_from(n - 1).unwrap_or(i64::MAX))
        .fetch_all(pool)
        .await?;
    let mut out: Vec<(String, Vec<Displacement>)> = Vec::new();
    for row in &rows {
        let d = history_row_postgres(row)?;
        match out.iter_mut().rev().find(|(p, _)| *p == d.point) {
            Some((_, list)) => list.push(d),
            None => out.push((d.point.clone(), vec![d])),
        }
    }
    for (_, list) in &mut out {
        if !list.is_sorted_by(|a, b| a.observed_at >= b.observed_at) {
            list.sort_by(|a, b| b.observed_at.cmp(&a.observed_at));
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(out)
}

/// A row of [`HISTORY_COLUMNS`] read by the native PostgreSQL driver (`significant` as the
/// BOOLEAN it is; the columns not read stay `None`).
fn history_row_postgres(row: &sqlx::postgres::PgRow) -> Result<Displacement, sqlx::Error> {
    use sqlx::Row;
    Ok(Displacement {
        point: row.try_get(0)?,
        epoch: row.try_get(1)?,
        observed_at: row.try_get(2)?,
        reference_epoch: row.try_get(3)?,
        dx_mm: row.try_get(4)?,
        dy_mm: row.try_get(5)?,
        dz_mm: row.try_get(6)?,
        d_mm: row.try_get(7)?,
        sigma_dx_mm: row.try_get(8)?,
        sigma_dy_mm: row.try_get(9)?,
        sigma_dz_mm: row.try_get(10)?,
        sigma_mm: row.try_get(11)?,
        d_along_mm: row.try_get(12)?,
        significant: row.try_get(13)?,
        velocity_mm_per_day: row.try_get(14)?,
        time_to_failure_hours: row.try_get(15)?,
        cov_dxdy_mm2: row.try_get(16)?,
        cov_dxdz_mm2: row.try_get(17)?,
        cov_dydz_mm2: row.try_get(18)?,
        ..Displacement::default()
    })
}

/// A row of [`HISTORY_COLUMNS`] read through the C API (the columns not read stay `None`).
fn history_row(row: &sqlite_raw::Row) -> Displacement {
    let text = |i| String::from_utf8_lossy(row.text(i)).into_owned();
    Displacement {
        point: text(0),
        epoch: row.int(1),
        observed_at: text(2),
        reference_epoch: row.int(3),
        dx_mm: row.double(4),
        dy_mm: row.double(5),
        dz_mm: row.double(6),
        d_mm: row.double(7),
        sigma_dx_mm: row.double(8),
        sigma_dy_mm: row.double(9),
        sigma_dz_mm: row.double(10),
        sigma_mm: row.double(11),
        d_along_mm: row.opt_double(12),
        significant: row.int(13) != 0,
        velocity_mm_per_day: row.opt_double(14),
        time_to_failure_hours: row.opt_double(15),
        cov_dxdy_mm2: row.opt_double(16),
        cov_dxdz_mm2: row.opt_double(17),
        cov_dydz_mm2: row.opt_double(18),
        ..Displacement::default()
    }
}

/// The displacements of one epoch.
///
/// SQLite, without statistics, read them through the primary key (site, point, time), that is
/// every displacement of the site (2 ms for 45 epochs of 28 points, growing with the history),
/// rather than through `displacements_by_epoch`: the index is named there (`INDEXED BY`,
/// SQLite's syntax; PostgreSQL's planner has statistics and needs no hint).
pub async fn of_epoch(
    db: &mut AnyConnection,
    site: &str,
    epoch: i64,
) -> Result<Vec<Displacement>, StoreError> {
    let columns = select_list(COLUMNS, "");
    let hint = if super::is_postgres(db) {
        ""
    } else {
        "INDEXED BY displacements_by_epoch "
    };
    let rows: Vec<Displacement> = sqlx::query_as(&format!(
        "SELECT {columns} FROM displacements {hint}WHERE site_id = $1 AND epoch_id = $2 ORDER BY point"
    ))
    .bind(site)
    .bind(epoch)
    .fetch_all(db)
    .await?;
    Ok(display(rows))
}

/// The latest displacement of every point of the site: one index seek per point however long
/// the history, on SQLite with the points as the outer loop of the `CROSS JOIN`, on PostgreSQL
/// with each point's newest row read `LATERAL`ly (as [`super::points::latest_coordinates`]).
pub async fn latest(db: &mut AnyConnection, site: &str) -> Result<Vec<Displacement>, StoreError> {
    let cols = select_list(COLUMNS, "d.");
    let sql = if super::is_postgres(db) {
        format!(
            "SELECT {cols} FROM points p CROSS JOIN LATERAL (SELECT * FROM displacements d2 \
             WHERE d2.site_id = p.site_id AND d2.point = p.name ORDER BY d2.observed_at DESC LIMIT 1) d \
             WHERE p.site_id = $1"
        )
    } else {
        format!(
            "SELECT {cols} FROM points p CROSS JOIN displacements d \
             WHERE p.site_id = $1 AND d.site_id = p.site_id AND d.point = p.name AND d.observed_at = \
             (SELECT MAX(d2.observed_at) FROM displacements d2 WHERE d2.site_id = p.site_id AND d2.point = p.name)"
        )
    };
    let rows: Vec<Displacement> = sqlx::query_as(&sql).bind(site).fetch_all(db).await?;
    Ok(display(rows))
}

/// The displacement of `point` in the latest epoch observed before `before` (store format):
/// `(observed_at, d_mm)`, for the velocity.
pub async fn previous(
    db: impl AnyExecutor<'_>,
    site: &str,
    point: &str,
    before: &str,
) -> Result<Option<(String, f64)>, StoreError> {
    Ok(sqlx::query_as(
        "SELECT observed_at, d_mm FROM displacements WHERE site_id = $1 AND point = $2 AND observed_at < $3 \
         ORDER BY observed_at DESC LIMIT 1",
    )
    .bind(site)
    .bind(point)
    .bind(before)
    .fetch_optional(db)
    .await?)
}

//! Copying a whole installation from one store to another (SQLite ↔ PostgreSQL, `cliffwatch
//! migrate-store`): every table, parents first, in one transaction on the target, which must be
//! empty. Each table's columns are listed here with their kind, and checked against the two
//! databases before anything is copied, so a column added later cannot be dropped silently.

use futures_util::TryStreamExt;
use sqlx::{AnyConnection, Row};

use super::{Backend, Store, StoreError};

/// The kind of a column's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Text.
    T,
    /// 64-bit integer.
    I,
    /// Double.
    F,
    /// Boolean (read as `CAST(… AS INTEGER)`, see [`super::Flag`]).
    B,
    /// Bytes.
    X,
}
use Kind::{B, F, I, T, X};

/// The columns of the displacement series tables after the name column.
const SERIES: [(&str, Kind); 33] = [
    ("epoch_id", I),
    ("observed_at", T),
    ("reference_epoch", I),
    ("dx_mm", F),
    ("dy_mm", F),
    ("dz_mm", F),
    ("d_mm", F),
    ("sigma_dx_mm", F),
    ("sigma_dy_mm", F),
    ("sigma_dz_mm", F),
    ("sigma_mm", F),
    ("d_along_mm", F),
    ("significant", B),
    ("velocity_mm_per_day", F),
    ("time_to_failure_hours", F),
    ("cov_dxdy_mm2", F),
    ("cov_dxdz_mm2", F),
    ("cov_dydz_mm2", F),
    ("time_to_failure_sigma_hours", F),
    ("f_dx_mm", F),
    ("f_dy_mm", F),
    ("f_dz_mm", F),
    ("f_d_mm", F),
    ("sigma_f_dx_mm", F),
    ("sigma_f_dy_mm", F),
    ("sigma_f_dz_mm", F),
    ("sigma_f_d_mm", F),
    ("f_velocity_mm_per_day", F),
    ("sigma_f_velocity_mm_per_day", F),
    ("f_acceleration_mm_per_day2", F),
    ("sigma_f_acceleration_mm_per_day2", F),
    ("f_time_to_failure_hours", F),
    ("sigma_f_time_to_failure_hours", F),
];

/// Every table, parents before children, with its columns (the series tables' are [`SERIES`]
/// after `site_id` and their name column). Not `sessions` ([`super::sessions`]): a dashboard
/// session is a sign-in on the old installation; after the move staff sign in again, and no
/// cookie issued before it stays valid.
const TABLES: &[(&str, &[(&str, Kind)])] = &[
    (
        "sites",
        &[
            ("id", T),
            ("name", T),
            ("model", T),
            ("schedule_hours", F),
            ("confidence", F),
            ("alert_rules", T),
            ("reference_epoch", I),
            ("created_at", T),
            ("reference_epochs", I),
            ("process_noise", F),
            ("analysis_version", I),
            ("time_zone", T),
            ("area", T),
            ("response_text", T),
            ("contacts", T),
            ("image_weights", T),
            ("frame", T),
            ("apriori_sigma", T),
            ("detection", T),
            ("retired_at", T),
            ("retired_reason", T),
            ("exported_at", T),
        ],
    ),
    (
        "cameras",
        &[
            ("site_id", T),
            ("id", T),
            ("definition", T),
            ("updated_at", T),
        ],
    ),
    (
        "stations",
        &[("site_id", T), ("name", T), ("first_epoch", I)],
    ),
    (
        "points",
        &[
            ("site_id", T),
            ("name", T),
            ("role", T),
            ("grp", T),
            ("dir_x", F),
            ("dir_y", F),
            ("dir_z", F),
        ],
    ),
    (
        "groups",
        &[
            ("site_id", T),
            ("name", T),
            ("kind", T),
            ("direction", T),
            ("points", T),
            ("process_noise", F),
            ("updated_at", T),
        ],
    ),
    (
        "epochs",
        &[
            ("site_id", T),
            ("id", I),
            ("observed_at", T),
            ("label", T),
            ("status", T),
            ("model", T),
            ("sigma0_mm", F),
            ("c_mm", F),
            ("c_sigma_mm", F),
            ("iterations", I),
            ("dropped_observations", I),
            ("body_sha256", T),
            ("cameras", T),
            ("report", T),
            ("created_at", T),
            ("observations_pruned_at", T),
            ("variance_factor", F),
            ("dof", I),
            ("variance_components", T),
        ],
    ),
    (
        "images",
        &[
            ("site_id", T),
            ("epoch_id", I),
            ("id", T),
            ("camera", T),
            ("station", T),
            ("seq", I),
        ],
    ),
    (
        "observations",
        &[
            ("site_id", T),
            ("epoch_id", I),
            ("image_id", T),
            ("point", T),
            ("seq", I),
            ("x_mm", F),
            ("y_mm", F),
            ("col_px", F),
            ("row_px", F),
            ("vx_mm", F),
            ("vy_mm", F),
            ("w", F),
            ("dropped", B),
        ],
    ),
    (
        "coordinates",
        &[
            ("site_id", T),
            ("epoch_id", I),
            ("point", T),
            ("observed_at", T),
            ("x_m", F),
            ("y_m", F),
            ("z_m", F),
            ("cxx_m2", F),
            ("cxy_m2", F),
            ("cxz_m2", F),
            ("cyy_m2", F),
            ("cyz_m2", F),
            ("czz_m2", F),
        ],
    ),
    (
        "joint_covariances",
        &[
            ("site_id", T),
            ("epoch_id", I),
            ("points", T),
            ("matrix_m2", T),
            ("upper_m2", X),
        ],
    ),
    ("displacements", &[]),
    ("block_motions", &[]),
    (
        "pooled_forecasts",
        &[
            ("site_id", T),
            ("epoch_id", I),
            ("point", T),
            ("pooled_with", T),
        ],
    ),
    (
        "series_blocks",
        &[
            ("site_id", T),
            ("point", T),
            ("last_at", T),
            ("first_at", T),
            ("n_rows", I),
            ("extremes", X),
            ("data", X),
        ],
    ),
    (
        "series_seals",
        &[("site_id", T), ("sealed_until", T), ("pending", I)],
    ),
    (
        "alerts",
        &[
            ("id", T),
            ("site_id", T),
            ("point", T),
            ("points", T),
            ("level", T),
            ("rule", T),
            ("value", F),
            ("threshold", F),
            ("unit", T),
            ("epoch_id", I),
            ("observed_at", T),
            ("message", T),
            ("state", T),
            ("raised_at", T),
            ("updated_at", T),
            ("acknowledged_by", T),
            ("ack_comment", T),
            ("group_name", T),
            ("raised_epoch_id", I),
            ("raised_observed_at", T),
        ],
    ),
    (
        "alert_states",
        &[("site_id", T), ("state", T), ("updated_at", T)],
    ),
    (
        "webhooks",
        &[
            ("id", T),
            ("url", T),
            ("secret", T),
            ("min_level", T),
            ("source", T),
            ("created_at", T),
            ("enabled", B),
            ("format", T),
        ],
    ),
    (
        "audit",
        &[
            ("id", T),
            ("site_id", T),
            ("at", T),
            ("actor", T),
            ("source", T),
            ("action", T),
            ("target", T),
            ("value_before", T),
            ("value_after", T),
        ],
    ),
    (
        "webhook_outbox",
        &[
            ("id", T),
            ("event_type", T),
            ("alert_id", T),
            ("level", T),
            ("payload", T),
            ("created_at", T),
            ("epoch_id", I),
        ],
    ),
    (
        "webhook_deliveries",
        &[
            ("outbox_id", T),
            ("webhook_id", T),
            ("state", T),
            ("attempts", I),
            ("next_attempt_at", T),
            ("last_status", I),
            ("last_error", T),
            ("delivered_at", T),
            ("payload", T),
        ],
    ),
    (
        "watch_orientations",
        &[
            ("site_id", T),
            ("station", T),
            ("camera", T),
            ("rotation", T),
            ("center", T),
            ("epoch_id", I),
            ("updated_at", T),
        ],
    ),
    (
        "watch_folders",
        &[
            ("site_id", T),
            ("hash", T),
            ("epoch_id", I),
            ("taken_at", T),
        ],
    ),
];

/// The columns of `table`.
fn columns(table: &str, listed: &[(&'static str, Kind)]) -> Vec<(&'static str, Kind)> {
    let name = match table {
        "displacements" => "point",
        "block_motions" => "block",
        _ => return listed.to_vec(),
    };
    let mut out = vec![("site_id", T), (name, T)];
    out.extend(SERIES);
    out
}

/// Number of columns `table` has in the database of `conn`.
async fn column_count(
    conn: &mut AnyConnection,
    backend: Backend,
    table: &str,
) -> Result<i64, StoreError> {
    let sql = match backend {
        Backend::Sqlite => "SELECT COUNT(*) FROM pragma_table_info($1)",
        Backend::Postgres => {
            "SELECT COUNT(*) FROM information_schema.columns \
             WHERE table_schema = current_schema() AND table_name = $1"
        }
    };
    Ok(sqlx::query_scalar(sql)
        .bind(table)
        .fetch_one(&mut *conn)
        .await?)
}

/// Rows read from the source and inserted into the target at a time: what is held in memory
/// (a few MB even for the packed series blocks), whatever the size of the installation.
const COPY_CHUNK_ROWS: usize = 500;

/// Rows copied per table, in copy order.
pub type Copied = Vec<(&'static str, u64)>;

/// Copies every row of `from` into `to`, whose tables must all be empty, in one transaction on
/// `to` (nothing is written when anything fails). The source is read in one read transaction,
/// one snapshot (PostgreSQL: repeatable read), so an epoch committed during the copy is copied
/// whole or not at all. Each table is streamed, [`COPY_CHUNK_ROWS`] rows per multi-row insert, so
/// memory stays flat however large the installation. Stop the daemons of both first.
pub async fn copy_all(from: &Store, to: &Store) -> Result<Copied, StoreError> {
    let mut read = from.read().await?;
    let mut source = sqlx::Connection::begin(&mut *read).await?;
    if from.backend() == Backend::Postgres {
        sqlx::query("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ, READ ONLY")
            .execute(&mut *source)
            .await?;
    }
    let mut tx = to.begin_write().await?;
    for (table, _) in TABLES {
        let existing: i64 = sqlx::query_scalar(&format!("SELECT COUNT(*) FROM {table}"))
            .fetch_one(&mut *tx)
            .await?;
        if existing > 0 {
            return Err(StoreError::Corrupt(format!(
                "the target's table {table} holds {existing} row(s): migrate-store copies into \
                 an empty store only"
            )));
        }
    }
    for (table, listed) in TABLES {
        let cols = columns(table, listed);
        for (conn, backend) in [(&mut *source, from.backend()), (&mut *tx, to.backend())] {
            let n = column_count(conn, backend, table).await?;
            if n != cols.len() as i64 {
                return Err(StoreError::Corrupt(format!(
                    "table {table} has {n} columns in the {backend:?} store; this version copies {}",
                    cols.len()
                )));
            }
        }
    }
    let mut copied = Vec::new();
    for (table, listed) in TABLES {
        let cols = columns(table, listed);
        let select: Vec<String> = cols
            .iter()
            .map(|(c, k)| match k {
                B => format!("CAST({c} AS INTEGER) AS {c}"),
                _ => c.to_string(),
            })
            .collect();
        let names: Vec<&str> = cols.iter().map(|(c, _)| *c).collect();
        let per_insert = super::rows_per_insert(cols.len()).min(COPY_CHUNK_ROWS);
        let insert_of = |db: &AnyConnection, rows: usize| {
            format!(
                "INSERT INTO {table} ({}) VALUES {}",
                names.join(", "),
                super::values_list(db, rows, cols.len())
            )
        };
        let full_insert = insert_of(&tx, per_insert);
        let read_all = format!("SELECT {} FROM {table}", select.join(", "));
        let mut rows = sqlx::query(&read_all).fetch(&mut *source);
        let mut chunk = Vec::with_capacity(per_insert);
        let mut n = 0u64;
        loop {
            let row = rows.try_next().await?;
            let done = row.is_none();
            chunk.extend(row);
            if chunk.len() == per_insert || (done && !chunk.is_empty()) {
                let last = (chunk.len() < per_insert).then(|| insert_of(&tx, chunk.len()));
                let mut q = sqlx::query(last.as_deref().unwrap_or(&full_insert));
                for row in &chunk {
                    for (i, (_, kind)) in cols.iter().enumerate() {
                        q = match kind {
                            T => q.bind(row.try_get::<Option<String>, _>(i)?),
                            I => q.bind(row.try_get::<Option<i64>, _>(i)?),
                            F => q.bind(row.try_get::<Option<f64>, _>(i)?),
                            B => q.bind(row.try_get::<Option<i64>, _>(i)?.map(|v| v != 0)),
                            X => q.bind(row.try_get::<Option<Vec<u8>>, _>(i)?),
                        };
                    }
                }
                q.execute(&mut *tx).await?;
                n += chunk.len() as u64;
                chunk.clear();
            }
            if done {
                break;
            }
        }
        copied.push((*table, n));
    }
    tx.commit().await?;
    source.rollback().await?;
    Ok(copied)
}

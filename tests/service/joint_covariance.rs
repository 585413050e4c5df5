//! The joint covariance is stored as its upper triangle in binary; the rows an older version
//! stored as JSON text survive the migration and are still read.

use std::borrow::Cow;

use cliffwatch::store::{joint_covariances, Store, StoreOptions, SQLITE_MIGRATOR};
use sqlx::sqlite::{SqliteConnectOptions, SqlitePoolOptions};

/// The first migration that stores the matrix in binary.
const BINARY_VERSION: i64 = 20261126001400;

/// A symmetric 6 × 6 matrix (two points), m².
fn matrix() -> Vec<f64> {
    let n = 6;
    let mut m = vec![0.0; n * n];
    for i in 0..n {
        for j in i..n {
            let v = if i == j {
                1.0 + i as f64
            } else {
                0.125 * (i + j) as f64 - 0.5
            };
            m[i * n + j] = v * 1e-6;
            m[j * n + i] = v * 1e-6;
        }
    }
    m
}

async fn insert_epoch(pool: &sqlx::SqlitePool, id: i64) {
    sqlx::query(
        "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, body_sha256, cameras, report, created_at) \
         VALUES ('s', ?, ?, 'adjusted', 'orthogonal', 0.001, 3, ?, '[]', '{}', '2026-01-01T00:00:00.000000Z')",
    )
    .bind(id)
    .bind(format!("2026-01-0{id}T00:00:00.000000Z"))
    .bind(format!("{id:064}"))
    .execute(pool)
    .await
    .unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn json_rows_of_an_older_database_survive_the_migration_and_binary_rows_read_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cliffwatch.db");
    // The database as the version before the binary column left it, with one JSON row.
    let before = sqlx::migrate::Migrator {
        migrations: Cow::Owned(
            SQLITE_MIGRATOR
                .iter()
                .filter(|m| m.version < BINARY_VERSION)
                .cloned()
                .collect(),
        ),
        ignore_missing: false,
        locking: true,
        no_tx: false,
    };
    assert!(before.iter().count() < SQLITE_MIGRATOR.iter().count());
    let pool = SqlitePoolOptions::new()
        .max_connections(1)
        .connect_with(
            SqliteConnectOptions::new()
                .filename(&path)
                .create_if_missing(true)
                .foreign_keys(true),
        )
        .await
        .unwrap();
    before.run(&pool).await.unwrap();
    sqlx::query(
        "INSERT INTO sites (id, name, created_at) VALUES ('s', 'S', '2026-01-01T00:00:00.000000Z')",
    )
    .execute(&pool)
    .await
    .unwrap();
    insert_epoch(&pool, 1).await;
    insert_epoch(&pool, 2).await;
    sqlx::query(
        "INSERT INTO joint_covariances (site_id, epoch_id, points, matrix_m2) VALUES ('s', 1, '[\"A\",\"B\"]', ?)",
    )
    .bind(serde_json::to_string(&matrix()).unwrap())
    .execute(&pool)
    .await
    .unwrap();
    pool.close().await;

    // This version opens it, migrates, and reads the old row.
    let store = Store::open(&path, &StoreOptions::default()).await.unwrap();
    let old = joint_covariances::get(store.reader(), "s", 1)
        .await
        .unwrap()
        .expect("the JSON row");
    assert_eq!(old.points, ["A", "B"]);
    // serde_json's text-to-f64 is not always exact: within an ulp or two.
    assert_eq!(old.matrix_m2.len(), 36);
    assert!(old
        .matrix_m2
        .iter()
        .zip(matrix())
        .all(|(a, b)| (a - b).abs() <= 4.0 * f64::EPSILON * b.abs()));

    // A new row is the upper triangle in binary, read back bit for bit.
    let points = vec!["A".to_string(), "B".to_string()];
    let mut tx = store.begin_write().await.unwrap();
    joint_covariances::insert(&mut *tx, "s", 2, &points, &matrix())
        .await
        .unwrap();
    tx.commit().await.unwrap();
    let (bytes, json): (i64, Option<String>) = sqlx::query_as(
        "SELECT length(upper_m2), matrix_m2 FROM joint_covariances WHERE epoch_id = 2",
    )
    .fetch_one(store.reader())
    .await
    .unwrap();
    assert_eq!((bytes, json), (21 * 8, None));
    let new = joint_covariances::get(store.reader(), "s", 2)
        .await
        .unwrap()
        .expect("the binary row");
    assert_eq!(new.points, points);
    assert!(new
        .matrix_m2
        .iter()
        .zip(matrix())
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // An epoch without one has none.
    assert!(joint_covariances::get(store.reader(), "s", 3)
        .await
        .unwrap()
        .is_none());
    store.close().await;
}

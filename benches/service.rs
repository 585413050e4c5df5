//! Service benchmarks (figures in `docs/performance.md`, section "Service"):
//! - `upload_5x28` (`_postgres`): upload of a 5-image × 28-point epoch, end to end over HTTP
//!   (parse, validate, adjust, store in one transaction, answer the summary), on SQLite and on
//!   PostgreSQL (a throwaway cluster, `tests/support/pg.rs`);
//! - `uploads_30/*`: 30 such uploads by 6 concurrent clients to 6 sites, over 1 node (SQLite,
//!   PostgreSQL) or 2 and 3 nodes on one PostgreSQL database: uploads per second;
//! - `series_87600/*`: the displacement time series of one point of a site with 87 600 epochs
//!   (10 years hourly) × 30 points: as CSV (whole series, streamed), the CSV's store part alone
//!   (read and format, no HTTP), one JSON page of 1000, and every JSON page following the cursor;
//! - `series_87600_postgres/*`: the same store part, the JSON page and every JSON page on
//!   PostgreSQL (a throwaway cluster, `tests/support/pg.rs`);
//! - `dashboard/*`: server time of the site page (30 points) and of the point page's plot data
//!   (downsampled to 800 px) on a site of 87 600 epochs and on one of 40, and the weight of each
//!   page with its embedded assets, gzip (printed);
//! - the database size per 10 000 epochs of 30 points (printed, from `CLIFFWATCH_BENCH_SIZE_EPOCHS`
//!   real uploads, default 500, scaled linearly).

#[path = "../tests/support/mod.rs"]
mod support;

use std::cell::Cell;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use support::server::{synthetic_epoch, TestServer};

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn observed_at(k: usize) -> String {
    let t = chrono::DateTime::parse_from_rfc3339("2020-01-01T00:00:00Z").unwrap()
        + chrono::Duration::hours(k as i64);
    t.to_rfc3339_opts(chrono::SecondsFormat::Secs, true)
}

fn upload(c: &mut Criterion) {
    upload_on(c, "service/upload_5x28", None);
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("upload");
    upload_on(c, "service/upload_5x28_postgres", Some(url));
}

fn upload_on(c: &mut Criterion, name: &str, database_url: Option<String>) {
    let rt = runtime();
    let server = rt.block_on(TestServer::start(move |c| c.database_url = database_url));
    rt.block_on(server.create_site("bench"));
    let k = Cell::new(0usize);
    c.bench_function(name, |b| {
        b.iter_batched(
            || {
                k.set(k.get() + 1);
                serde_json::to_vec(&synthetic_epoch(
                    5,
                    28,
                    &observed_at(k.get()),
                    k.get() as u64,
                    0.0,
                    28,
                ))
                .unwrap()
            },
            |body| {
                rt.block_on(async {
                    let (status, len) = server.upload_bytes("bench", body).await;
                    assert_eq!(status, 201);
                    len
                })
            },
            criterion::BatchSize::SmallInput,
        )
    });
    let _ = rt.block_on(server.stop());
}

/// Sites and concurrent clients of the throughput benchmark; each iteration uploads
/// `THROUGHPUT_SITES × THROUGHPUT_ROUNDS` new 5 × 28 epochs.
const THROUGHPUT_SITES: usize = 6;
const THROUGHPUT_ROUNDS: usize = 5;

/// Uploads per second: 6 clients, one per site, each uploading 5 epochs in a row, spread over 1,
/// 2 or 3 nodes (in this process, so on this machine's 2 cores) on one database.
fn throughput(c: &mut Criterion) {
    let cluster = support::pg::PgCluster::start();
    let mut g = c.benchmark_group("service/uploads_30");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    let cases: Vec<(&str, usize, Option<String>)> = vec![
        ("sqlite_1_node", 1, None),
        ("postgres_1_node", 1, Some(cluster.create_database("t1"))),
        ("postgres_2_nodes", 2, Some(cluster.create_database("t2"))),
        ("postgres_3_nodes", 3, Some(cluster.create_database("t3"))),
    ];
    for (name, nodes, url) in cases {
        let rt = runtime();
        let servers: Vec<TestServer> = (0..nodes)
            .map(|_| {
                let url = url.clone();
                rt.block_on(TestServer::start(move |c| c.database_url = url))
            })
            .collect();
        for s in 0..THROUGHPUT_SITES {
            rt.block_on(servers[0].create_site(&format!("t{s}")));
        }
        let next = Cell::new(0usize);
        g.bench_function(name, |b| {
            b.iter(|| {
                let round = next.get();
                next.set(round + THROUGHPUT_ROUNDS);
                rt.block_on(async {
                    let mut tasks = Vec::new();
                    for s in 0..THROUGHPUT_SITES {
                        let server = &servers[s % nodes];
                        let (client, url) = (
                            server.client.clone(),
                            server.url(&format!("/api/v1/sites/t{s}/epochs")),
                        );
                        tasks.push(tokio::spawn(async move {
                            for k in round..round + THROUGHPUT_ROUNDS {
                                let body =
                                    synthetic_epoch(5, 28, &observed_at(k), k as u64, 0.0, 28);
                                let r = client.post(&url).json(&body).send().await.unwrap();
                                assert_eq!(r.status(), 201);
                            }
                        }));
                    }
                    for t in tasks {
                        t.await.unwrap();
                    }
                })
            })
        });
        for s in servers {
            let _ = rt.block_on(s.stop());
        }
    }
    g.finish();
}

/// The report every bench epoch stores: what an adjustment's report always holds, nothing more.
const REPORT: &str = r#"{"converged":true,"dof":250,"variance_factor":1.0,"cameras":[],"points":[],"images":[],"dropped":[],"warnings":[]}"#;

/// Fills a site with `epochs` hourly epochs × `points` points of displacements with covariances
/// and filtered values (as an analysis stores them), directly in SQL
/// (bench set-up only: no adjustment), then packs the series (`series_blocks::rebuild`).
async fn fill_history(server: &TestServer, site: &str, epochs: usize, points: usize) {
    server.create_site(site).await;
    let mut tx = server.store.begin_write().await.unwrap();
    for p in 0..points {
        sqlx::query("INSERT INTO points (site_id, name, role) VALUES (?, ?, 'monitored')")
            .bind(site)
            .bind(format!("T{:03}", p + 1))
            .execute(&mut *tx)
            .await
            .unwrap();
    }
    sqlx::query(&
        "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, body_sha256, cameras, report, created_at) \
         WITH RECURSIVE seq(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM seq WHERE n < ?) \
         SELECT ?, n, strftime('%Y-%m-%dT%H:%M:%S.000000Z', '2015-01-01', '+' || n || ' hours'), 'adjusted', 'orthogonal', 0.001, 5, \
         printf('%064d', n), '[]', '{REPORT}', '2026-01-01T00:00:00.000000Z' FROM seq"
        .replace("{REPORT}", REPORT),
    )
    .bind(epochs as i64).bind(site).execute(&mut *tx).await.unwrap();
    sqlx::query(
        "INSERT INTO displacements (site_id, epoch_id, point, observed_at, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
         sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, d_along_mm, significant, velocity_mm_per_day, time_to_failure_hours, \
         cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2, f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, sigma_f_dy_mm, \
         sigma_f_dz_mm, sigma_f_d_mm, f_velocity_mm_per_day, sigma_f_velocity_mm_per_day, f_acceleration_mm_per_day2, \
         sigma_f_acceleration_mm_per_day2) \
         SELECT e.site_id, e.id, p.name, e.observed_at, 1, e.id * 0.0001, -e.id * 0.0002, e.id * 0.00005, e.id * 0.000229, \
         0.11, 0.12, 0.31, 0.2, NULL, e.id > 100, 0.0055, NULL, 0.0012, -0.0031, 0.021, \
         e.id * 0.0000998, -e.id * 0.0001997, e.id * 0.0000501, e.id * 0.0002287, 0.051, 0.056, 0.143, 0.093, \
         0.0054, 0.0021, 0.00001 * (e.id % 17), 0.0004 FROM epochs e CROSS JOIN points p \
         WHERE e.site_id = ? AND p.site_id = ?",
    )
    .bind(site).bind(site).execute(&mut *tx).await.unwrap();
    // the rows went in by SQL: pack the series as ingestion would have
    cliffwatch::store::series::blocks::rebuild(&mut tx, site)
        .await
        .unwrap();
    tx.commit().await.unwrap();
}

/// [`fill_history`] on PostgreSQL (`generate_series`, `to_char`).
async fn fill_history_postgres(server: &TestServer, site: &str, epochs: usize, points: usize) {
    server.create_site(site).await;
    let mut tx = server.store.begin_write().await.unwrap();
    sqlx::query(
        "INSERT INTO points (site_id, name, role) \
         SELECT $1, 'T' || lpad(n::text, 3, '0'), 'monitored' FROM generate_series(1, $2) n",
    )
    .bind(site)
    .bind(points as i64)
    .execute(&mut *tx)
    .await
    .unwrap();
    sqlx::query(&
        "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, body_sha256, cameras, report, created_at) \
         SELECT $1, n, to_char(timestamp '2015-01-01' + n * interval '1 hour', 'YYYY-MM-DD\"T\"HH24:MI:SS.US\"Z\"'), \
         'adjusted', 'orthogonal', 0.001, 5, lpad(n::text, 64, '0'), '[]', '{REPORT}', '2026-01-01T00:00:00.000000Z' \
         FROM generate_series(1, $2) n"
        .replace("{REPORT}", REPORT),
    )
    .bind(site).bind(epochs as i64).execute(&mut *tx).await.unwrap();
    sqlx::query(
        "INSERT INTO displacements (site_id, epoch_id, point, observed_at, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
         sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, d_along_mm, significant, velocity_mm_per_day, time_to_failure_hours, \
         cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2, f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, sigma_f_dy_mm, \
         sigma_f_dz_mm, sigma_f_d_mm, f_velocity_mm_per_day, sigma_f_velocity_mm_per_day, f_acceleration_mm_per_day2, \
         sigma_f_acceleration_mm_per_day2) \
         SELECT e.site_id, e.id, p.name, e.observed_at, 1, e.id * 0.0001, -e.id * 0.0002, e.id * 0.00005, e.id * 0.000229, \
         0.11, 0.12, 0.31, 0.2, NULL, e.id > 100, 0.0055, NULL, 0.0012, -0.0031, 0.021, \
         e.id * 0.0000998, -e.id * 0.0001997, e.id * 0.0000501, e.id * 0.0002287, 0.051, 0.056, 0.143, 0.093, \
         0.0054, 0.0021, 0.00001 * (e.id % 17), 0.0004 FROM epochs e CROSS JOIN points p \
         WHERE e.site_id = $1 AND p.site_id = $2",
    )
    .bind(site).bind(site).execute(&mut *tx).await.unwrap();
    cliffwatch::store::series::blocks::rebuild(&mut tx, site)
        .await
        .unwrap();
    tx.commit().await.unwrap();
}

/// The store part of the whole CSV series of `long`/T017 (read, format, collect the chunks).
async fn csv_store_only(server: &TestServer) {
    let q = cliffwatch::store::series::SeriesQuery {
        site: "long".into(),
        point: "T017".into(),
        ..Default::default()
    };
    let mut rx = cliffwatch::store::series::stream_csv(&server.store, q)
        .await
        .unwrap();
    let mut lines = 0;
    while let Some(chunk) = rx.recv().await {
        lines += chunk.unwrap().iter().filter(|&&c| c == b'\n').count();
    }
    assert_eq!(lines, 87_601);
}

fn series_postgres(c: &mut Criterion) {
    let rt = runtime();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("bench");
    let server = rt.block_on(TestServer::start(move |c| c.database_url = Some(url)));
    rt.block_on(fill_history_postgres(&server, "long", 87_600, 30));
    let mut g = c.benchmark_group("service/series_87600_postgres");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    g.bench_function("csv_all_store_only", |b| {
        b.iter(|| rt.block_on(csv_store_only(&server)))
    });
    g.bench_function("json_page_1000", |b| {
        b.iter(|| rt.block_on(json_page_1000(&server)))
    });
    g.sample_size(10);
    g.bench_function("json_all_pages", |b| {
        b.iter(|| rt.block_on(json_all_pages(&server)))
    });
    g.finish();
    let _ = rt.block_on(server.stop());
}

/// One JSON page of 1000 rows of `long`/T017 from 2020 on, the client reads every byte.
async fn json_page_1000(server: &TestServer) {
    let url = server.url("/api/v1/sites/long/points/T017/displacements?limit=1000&from=2020-01-01");
    let body = server
        .client
        .get(&url)
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    assert!(body.len() > 1000);
}

/// The whole series of `long`/T017 as JSON: every page of 1000 (the contract's largest),
/// following the cursor, each parsed by the client.
async fn json_all_pages(server: &TestServer) {
    let first = server.url("/api/v1/sites/long/points/T017/displacements?limit=1000");
    let mut url = first.clone();
    let mut rows = 0;
    loop {
        let page: serde_json::Value = server
            .client
            .get(&url)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        rows += page["items"].as_array().unwrap().len();
        match page["next_cursor"].as_str() {
            Some(c) => url = format!("{first}&cursor={c}"),
            None => break,
        }
    }
    assert_eq!(rows, 87_600);
}

fn series(c: &mut Criterion) {
    let rt = runtime();
    let server = rt.block_on(TestServer::start(|_| {}));
    rt.block_on(fill_history(&server, "long", 87_600, 30));
    let csv = server.url("/api/v1/sites/long/points/T017/displacements?format=csv");
    let mut g = c.benchmark_group("service/series_87600");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    g.bench_function("csv_all", |b| {
        b.iter(|| {
            rt.block_on(async {
                let body = server
                    .client
                    .get(&csv)
                    .send()
                    .await
                    .unwrap()
                    .bytes()
                    .await
                    .unwrap();
                assert_eq!(body.iter().filter(|&&c| c == b'\n').count(), 87_601);
            })
        })
    });
    g.bench_function("json_page_1000", |b| {
        b.iter(|| rt.block_on(json_page_1000(&server)))
    });
    // the store's part of the CSV alone (no HTTP): read, format in batches, collect the chunks
    g.bench_function("csv_all_store_only", |b| {
        b.iter(|| rt.block_on(csv_store_only(&server)))
    });
    // the whole series as JSON: every page of 1000 (the contract's largest), following the cursor
    g.sample_size(10);
    g.bench_function("json_all_pages", |b| {
        b.iter(|| rt.block_on(json_all_pages(&server)))
    });
    g.finish();
    let _ = rt.block_on(server.stop());
}

/// gzip size of `bytes` (default level), in bytes.
fn gzip_len(bytes: &[u8]) -> usize {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap().len()
}

fn dashboard(c: &mut Criterion) {
    let rt = runtime();
    let server = rt.block_on(TestServer::start(|_| {}));
    rt.block_on(fill_history(&server, "long", 87_600, 30));
    rt.block_on(fill_history(&server, "short", 40, 30));
    let get = |path: &str| {
        let url = server.url(path);
        rt.block_on(async {
            let r = server.client.get(&url).send().await.unwrap();
            assert_eq!(r.status(), 200, "{url}");
            r.bytes().await.unwrap()
        })
    };
    let mut g = c.benchmark_group("dashboard");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for (name, path) in [
        ("site_page_30_points/87600_epochs", "/sites/long"),
        ("site_page_30_points/40_epochs", "/sites/short"),
        (
            "plot_data_800px/87600_epochs",
            "/dashboard/plot/long/T017?width=800",
        ),
        (
            "plot_data_800px/40_epochs",
            "/dashboard/plot/short/T017?width=800",
        ),
        ("point_page/87600_epochs", "/sites/long/points/T017"),
    ] {
        g.bench_function(name, |b| b.iter(|| get(path)));
    }
    // The store part of the long plot: the read of the blocks' extremes, each record decoded.
    let query = cliffwatch::store::series::SeriesQuery {
        site: "long".into(),
        point: "T017".into(),
        extremes_above: Some(200 * cliffwatch::store::series::blocks::BLOCK_EPOCHS),
        ..Default::default()
    };
    g.bench_function("plot_read_store_only/87600_epochs", |b| {
        b.iter(|| {
            rt.block_on(cliffwatch::store::series::columns::fold(
                &server.store,
                query.clone(),
                |_| 0usize,
                |n, r| {
                    *n += r.v.len();
                    true
                },
            ))
            .unwrap()
        })
    });
    g.finish();
    // Page weight: the HTML and every embedded asset it links, each gzip-compressed.
    for path in [
        "/",
        "/sites/long",
        "/sites/long/points/T017",
        "/sites/long/epochs/1",
        "/sites/short/report",
    ] {
        let html = get(path);
        let text = String::from_utf8_lossy(&html).to_string();
        let mut assets: Vec<String> = text
            .split(['"', '\''])
            .filter(|s| s.starts_with("/assets/"))
            .map(str::to_string)
            .collect();
        assets.sort();
        assets.dedup();
        let asset_bytes: usize = assets.iter().map(|a| gzip_len(&get(a))).sum();
        println!(
            "page weight {path}: html {} B gzip, assets {} ({} B gzip), total {:.1} kB gzip",
            gzip_len(&html),
            assets.len(),
            asset_bytes,
            (gzip_len(&html) + asset_bytes) as f64 / 1000.0
        );
    }
    let _ = rt.block_on(server.stop());
}

fn database_size(_c: &mut Criterion) {
    let n: usize = std::env::var("CLIFFWATCH_BENCH_SIZE_EPOCHS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(500);
    if n == 0 {
        return;
    }
    let rt = runtime();
    let server = rt.block_on(TestServer::start(|_| {}));
    let path = server.dir.path().join("cliffwatch.db");
    let base = rt.block_on(async {
        server.create_site("size").await;
        let base = std::fs::metadata(&path).unwrap().len();
        upload_size_epochs(&server, n).await;
        // where the bytes are (SQLite's dbstat table: pages per table and index)
        let tables: Vec<(String, i64)> = sqlx::query_as(
            "SELECT name, SUM(pgsize) FROM dbstat GROUP BY name ORDER BY 2 DESC LIMIT 16",
        )
        .fetch_all(server.store.reader())
        .await
        .unwrap();
        for (name, bytes) in tables {
            println!(
                "service/database_size: {name}: {:.1} kB per epoch",
                bytes as f64 / n as f64 / 1000.0
            );
        }
        base
    });
    // Closing the last connection checkpoints the WAL into the file: measure after the stop.
    let dir = rt.block_on(server.stop());
    let keep = dir.path().to_path_buf();
    let mut size = std::fs::metadata(keep.join("cliffwatch.db")).unwrap().len();
    if let Ok(m) = std::fs::metadata(keep.join("cliffwatch.db-wal")) {
        size += m.len();
    }
    let per_10k = (size - base) as f64 / n as f64 * 10_000.0;
    println!(
        "service/database_size: {n} epochs of 5 images x 30 points: {:.1} MiB; per 10 000 epochs: {:.0} MiB ({:.1} kB per epoch)",
        size as f64 / 1048576.0,
        per_10k / 1048576.0,
        per_10k / 10_000.0 / 1000.0
    );
    database_size_postgres(n);
}

/// Uploads `n` real 5 × 30 epochs to site `size`.
async fn upload_size_epochs(server: &TestServer, n: usize) {
    for k in 0..n {
        let epoch = synthetic_epoch(5, 30, &observed_at(k), k as u64, 0.0, 30);
        assert_eq!(server.upload("size", &epoch).await.0, 201);
    }
}

/// [`database_size`] on PostgreSQL: bytes per epoch of every table with its indexes and TOAST
/// (`pg_total_relation_size`), after `VACUUM ANALYZE`.
fn database_size_postgres(n: usize) {
    let rt = runtime();
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("size");
    let server = rt.block_on(TestServer::start(move |c| c.database_url = Some(url)));
    rt.block_on(async {
        server.create_site("size").await;
        upload_size_epochs(&server, n).await;
        sqlx::query("VACUUM ANALYZE")
            .execute(server.store.reader())
            .await
            .unwrap();
        let tables: Vec<(String, i64)> = sqlx::query_as(
            "SELECT relname::text, pg_total_relation_size(relid) FROM pg_catalog.pg_statio_user_tables \
             ORDER BY 2 DESC LIMIT 16",
        )
        .fetch_all(server.store.reader())
        .await
        .unwrap();
        let mut total = 0;
        for (name, bytes) in tables {
            total += bytes;
            println!(
                "service/database_size_postgres: {name}: {:.1} kB per epoch",
                bytes as f64 / n as f64 / 1000.0
            );
        }
        println!(
            "service/database_size_postgres: {n} epochs of 5 images x 30 points: {:.1} kB per epoch",
            total as f64 / n as f64 / 1000.0
        );
    });
    let _ = rt.block_on(server.stop());
}

criterion_group!(
    benches,
    upload,
    throughput,
    series,
    series_postgres,
    dashboard,
    database_size
);
criterion_main!(benches);

//! The displacement time series' fast path (`store::series`: SQLite C API, values formatted straight
//! into the body, the CSV streamed in batches) against the portable sqlx read
//! (`store::displacements::series`) of the same rows: the CSV's values and the JSON pages' bytes.

use crate::support;

use chrono::{DateTime, SecondsFormat, Utc};
use cliffwatch::store::displacements::{self, Displacement};
use cliffwatch::store::series::blocks::{self, BLOCK_EPOCHS};
use cliffwatch::store::series::BATCH_ROWS;
use cliffwatch::store::{display_timestamp, timestamp, Store, StoreOptions};
use serde_json::json;
use support::server::TestServer;

/// Rows spanning three CSV batches and one part-batch.
const ROWS: usize = 2 * BATCH_ROWS + 37;

/// Fills `site`/`P1` (and a neighbour `P2`, which must not leak in) with `ROWS` epochs whose
/// values vary in sign and magnitude (1e-9 … 1e5 mm), NULLs in the optional columns, and times
/// with no fraction, whole milliseconds and microseconds.
async fn fill(s: &TestServer, site: &str) {
    s.create_site(site).await;
    let mut tx = s.store.begin_write().await.unwrap();
    for p in ["P1", "P2"] {
        sqlx::query("INSERT INTO points (site_id, name, role) VALUES (?, ?, 'monitored')")
            .bind(site)
            .bind(p)
            .execute(&mut *tx)
            .await
            .unwrap();
    }
    sqlx::query(
        "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, body_sha256, cameras, report, created_at) \
         WITH RECURSIVE seq(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM seq WHERE n < ?) \
         SELECT ?, n, strftime('%Y-%m-%dT%H:%M:%S', '2015-01-01', '+' || n || ' hours') || \
         printf('.%06dZ', CASE n % 3 WHEN 0 THEN 0 WHEN 1 THEN (n * 1000) % 1000000 ELSE (n * 7) % 1000000 END), \
         'adjusted', 'orthogonal', 0.001, 5, printf('%064d', n), '[]', '{}', '2026-01-01T00:00:00.000000Z' FROM seq",
    )
    .bind(ROWS as i64)
    .bind(site)
    .execute(&mut *tx)
    .await
    .unwrap();
    sqlx::query(
        "INSERT INTO displacements (site_id, epoch_id, point, observed_at, reference_epoch, dx_mm, dy_mm, dz_mm, d_mm, \
         sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, d_along_mm, significant, velocity_mm_per_day, time_to_failure_hours, \
         cov_dxdy_mm2, cov_dxdz_mm2, cov_dydz_mm2) \
         SELECT e.site_id, e.id, p.name, e.observed_at, 1, e.id * 0.0001 * (1 - 2 * (e.id % 2)), \
         CASE WHEN e.id % 5 = 0 THEN 1e-9 * e.id ELSE -e.id * 17.3 END, e.id / 3.0, e.id * 0.000229, \
         0.11, 0.1 + e.id * 1e-7, 0.31, 0.2, NULL, e.id % 2, \
         CASE WHEN e.id % 4 = 0 THEN NULL ELSE 0.0055 * e.id END, \
         CASE WHEN e.id % 7 = 0 THEN 48.0 / e.id ELSE NULL END, \
         CASE WHEN e.id % 3 = 0 THEN NULL ELSE 0.001 * e.id END, -0.0021, 1e-5 * e.id \
         FROM epochs e CROSS JOIN points p WHERE e.site_id = ? AND p.site_id = ?",
    )
    .bind(site)
    .bind(site)
    .execute(&mut *tx)
    .await
    .unwrap();
    // the forecast's σ and the filtered values: absent on some rows, the optional ones on others
    sqlx::query(
        "UPDATE displacements SET \
         time_to_failure_sigma_hours = CASE WHEN epoch_id % 7 = 0 THEN 3.5 / epoch_id ELSE NULL END, \
         f_dx_mm = dx_mm * 0.9, f_dy_mm = -dy_mm, f_dz_mm = 1e-7 * epoch_id, f_d_mm = d_mm * 1.01, \
         sigma_f_dx_mm = 0.05, sigma_f_dy_mm = 0.06 + epoch_id * 1e-9, sigma_f_dz_mm = 0.17, \
         sigma_f_d_mm = 0.1, f_velocity_mm_per_day = -0.003 * epoch_id, sigma_f_velocity_mm_per_day = 0.02, \
         f_acceleration_mm_per_day2 = CASE WHEN epoch_id % 6 = 0 THEN NULL ELSE 1e-4 * epoch_id END, \
         sigma_f_acceleration_mm_per_day2 = CASE WHEN epoch_id % 6 = 0 THEN NULL ELSE 0.001 END, \
         f_time_to_failure_hours = CASE WHEN epoch_id % 11 = 0 THEN 96.0 + epoch_id ELSE NULL END, \
         sigma_f_time_to_failure_hours = CASE WHEN epoch_id % 11 = 0 THEN 7.25 ELSE NULL END \
         WHERE site_id = ? AND epoch_id % 5 <> 2",
    )
    .bind(site)
    .execute(&mut *tx)
    .await
    .unwrap();
    tx.commit().await.unwrap();
}

/// The reference rows through sqlx, with `d_along_mm` as the API defines it.
async fn reference(s: &TestServer, site: &str, direction: Option<[f64; 3]>) -> Vec<Displacement> {
    let mut rows = displacements::series(s.store.reader(), site, "P1", None, None, None, None)
        .await
        .unwrap();
    for d in &mut rows {
        d.d_along_mm = direction.map(|n| {
            let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            (d.dx_mm * n[0] + d.dy_mm * n[1] + d.dz_mm * n[2]) / norm
        });
    }
    rows
}

fn field(v: &str) -> Option<f64> {
    (!v.is_empty()).then(|| v.parse().expect("number"))
}

#[tokio::test]
async fn csv_and_json_pages_equal_the_portable_read() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, "fast").await;
    let direction = [0.0, -2.0, 1.0];
    // Set in the table: the API's PUT would recompute the site from its (absent) coordinates.
    let mut tx = s.store.begin_write().await.unwrap();
    sqlx::query(
        "UPDATE points SET dir_x = ?, dir_y = ?, dir_z = ? WHERE site_id = 'fast' AND name = 'P1'",
    )
    .bind(direction[0])
    .bind(direction[1])
    .bind(direction[2])
    .execute(&mut *tx)
    .await
    .unwrap();
    tx.commit().await.unwrap();
    // rows written by SQL, not packed: the whole series is tail rows
    assert_served_as_stored(&s, "fast", Some(direction), ROWS).await;
    // packed: BLOCK_EPOCHS-epoch blocks, then a tail of the rest
    let mut tx = s.store.begin_write().await.unwrap();
    blocks::rebuild(&mut tx, "fast").await.unwrap();
    tx.commit().await.unwrap();
    let (blocks, sealed): (i64, i64) = sqlx::query_as(
        "SELECT COUNT(*), SUM(n_rows) FROM series_blocks WHERE site_id = 'fast' AND point = 'P1'",
    )
    .fetch_one(s.store.reader())
    .await
    .unwrap();
    assert_eq!(blocks as usize, ROWS / BLOCK_EPOCHS);
    assert_eq!(sealed as usize, ROWS / BLOCK_EPOCHS * BLOCK_EPOCHS);
    assert_served_as_stored(&s, "fast", Some(direction), ROWS).await;
    s.stop().await;
}

/// The CSV and every JSON page of `site`/`P1` against the portable read of the displacements
/// table: the CSV's values parse back to the stored ones, the pages are serde's bytes; a range
/// through both.
async fn assert_served_as_stored(
    s: &TestServer,
    site: &str,
    direction: Option<[f64; 3]>,
    rows: usize,
) {
    let want = reference(s, site, direction).await;
    assert_eq!(want.len(), rows);
    let base = format!("/api/v1/sites/{site}/points/P1/displacements");

    // CSV: every value parses back to the stored one exactly, in order, over several batches
    let r = s
        .client
        .get(s.url(&format!("{base}?format=csv")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let text = r.text().await.unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(cliffwatch::api::points::CSV_HEADER));
    let mut n = 0;
    for (line, d) in lines.zip(&want) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 29, "{line}");
        assert_eq!(f[0].parse::<i64>().unwrap(), d.epoch, "{line}");
        assert_eq!(f[1], d.observed_at, "{line}");
        let values = [
            d.dx_mm,
            d.dy_mm,
            d.dz_mm,
            d.d_mm,
            d.sigma_dx_mm,
            d.sigma_dy_mm,
            d.sigma_dz_mm,
            d.sigma_mm,
        ];
        for (k, v) in values.iter().enumerate() {
            assert_eq!(
                field(f[2 + k]).map(f64::to_bits),
                Some(v.to_bits()),
                "column {} of {line}",
                2 + k
            );
        }
        assert_eq!(field(f[10]), d.d_along_mm, "{line}");
        assert_eq!(f[11], d.significant.to_string(), "{line}");
        assert_eq!(field(f[12]), d.velocity_mm_per_day, "{line}");
        assert_eq!(field(f[13]), d.time_to_failure_hours, "{line}");
        let extra = [
            d.time_to_failure_sigma_hours,
            d.f_dx_mm,
            d.f_dy_mm,
            d.f_dz_mm,
            d.f_d_mm,
            d.sigma_f_dx_mm,
            d.sigma_f_dy_mm,
            d.sigma_f_dz_mm,
            d.sigma_f_d_mm,
            d.f_velocity_mm_per_day,
            d.sigma_f_velocity_mm_per_day,
            d.f_acceleration_mm_per_day2,
            d.sigma_f_acceleration_mm_per_day2,
            d.f_time_to_failure_hours,
            d.sigma_f_time_to_failure_hours,
        ];
        for (k, v) in extra.iter().enumerate() {
            assert_eq!(
                field(f[14 + k]).map(f64::to_bits),
                v.map(f64::to_bits),
                "column {} of {line}",
                14 + k
            );
        }
        n += 1;
    }
    assert_eq!(n, rows);
    assert_eq!(text.lines().count(), rows + 1);

    // JSON: each page byte for byte what serde writes for the reference rows
    let limit = 997;
    let mut cursor: Option<String> = None;
    let mut offset = 0;
    loop {
        let mut path = format!("{base}?limit={limit}");
        if let Some(c) = &cursor {
            path.push_str(&format!("&cursor={c}"));
        }
        let r = s.client.get(s.url(&path)).send().await.unwrap();
        assert_eq!(r.status(), 200);
        assert!(r.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("application/json"));
        let body = r.text().await.unwrap();
        let end = (offset + limit).min(rows);
        let items = &want[offset..end];
        let next = (end < rows).then(|| {
            let last = DateTime::parse_from_rfc3339(&items[items.len() - 1].observed_at)
                .unwrap()
                .with_timezone(&Utc);
            cliffwatch::api::list::encode(cliffwatch::api::list::Listing::Series, &timestamp(last))
        });
        let expected = serde_json::to_string(&cliffwatch::api::list::Page {
            items: items.to_vec(),
            next_cursor: next.clone(),
        })
        .unwrap();
        let differ = body.bytes().zip(expected.bytes()).position(|(a, b)| a != b);
        assert!(
            body == expected,
            "page at {offset}: differs at byte {differ:?}: {:?} vs {:?}",
            &body[differ.unwrap_or(0).saturating_sub(80)
                ..(differ.unwrap_or(0) + 80).min(body.len())],
            &expected[differ.unwrap_or(0).saturating_sub(80)
                ..(differ.unwrap_or(0) + 80).min(expected.len())]
        );
        offset = end;
        match next {
            Some(c) => cursor = Some(c),
            None => break,
        }
    }
    assert_eq!(offset, rows);

    // a range through both paths: from/to inclusive, CSV and JSON agree with the reference
    let (_, page) = s
        .get(&format!("{base}?from=2015-01-02&to=2015-01-03&limit=1000"))
        .await;
    let inside: Vec<&Displacement> = want
        .iter()
        .filter(|d| d.observed_at.as_str() >= "2015-01-02" && d.observed_at.as_str() < "2015-01-04")
        .collect();
    assert_eq!(page["items"].as_array().unwrap().len(), inside.len());
    if let Some(first) = inside.first() {
        assert_eq!(page["items"][0]["epoch"], first.epoch);
    }
    let text = s
        .client
        .get(s.url(&format!("{base}?format=csv&from=2015-01-02&to=2015-01-03")))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert_eq!(text.lines().count(), inside.len() + 1);
}

/// The stored time of epoch `n` of [`fill`] (whole seconds, milliseconds, microseconds).
fn time_of(n: i64) -> String {
    let micros = match n % 3 {
        0 => 0,
        1 => (n * 1000) % 1_000_000,
        _ => (n * 7) % 1_000_000,
    };
    let base = DateTime::parse_from_rfc3339("2015-01-01T00:00:00Z")
        .unwrap()
        .with_timezone(&Utc);
    timestamp(base + chrono::Duration::hours(n) + chrono::Duration::microseconds(micros))
}

/// Epochs `ns` and their rows of P1 and P2 in one transaction, as ingestion writes them (the rows
/// through `displacements::insert`, in one call).
async fn ingest(s: &TestServer, site: &str, ns: &[i64]) {
    let mut tx = s.store.begin_write().await.unwrap();
    let mut rows = Vec::new();
    for &n in ns {
        sqlx::query(
            "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, \
             body_sha256, cameras, report, created_at) \
             VALUES (?, ?, ?, 'adjusted', 'orthogonal', 0.001, 5, ?, '[]', '{}', '2026-01-01T00:00:00.000000Z')",
        )
        .bind(site)
        .bind(n)
        .bind(time_of(n))
        .bind(format!("{n:064}"))
        .execute(&mut *tx)
        .await
        .unwrap();
        for p in ["P1", "P2"] {
            rows.push(row(n, p, &time_of(n)));
        }
    }
    displacements::insert(&mut tx, site, &rows).await.unwrap();
    tx.commit().await.unwrap();
}

/// A row as the analysis would give it; every tenth with a negative zero and a NaN covariance
/// (the table keeps 0 and NULL).
fn row(n: i64, point: &str, observed_at: &str) -> Displacement {
    Displacement {
        point: point.into(),
        epoch: n,
        observed_at: observed_at.into(),
        reference_epoch: 1,
        dx_mm: if n % 10 == 0 { -0.0 } else { n as f64 * 1.1e-3 },
        dy_mm: -(n as f64) / 7.0,
        dz_mm: 1e-9 * n as f64,
        d_mm: (n as f64).sqrt(),
        sigma_dx_mm: 0.1,
        sigma_dy_mm: 0.2,
        sigma_dz_mm: 0.3,
        sigma_mm: 0.25,
        cov_dxdy_mm2: (n % 10 == 0).then_some(f64::NAN),
        cov_dxdz_mm2: (n % 3 != 0).then_some(-2.5e-3),
        cov_dydz_mm2: None,
        d_along_mm: None,
        significant: n % 2 == 0,
        velocity_mm_per_day: (n % 4 != 0).then_some(0.01 * n as f64),
        time_to_failure_hours: None,
        f_dx_mm: (n % 3 == 0).then_some(n as f64 * 1e-3),
        f_dy_mm: (n % 3 == 0).then_some(-0.5),
        f_dz_mm: (n % 3 == 0).then_some(0.25),
        f_d_mm: (n % 3 == 0).then_some(0.6),
        sigma_f_dx_mm: (n % 3 == 0).then_some(0.05),
        sigma_f_dy_mm: (n % 3 == 0).then_some(0.06),
        sigma_f_dz_mm: (n % 3 == 0).then_some(0.07),
        sigma_f_d_mm: (n % 3 == 0).then_some(0.08),
        f_velocity_mm_per_day: (n % 3 == 0).then_some(-1e-4 * n as f64),
        sigma_f_velocity_mm_per_day: (n % 3 == 0).then_some(0.01),
        f_acceleration_mm_per_day2: (n % 6 == 0).then_some(2e-5),
        sigma_f_acceleration_mm_per_day2: (n % 6 == 0).then_some(1e-5),
        ..Default::default()
    }
}

async fn sealed_until(s: &TestServer, site: &str) -> String {
    sqlx::query_scalar("SELECT sealed_until FROM series_seals WHERE site_id = ?")
        .bind(site)
        .fetch_one(s.store.reader())
        .await
        .unwrap()
}

#[tokio::test]
async fn ingest_paths_keep_the_packed_series_equal_to_the_table() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("ing").await;
    let mut tx = s.store.begin_write().await.unwrap();
    for p in ["P1", "P2"] {
        sqlx::query("INSERT INTO points (site_id, name, role) VALUES ('ing', ?, 'monitored')")
            .bind(p)
            .execute(&mut *tx)
            .await
            .unwrap();
    }
    tx.commit().await.unwrap();
    let epochs = 3 * BLOCK_EPOCHS as i64 + 37;
    let late = |n: i64| n % 50 == 25;
    // one epoch per transaction, in time order, except the late ones and the last 40
    let in_order: Vec<i64> = (1..=epochs - 40).filter(|&n| !late(n)).collect();
    for &n in &in_order {
        ingest(&s, "ing", &[n]).await;
    }
    let before = sealed_until(&s, "ing").await;
    assert_eq!(
        before,
        time_of(in_order[2 * BLOCK_EPOCHS - 1]),
        "two blocks sealed"
    );
    assert_served_as_stored(&s, "ing", None, in_order.len()).await;
    // the late epochs arrive: older than the sealed part, so the site is packed anew
    let late: Vec<i64> = (1..=epochs - 40).filter(|&n| late(n)).collect();
    ingest(&s, "ing", &late).await;
    assert_eq!(
        sealed_until(&s, "ing").await,
        time_of(2 * BLOCK_EPOCHS as i64)
    );
    assert_served_as_stored(&s, "ing", None, (epochs - 40) as usize).await;
    // the last 40 at once: tail
    let last: Vec<i64> = (epochs - 39..=epochs).collect();
    ingest(&s, "ing", &last).await;
    assert_served_as_stored(&s, "ing", None, epochs as usize).await;
    // a recompute: everything deleted and written again in one transaction
    let mut all = Vec::new();
    for p in ["P1", "P2"] {
        all.extend((1..=epochs).map(|n| row(n, p, &time_of(n))));
    }
    let mut tx = s.store.begin_write().await.unwrap();
    displacements::delete_site(&mut tx, "ing").await.unwrap();
    displacements::insert(&mut tx, "ing", &all).await.unwrap();
    tx.commit().await.unwrap();
    assert_eq!(
        sealed_until(&s, "ing").await,
        time_of(3 * BLOCK_EPOCHS as i64)
    );
    assert_served_as_stored(&s, "ing", None, epochs as usize).await;
    s.stop().await;
}

#[tokio::test]
async fn open_packs_series_stored_before_the_migration() {
    // rows by SQL and no series_seals row: what migration 7 leaves of an older database
    let s = TestServer::start(|_| {}).await;
    fill(&s, "old").await;
    let dir = s.stop().await;
    let store = Store::open(&dir.path().join("cliffwatch.db"), &StoreOptions::default())
        .await
        .unwrap();
    let (blocks, sealed): (i64, String) = sqlx::query_as(
        "SELECT (SELECT COUNT(*) FROM series_blocks WHERE site_id = 'old'), \
         (SELECT sealed_until FROM series_seals WHERE site_id = 'old')",
    )
    .fetch_one(store.reader())
    .await
    .unwrap();
    let full = ROWS / BLOCK_EPOCHS;
    assert_eq!(blocks as usize, 2 * full, "P1 and P2");
    assert_eq!(sealed, time_of((full * BLOCK_EPOCHS) as i64));
    store.close().await;
}

#[tokio::test]
async fn empty_series_is_the_header_or_an_empty_page() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("none").await;
    let r = s
        .client
        .put(s.url("/api/v1/sites/none/points/P1"))
        .json(&json!({"role": "monitored"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let text = s
        .client
        .get(s.url("/api/v1/sites/none/points/P1/displacements?format=csv"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert_eq!(text, format!("{}\n", cliffwatch::api::points::CSV_HEADER));
    let (status, page) = s.get("/api/v1/sites/none/points/P1/displacements").await;
    assert_eq!(status, 200);
    assert_eq!(page, json!({"items": [], "next_cursor": null}));
    s.stop().await;
}

#[test]
fn stored_times_display_as_chrono_prints_them() {
    // whole seconds, whole milliseconds, microseconds; across a leap day and the years' range
    let base = DateTime::parse_from_rfc3339("1999-12-31T23:59:59Z")
        .unwrap()
        .with_timezone(&Utc);
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    for k in 0..5000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let secs = (state % (40 * 365 * 86_400)) as i64;
        let micros = match k % 3 {
            0 => 0,
            1 => (state >> 20) as i64 % 1000 * 1000,
            _ => (state >> 20) as i64 % 1_000_000,
        };
        let t = base + chrono::Duration::seconds(secs) + chrono::Duration::microseconds(micros);
        let stored = timestamp(t);
        assert_eq!(
            display_timestamp(&stored),
            t.to_rfc3339_opts(SecondsFormat::AutoSi, true),
            "{stored}"
        );
    }
    // anything not in the store's form is left to chrono (or shown as is)
    assert_eq!(
        display_timestamp("2020-01-01T00:00:00+02:00"),
        "2019-12-31T22:00:00Z"
    );
    assert_eq!(display_timestamp("not a time"), "not a time");
}

#[test]
fn analysis_records_map_to_rows_and_back() {
    use cliffwatch_core::analysis::DisplacementRecord;
    let t = DateTime::parse_from_rfc3339("2026-03-01T12:34:56.789012Z")
        .unwrap()
        .with_timezone(&Utc);
    let record = DisplacementRecord {
        point: "T7".into(),
        epoch: 42,
        observed_at: t,
        dx_mm: 1.25,
        dy_mm: -0.5,
        dz_mm: 3e-7,
        d_mm: 1.3462912017836262,
        sigma_dx_mm: 0.1,
        sigma_dy_mm: 0.2,
        sigma_dz_mm: 0.3,
        sigma_mm: 0.15,
        cov_dxdy_mm2: Some(0.004),
        cov_dxdz_mm2: None,
        cov_dydz_mm2: Some(-1e-3),
        d_along_mm: Some(-0.5),
        significant: true,
        velocity_mm_per_day: None,
        time_to_failure_hours: Some(36.0),
        time_to_failure_sigma_hours: Some(4.5),
        filtered: Some(cliffwatch_core::analysis::FilteredValues {
            f_dx_mm: 1.2,
            f_dy_mm: -0.45,
            f_dz_mm: 0.01,
            f_d_mm: 1.28,
            sigma_f_dx_mm: 0.04,
            sigma_f_dy_mm: 0.05,
            sigma_f_dz_mm: 0.06,
            sigma_f_d_mm: 0.045,
            f_velocity_mm_per_day: 0.3,
            sigma_f_velocity_mm_per_day: 0.02,
            f_acceleration_mm_per_day2: Some(0.01),
            sigma_f_acceleration_mm_per_day2: Some(0.004),
            f_time_to_failure_hours: Some(40.0),
            sigma_f_time_to_failure_hours: Some(6.0),
        }),
    };
    let row = Displacement::from_record(&record, 3);
    assert_eq!(row.reference_epoch, 3);
    assert_eq!(row.observed_at, "2026-03-01T12:34:56.789012Z");
    assert_eq!(row.to_record(), Some(record.clone()));
    // without the filter's values, none is stored and none comes back
    let bare = DisplacementRecord {
        filtered: None,
        ..record
    };
    let row = Displacement::from_record(&bare, 3);
    assert_eq!(row.f_dx_mm, None);
    assert_eq!(row.to_record(), Some(bare));
}

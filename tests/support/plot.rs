//! The plot of a long history, checked on either backend: 4 000 hourly epochs of one point,
//! packed into blocks of 128, with a spike, a dip and an alert epoch inside a block.
#![allow(dead_code)]

use cliffwatch::store::series::columns;
use cliffwatch::store::series::SeriesQuery;
use cliffwatch::store::Store;
use serde_json::{json, Value};

const SITE: &str = "long";
const N: usize = 4000;
const ALERT_EPOCH: i64 = 1234;

/// Pseudo-random displacements (mm) of epoch `k` (1-based): dx with a spike at 2345, dy with a
/// dip at 777, dz and d with trends.
fn values(k: i64) -> [f64; 4] {
    [
        ((k * 7919) % 1000) as f64 * 0.001 + if k == 2345 { 9.0 } else { 0.0 },
        ((k * 104_729) % 997) as f64 * -0.002 - if k == 777 { 5.0 } else { 0.0 },
        ((k * 31) % 101) as f64 * 0.01 + k as f64 * 0.0001,
        ((k * 7919) % 1000) as f64 * 0.001 + k as f64 * 0.0002,
    ]
}

/// Fills site `long` (created through the API at `base`) in SQL, as an analysis would have
/// stored it, and packs its series.
async fn fill(store: &Store, base: &str) {
    let r = reqwest::Client::new()
        .post(format!("{base}/api/v1/sites"))
        .json(&json!({"id": SITE, "name": SITE, "model": "orthogonal"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let start = chrono::DateTime::parse_from_rfc3339("2015-01-01T00:00:00Z").unwrap();
    let mut tx = store.begin_write().await.unwrap();
    sqlx::query("INSERT INTO points (site_id, name, role) VALUES ($1, 'T001', 'monitored')")
        .bind(SITE)
        .execute(&mut *tx)
        .await
        .unwrap();
    for k in 1..=N as i64 {
        let t = (start + chrono::Duration::hours(k))
            .format("%Y-%m-%dT%H:%M:%S.000000Z")
            .to_string();
        sqlx::query(
            "INSERT INTO epochs (site_id, id, observed_at, status, model, sigma0_mm, iterations, \
             body_sha256, cameras, report, created_at) \
             VALUES ($1, $2, $3, 'adjusted', 'orthogonal', 0.001, 5, $4, '[]', '{}', '2026-01-01T00:00:00.000000Z')",
        )
        .bind(SITE)
        .bind(k)
        .bind(&t)
        .bind(format!("{k:064}"))
        .execute(&mut *tx)
        .await
        .unwrap();
        let v = values(k);
        sqlx::query(
            "INSERT INTO displacements (site_id, epoch_id, point, observed_at, reference_epoch, \
             dx_mm, dy_mm, dz_mm, d_mm, sigma_dx_mm, sigma_dy_mm, sigma_dz_mm, sigma_mm, significant, \
             velocity_mm_per_day, f_dx_mm, f_dy_mm, f_dz_mm, f_d_mm, sigma_f_dx_mm, sigma_f_dy_mm, \
             sigma_f_dz_mm, sigma_f_d_mm, f_velocity_mm_per_day, sigma_f_velocity_mm_per_day) \
             VALUES ($1, $2, 'T001', $3, 1, $4, $5, $6, $7, 0.11, 0.12, 0.31, 0.2, $8, 0.005, \
             0.1, 0.2, 0.3, $9, 0.05, 0.05, 0.1, 0.1, 0.005, 0.002)",
        )
        .bind(SITE)
        .bind(k)
        .bind(&t)
        .bind(v[0])
        .bind(v[1])
        .bind(v[2])
        .bind(v[3])
        .bind(k > 100)
        .bind(0.4 + k as f64 * 1e-4)
        .execute(&mut *tx)
        .await
        .unwrap();
        if k == ALERT_EPOCH {
            sqlx::query(
                "INSERT INTO alerts (id, site_id, point, level, rule, epoch_id, observed_at, \
                 message, state, raised_at, updated_at) \
                 VALUES ('a1', $1, 'T001', 'watch', 'r', $2, $3, 'm', 'open', $4, $5)",
            )
            .bind(SITE)
            .bind(k)
            .bind(&t)
            .bind(&t)
            .bind(&t)
            .execute(&mut *tx)
            .await
            .unwrap();
        }
    }
    cliffwatch::store::series::blocks::rebuild(&mut tx, SITE)
        .await
        .unwrap();
    tx.commit().await.unwrap();
}

/// A long history plotted 100 px wide: each bucket spans more than a block, so the read takes
/// the blocks' extremes. The plot keeps the ends, the alert epoch (inside a block, not one of
/// its extremes), every column's extremes and its envelope at the plot's resolution, with the
/// stored values; 200 px wide (buckets shorter than a block) it reads every row and keeps
/// exactly what the picker keeps. `base`: the server's URL.
pub async fn long_history_plot(store: &Store, base: &str) {
    fill(store, base).await;
    let full = columns::read(
        store,
        SeriesQuery {
            site: SITE.into(),
            point: "T001".into(),
            ..Default::default()
        },
    )
    .await
    .unwrap();
    assert_eq!(full.epoch.len(), N);
    let index_of = |e: i64| full.epoch.iter().position(|&x| x == e).unwrap();
    let cols = ["dx", "dy", "dz", "d"];
    let client = reqwest::Client::new();
    // The JSON pages, whose limits cut the packed blocks anywhere: every epoch once, in order.
    let mut paged = Vec::new();
    let mut cursor: Option<String> = None;
    loop {
        let mut url = format!("{base}/api/v1/sites/{SITE}/points/T001/displacements?limit=300");
        if let Some(c) = &cursor {
            url.push_str(&format!("&cursor={c}"));
        }
        let page: Value = client.get(url).send().await.unwrap().json().await.unwrap();
        let items = page["items"].as_array().unwrap();
        assert!(items.len() <= 300);
        paged.extend(items.iter().map(|i| i["epoch"].as_i64().unwrap()));
        match page["next_cursor"].as_str() {
            Some(c) => {
                assert_eq!(
                    items.len(),
                    300,
                    "a page short of its limit says more follow"
                );
                cursor = Some(c.to_string());
            }
            None => break,
        }
    }
    assert_eq!(paged, full.epoch, "the pages of 300");
    for width in [100usize, 200] {
        let plot: Value = client
            .get(format!("{base}/dashboard/plot/{SITE}/T001?width={width}"))
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        assert_eq!(plot["total"], json!(N), "{plot}");
        let epochs: Vec<i64> = plot["epoch"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_i64().unwrap())
            .collect();
        let idx: Vec<usize> = epochs.iter().map(|&e| index_of(e)).collect();
        assert!(idx.windows(2).all(|w| w[0] < w[1]), "in time order, once");
        assert!(
            idx.len() <= 2 * width + 4,
            "{} rows at {width} px",
            idx.len()
        );
        assert_eq!((idx[0], *idx.last().unwrap()), (0, N - 1));
        assert!(
            epochs.contains(&ALERT_EPOCH),
            "alert epoch kept at {width} px"
        );
        // the stored values (to the last bit or so: serde_json's default parse of the answer
        // may be one ulp off)
        let same = |a: &Value, b: f64| (a.as_f64().unwrap() - b).abs() <= 1e-12 * b.abs().max(1.0);
        for (k, &i) in idx.iter().enumerate() {
            for (c, col) in cols.iter().enumerate() {
                assert!(same(&plot[*col][k], full.d[c][i]), "{col} at {i}");
            }
            assert!(same(&plot["f_d"][k], full.f_d[3][i]));
            assert!(same(&plot["sdz"][k], full.sigma[2][i]));
        }
        // every column's envelope at the plot's resolution: each window of 512 epochs has its
        // maximum and minimum drawn within one window on either side
        let range = |xs: &mut dyn Iterator<Item = f64>| {
            xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            })
        };
        let drawn = |c: usize, lo: usize, hi: usize| {
            range(
                &mut idx
                    .iter()
                    .filter(|&&i| i >= lo && i < hi)
                    .map(|&i| full.d[c][i]),
            )
        };
        for (c, col) in cols.iter().enumerate() {
            assert_eq!(
                drawn(c, 0, N),
                range(&mut full.d[c].iter().copied()),
                "{} at {width} px",
                col
            );
            for w in (0..N).step_by(512) {
                let end = (w + 512).min(N);
                let (wmin, wmax) = range(&mut full.d[c][w..end].iter().copied());
                let (nmin, nmax) = drawn(c, w.saturating_sub(512), end + 512);
                assert!(
                    nmax >= wmax && nmin <= wmin,
                    "{} window {w} at {width} px",
                    col
                );
            }
        }
        if width == 200 {
            // buckets shorter than a block: every row read, exactly the picker's choice
            let columns: Vec<&[f64]> = full.d.iter().map(Vec::as_slice).collect();
            let expected = cliffwatch::dashboard::downsample::plot_indices(
                N,
                &columns,
                &[index_of(ALERT_EPOCH)],
                width,
            );
            assert_eq!(idx, expected);
        }
    }
}

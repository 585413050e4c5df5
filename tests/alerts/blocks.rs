//! Blocks and the site settings of the filtered analysis, through the daemon's HTTP API: a declared
//! block group raises one group alert (`point` null, `group`, its points) from the block's motion;
//! `reference_epochs` averages the first epochs into the reference and recomputes; bad settings
//! answer 422 naming the field and store nothing.

use crate::support;

use reqwest::Method;
use serde_json::{json, Value};
use support::alerts::{day, mark_stable, upload_new, write_config, Daemon, Scene};

async fn alerts(d: &Daemon, site: &str) -> Vec<Value> {
    let (s, a) = d
        .get(&format!("/api/v1/alerts?site={site}&limit=1000"))
        .await;
    assert_eq!(s, 200, "{a}");
    a["items"].as_array().unwrap().clone()
}

/// `a` and `b` have the same structure, strings and nulls, and numbers within 1e-6 (absolute,
/// or relative for large ones).
fn assert_close(a: &Value, b: &Value, what: &str) {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= 1e-6 * x.abs().max(y.abs()).max(1.0),
                "{what}: {x} against {y}"
            );
        }
        (Value::Array(x), Value::Array(y)) => {
            assert_eq!(x.len(), y.len(), "{what}: {a} against {b}");
            for (x, y) in x.iter().zip(y) {
                assert_close(x, y, what);
            }
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{what}"
            );
            for (k, v) in x {
                assert_close(v, &y[k], &format!("{what}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{what}"),
    }
}

fn num(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} is not a number in {v}"))
}

/// The block's motion series (JSON and CSV) against its points' series: one row per epoch,
/// named by the group, the translation close to the points' common displacement and more precise
/// than any single point's.
async fn assert_block_motion(d: &Daemon, point_items: &[Value]) {
    let (s, m) = d.get("/api/v1/sites/cliff/groups/B1/motion").await;
    assert_eq!(s, 200, "{m}");
    let rows = m["items"].as_array().unwrap();
    // one row per epoch: at the reference epoch zero with σ 0, as the points' rows
    assert_eq!(rows.len(), point_items.len(), "{m}");
    let first = &rows[0];
    assert_eq!(first["epoch"], point_items[0]["epoch"], "{first}");
    assert!(
        num(first, "d_mm") == 0.0 && num(first, "sigma_mm") == 0.0 && first["significant"] == false,
        "{first}"
    );
    for (r, p) in rows[1..].iter().zip(&point_items[1..]) {
        assert_eq!(r["point"], "B1");
        assert_eq!(r["epoch"], p["epoch"]);
        assert!(
            (num(r, "d_mm") - num(p, "d_mm")).abs() < 3.0,
            "{r} against {p}"
        );
        assert!(num(r, "sigma_mm") < num(p, "sigma_mm"), "{r} against {p}");
        assert!(
            r["f_d_mm"].is_number() && r["sigma_f_velocity_mm_per_day"].is_number(),
            "{r}"
        );
    }
    let last = rows.last().unwrap();
    assert!((num(last, "d_mm") - 16.0).abs() < 3.0, "{last}");
    // the block's direction is -Y: along it the block moved by its |dy|
    assert!(
        (num(last, "d_along_mm") + num(last, "dy_mm")).abs() < 1e-9,
        "{last}"
    );
    let csv = d
        .client
        .get(d.url("/api/v1/sites/cliff/groups/B1/motion?format=csv"))
        .send()
        .await
        .unwrap();
    assert_eq!(csv.status(), 200);
    let text = csv.text().await.unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), rows.len() + 1, "{text}");
    assert_eq!(lines[0], cliffwatch::api::points::CSV_HEADER);
    assert!(
        lines[1..].iter().all(|l| l.split(',').count() == 29),
        "{text}"
    );
    let (s, _) = d.get("/api/v1/sites/cliff/groups/B9/motion").await;
    assert_eq!(s, 404);
    let (s, _) = d
        .get("/api/v1/sites/cliff/groups/B1/motion?format=xml")
        .await;
    assert_eq!(s, 400);
}

/// Makes the database look like one written before the filtered series existed.
async fn age_database(path: &std::path::Path) {
    use sqlx::ConnectOptions;
    let mut db = sqlx::sqlite::SqliteConnectOptions::new()
        .filename(path)
        .connect()
        .await
        .unwrap();
    for sql in [
        "UPDATE sites SET analysis_version = 0",
        "UPDATE displacements SET f_dx_mm = NULL, f_dy_mm = NULL, f_dz_mm = NULL, f_d_mm = NULL, \
         sigma_f_dx_mm = NULL, sigma_f_dy_mm = NULL, sigma_f_dz_mm = NULL, sigma_f_d_mm = NULL, \
         f_velocity_mm_per_day = NULL, sigma_f_velocity_mm_per_day = NULL, \
         f_acceleration_mm_per_day2 = NULL, sigma_f_acceleration_mm_per_day2 = NULL",
        "DELETE FROM block_motions",
    ] {
        sqlx::query(sql).execute(&mut db).await.unwrap();
    }
    let (n,): (i64,) =
        sqlx::query_as("SELECT COUNT(*) FROM displacements WHERE f_dx_mm IS NOT NULL")
            .fetch_one(&mut db)
            .await
            .unwrap();
    assert_eq!(n, 0);
}

async fn create(d: &Daemon, body: Value) -> (u16, Value) {
    d.send(Method::POST, "/api/v1/sites", Some(&body)).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_declared_block_raises_one_group_alert() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 16, stable: 8 };
    // A warning rule for the block only; no point rule.
    let (s, b) = create(
        &d,
        json!({"id": "cliff", "alert_rules": [
            {"level": "warning", "metric": "displacement_mm", "above": 10.0, "group": "B1"}]}),
    )
    .await;
    assert_eq!(s, 201, "{b}");
    mark_stable(&d, "cliff", &scene).await;
    let block: Vec<String> = (scene.stable..scene.n).map(Scene::name).collect();
    let (s, g) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/groups/B1",
            Some(&json!({"kind": "block", "direction": [0.0, -1.0, 0.0], "points": block})),
        )
        .await;
    assert_eq!(s, 200, "{g}");
    assert_eq!(g["name"], "B1");
    assert_eq!(g["points"].as_array().unwrap().len(), block.len());
    let (s, all) = d.get("/api/v1/sites/cliff/groups").await;
    assert_eq!(s, 200, "{all}");
    assert_eq!(all["items"].as_array().unwrap().len(), 1, "{all}");
    assert!(all["next_cursor"].is_null(), "{all}");
    for k in 0..3 {
        upload_new(
            &d,
            "cliff",
            &scene.epoch(&day(k), 300 + k as u64, 8.0 * k as f64),
        )
        .await;
    }
    // 16 mm: the block's translation (8 points averaged) exceeds 10 mm at 99 %.
    let open = alerts(&d, "cliff").await;
    assert_eq!(open.len(), 1, "{open:?}");
    let a = &open[0];
    assert_eq!(a["rule"], "displacement_mm");
    assert_eq!(a["level"], "warning");
    assert!(a["point"].is_null(), "{a}");
    assert_eq!(a["group"], "B1");
    let points: Vec<&str> = a["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_str().unwrap())
        .collect();
    assert_eq!(points.len(), block.len(), "{a}");
    let v = a["value"].as_f64().unwrap();
    assert!(
        (v - 16.0).abs() < 3.0,
        "block translation {v} mm against 16 mm"
    );
    // The series carries the filtered state of every point after the first epochs.
    let (s, series) = d
        .get(&format!(
            "/api/v1/sites/cliff/points/{}/displacements",
            block[0]
        ))
        .await;
    assert_eq!(s, 200, "{series}");
    let items = series["items"].as_array().unwrap().clone();
    assert_eq!(items.len(), 3);
    // the reference epoch (zero, σ 0) has no filter state; every later epoch has
    assert_eq!(num(&items[0], "sigma_mm"), 0.0);
    assert!(items[0]["f_d_mm"].is_null());
    for it in &items[1..] {
        let (d, f, sd) = (num(it, "d_mm"), num(it, "f_d_mm"), num(it, "sigma_mm"));
        // the filter follows the raw series within its noise (3 epochs, 8 mm a day)
        assert!((f - d).abs() < 4.0 * sd + 1.0, "{it}");
        assert!(num(it, "sigma_f_d_mm") > 0.0, "{it}");
        assert!(it["f_velocity_mm_per_day"].is_number(), "{it}");
    }
    assert_block_motion(&d, &items).await;
    // An older database: rows without the filtered values and no block motions, marked as
    // derived by an older binary. The next start recomputes them, to the same values.
    let before_points = d
        .get(&format!(
            "/api/v1/sites/cliff/points/{}/displacements",
            block[0]
        ))
        .await
        .1;
    let before_motion = d.get("/api/v1/sites/cliff/groups/B1/motion").await.1;
    d.kill9();
    age_database(&dir.path().join("data").join("cliffwatch.db")).await;
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let after_points = d
        .get(&format!(
            "/api/v1/sites/cliff/points/{}/displacements",
            block[0]
        ))
        .await
        .1;
    // the upload path works on the adjustment in memory, the recompute on coordinates read back
    // from the store: equal to ~1e-9 mm, not bit for bit
    assert_close(
        &after_points,
        &before_points,
        "point series recomputed at start",
    );
    let after_motion = d.get("/api/v1/sites/cliff/groups/B1/motion").await.1;
    assert_close(
        &after_motion,
        &before_motion,
        "block motion recomputed at start",
    );
    // The reference moved to the last epoch: the block's displacement from it is zero and its
    // warning resolves, but its filtered velocity there is still the motion's.
    let last_epoch = &after_motion["items"][2];
    let (s, b) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/reference",
            Some(&json!({"epoch": last_epoch["epoch"]})),
        )
        .await;
    assert_eq!(s, 200, "{b}");
    let open = alerts(&d, "cliff").await;
    assert!(
        open.len() == 1 && open[0]["state"] == "resolved",
        "{open:?}"
    );
    let (_, moved) = d.get("/api/v1/sites/cliff/groups/B1/motion").await;
    let now = &moved["items"][2];
    assert_eq!(now["epoch"], last_epoch["epoch"], "{moved}");
    assert_eq!(num(now, "d_mm"), 0.0, "{now}");
    let (v_before, v_now) = (
        num(last_epoch, "f_velocity_mm_per_day"),
        num(now, "f_velocity_mm_per_day"),
    );
    assert!(
        (v_now - v_before).abs() < 0.1 * v_before.abs() && v_before > 5.0,
        "{v_now} mm/day against {v_before} mm/day"
    );
    // A block with a misspelt member and one measured point: stored, the misspelt name listed as
    // unmeasured, and no motion (a one-point block would repeat its point's alerts).
    let (s, g) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/groups/B3",
            Some(&json!({"kind": "block", "points": [block[0], "NOPE"]})),
        )
        .await;
    assert_eq!(s, 200, "{g}");
    assert_eq!(g["members"], json!([block[0], "NOPE"]), "{g}");
    assert_eq!(g["unmeasured_points"], json!(["NOPE"]), "{g}");
    let (s, m) = d.get("/api/v1/sites/cliff/groups/B3/motion").await;
    assert_eq!(s, 200, "{m}");
    assert_eq!(m["items"], json!([]), "{m}");
    let (_, g1) = d.get("/api/v1/sites/cliff/groups/B1").await;
    assert_eq!(g1["unmeasured_points"], json!([]), "{g1}");
    assert_eq!(g1["members"].as_array().unwrap().len(), block.len(), "{g1}");
    // Unknown site and bad bodies.
    let (s, _) = d
        .send(
            Method::PUT,
            "/api/v1/sites/nowhere/groups/B1",
            Some(&json!({"kind": "block"})),
        )
        .await;
    assert_eq!(s, 404);
    for (body, field) in [
        (json!({"kind": "slab"}), "kind"),
        (
            json!({"kind": "block", "direction": [0.0, 0.0, 0.0]}),
            "direction",
        ),
        (
            json!({"kind": "block", "process_noise": -1.0}),
            "process_noise",
        ),
        (json!({"kind": "block", "points": ["a b"]}), "points"),
    ] {
        let (s, b) = d
            .send(Method::PUT, "/api/v1/sites/cliff/groups/B2", Some(&body))
            .await;
        assert_eq!(s, 422, "{body}: {b}");
        assert!(
            b["error"]["message"].as_str().unwrap().contains(field),
            "{body}: {b}"
        );
    }
    let (s, _) = d.get("/api/v1/sites/cliff/groups/B2").await;
    assert_eq!(s, 404, "nothing stored");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn site_settings_are_validated_and_a_reference_of_several_epochs_is_averaged() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    for (body, field) in [
        (
            json!({"id": "a", "reference_epochs": 0}),
            "reference_epochs",
        ),
        (json!({"id": "a", "process_noise": 0.0}), "process_noise"),
        (json!({"id": "a", "confidence": 0.4}), "confidence"),
        (
            json!({"id": "a", "alert_rules": [{"level": "watch", "metric": "displacement_mm", "above": 5, "for_epochs": 0}]}),
            "for_epochs",
        ),
        (
            json!({"id": "a", "alert_rules": [{"level": "watch", "metric": "displacement_mm", "above": 5, "source": "smoothed"}]}),
            "alert_rules[0]",
        ),
    ] {
        let (s, b) = create(&d, body.clone()).await;
        assert_eq!(s, 422, "{body}: {b}");
        assert!(
            b["error"]["message"].as_str().unwrap().contains(field),
            "{body}: {b}"
        );
        let (s, _) = d.get("/api/v1/sites/a").await;
        assert_eq!(s, 404, "nothing stored for {body}");
    }
    // Two sites fed the same still epochs: one against epoch 1, one against the mean of 3.
    let scene = Scene { n: 12, stable: 6 };
    for (id, k) in [("one", 1), ("three", 3)] {
        let (s, b) = create(&d, json!({"id": id, "reference_epochs": k})).await;
        assert_eq!(s, 201, "{b}");
        assert_eq!(b["reference_epochs"], k);
        mark_stable(&d, id, &scene).await;
        for e in 0..5 {
            upload_new(&d, id, &scene.epoch(&day(e), 500 + e as u64, 0.0)).await;
        }
    }
    let point = Scene::name(9);
    let mut sigma = vec![];
    for id in ["one", "three"] {
        let (s, b) = d
            .get(&format!("/api/v1/sites/{id}/points/{point}/displacements"))
            .await;
        assert_eq!(s, 200, "{b}");
        let items = b["items"].as_array().unwrap().clone();
        assert_eq!(items.len(), 5);
        sigma.push(items[4]["sigma_dz_mm"].as_f64().unwrap());
        if id == "three" {
            // The first epoch is part of the mean: its displacement is no longer exactly zero.
            assert!(items[0]["d_mm"].as_f64().unwrap() > 0.0, "{:?}", items[0]);
        }
    }
    // σ of a displacement against the mean of 3 epochs: √(1 + 1/3) instead of √2 times one
    // epoch's (the stable-point datum adds a little to both).
    let ratio = sigma[1] / sigma[0];
    assert!(
        (0.7..0.95).contains(&ratio),
        "σ against the mean of 3 / against one epoch = {ratio} ({sigma:?})"
    );
}

/// A network of more than 40 points keeps the joint covariance of its stable points and its
/// declared blocks' members only (not of all points), and the block's motion still rests on the
/// members' cross-covariances: the datum's and the reference epoch's errors are common to the
/// members, so the block's σ is wider than the members' σ combined as if independent.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_large_network_keeps_the_blocks_members_in_the_joint_covariance() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_config(dir.path(), "");
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let scene = Scene { n: 48, stable: 8 };
    let (s, b) = create(&d, json!({"id": "cliff"})).await;
    assert_eq!(s, 201, "{b}");
    mark_stable(&d, "cliff", &scene).await;
    // The block: the last 8 of the 40 moving points.
    let block: Vec<String> = (40..48).map(Scene::name).collect();
    let (s, g) = d
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/groups/B1",
            Some(&json!({"kind": "block", "points": block})),
        )
        .await;
    assert_eq!(s, 200, "{g}");
    for k in 0..3 {
        upload_new(
            &d,
            "cliff",
            &scene.epoch(&day(k), 700 + k as u64, 8.0 * k as f64),
        )
        .await;
    }
    // The stored joint covariances: the stable points and the block's members, once each.
    d.kill9();
    {
        use sqlx::ConnectOptions;
        let mut db = sqlx::sqlite::SqliteConnectOptions::new()
            .filename(dir.path().join("data").join("cliffwatch.db"))
            .connect()
            .await
            .unwrap();
        let rows: Vec<(String,)> = sqlx::query_as("SELECT points FROM joint_covariances")
            .fetch_all(&mut db)
            .await
            .unwrap();
        assert_eq!(rows.len(), 3, "one joint covariance per epoch");
        let mut expected: Vec<String> = (0..8).map(Scene::name).chain(block.clone()).collect();
        expected.sort();
        for (points,) in rows {
            let mut got: Vec<String> = serde_json::from_str(&points).unwrap();
            got.sort();
            assert_eq!(got, expected);
        }
    }
    let d = Daemon::start(&dir.path().join("data"), &config).await;
    let (s, m) = d.get("/api/v1/sites/cliff/groups/B1/motion").await;
    assert_eq!(s, 200, "{m}");
    let rows = m["items"].as_array().unwrap();
    assert_eq!(rows.len(), 3, "{m}");
    assert_eq!(num(&rows[0], "d_mm"), 0.0, "the reference epoch: {m}");
    for (k, r) in rows[1..].iter().enumerate() {
        let truth = 8.0 * (k + 1) as f64;
        let sigma = num(r, "sigma_mm");
        assert!(
            (num(r, "d_mm") - truth).abs() < 4.0 * sigma + 0.5,
            "{r} against {truth} mm"
        );
        // The members' σ at this epoch, combined as if their errors were independent.
        let mut info = 0.0;
        for p in &block {
            let (s, series) = d
                .get(&format!("/api/v1/sites/cliff/points/{p}/displacements"))
                .await;
            assert_eq!(s, 200, "{series}");
            let it = &series["items"].as_array().unwrap()[k + 1];
            assert_eq!(it["epoch"], r["epoch"]);
            info += num(it, "sigma_mm").powi(-2);
        }
        let independent = info.sqrt().recip();
        println!("epoch {k}: block σ {sigma:.3} mm, members as if independent {independent:.3} mm");
        assert!(sigma > 1.05 * independent, "{sigma} against {independent}");
    }
}

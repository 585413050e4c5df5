//! Uploads against a real server (in process, ephemeral port, temporary data dir): the paper
//! epochs stored and read back, idempotency and conflicts, the CSV form with the site's cameras.

use crate::support;

use cliffwatch_core::photogrammetry::{adjust, AdjustOptions, EpochInput};
use serde_json::{json, Value};
use support::server::{paper, TestServer, PAPER};

#[tokio::test]
async fn paper_epochs_upload_and_read_back() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("paper").await;
    // The first epoch of the site has no history: the stored coordinates are adjust()'s exactly.
    let first = paper(PAPER[0]);
    let (status, summary) = s.upload("paper", &first).await;
    assert_eq!(status, 201, "{summary}");
    assert_eq!(summary["id"], 1);
    assert!(summary["sigma0_mm"].is_number() && summary["cameras"][0]["c_mm"].is_number());
    let input: EpochInput = serde_json::from_value(first.clone()).unwrap();
    let expected = adjust(&input, &AdjustOptions::default()).unwrap();
    let (_, full) = s.get("/api/v1/sites/paper/epochs/1").await;
    // the stored coordinates are adjust()'s points, bit for bit (read from the database: JSON
    // parsing without serde_json's float_roundtrip may move the last bit)
    let stored = cliffwatch::store::points::epoch_coordinates(s.store.reader(), "paper", 1)
        .await
        .unwrap();
    assert_eq!(stored.len(), expected.points.len());
    for p in &expected.points {
        let c = stored.iter().find(|c| c.point == p.name).unwrap();
        assert_eq!(c.xyz, p.xyz, "point {}", p.name);
        for i in 0..3 {
            for j in i..3 {
                assert_eq!(
                    c.covariance_m2[i][j], p.covariance_m2[i][j],
                    "point {} covariance (upper triangle)",
                    p.name
                );
            }
        }
    }
    // the stored report is adjust()'s report
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
    for p in &expected.report.points {
        let got = full["points"]
            .as_array()
            .unwrap()
            .iter()
            .find(|q| q["point"] == p.point.as_str())
            .unwrap();
        assert!(
            close(got["X"].as_f64().unwrap(), p.X)
                && close(got["Y"].as_f64().unwrap(), p.Y)
                && close(got["Z"].as_f64().unwrap(), p.Z),
            "point {}",
            p.point
        );
    }
    assert!(close(
        full["sigma0_mm"].as_f64().unwrap(),
        expected.report.sigma0_mm
    ));
    let residuals = full["residuals"].as_array().unwrap();
    assert_eq!(
        residuals.len(),
        input
            .images
            .iter()
            .map(|i| i.observations.len())
            .sum::<usize>()
    );
    let (_, points) = s.get("/api/v1/sites/paper/points").await;
    for p in &expected.points {
        let item = points["items"]
            .as_array()
            .unwrap()
            .iter()
            .find(|q| q["point"] == p.name.as_str())
            .unwrap();
        let latest = &item["latest"];
        assert!(
            close(latest["X"].as_f64().unwrap(), p.xyz[0])
                && close(latest["Z"].as_f64().unwrap(), p.xyz[2])
        );
        let sx = (p.covariance_m2[0][0]).sqrt() * 1000.0;
        assert!((item["latest"]["sigma_X_mm"].as_f64().unwrap() - sx).abs() < 1e-12);
    }

    for (k, name) in PAPER.iter().enumerate().skip(1) {
        let (status, summary) = s.upload("paper", &paper(name)).await;
        assert_eq!(status, 201, "{name}: {summary}");
        assert_eq!(summary["id"], k as i64 + 1);
    }
    let (status, epochs) = s.get("/api/v1/sites/paper/epochs").await;
    assert_eq!(status, 200);
    let items = epochs["items"].as_array().unwrap();
    assert_eq!(items.len(), 9);
    assert_eq!(
        items[0]["observed_at"], "2000-03-20T00:00:00Z",
        "newest first"
    );
    assert!(epochs["next_cursor"].is_null());
    let (_, page) = s.get("/api/v1/sites/paper/epochs?limit=4").await;
    assert_eq!(page["items"].as_array().unwrap().len(), 4);
    let cursor = page["next_cursor"].as_str().unwrap().to_string();
    let (_, page2) = s
        .get(&format!(
            "/api/v1/sites/paper/epochs?limit=4&cursor={cursor}"
        ))
        .await;
    assert_eq!(page2["items"][0]["id"], items[4]["id"]);
    // A cursor is a position in its own listing only: another listing's, or a forged one, is a
    // 400 that says so, not a page read from some other position.
    let (_, points) = s.get("/api/v1/sites/paper/points?limit=2").await;
    let point_cursor = points["next_cursor"].as_str().unwrap().to_string();
    for (path, says) in [
        (
            format!("/api/v1/sites/paper/epochs?cursor={point_cursor}"),
            "cursor: it belongs to the points listing, not to the epochs listing",
        ),
        (
            format!("/api/v1/sites/paper/points/5/displacements?cursor={cursor}"),
            "cursor: it belongs to the epochs listing, not to the series listing",
        ),
        (
            "/api/v1/sites/paper/epochs?cursor=VDEwNQ".to_string(),
            "cursor: not a next_cursor of this listing",
        ),
    ] {
        let (status, body) = s.get(&path).await;
        assert_eq!(status, 400, "{path}: {body}");
        let message = body["error"]["message"].as_str().unwrap();
        assert!(message.starts_with(says), "{path}: {message}");
    }
    let (status, next) = s
        .get(&format!(
            "/api/v1/sites/paper/points?limit=2&cursor={point_cursor}"
        ))
        .await;
    assert_eq!(status, 200, "{next}");
    // A page size below 1 is refused, naming the parameter; above 1000 is read as 1000.
    for limit in ["0", "-1", "abc"] {
        let (status, body) = s
            .get(&format!("/api/v1/sites/paper/epochs?limit={limit}"))
            .await;
        assert_eq!(status, 400, "{body}");
        assert!(
            body["error"]["message"]
                .as_str()
                .unwrap()
                .starts_with("limit:"),
            "{body}"
        );
    }
    for path in [
        "/api/v1/sites/paper/points/5/displacements?format=csv&limit=0",
        "/api/v1/sites/paper/points/5/displacements?limit=-1",
    ] {
        let r = s.client.get(s.url(path)).send().await.unwrap();
        assert_eq!(r.status().as_u16(), 400, "{path}");
    }
    // A misspelt site is named, not answered with an empty list that reads as "all quiet".
    let (status, body) = s.get("/api/v1/alerts?site=papr").await;
    assert_eq!(status, 404, "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("'papr'"),
        "{body}"
    );
    let (status, page) = s.get("/api/v1/sites/paper/epochs?limit=5000").await;
    assert_eq!((status, page["items"].as_array().unwrap().len()), (200, 9));

    let (status, series) = s.get("/api/v1/sites/paper/points/5/displacements").await;
    assert_eq!(status, 200);
    let rows = series["items"].as_array().unwrap();
    assert_eq!(rows.len(), 9);
    assert_eq!(rows[0]["epoch"], 1);
    assert_eq!(rows[0]["d_mm"], 0.0);
    assert!(
        rows.windows(2)
            .all(|w| w[0]["observed_at"].as_str() < w[1]["observed_at"].as_str()),
        "oldest first"
    );
    // displacement against the reference epoch, in mm, in the reference datum
    let (_, e9) = s.get("/api/v1/sites/paper/epochs/9").await;
    let p9 = e9["points"]
        .as_array()
        .unwrap()
        .iter()
        .find(|q| q["point"] == "5")
        .unwrap();
    let p1 = full["points"]
        .as_array()
        .unwrap()
        .iter()
        .find(|q| q["point"] == "5")
        .unwrap();
    let dx = (p9["X"].as_f64().unwrap() - p1["X"].as_f64().unwrap()) * 1000.0;
    // The paper epochs observe one unmoved object: after the analysis' datum transformation (IWST:
    // no point is stable) the displacement is noise, not the raw coordinate difference between the
    // cases' datums.
    let got = rows[8]["dx_mm"].as_f64().unwrap();
    let sigma = rows[8]["sigma_dx_mm"].as_f64().unwrap();
    assert!(
        sigma > 0.0 && got.abs() <= 3.0 * sigma,
        "dx {got} ± {sigma} mm"
    );
    assert!(
        (got - dx).abs() > 0.0,
        "the datum transformation applied (raw {dx} mm)"
    );

    let r = s
        .client
        .get(s.url("/api/v1/sites/paper/points/5/displacements?format=csv&from=2000-02-01"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers()["content-type"]
        .to_str()
        .unwrap()
        .starts_with("text/csv"));
    let text = r.text().await.unwrap();
    assert!(text.starts_with("epoch,observed_at,dx_mm"));
    assert_eq!(text.lines().count(), 1 + 6);

    // direction of interest, then reference change
    let r = s
        .client
        .put(s.url("/api/v1/sites/paper/points/5"))
        .json(&json!({"role": "monitored", "direction": [0.0, -1.0, 0.0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let (_, series) = s.get("/api/v1/sites/paper/points/5/displacements").await;
    assert!(series["items"][8]["d_along_mm"].is_number());
    let r = s
        .client
        .put(s.url("/api/v1/sites/paper/reference"))
        .json(&json!({"epoch": 9}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let (_, series) = s.get("/api/v1/sites/paper/points/5/displacements").await;
    assert_eq!(series["items"][8]["d_mm"], 0.0);
    assert_eq!(series["items"][0]["reference_epoch"], 9);
    let (status, _) = s.get("/api/v1/sites/paper/points/nope/displacements").await;
    assert_eq!(status, 404);
    let (status, _) = s.get("/api/v1/sites/paper/epochs/99").await;
    assert_eq!(status, 404);
    s.stop().await;
}

#[tokio::test]
async fn same_body_is_idempotent_other_body_conflicts() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("idem").await;
    let body = paper("paper-case3-seed102");
    let (status, first) = s.upload("idem", &body).await;
    assert_eq!(status, 201, "{first}");
    let before = s.snapshot().await;
    let (status, again) = s.upload("idem", &body).await;
    assert_eq!(status, 200);
    assert_eq!(again, first, "the same result");
    // Bodies compare as parsed JSON: another layout of the same JSON is the same body.
    let pretty = serde_json::to_string_pretty(&body).unwrap();
    let r = s
        .client
        .post(s.url("/api/v1/sites/idem/epochs"))
        .header("content-type", "application/json")
        .body(pretty)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let mut other = body.clone();
    let x = other["images"][0]["observations"][0]["x_mm"]
        .as_f64()
        .unwrap();
    other["images"][0]["observations"][0]["x_mm"] = json!(x + 0.0005);
    let (status, err) = s.upload("idem", &other).await;
    assert_eq!(status, 409, "{err}");
    assert_eq!(err["error"]["code"], "conflict");
    assert_eq!(s.snapshot().await, before, "nothing stored");
    s.stop().await;
}

#[tokio::test]
async fn csv_upload_uses_the_site_cameras() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("csv").await;
    // Before any JSON epoch the site has no cameras: a state conflict, not a bad body.
    let r = s
        .client
        .post(s.url("/api/v1/sites/csv/epochs?observed_at=2000-03-18T00:00:00Z"))
        .header("content-type", "text/csv")
        .body("image,point,x_mm,y_mm\n")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let e: Value = crate::support::server::checked_json(r).await;
    assert_eq!(e["error"]["code"], "no_cameras");
    let first = paper(PAPER[6]);
    assert_eq!(s.upload("csv", &first).await.0, 201);
    let second = paper(PAPER[7]);
    let mut text = String::from("image,point,x_mm,y_mm\n");
    for im in second["images"].as_array().unwrap() {
        for o in im["observations"].as_array().unwrap() {
            text += &format!(
                "{},{},{},{}\n",
                im["id"].as_str().unwrap(),
                o["point"].as_str().unwrap(),
                o["x_mm"],
                o["y_mm"]
            );
        }
    }
    let url = s.url("/api/v1/sites/csv/epochs?observed_at=2000-03-19T00:00:00Z");
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body(text.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201, "{}", r.text().await.unwrap());
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body(text.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body("A,1,x,y\n")
        .send()
        .await
        .unwrap();
    // A coordinate that is not a number: CSV of the wrong shape, 422 naming the line.
    assert_eq!(r.status(), 422);
    let e: Value = crate::support::server::checked_json(r).await;
    assert!(
        e["error"]["message"].as_str().unwrap().contains("line 1"),
        "{e}"
    );
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body("A,1,2\n")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body("A,1,2,3\nB,1,2\n")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422, "a short second line");
    let r = s
        .client
        .post(&url)
        .header("content-type", "text/csv")
        .body(vec![0xffu8, 0xfe, b',', b'1'])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 400, "not CSV (not text) at all");
    // A second camera, brought by a JSON epoch: a CSV upload must now name its camera (the
    // first by name, "a-zoom", is not the one its images were taken with).
    let mut third = paper(PAPER[8]);
    let cam = third["cameras"][0]["id"].as_str().unwrap().to_string();
    let mut zoom = third["cameras"][0].clone();
    zoom["id"] = json!("a-zoom");
    zoom["c_mm"] = json!(800.0);
    third["cameras"].as_array_mut().unwrap().push(zoom);
    assert_eq!(s.upload("csv", &third).await.0, 201);
    let at = "observed_at=2000-03-25T00:00:00Z";
    for (query, want) in [
        (String::new(), 422),
        ("&camera=nikon".to_string(), 422),
        (format!("&camera={cam}"), 201),
    ] {
        let r = s
            .client
            .post(s.url(&format!("/api/v1/sites/csv/epochs?{at}{query}")))
            .header("content-type", "text/csv")
            .body(text.clone())
            .send()
            .await
            .unwrap();
        let status = r.status();
        let body: Value = crate::support::server::checked_json(r).await;
        assert_eq!(status, want, "{query}: {body}");
        if want == 422 {
            let m = body["error"]["message"].as_str().unwrap();
            assert!(m.contains("a-zoom") && m.contains(&cam), "{m}");
        }
    }
    s.stop().await;
}

//! The HTTP API against a real server (in process, ephemeral port, temporary data dir): uploads of
//! the paper epochs, read-back, idempotency, conflicts, rejections that store nothing, auth.

use crate::service_support;

use cliffwatch::config::{Role, TokenConfig};
use cliffwatch::photogrammetry::{adjust, AdjustOptions, EpochInput};
use serde_json::{json, Value};
use service_support::{paper, TestServer, PAPER};

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

/// Free text with NUL: 422 naming the field (the same on PostgreSQL, tests/postgres/store.rs).
#[tokio::test]
async fn text_with_nul_is_refused() {
    let server = TestServer::start(|_| {}).await;
    server.assert_nul_text_refused().await;
    server.stop().await;
}

#[tokio::test]
async fn rejections_store_nothing() {
    let s = TestServer::start(|c| c.body_limit_bytes = 1 << 20).await;
    s.create_site("rej").await;
    let good = paper("paper-case3-seed101");
    assert_eq!(s.upload("rej", &good).await.0, 201);
    let before = s.snapshot().await;
    let post = |body: Vec<u8>| {
        s.client
            .post(s.url("/api/v1/sites/rej/epochs"))
            .header("content-type", "application/json")
            .body(body)
            .send()
    };

    let r = post(br#"{"observed_at": "2001-01-01T00:00:00Z", "images": ["#.to_vec())
        .await
        .unwrap();
    assert_eq!(r.status(), 400);
    let e: Value = r.json().await.unwrap();
    assert_eq!(e["error"]["code"], "bad_request");

    // a point seen in one image only, no approximations: cannot be adjusted → 422 naming it
    let mut bad = good.clone();
    bad["observed_at"] = json!("2001-02-01T00:00:00Z");
    bad["images"][1]["observations"] =
        json!(bad["images"][1]["observations"].as_array().unwrap()[..2]);
    bad.as_object_mut().unwrap().remove("approx");
    let (status, e) = s.upload("rej", &bad).await;
    assert_eq!(status, 422, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(msg.contains("image '") || msg.contains("point '"), "{msg}");

    // schema errors: unknown camera, duplicate observation, missing field
    let mut unknown = good.clone();
    unknown["observed_at"] = json!("2001-03-01T00:00:00Z");
    unknown["images"][0]["camera"] = json!("nikon");
    let (status, e) = s.upload("rej", &unknown).await;
    assert_eq!(status, 422);
    assert!(e["error"]["message"].as_str().unwrap().contains("nikon"));
    let mut dup = good.clone();
    dup["observed_at"] = json!("2001-04-01T00:00:00Z");
    let o = dup["images"][0]["observations"][0].clone();
    dup["images"][0]["observations"]
        .as_array_mut()
        .unwrap()
        .push(o);
    assert_eq!(s.upload("rej", &dup).await.0, 422);
    let (status, _) = s.upload("rej", &json!({"images": []})).await;
    assert_eq!(status, 422);
    // A value of the wrong type: 422 naming the field by its path.
    let mut typed = good.clone();
    typed["observed_at"] = json!("2001-05-01T00:00:00Z");
    typed["cameras"][0]["c_mm"] = json!("300");
    let (status, e) = s.upload("rej", &typed).await;
    assert_eq!(status, 422, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(msg.starts_with("cameras[0].c_mm: invalid type"), "{msg}");
    // A misspelt member is refused by its path, not ignored (c would silently stay fixed).
    let mut misspelt = good.clone();
    misspelt["observed_at"] = json!("2001-05-02T00:00:00Z");
    misspelt["cameras"][0]["calibrate_C"] = json!(true);
    let (status, e) = s.upload("rej", &misspelt).await;
    assert_eq!(status, 422, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(
        msg.starts_with("cameras[0].calibrate_C: unknown field"),
        "{msg}"
    );
    // An epoch more than a year after the server's clock (a mistyped year): 422 naming it.
    let mut ahead = good.clone();
    let at = (chrono::Utc::now() + chrono::Duration::days(367))
        .to_rfc3339_opts(chrono::SecondsFormat::Secs, true);
    ahead["observed_at"] = json!(at);
    let (status, e) = s.upload("rej", &ahead).await;
    assert_eq!(status, 422, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(
        msg.contains(&at) && msg.contains("after the server's clock"),
        "{msg}"
    );
    // A number beyond f64 is valid JSON: 422 naming its field, not 400.
    let mut huge = good.clone();
    huge["observed_at"] = json!("2001-05-03T00:00:00Z");
    huge["cameras"][0]["c_mm"] = json!(12345.678);
    let text = serde_json::to_string(&huge)
        .unwrap()
        .replace("12345.678", "1e400");
    let r = post(text.into_bytes()).await.unwrap();
    assert_eq!(r.status(), 422);
    let e: Value = r.json().await.unwrap();
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(
        msg.starts_with("cameras[0].c_mm: number out of range"),
        "{msg}"
    );
    // More images than an epoch holds (the camera block is dense): 422 with the counts.
    let mut many = good.clone();
    many["observed_at"] = json!("2001-05-04T00:00:00Z");
    let image = good["images"][0].clone();
    many["images"] = (0..201)
        .map(|k| {
            let mut im = image.clone();
            im["id"] = json!(format!("I{k}"));
            im
        })
        .collect();
    let (status, e) = s.upload("rej", &many).await;
    assert_eq!(status, 422, "{e}");
    let msg = e["error"]["message"].as_str().unwrap();
    assert!(msg.contains("images: 201 given, at most 200"), "{msg}");
    // A body that is neither JSON nor CSV by its content type: 415, whatever it holds.
    let mut other = good.clone();
    other["observed_at"] = json!("2001-06-01T00:00:00Z");
    for ctype in [
        Some("text/plain"),
        Some("application/x-www-form-urlencoded"),
        None,
    ] {
        let mut r = s
            .client
            .post(s.url("/api/v1/sites/rej/epochs"))
            .body(serde_json::to_vec(&other).unwrap());
        if let Some(c) = ctype {
            r = r.header("content-type", c);
        }
        let r = r.send().await.unwrap();
        assert_eq!(r.status(), 415, "{ctype:?}");
        let e: Value = r.json().await.unwrap();
        assert_eq!(e["error"]["code"], "unsupported_media_type");
    }

    // A time that its offset carries beyond the years 0000–9999 in UTC: 422 naming it. (Stored
    // as "+10000-…", it sorted before every epoch, became the reference and emptied the series.)
    for at in ["9999-12-31T23:30:00-01:00", "0000-01-01T00:30:00+01:00"] {
        let mut far = good.clone();
        far["observed_at"] = json!(at);
        let (status, e) = s.upload("rej", &far).await;
        assert_eq!(status, 422, "{at}: {e}");
        let msg = e["error"]["message"].as_str().unwrap();
        assert!(msg.contains(at) && msg.contains("0000–9999"), "{msg}");
    }
    // As query bounds the same times bound nothing: the whole series.
    for bounds in [
        "to=9999-12-31T23:30:00-01:00",
        "from=0000-01-01T00:30:00%2B01:00",
        "from=0000-01-01T00:30:00%2B01:00&to=9999-12-31T23:30:00-01:00",
    ] {
        let (status, page) = s
            .get(&format!(
                "/api/v1/sites/rej/points/5/displacements?{bounds}"
            ))
            .await;
        assert_eq!(status, 200, "{bounds}: {page}");
        assert_eq!(
            page["items"].as_array().unwrap().len(),
            1,
            "{bounds}: {page}"
        );
    }

    let r = post(vec![b' '; (1 << 20) + 10]).await.unwrap();
    assert_eq!(r.status(), 413);
    let e: Value = r.json().await.unwrap();
    assert_eq!(e["error"]["code"], "payload_too_large");

    let (status, _) = s.upload("nosuchsite", &good).await;
    assert_eq!(status, 404);
    // An invalid body to an unknown site: the site is named first.
    let (status, e) = s.upload("nosuchsite", &json!({"images": []})).await;
    assert_eq!(status, 404, "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap()
            .contains("nosuchsite"),
        "{e}"
    );
    assert_eq!(
        s.snapshot().await,
        before,
        "nothing stored by any rejection"
    );
    s.stop().await;
}

/// With tokens configured, every operation of the document is tried without a token and, if it
/// changes something, with the read token: the answer is 401 or 403 and the document lists it for
/// that operation, with the bearer scheme among its security alternatives.
#[tokio::test]
async fn the_document_lists_the_answers_of_authorization() {
    let s = TestServer::start(|c| {
        c.tokens = vec![TokenConfig {
            token: "r".repeat(20),
            role: Role::Read,
        }]
    })
    .await;
    let doc: Value = s
        .client
        .get(s.url("/api/v1/openapi.json"))
        .bearer_auth("r".repeat(20))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let mut tried = 0;
    for (path, item) in doc["paths"].as_object().unwrap() {
        let url = s.url(&path.replace(['{', '}'], ""));
        for (method, op) in item.as_object().unwrap() {
            if !["get", "put", "post", "delete", "patch"].contains(&method.as_str()) {
                continue;
            }
            let m = reqwest::Method::from_bytes(method.to_uppercase().as_bytes()).unwrap();
            if op.get("security").is_none() {
                let r = s.client.request(m.clone(), &url).send().await.unwrap();
                assert_ne!(r.status(), 401, "{method} {path} needs no token");
                continue;
            }
            let security = op["security"].to_string();
            assert!(
                security.contains("bearer") && security.contains("{}"),
                "{method} {path}: {security}"
            );
            let r = s.client.request(m.clone(), &url).send().await.unwrap();
            assert_eq!(r.status(), 401, "{method} {path} without a token");
            assert!(
                op["responses"].get("401").is_some(),
                "{method} {path} lists 401"
            );
            tried += 1;
            // every role reads, except the webhooks' list (their URLs are capabilities)
            if m != reqwest::Method::GET || path == "/api/v1/webhooks" {
                let r = s
                    .client
                    .request(m, &url)
                    .bearer_auth("r".repeat(20))
                    .send()
                    .await
                    .unwrap();
                assert_eq!(r.status(), 403, "{method} {path} with the read token");
                assert!(
                    op["responses"].get("403").is_some(),
                    "{method} {path} lists 403"
                );
            }
        }
        for (method, op) in item.as_object().unwrap() {
            if let Some(responses) = op.get("responses") {
                for code in ["408", "500"] {
                    assert!(
                        responses.get(code).is_some(),
                        "{method} {path} lists {code}"
                    );
                }
            }
        }
    }
    assert!(tried > 20, "{tried} operations tried");
    s.stop().await;
}

/// A request not answered within `request_timeout_secs` (here an upload whose body stalls) gets
/// 408 with the error body, as the document says; nothing is stored.
#[tokio::test]
async fn a_request_over_the_time_limit_is_a_408_with_the_error_body() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let s = TestServer::start(|c| {
        c.request_timeout_secs = 1;
        c.upload_queue_secs = 0.5;
    })
    .await;
    s.create_site("slow").await;
    let before = s.snapshot().await;
    let body = serde_json::to_vec(&paper("paper-case3-seed101")).unwrap();
    let host = s.base.trim_start_matches("http://");
    let mut conn = tokio::net::TcpStream::connect(host).await.unwrap();
    let head = format!(
        "POST /api/v1/sites/slow/epochs HTTP/1.1\r\nHost: {host}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    conn.write_all(head.as_bytes()).await.unwrap();
    conn.write_all(&body[..body.len() / 2]).await.unwrap();
    let mut answer = Vec::new();
    tokio::time::timeout(
        std::time::Duration::from_secs(10),
        conn.read_to_end(&mut answer),
    )
    .await
    .expect("an answer before the rest of the body")
    .unwrap();
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    let json = &answer[answer.find("\r\n\r\n").unwrap() + 4..];
    let e: Value = serde_json::from_str(json).unwrap();
    assert_eq!(e["error"]["code"], "timeout", "{e}");
    assert_eq!(s.snapshot().await, before);
    s.stop().await;
}

#[tokio::test]
async fn tokens_and_roles() {
    let s = TestServer::start(|c| {
        c.tokens = vec![
            TokenConfig {
                token: "r".repeat(20),
                role: Role::Read,
            },
            TokenConfig {
                token: "u".repeat(20),
                role: Role::Upload,
            },
            TokenConfig {
                token: "a".repeat(20),
                role: Role::Admin,
            },
        ]
    })
    .await;
    let site = json!({"id": "auth"});
    let post = |token: Option<String>| {
        let mut r = s.client.post(s.url("/api/v1/sites")).json(&site);
        if let Some(t) = token {
            r = r.bearer_auth(t);
        }
        r.send()
    };
    assert_eq!(post(None).await.unwrap().status(), 401);
    assert_eq!(post(Some("wrong".into())).await.unwrap().status(), 401);
    assert_eq!(post(Some("r".repeat(20))).await.unwrap().status(), 403);
    assert_eq!(post(Some("u".repeat(20))).await.unwrap().status(), 403);
    let before = s.snapshot().await;
    let r = s
        .client
        .post(s.url("/api/v1/sites/auth/epochs"))
        .bearer_auth("r".repeat(20))
        .json(&paper(PAPER[0]))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 403);
    let e: Value = r.json().await.unwrap();
    assert_eq!(e["error"]["code"], "forbidden");
    assert_eq!(s.snapshot().await, before);
    assert_eq!(post(Some("a".repeat(20))).await.unwrap().status(), 201);
    let r = s.client.get(s.url("/api/v1/sites")).send().await.unwrap();
    assert_eq!(r.status(), 401);
    let r = s
        .client
        .get(s.url("/api/v1/sites"))
        .bearer_auth("r".repeat(20))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    // The webhooks' list shows their URLs, often capabilities: admin only.
    for (token, status) in [("r", 403), ("u", 403), ("a", 200)] {
        let r = s
            .client
            .get(s.url("/api/v1/webhooks"))
            .bearer_auth(token.repeat(20))
            .send()
            .await
            .unwrap();
        assert_eq!(
            r.status(),
            status,
            "GET /api/v1/webhooks with the {token} token"
        );
    }
    assert_eq!(
        s.client
            .get(s.url("/healthz"))
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    s.stop().await;
}

/// Without tokens, a request is served only when its `Host` names the loopback or `public_url`'s
/// host: a page whose DNS name was re-pointed at 127.0.0.1 (DNS rebinding) sends same-origin
/// requests with its own name as `Host`, and must get nothing, neither a read nor a change.
#[tokio::test]
async fn without_tokens_only_local_host_names_are_served() {
    let s = TestServer::start(|c| c.public_url = Some("https://cliff.example.org/".into())).await;
    let port = s.base.rsplit(':').next().unwrap().to_string();
    let hook = json!({"url": "https://attacker.example/x", "secret": format!("whsec_{}", "QUJD".repeat(8))});
    let get = |path: &str, host: &str| s.client.get(s.url(path)).header("host", host).send();
    let before = s.snapshot().await;
    for host in [
        "rebind.attacker.example",
        "127.0.0.1.attacker.example",
        "10.0.0.1",
    ] {
        let host = format!("{host}:{port}");
        let r = get("/api/v1/sites", &host).await.unwrap();
        assert_eq!(r.status(), 403, "GET with Host {host}");
        let e: Value = r.json().await.unwrap();
        assert!(
            e["error"]["message"].as_str().unwrap().contains("loopback"),
            "{e}"
        );
        let r = s
            .client
            .post(s.url("/api/v1/webhooks"))
            .header("host", &host)
            .header("origin", format!("http://{host}"))
            .header("sec-fetch-site", "same-origin")
            .json(&hook)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 403, "POST with Host {host}");
        // liveness and the dashboard's assets expose nothing and stay open
        let r = get("/healthz", &host).await.unwrap();
        assert_eq!(r.status(), 200, "/healthz with Host {host}");
    }
    assert_eq!(s.snapshot().await, before, "nothing stored");
    for host in [
        format!("localhost:{port}"),
        format!("127.0.0.1:{port}"),
        format!("127.1.2.3:{port}"),
        format!("[::1]:{port}"),
        "cliff.example.org".to_string(),
        "CLIFF.example.org:443".to_string(),
    ] {
        let r = get("/api/v1/sites", &host).await.unwrap();
        assert_eq!(r.status(), 200, "GET with Host {host}");
    }
    s.stop().await;
}

#[tokio::test]
async fn health_metrics_openapi_and_request_ids() {
    let s = TestServer::start(|_| {}).await;
    assert_eq!(s.get("/healthz").await.0, 200);
    assert_eq!(s.get("/readyz").await.0, 200);
    let (status, doc) = s.get("/api/v1/openapi.json").await;
    assert_eq!(status, 200);
    for path in [
        "/api/v1/sites/{site}/epochs",
        "/api/v1/sites/{site}/points/{point}/displacements",
        "/api/v1/alerts/{id}/ack",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path}");
    }
    let r = s.client.get(s.url("/metrics")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers().contains_key("x-request-id"));
    assert!(r.text().await.unwrap().contains("# TYPE"));
    let (status, e) = s.get("/api/v1/sites/none").await;
    assert_eq!(status, 404);
    assert_eq!(e["error"]["code"], "not_found");
    let (status, alerts) = s.get("/api/v1/alerts?state=open").await;
    assert_eq!(status, 200);
    assert_eq!(alerts, json!({"items": [], "next_cursor": null}));
    assert_eq!(
        s.client
            .post(s.url("/api/v1/alerts/x/ack"))
            .json(&json!({"by": "me"}))
            .send()
            .await
            .unwrap()
            .status(),
        404
    );
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/hook", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let (_, hooks) = s.get("/api/v1/webhooks").await;
    assert_eq!(hooks["items"].as_array().unwrap().len(), 1);
    assert!(hooks["items"][0].get("secret").is_none());
    assert_eq!(hooks["items"][0]["format"], "standard");
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/am", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", "format": "alertmanager_api_v2"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let created: Value = r.json().await.unwrap();
    assert_eq!(created["format"], "alertmanager_api_v2");
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/am", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", "format": "prometheus"})).send().await.unwrap();
    assert_eq!(r.status(), 422);
    let e: Value = r.json().await.unwrap();
    assert!(
        e["error"]["message"].as_str().unwrap().contains("format"),
        "{e}"
    );
    let (_, hooks) = s.get("/api/v1/webhooks").await;
    assert_eq!(hooks["items"].as_array().unwrap().len(), 2);
    // A secret whose base64 does not decode would fail every delivery: refused at creation, and
    // the document's pattern says which secrets are taken.
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let pattern = doc["components"]["schemas"]["NewWebhook"]["properties"]["secret"]["pattern"]
        .as_str()
        .expect("the secret's pattern");
    let pattern = regex::Regex::new(pattern).unwrap();
    for (secret, want) in [
        ("whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", 201),
        ("whsec_Y2xpZmZ3YXRjaC1hbS13ZWJob29rLXY0", 201),
        ("whsec_YWJj", 201),
        ("whsec_YWJjZA==", 201),
        ("whsec_YWJjZGU=", 201),
        ("whsec_abcdef", 422),
        ("whsec_not base64!", 422),
        ("whsec_YWJjZB==", 422),
        ("whsec_YQ==", 422),
        ("MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", 422),
    ] {
        let r = s
            .client
            .post(s.url("/api/v1/webhooks"))
            .json(&json!({"url": "http://127.0.0.1:9/h", "secret": secret}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), want, "{secret}");
        assert_eq!(pattern.is_match(secret), want == 201, "pattern on {secret}");
    }
    // A URL that does not parse, or names no host, could never be delivered to.
    for url in ["http://[", "https://", "http:///path", "ftp://a.example/h"] {
        let r = s
            .client
            .post(s.url("/api/v1/webhooks"))
            .json(&json!({"url": url, "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 422, "{url}");
    }
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
    let e: Value = r.json().await.unwrap();
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
    let e: Value = r.json().await.unwrap();
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
        let body: Value = r.json().await.unwrap();
        assert_eq!(status, want, "{query}: {body}");
        if want == 422 {
            let m = body["error"]["message"].as_str().unwrap();
            assert!(m.contains("a-zoom") && m.contains(&cam), "{m}");
        }
    }
    s.stop().await;
}

/// Follows `$ref`s of the OpenAPI document to the schema itself.
fn resolve<'a>(doc: &'a Value, schema: &'a Value) -> &'a Value {
    match schema["$ref"].as_str() {
        Some(r) => {
            let name = r.trim_start_matches("#/components/schemas/");
            resolve(doc, &doc["components"]["schemas"][name])
        }
        None => schema,
    }
}

/// The property names of an object schema (through `$ref` and `allOf`).
fn properties(doc: &Value, schema: &Value) -> Vec<String> {
    let s = resolve(doc, schema);
    let mut names: Vec<String> = s["properties"]
        .as_object()
        .map(|p| p.keys().cloned().collect())
        .unwrap_or_default();
    for part in s["allOf"].as_array().into_iter().flatten() {
        names.extend(properties(doc, part));
    }
    names
}

/// Checks `value` against `schema` of the OpenAPI document (3.1: `$ref`, `allOf`, `oneOf`,
/// `anyOf`, `type` as a name or a list, `enum`, `properties`, `required`, `items`); an object
/// member the schema does not name is an error too. Appends what does not conform to `errors`.
fn conforms(doc: &Value, schema: &Value, value: &Value, at: &str, errors: &mut Vec<String>) {
    let s = resolve(doc, schema);
    if let Some(parts) = s["allOf"].as_array() {
        // members are checked against the union of the parts' properties below
        for part in parts {
            let part = resolve(doc, part);
            for name in part["required"].as_array().into_iter().flatten() {
                if value.get(name.as_str().unwrap()).is_none() {
                    errors.push(format!("{at}: required member {name} missing"));
                }
            }
        }
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(alternatives) = s[key].as_array() {
            let fits = alternatives.iter().any(|a| {
                let mut e = Vec::new();
                conforms(doc, a, value, at, &mut e);
                e.is_empty()
            });
            if !fits {
                errors.push(format!("{at}: {value} fits none of {key}"));
            }
            return;
        }
    }
    let type_ok = |t: &str| match t {
        "null" => value.is_null(),
        "boolean" => value.is_boolean(),
        "string" => value.is_string(),
        "integer" => value.is_i64() || value.is_u64(),
        "number" => value.is_number(),
        "array" => value.is_array(),
        "object" => value.is_object(),
        _ => true,
    };
    let types: Vec<&str> = match &s["type"] {
        Value::String(t) => vec![t.as_str()],
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    if !types.is_empty() && !types.iter().any(|t| type_ok(t)) {
        errors.push(format!("{at}: {value} is not {types:?}"));
        return;
    }
    if let Some(allowed) = s["enum"].as_array() {
        if !allowed.contains(value) {
            errors.push(format!("{at}: {value} not in {allowed:?}"));
        }
    }
    if let (Some(items), Some(values)) = (s.get("items"), value.as_array()) {
        for (k, v) in values.iter().enumerate() {
            conforms(doc, items, v, &format!("{at}[{k}]"), errors);
        }
    }
    if let Some(members) = value.as_object() {
        let names = properties(doc, s);
        if names.is_empty() {
            return; // a free-form object
        }
        for name in s["required"].as_array().into_iter().flatten() {
            if !members.contains_key(name.as_str().unwrap()) {
                errors.push(format!("{at}: required member {name} missing"));
            }
        }
        for (name, v) in members {
            let Some(member_schema) = member_schema(doc, s, name) else {
                errors.push(format!("{at}: member '{name}' is not in the schema"));
                continue;
            };
            conforms(doc, member_schema, v, &format!("{at}.{name}"), errors);
        }
    }
}

/// The schema of member `name` of an object schema (through `$ref` and `allOf`).
fn member_schema<'a>(doc: &'a Value, schema: &'a Value, name: &str) -> Option<&'a Value> {
    let s = resolve(doc, schema);
    if let Some(m) = s["properties"].get(name) {
        return Some(m);
    }
    s["allOf"]
        .as_array()
        .into_iter()
        .flatten()
        .find_map(|part| member_schema(doc, part, name))
}

#[tokio::test]
async fn epoch_summaries_and_errors_conform_to_their_schemas() {
    let s = TestServer::start(|_| {}).await;
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let schema = |name: &str| json!({ "$ref": format!("#/components/schemas/{name}") });
    s.create_site("paper").await;
    // an epoch with a blunder, so that `dropped` and the residuals' `w` are filled
    let mut body = paper(PAPER[3]);
    let blunder = &mut body["images"][0]["observations"][3]["x_mm"];
    *blunder = json!(blunder.as_f64().unwrap() + 0.05);
    let (status, created) = s.upload("paper", &body).await;
    assert_eq!(status, 201, "{created}");
    assert!(
        !created["dropped"].as_array().unwrap().is_empty(),
        "the blunder is dropped: {}",
        created["dropped"]
    );
    // The epoch list counts them (the site page's column) without reading the report.
    let n_dropped = json!(created["dropped"].as_array().unwrap().len());
    assert_eq!(created["dropped_observations"], n_dropped);
    let (status, list) = s.get("/api/v1/sites/paper/epochs").await;
    assert_eq!(status, 200);
    assert_eq!(
        list["items"][0]["dropped_observations"], n_dropped,
        "{list}"
    );
    let (status, full) = s.get("/api/v1/sites/paper/epochs/1").await;
    assert_eq!(status, 200);
    assert!(!full["residuals"].as_array().unwrap().is_empty());
    assert!(created.get("residuals").is_none(), "detail view only");
    // The global test: the reported variance factor against χ²(r)/r bounds around 1, 0.1 % in
    // each tail; the paper's noise matches its a-priori σ, so it is accepted.
    let t = &full["global_test"];
    let (lower, upper, vf) = (
        t["lower"].as_f64().unwrap(),
        t["upper"].as_f64().unwrap(),
        t["variance_factor"].as_f64().unwrap(),
    );
    assert_eq!(vf, full["variance_factor"].as_f64().unwrap());
    assert!(lower < 1.0 && 1.0 < upper, "{t}");
    assert_eq!(t["accepted"], json!((lower..=upper).contains(&vf)), "{t}");
    assert_eq!(t["accepted"], json!(true), "{t}");
    assert_eq!(t["confidence"], json!(0.998));
    let (status, missing) = s.get("/api/v1/sites/paper/epochs/9").await;
    assert_eq!(status, 404);
    let (status, healthy) = s.get("/healthz").await;
    assert_eq!(status, 200);
    let mut errors = Vec::new();
    conforms(
        &doc,
        &schema("EpochSummary"),
        &created,
        "upload",
        &mut errors,
    );
    conforms(&doc, &schema("EpochSummary"), &full, "epoch", &mut errors);
    conforms(&doc, &schema("ErrorBody"), &missing, "404", &mut errors);
    conforms(&doc, &schema("Status"), &healthy, "healthz", &mut errors);
    assert!(errors.is_empty(), "{errors:#?}");
    // the checker itself: a wrong type, an unknown member and a missing one are caught
    let mut wrong = full.clone();
    wrong["cameras"][0]["c_mm"] = json!("300");
    wrong["points"][0]["extra"] = json!(1);
    wrong["images"][0].as_object_mut().unwrap().remove("rms_mm");
    let mut errors = Vec::new();
    conforms(&doc, &schema("EpochSummary"), &wrong, "epoch", &mut errors);
    assert_eq!(errors.len(), 3, "{errors:#?}");
    s.stop().await;
}

/// Every `pattern` in the document (schemas and parameters), recursively.
fn patterns(v: &Value, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                match (k.as_str(), x) {
                    ("pattern", Value::String(p)) => out.push(p.clone()),
                    _ => patterns(x, out),
                }
            }
        }
        Value::Array(a) => a.iter().for_each(|x| patterns(x, out)),
        _ => {}
    }
}

#[tokio::test]
async fn upload_form_bounds_in_the_document_are_the_cores_limits() {
    use cliffwatch::photogrammetry::input::epoch::{MAX_IMAGE_COORDINATE, MAX_OBJECT_COORDINATE_M};
    let s = TestServer::start(|_| {}).await;
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let schemas = &doc["components"]["schemas"];
    let bounds: [(&str, &[&str], f64); 3] = [
        (
            "ObservationInput",
            &["x_mm", "y_mm", "col", "row"],
            MAX_IMAGE_COORDINATE,
        ),
        ("ControlInput", &["X", "Y", "Z"], MAX_OBJECT_COORDINATE_M),
        ("ApproxInput", &["X", "Y", "Z"], MAX_OBJECT_COORDINATE_M),
    ];
    for (schema, fields, limit) in bounds {
        for field in fields {
            let p = &schemas[schema]["properties"][field];
            assert_eq!(p["maximum"].as_f64(), Some(limit), "{schema}.{field}: {p}");
            assert_eq!(p["minimum"].as_f64(), Some(-limit), "{schema}.{field}: {p}");
        }
    }
    // one identifier rule everywhere: every identifier pattern of the document (the other
    // patterns are cursors, URLs, secrets, …) is the core's rule, which refuses what it refuses
    let mut found = Vec::new();
    patterns(&doc, &mut found);
    let identifiers: Vec<&String> = found.iter().filter(|p| p.contains("A-Za-z0-9._")).collect();
    assert!(identifiers.len() >= 5, "{found:?}");
    assert!(
        identifiers.iter().all(|p| *p == "^[A-Za-z0-9._-]{1,64}$"),
        "{identifiers:?}"
    );
    use cliffwatch::photogrammetry::input::epoch::is_valid_identifier as valid;
    assert!(valid(&"a".repeat(64)) && valid("T-1.b_2"));
    assert!(!valid(&"a".repeat(65)) && !valid("") && !valid("a b") && !valid("é"));
    s.stop().await;
}

#[tokio::test]
async fn openapi_describes_every_contract_endpoint_with_schemas() {
    let s = TestServer::start(|_| {}).await;
    let (status, doc) = s.get("/api/v1/openapi.json").await;
    assert_eq!(status, 200);
    // (method, path, success status, list endpoint, request body)
    let endpoints = [
        ("get", "/healthz", "200", false, false),
        ("get", "/readyz", "200", false, false),
        ("get", "/metrics", "200", false, false),
        ("post", "/api/v1/sites", "201", false, true),
        ("get", "/api/v1/sites", "200", true, false),
        ("get", "/api/v1/sites/{site}", "200", false, false),
        ("post", "/api/v1/sites/{site}/epochs", "201", false, true),
        ("get", "/api/v1/sites/{site}/epochs", "200", true, false),
        (
            "get",
            "/api/v1/sites/{site}/epochs/{epoch}",
            "200",
            false,
            false,
        ),
        ("put", "/api/v1/sites/{site}/reference", "200", false, true),
        ("get", "/api/v1/sites/{site}/points", "200", true, false),
        (
            "put",
            "/api/v1/sites/{site}/points/{point}",
            "200",
            false,
            true,
        ),
        (
            "get",
            "/api/v1/sites/{site}/points/{point}/displacements",
            "200",
            true,
            false,
        ),
        ("get", "/api/v1/alerts", "200", true, false),
        ("post", "/api/v1/alerts/{id}/ack", "200", false, true),
        ("post", "/api/v1/webhooks", "201", false, true),
        ("get", "/api/v1/webhooks", "200", true, false),
    ];
    for (method, path, ok, list, request) in endpoints {
        let op = &doc["paths"][path][method];
        assert!(op.is_object(), "{method} {path} missing");
        let content = &op["responses"][ok]["content"];
        let (media, body) = content
            .as_object()
            .and_then(|c| c.iter().next())
            .unwrap_or_else(|| panic!("{method} {path}: no {ok} response schema"));
        let schema = &body["schema"];
        assert!(
            schema.is_object(),
            "{method} {path}: {media} without schema"
        );
        if media == "application/json" {
            let props = properties(&doc, schema);
            assert!(!props.is_empty(), "{method} {path}: no properties");
            if list {
                assert!(
                    props.contains(&"items".to_string())
                        && props.contains(&"next_cursor".to_string()),
                    "{method} {path}: not the list shape: {props:?}"
                );
                let item = &resolve(&doc, schema)["properties"]["items"]["items"];
                assert!(
                    !properties(&doc, item).is_empty(),
                    "{method} {path}: list items without a schema"
                );
            }
        }
        if request {
            assert!(
                op["requestBody"]["content"]["application/json"]["schema"].is_object(),
                "{method} {path}: no request schema"
            );
        }
        // every error answer names the error body
        for (code, r) in op["responses"].as_object().unwrap() {
            if code.starts_with('4') || code.starts_with('5') {
                assert!(
                    r["content"]["application/json"]["schema"].is_object(),
                    "{method} {path} {code}: no error schema"
                );
            }
        }
    }
    // the webhook schemas name the body formats
    for name in ["NewWebhook", "Webhook"] {
        let format = &doc["components"]["schemas"][name]["properties"]["format"];
        assert_eq!(
            format["enum"],
            json!(["standard", "alertmanager_webhook", "alertmanager_api_v2"]),
            "{name}.format: {format}"
        );
    }
    // the documented upload form names every field the paper epochs use
    let form = &doc["paths"]["/api/v1/sites/{site}/epochs"]["post"]["requestBody"]["content"]
        ["application/json"]["schema"];
    let epoch = paper(PAPER[0]);
    let top = properties(&doc, form);
    let form = resolve(&doc, form);
    for (key, value) in epoch.as_object().unwrap() {
        assert!(top.contains(key), "upload form lacks '{key}'");
        if let Some(first) = value.as_array().and_then(|a| a.first()) {
            let item = &form["properties"][key]["items"];
            let names = properties(&doc, item);
            for k in first.as_object().unwrap().keys() {
                assert!(names.contains(k), "upload form: {key} lacks '{k}'");
            }
        }
    }
    // null where the document allows it, and only there: the schema is that of the types that
    // read the form (a hand-written copy once documented null for fields the server refused)
    let camera = resolve(&doc, &form["properties"]["cameras"]["items"]).clone();
    let nullable = |schema: &Value, field: &str| {
        schema["properties"][field]["type"]
            .as_array()
            .is_some_and(|t| t.contains(&json!("null")))
    };
    s.create_site("n").await;
    for (k, (field, on_camera)) in [
        ("label", false),
        ("control", false),
        ("calibrate_c", true),
        ("k1", true),
        ("sigma_mm", true),
    ]
    .into_iter()
    .enumerate()
    {
        let mut body = paper(PAPER[0]);
        body["observed_at"] = json!(format!("2026-02-0{}T00:00:00Z", k + 1));
        if on_camera {
            body["cameras"][0][field] = Value::Null;
        } else {
            body[field] = Value::Null;
        }
        let documented = nullable(if on_camera { &camera } else { form }, field);
        let (status, answer) = s.upload("n", &body).await;
        assert_eq!(
            status == 201,
            documented,
            "{field}: null documented {documented}, answered {status} {answer}"
        );
    }
    // the bounds the core checks are in the document: c_mm in (0, 100 m], the distortion terms
    // within ±1000, calibrate's names
    let c = &camera["properties"];
    assert_eq!(c["c_mm"]["exclusiveMinimum"], json!(0));
    assert_eq!(c["c_mm"]["maximum"], json!(100_000));
    assert_eq!(c["k1"]["maximum"], json!(1000));
    assert_eq!(
        c["calibrate"]["items"]["enum"],
        json!(cliffwatch::photogrammetry::model::camera::INTERIOR_NAMES)
    );
    for (k, (field, value)) in [("c_mm", json!(0.0)), ("k1", json!(1000.5))]
        .into_iter()
        .enumerate()
    {
        let mut body = paper(PAPER[0]);
        body["observed_at"] = json!(format!("2026-03-0{}T00:00:00Z", k + 1));
        body["cameras"][0][field] = value;
        assert_eq!(s.upload("n", &body).await.0, 422, "{field}");
    }
    s.stop().await;
}

/// What the OpenAPI document promises of bodies: an object (an array is refused although serde
/// would read a struct from one), integers also written as integral floats, bounds that hold
/// after parsing.
#[tokio::test]
async fn bodies_are_objects_integers_may_be_integral_floats() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("b").await;
    assert_eq!(s.upload("b", &paper(PAPER[6])).await.0, 201);
    let send = |method: reqwest::Method, path: &str, body: Value| {
        s.client.request(method, s.url(path)).json(&body).send()
    };
    let status = |r: reqwest::Response| r.status().as_u16();
    let put = reqwest::Method::PUT;
    let post = reqwest::Method::POST;
    let r = send(put.clone(), "/api/v1/sites/b/points/1", json!([null, null]));
    assert_eq!(status(r.await.unwrap()), 422);
    let r = send(
        put.clone(),
        "/api/v1/sites/b/points/1",
        json!({"role": "stable"}),
    );
    assert_eq!(status(r.await.unwrap()), 200);
    let r = send(
        put.clone(),
        "/api/v1/sites/b/reference",
        json!({"epoch": 1.0}),
    );
    assert_eq!(status(r.await.unwrap()), 200);
    let r = send(
        put.clone(),
        "/api/v1/sites/b/reference",
        json!({"epoch": 1.5}),
    );
    assert_eq!(status(r.await.unwrap()), 422);
    let r = send(
        put.clone(),
        "/api/v1/sites/b/reference",
        json!({"epoch": 99.0}),
    );
    // An epoch the site does not have, named in the body: 422 like an unknown camera (404 is for
    // what the path names).
    assert_eq!(status(r.await.unwrap()), 422);
    // A misspelt member is refused, not read as "back to the earliest epoch".
    for body in [json!({"epoch_id": 1}), json!({"epoch": 1, "epochs": 2})] {
        let r = send(put.clone(), "/api/v1/sites/b/reference", body.clone());
        assert_eq!(status(r.await.unwrap()), 422, "{body}");
    }
    let rule = |for_epochs: Value| {
        json!({"id": "r", "alert_rules": [{"level": "watch", "metric": "displacement_mm",
               "above": 5.0, "for_epochs": for_epochs}]})
    };
    for (body, want) in [
        (rule(json!(2.0)), 201),
        (rule(json!(0)), 422),
        (rule(json!(1001)), 422),
        (json!({"id": "h", "schedule_hours": -1.0}), 422),
        (json!({"id": "h", "schedule_hours": 24}), 201),
        (json!({"id": "c", "confidence": 0.999}), 201),
        (
            json!({"id": "t", "alert_rules": [{"level": "alarm", "metric": "time_to_failure_hours",
                   "below": 96, "confidence": 1.0}]}),
            422,
        ),
        (
            json!({"id": "t", "alert_rules": [{"level": "alarm", "metric": "time_to_failure_hours",
                   "below": 96, "confidence": 0.99}]}),
            201,
        ),
        // Rules that would fire on everything or nothing: a time to failure "above" a number of
        // hours, a negative or zero horizon, a negative length.
        (
            json!({"id": "u", "alert_rules": [{"level": "alarm", "metric": "time_to_failure_hours",
                   "above": 96}]}),
            422,
        ),
        (
            json!({"id": "u", "alert_rules": [{"level": "alarm", "metric": "time_to_failure_hours",
                   "below": 0}]}),
            422,
        ),
        (
            json!({"id": "u", "alert_rules": [{"level": "watch", "metric": "displacement_mm",
                   "above": -1}]}),
            422,
        ),
        (
            json!({"id": "u", "alert_rules": [{"level": "watch", "metric": "displacement_mm",
                   "below": 5}]}),
            422,
        ),
        (
            json!({"id": "u", "alert_rules": [{"level": "watch", "metric": "displacement_mm",
                   "above": 5, "clear_bellow": 3}]}),
            422,
        ),
        (
            json!({"id": "u", "alert_rules": [{"level": "watch", "metric": "displacement_along_mm",
                   "below": -5}]}),
            201,
        ),
    ] {
        let r = send(post.clone(), "/api/v1/sites", body.clone())
            .await
            .unwrap();
        assert_eq!(status(r), want, "{body}");
    }
    // 0.99999999999999999 is below 1 as written but reads as 1.0: refused, as the document's
    // maximum (0.999999) says.
    let r = s
        .client
        .post(s.url("/api/v1/sites"))
        .header("content-type", "application/json")
        .body(r#"{"id": "d", "confidence": 0.99999999999999999}"#)
        .send()
        .await
        .unwrap();
    assert_eq!(status(r), 422);
    s.stop().await;
}

#[tokio::test]
async fn point_settings_keep_what_is_left_out_and_clear_what_is_null() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("pts").await;
    let put = |body: Value| {
        let req = s
            .client
            .put(s.url("/api/v1/sites/pts/points/P1"))
            .json(&body);
        async move {
            let r = req.send().await.unwrap();
            let status = r.status().as_u16();
            (status, r.json::<Value>().await.unwrap())
        }
    };
    let (st, p) = put(json!({"group": "B1", "direction": [0.0, -2.0, 1.0]})).await;
    assert_eq!(st, 200, "{p}");
    assert_eq!(
        (&p["role"], &p["group"], &p["direction"]),
        (&json!("monitored"), &json!("B1"), &json!([0.0, -2.0, 1.0]))
    );
    // Left out: kept.
    let (st, p) = put(json!({"role": "stable"})).await;
    assert_eq!(st, 200, "{p}");
    assert_eq!(
        (&p["role"], &p["group"], &p["direction"]),
        (&json!("stable"), &json!("B1"), &json!([0.0, -2.0, 1.0]))
    );
    // null: cleared, one member at a time.
    let (st, p) = put(json!({"group": null})).await;
    assert_eq!(st, 200, "{p}");
    assert_eq!(
        (&p["group"], &p["direction"]),
        (&Value::Null, &json!([0.0, -2.0, 1.0]))
    );
    let (st, p) = put(json!({"direction": null})).await;
    assert_eq!(st, 200, "{p}");
    assert_eq!(
        (&p["role"], &p["group"], &p["direction"]),
        (&json!("stable"), &Value::Null, &Value::Null)
    );
    // A group name is an identifier; nothing is stored when it is not.
    let (st, e) = put(json!({"group": "B 1", "role": "monitored"})).await;
    assert_eq!(st, 422, "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap()
            .contains("group 'B 1'"),
        "{e}"
    );
    // A direction whose length overflows (or is zero) has no unit vector: refused.
    for d in [json!([1e308, 1e308, 0.0]), json!([0.0, 0.0, 0.0])] {
        let (st, e) = put(json!({"direction": d})).await;
        assert_eq!(st, 422, "{d}: {e}");
        assert!(
            e["error"]["message"]
                .as_str()
                .unwrap()
                .starts_with("direction:"),
            "{e}"
        );
    }
    let (_, list) = s.get("/api/v1/sites/pts/points").await;
    assert_eq!(list["items"][0]["role"], "stable", "{list}");
    assert_eq!(list["items"][0]["direction"], Value::Null, "{list}");
    s.stop().await;
}

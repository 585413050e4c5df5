//! Bad input refused by name, storing nothing: text with NUL, every malformed or out-of-bounds
//! upload, bodies that are not objects, integers sent as integral floats.

use crate::support;

use serde_json::{json, Value};
use support::server::{paper, TestServer, PAPER};

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
    let e: Value = crate::support::server::checked_json(r).await;
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
    let e: Value = crate::support::server::checked_json(r).await;
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
        let e: Value = crate::support::server::checked_json(r).await;
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
    let e: Value = crate::support::server::checked_json(r).await;
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

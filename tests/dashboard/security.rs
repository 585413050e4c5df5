//! What the service refuses or forbids on every answer, against a real server: no answer may be
//! framed or type-sniffed, a browser's change from another origin is refused with or without a
//! bearer token, `.` and `..` are not ids, and every free-text field is bounded (422 naming it).

use crate::support;

use cliffwatch::config::{Role, TokenConfig};
use serde_json::{json, Value};
use support::dashboard::{fill, SITE};
use support::server::TestServer;

#[tokio::test]
async fn every_answer_forbids_framing_and_sniffing() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 2, None).await;
    for path in [
        "/".to_string(),
        format!("/sites/{SITE}"),
        "/sites/nope".to_string(),
        "/assets/dashboard.css".to_string(),
        "/api/v1/sites".to_string(),
        "/api/v1/nope".to_string(),
        "/healthz".to_string(),
    ] {
        let r = s.client.get(s.url(&path)).send().await.unwrap();
        let h = r.headers();
        assert_eq!(h["x-frame-options"], "DENY", "{path}");
        assert_eq!(h["x-content-type-options"], "nosniff", "{path}");
        assert_eq!(
            h["content-security-policy"], "frame-ancestors 'none'",
            "{path}"
        );
    }
    s.stop().await;
}

#[tokio::test]
async fn a_foreign_origin_is_refused_with_a_token_too() {
    let s = TestServer::start(|c| {
        c.tokens = vec![TokenConfig {
            token: "admin-token-1".into(),
            role: Role::Admin,
        }];
    })
    .await;
    let host = s
        .url("")
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let create = |origin: Option<String>, id: &str| {
        let mut r = s
            .client
            .post(s.url("/api/v1/sites"))
            .bearer_auth("admin-token-1")
            .json(&json!({"id": id}));
        if let Some(o) = origin {
            r = r.header("origin", o);
        }
        r.send()
    };
    // Another host, or this host and port under another scheme, or another port: 403.
    for origin in [
        "https://evil.example".to_string(),
        format!("https://{host}"),
        format!("http://{}:1", host.split(':').next().unwrap()),
    ] {
        let r = create(Some(origin.clone()), "a").await.unwrap();
        assert_eq!(r.status(), 403, "{origin}");
    }
    let sites: Value = s
        .client
        .get(s.url("/api/v1/sites"))
        .bearer_auth("admin-token-1")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(sites["items"], json!([]), "nothing was created");
    // The service's own origin, and a client that sends none, may.
    assert_eq!(
        create(Some(format!("http://{host}")), "b")
            .await
            .unwrap()
            .status(),
        201
    );
    assert_eq!(create(None, "c").await.unwrap().status(), 201);
    s.stop().await;
}

#[tokio::test]
async fn dot_ids_and_unbounded_text_are_refused_by_name() {
    let s = TestServer::start(|_| {}).await;
    for id in [".", ".."] {
        let (st, e) = s.post("/api/v1/sites", &json!({"id": id})).await;
        assert_eq!(st, 422, "{id}: {e}");
        assert!(message(&e).starts_with(&format!("id '{id}'")), "{e}");
    }
    // A long display name: 422 naming the field and its bound; nothing stored.
    let (st, e) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "k", "name": "x".repeat(201)}),
        )
        .await;
    assert_eq!(st, 422, "{e}");
    assert_eq!(message(&e), "name: 201 characters; at most 200");
    let (st, _) = s.get("/api/v1/sites/k").await;
    assert_eq!(st, 404);
    let (st, _) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "k", "name": "x".repeat(200)}),
        )
        .await;
    assert_eq!(st, 201);
    s.stop().await;
}

fn message(e: &Value) -> &str {
    e["error"]["message"].as_str().unwrap_or_default()
}

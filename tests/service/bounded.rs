//! Every field bounded (issue 79, item 4): a webhook URL over 2048 characters is refused with 422
//! naming `url` and the limit, and nothing is stored; an epoch's label over 200 characters the
//! same; a 10 000-character value repeated in an error (a site's id, an image's id, an unknown
//! enum name, a path segment) comes back cut to 80 characters and an ellipsis.

use crate::support;

use serde_json::{json, Value};
use support::server::{paper, TestServer};

/// The message of an error answer.
fn message(e: &Value) -> &str {
    e["error"]["message"].as_str().unwrap_or_default()
}

/// Asserts that `msg` repeats `value` (a run of one character) cut to 80 characters and `…`.
fn assert_cut(msg: &str, value: &str) {
    let c = value.chars().next().unwrap();
    let shown: String = std::iter::repeat_n(c, 80).collect();
    assert!(msg.contains(&format!("{shown}…")), "{msg}");
    assert!(
        !msg.contains(&format!("{shown}{c}")),
        "more than 80 repeated: {msg}"
    );
    assert!(
        msg.chars().count() < 400,
        "{} characters",
        msg.chars().count()
    );
}

#[tokio::test]
async fn an_overlong_webhook_url_is_refused_naming_url_and_the_limit_and_nothing_is_stored() {
    let s = TestServer::start(|_| {}).await;
    let before = s.snapshot().await;
    // 1 000 023 characters, as in the issue: a URL that parses, but could never be delivered
    let url = format!("https://hooks.example.org/{}", "a".repeat(1_000_023 - 26));
    assert_eq!(url.chars().count(), 1_000_023);
    let hook = json!({"url": url, "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"});
    let (status, e) = s.post("/api/v1/webhooks", &hook).await;
    assert_eq!(status, 422, "{e}");
    assert_eq!(e["error"]["code"], "invalid_webhook");
    assert_eq!(message(&e), "url: 1000023 characters; at most 2048");
    assert_eq!(s.snapshot().await, before, "nothing stored");
    let (status, list) = s.get("/api/v1/webhooks").await;
    assert_eq!(
        (status, list["items"].as_array().map(Vec::len)),
        (200, Some(0))
    );
    // at the limit: stored
    let at_limit = format!("https://hooks.example.org/{}", "a".repeat(2048 - 26));
    let ok = json!({"url": at_limit, "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"});
    let (status, e) = s.post("/api/v1/webhooks", &ok).await;
    assert_eq!(status, 201, "{e}");
    // an overlong secret: named with its limit
    let secret = format!("whsec_{}", "A".repeat(400));
    let hook = json!({"url": "https://hooks.example.org/x", "secret": secret});
    let (status, e) = s.post("/api/v1/webhooks", &hook).await;
    assert_eq!(status, 422, "{e}");
    assert_eq!(message(&e), "secret: 406 characters; at most 256");
    // the OpenAPI document states the limits
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let schemas = &doc["components"]["schemas"];
    assert_eq!(
        schemas["NewWebhook"]["properties"]["url"]["maxLength"],
        2048
    );
    assert_eq!(
        schemas["NewWebhook"]["properties"]["secret"]["maxLength"],
        256
    );
    assert_eq!(
        schemas["EpochInput"]["properties"]["label"]["maxLength"],
        200
    );
    // a URL that is no URL is repeated cut
    let junk = "u".repeat(2000);
    let hook = json!({"url": junk, "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"});
    let (status, e) = s.post("/api/v1/webhooks", &hook).await;
    assert_eq!(status, 422, "{e}");
    assert_cut(message(&e), &junk);
    s.stop().await;
}

#[tokio::test]
async fn a_long_value_in_an_error_is_cut_to_80_characters_and_an_ellipsis() {
    let s = TestServer::start(|_| {}).await;
    let long = "x".repeat(10_000);
    // a site's id (the service's own message)
    let (status, e) = s
        .post("/api/v1/sites", &json!({"id": long, "name": "cliff"}))
        .await;
    assert_eq!(status, 422, "{e}");
    assert!(message(&e).starts_with("id 'xxxx"), "{e}");
    assert_cut(message(&e), &long);
    // an unknown enum name (serde's message, backticks)
    let (status, e) = s
        .post("/api/v1/sites", &json!({"id": "kamo", "model": long}))
        .await;
    assert_eq!(status, 422, "{e}");
    assert!(message(&e).contains("model"), "{e}");
    assert_cut(message(&e), &long);
    // a string where a number belongs (serde's message, double quotes)
    let (status, e) = s
        .post("/api/v1/sites", &json!({"id": "kamo", "confidence": long}))
        .await;
    assert_eq!(status, 422, "{e}");
    assert_cut(message(&e), &long);
    // an image's id in an upload
    s.create_site("kamo").await;
    let mut epoch = paper("paper-case3-seed101");
    epoch["images"][0]["id"] = json!("i".repeat(10_000));
    let (status, e) = s.upload("kamo", &epoch).await;
    assert_eq!(status, 422, "{e}");
    assert_cut(message(&e), &"i".repeat(10_000));
    // a label over 200 characters
    let mut epoch = paper("paper-case3-seed101");
    epoch["label"] = json!("l".repeat(201));
    let (status, e) = s.upload("kamo", &epoch).await;
    assert_eq!(status, 422, "{e}");
    assert_eq!(message(&e), "label: 201 characters; at most 200");
    // a path segment
    let (status, e) = s
        .get(&format!("/api/v1/sites/{}", "p".repeat(10_000)))
        .await;
    assert_eq!(status, 404, "{e}");
    assert_cut(message(&e), &"p".repeat(10_000));
    let (status, e) = s
        .get(&format!("/api/v1/alerts?state={}", "s".repeat(10_000)))
        .await;
    assert_eq!(status, 400, "{e}");
    assert_cut(message(&e), &"s".repeat(10_000));
    s.stop().await;
}

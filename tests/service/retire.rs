//! The end of a site's life: retired (its open alerts resolved with the reason, uploads and
//! edits refused with 409 `site_retired`, its page kept with a banner), refused deletion before
//! the retirement and before an export made after it, the export (a JSON download, audited),
//! then the deletion in one transaction, which leaves every table without the site's rows but
//! keeps the audit trail, ending with the deletion's row.

use crate::support;

use reqwest::Method;
use serde_json::{json, Value};
use support::day;
use support::server::{snapshot, synthetic_epoch, TestServer};

use super::admin::{moving_site, open_alerts};

const REASON: &str = "Rockfall netting installed below the face; monitoring ended";

async fn audit(s: &TestServer) -> Vec<Value> {
    let (st, a) = s.get("/api/v1/sites/cliff/audit").await;
    assert_eq!(st, 200, "{a}");
    a["items"].as_array().unwrap().clone()
}

async fn audit_rows(s: &TestServer) -> i64 {
    sqlx::query_scalar("SELECT COUNT(*) FROM audit")
        .fetch_one(s.store.reader())
        .await
        .unwrap()
}

fn message(b: &Value) -> String {
    b["error"]["message"]
        .as_str()
        .unwrap_or_default()
        .to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_site_is_retired_exported_and_deleted_in_that_order() {
    let s = TestServer::start(|_| {}).await;
    moving_site(&s).await;
    let open = open_alerts(&s).await;
    assert!(!open.is_empty(), "the block's points alert");

    // Deleting a site in service is refused and says what to do first; nothing changes.
    let (snap, rows) = (snapshot(&s.store).await, audit_rows(&s).await);
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(st, 409, "{b}");
    assert_eq!(b["error"]["code"], "not_deletable", "{b}");
    assert!(message(&b).contains("retire it first"), "{b}");
    assert_eq!(snapshot(&s.store).await, snap, "nothing deleted");

    // A retirement needs a reason.
    for body in [
        json!({}),
        json!({"reason": "   "}),
        json!({"reason": "x", "why": 1}),
    ] {
        let (st, b) = s.post("/api/v1/sites/cliff/retire", &body).await;
        assert_eq!(st, 422, "{body}: {b}");
        assert!(
            message(&b).contains("reason") || message(&b).contains("why"),
            "{b}"
        );
    }
    assert_eq!(snapshot(&s.store).await, snap, "nothing stored");
    assert_eq!(audit_rows(&s).await, rows, "no audit row for a refusal");

    // Retired: every open alert resolved, its event naming the reason.
    let (st, site) = s
        .post("/api/v1/sites/cliff/retire", &json!({ "reason": REASON }))
        .await;
    assert_eq!(st, 200, "{site}");
    assert_eq!(site["retired_reason"], REASON, "{site}");
    assert!(site["retired_at"].as_str().is_some(), "{site}");
    assert!(open_alerts(&s).await.is_empty(), "every alert closed");
    for alert in &open {
        let (_, h) = s
            .get(&format!(
                "/api/v1/alerts/{}/events",
                alert["id"].as_str().unwrap()
            ))
            .await;
        let last = h["items"].as_array().unwrap().last().unwrap().clone();
        assert_eq!(last["type"], "alert.resolved", "{last}");
        let words = last["data"]["message"].as_str().unwrap();
        assert!(
            words.ends_with(&format!("the site was retired by anonymous: {REASON}")),
            "{words}"
        );
    }
    let trail = audit(&s).await;
    assert_eq!(trail[0]["action"], "site.retire", "{trail:#?}");
    assert_eq!(trail[0]["source"], "api");
    let after: Value = serde_json::from_str(trail[0]["value_after"].as_str().unwrap()).unwrap();
    assert_eq!(after["reason"], REASON);
    assert_eq!(after["alerts_closed"], open.len(), "{after}");

    // Uploads, edits and a second retirement are refused with the site's retirement named.
    let snap = snapshot(&s.store).await;
    let rows = audit_rows(&s).await;
    let body = synthetic_epoch(4, 12, &day(3), 43, 24.0, 6);
    let (st, b) = s.upload("cliff", &body).await;
    assert_eq!(st, 409, "{b}");
    assert_eq!(b["error"]["code"], "site_retired", "{b}");
    assert!(message(&b).contains("retired on"), "{b}");
    assert!(message(&b).contains("Rockfall netting"), "{b}");
    for (method, path, body) in [
        (Method::PATCH, "/api/v1/sites/cliff", json!({"name": "x"})),
        (
            Method::POST,
            "/api/v1/sites/cliff/retire",
            json!({"reason": "again"}),
        ),
        (
            Method::PUT,
            "/api/v1/sites/cliff/groups/B2",
            json!({"kind": "block", "points": ["T007", "T008"]}),
        ),
    ] {
        let (st, b) = s.send(method.clone(), path, Some(&body)).await;
        assert_eq!(st, 409, "{method} {path}: {b}");
        assert_eq!(b["error"]["code"], "site_retired", "{method} {path}: {b}");
    }
    assert_eq!(snapshot(&s.store).await, snap, "nothing stored");
    assert_eq!(audit_rows(&s).await, rows, "no audit row for a refusal");

    // The page stays, and says since when and why.
    let page = s
        .client
        .get(s.url("/sites/cliff"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(page.contains("Retired on"), "the banner");
    assert!(page.contains(REASON), "the reason on the page");

    // Not yet exported since the retirement: refused, saying so.
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(st, 409, "{b}");
    assert!(message(&b).contains("not been exported"), "{b}");

    // A HEAD of the export downloads nothing and records nothing: still refused.
    let head = s
        .client
        .head(s.url("/api/v1/sites/cliff/export"))
        .send()
        .await
        .unwrap();
    assert_eq!(head.status(), 200);
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(st, 409, "after a HEAD: {b}");
    assert!(message(&b).contains("not been exported"), "{b}");

    // The export: a JSON download of everything, recorded.
    let r = s
        .client
        .get(s.url("/api/v1/sites/cliff/export"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(
        r.headers()["content-disposition"],
        "attachment; filename=\"cliff.export.json\""
    );
    let export: Value = r.json().await.unwrap();
    assert_eq!(export["format"], "cliffwatch site export 1");
    assert_eq!(export["site"]["retired_reason"], REASON);
    assert_eq!(export["settings"]["alert_rules"][0]["above"], 5.0);
    assert_eq!(export["epochs"].as_array().unwrap().len(), 3);
    assert_eq!(export["points"].as_array().unwrap().len(), 12);
    assert_eq!(export["groups"][0]["name"], "B1");
    assert!(export["alerts"].as_array().unwrap().len() >= open.len());
    assert!(export["alerts"]
        .as_array()
        .unwrap()
        .iter()
        .all(|a| a["state"] == "resolved"));
    let actions: Vec<&str> = export["audit"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["action"].as_str().unwrap())
        .collect();
    assert_eq!(
        &actions[actions.len() - 2..],
        ["site.retire", "site.export"]
    );
    assert_eq!(audit(&s).await[0]["action"], "site.export");

    // Deleted: no row of the site is left but its audit trail, which ends with the deletion.
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(st, 204, "{b}");
    let (st, _) = s.get("/api/v1/sites/cliff").await;
    assert_eq!(st, 404);
    for (table, n) in snapshot(&s.store).await {
        assert_eq!(n, 0, "{table} still holds {n} rows");
    }
    let (id, action, before): (String, String, Option<String>) = sqlx::query_as(
        "SELECT id, action, value_before FROM audit WHERE site_id = 'cliff' \
         ORDER BY at DESC, id DESC LIMIT 1",
    )
    .fetch_one(s.store.reader())
    .await
    .unwrap();
    assert_eq!(action, "site.delete", "{id}");
    let before: Value = serde_json::from_str(&before.unwrap()).unwrap();
    assert_eq!(before["rows"]["epochs"], 3, "{before}");
    assert_eq!(before["rows"]["sites"], 1, "{before}");
    assert_eq!(audit_rows(&s).await, rows + 2, "export and delete recorded");
    s.stop().await;
}

/// A site of the configuration file can be neither retired nor deleted through the API.
#[tokio::test]
async fn a_configured_site_is_not_retired_or_deleted() {
    let s = TestServer::start(|c| {
        c.sites = vec![serde_json::from_value(json!({"id": "filed"})).unwrap()];
    })
    .await;
    let (st, b) = s
        .post("/api/v1/sites/filed/retire", &json!({"reason": "done"}))
        .await;
    assert_eq!(st, 409, "{b}");
    assert_eq!(b["error"]["code"], "configured_site", "{b}");
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/filed", None).await;
    assert_eq!(st, 409, "{b}");
    assert_eq!(b["error"]["code"], "configured_site", "{b}");
    s.stop().await;
}

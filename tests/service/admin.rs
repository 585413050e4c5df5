//! Running a site for years: its settings edited with a JSON merge patch (checked as a new site
//! is; a rule change re-evaluates the open alerts at once, and their events name the change), a
//! group deleted, each refused edit storing nothing, a site of the configuration file refused,
//! and every change in the site's audit trail (who, never the token; before and after).

use crate::support;

use reqwest::Method;
use serde_json::{json, Value};
use support::day;
use support::server::{snapshot, synthetic_epoch, TestServer};

const N: usize = 12;
const STABLE: usize = 6;

/// Site `cliff` with a watch rule above 5 mm, its first points stable, block B1 of the others,
/// and three epochs in which the block moves 8 mm a day.
pub(crate) async fn moving_site(s: &TestServer) {
    let (st, b) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "cliff", "alert_rules": [
                {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0}]}),
        )
        .await;
    assert_eq!(st, 201, "{b}");
    // The stable points in one call.
    let stable: serde_json::Map<String, Value> = (0..STABLE)
        .map(|i| (format!("T{:03}", i + 1), json!({"role": "stable"})))
        .collect();
    let (st, b) = s
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/points",
            Some(&Value::Object(stable)),
        )
        .await;
    assert_eq!(st, 200, "{b}");
    assert_eq!(b["items"].as_array().unwrap().len(), STABLE, "{b}");
    assert!(b["items"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["role"] == "stable"));
    let block: Vec<String> = (STABLE..N).map(|i| format!("T{:03}", i + 1)).collect();
    let (st, b) = s
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/groups/B1",
            Some(&json!({"kind": "block", "points": block})),
        )
        .await;
    assert_eq!(st, 200, "{b}");
    for k in 0..3 {
        let body = synthetic_epoch(4, N, &day(k), 40 + k as u64, 8.0 * k as f64, STABLE);
        let (st, b) = s.upload("cliff", &body).await;
        assert_eq!(st, 201, "{b}");
    }
}

pub(crate) async fn open_alerts(s: &TestServer) -> Vec<Value> {
    let (_, a) = s.get("/api/v1/alerts?site=cliff&limit=1000").await;
    a["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| a["state"] != "resolved")
        .cloned()
        .collect()
}

async fn audit(s: &TestServer) -> Vec<Value> {
    let (st, a) = s.get("/api/v1/sites/cliff/audit").await;
    assert_eq!(st, 200, "{a}");
    a["items"].as_array().unwrap().clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_site_is_edited_its_group_deleted_and_every_change_audited() {
    let s = TestServer::start(|_| {}).await;
    moving_site(&s).await;
    let watch = open_alerts(&s).await;
    assert!(!watch.is_empty(), "the block's points alert");
    // Creating the site is not an edit; the stable points and the group declaration are.
    let before = audit(&s).await;
    assert_eq!(before.len(), STABLE + 1, "{before:#?}");
    assert_eq!(before[0]["action"], "group.put");
    assert_eq!(before[0]["actor"], "anonymous");
    assert!(before[0]["value_before"].is_null());
    assert!(
        before[1..].iter().all(|r| r["action"] == "point.set"),
        "{before:#?}"
    );

    // Bulk point settings are all or nothing: one never-measured name refuses the whole change.
    let snap = snapshot(&s.store).await;
    let (st, b) = s
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/points",
            Some(&json!({"T007": {"role": "stable"}, "T999": {"role": "stable"}})),
        )
        .await;
    assert_eq!(st, 422, "{b}");
    assert!(
        b["error"]["message"].as_str().unwrap().contains("T999"),
        "{b}"
    );
    assert_eq!(snapshot(&s.store).await, snap, "nothing stored");
    for (body, words) in [
        (json!({"T007": []}), "JSON object"),
        (json!({"T007": {"role": "boss"}}), "boss"),
        (json!({}), "no point"),
    ] {
        let (st, b) = s
            .send(Method::PUT, "/api/v1/sites/cliff/points", Some(&body))
            .await;
        assert_eq!(st, 422, "{body}: {b}");
        assert!(
            b["error"]["message"].as_str().unwrap().contains(words),
            "{body}: {b}"
        );
        assert_eq!(snapshot(&s.store).await, snap, "{body}: nothing stored");
    }

    // The rule tuned after the first season: the open alerts are re-evaluated at once and say
    // which change decided them.
    let rules = json!([{"level": "watch", "metric": "displacement_mm", "above": 50.0, "clear_below": 40.0}]);
    let (st, site) = s
        .send(
            Method::PATCH,
            "/api/v1/sites/cliff",
            Some(&json!({"alert_rules": rules, "name": "Cliff above route 12"})),
        )
        .await;
    assert_eq!(st, 200, "{site}");
    assert_eq!(site["name"], "Cliff above route 12");
    assert_eq!(site["alert_rules"], rules);
    assert!(
        open_alerts(&s).await.is_empty(),
        "{:#?}",
        open_alerts(&s).await
    );
    let rows = audit(&s).await;
    let edit = &rows[0];
    assert_eq!(edit["action"], "site.update", "{rows:#?}");
    assert_eq!(edit["source"], "api");
    let b: Value = serde_json::from_str(edit["value_before"].as_str().unwrap()).unwrap();
    let a: Value = serde_json::from_str(edit["value_after"].as_str().unwrap()).unwrap();
    assert_eq!(b["alert_rules"][0]["above"], 5.0, "{b}");
    assert_eq!(a["alert_rules"], rules, "{a}");
    assert_eq!(b["name"], "cliff");
    assert_eq!(a["name"], "Cliff above route 12");
    assert!(b.get("time_zone").is_none(), "only what changed: {b}");
    let id = edit["id"].as_str().unwrap();
    let (_, all) = s.get("/api/v1/alerts?site=cliff&limit=1000").await;
    for alert in all["items"].as_array().unwrap() {
        let (_, h) = s
            .get(&format!(
                "/api/v1/alerts/{}/events",
                alert["id"].as_str().unwrap()
            ))
            .await;
        let last = h["items"].as_array().unwrap().last().unwrap().clone();
        assert_eq!(last["type"], "alert.resolved", "{last}");
        assert!(
            last["data"]["message"]
                .as_str()
                .unwrap()
                .ends_with(&format!(
                    "the site's settings were changed by anonymous (audit {id})"
                )),
            "{last}"
        );
    }

    // Null removes an optional setting; members not given stay.
    let (st, site) = s
        .send(
            Method::PATCH,
            "/api/v1/sites/cliff",
            Some(&json!({"time_zone": "Asia/Tokyo", "response_text": "Close route 12."})),
        )
        .await;
    assert_eq!(st, 200, "{site}");
    let (st, site) = s
        .send(
            Method::PATCH,
            "/api/v1/sites/cliff",
            Some(&json!({"response_text": null})),
        )
        .await;
    assert_eq!(st, 200, "{site}");
    assert!(site["response_text"].is_null(), "{site}");
    assert_eq!(site["time_zone"], "Asia/Tokyo");
    assert_eq!(site["alert_rules"], rules);

    // Refused edits name the field and store nothing (not even an audit row).
    let stored = snapshot(&s.store).await;
    for (patch, field) in [
        (json!({"confidence": 2.0}), "confidence"),
        (
            json!({"alert_rules": [{"level": "watch", "metric": "displacement_m", "above": 5}]}),
            "displacement_m",
        ),
        (json!({"colour": "red"}), "colour"),
        (json!({"id": "other"}), "id"),
        (json!({"model": "central"}), "model"),
        (json!({"time_zone": "Mars/Olympus"}), "time_zone"),
        (json!([1, 2]), "JSON object"),
    ] {
        let (st, b) = s
            .send(Method::PATCH, "/api/v1/sites/cliff", Some(&patch))
            .await;
        assert_eq!(st, 422, "{patch}: {b}");
        let message = b["error"]["message"].as_str().unwrap();
        assert!(message.contains(field), "{patch}: {message}");
        assert_eq!(snapshot(&s.store).await, stored, "{patch} stored something");
    }
    let (st, b) = s
        .send(
            Method::PATCH,
            "/api/v1/sites/nowhere",
            Some(&json!({"name": "x"})),
        )
        .await;
    assert_eq!(st, 404, "{b}");

    // The group is deleted: its points stay, the group is gone, the change is audited.
    let (st, _) = s
        .send(Method::DELETE, "/api/v1/sites/cliff/groups/B1", None)
        .await;
    assert_eq!(st, 204);
    let (st, _) = s.get("/api/v1/sites/cliff/groups/B1").await;
    assert_eq!(st, 404);
    let (st, b) = s
        .send(Method::DELETE, "/api/v1/sites/cliff/groups/B1", None)
        .await;
    assert_eq!(st, 404, "{b}");
    let (_, points) = s.get("/api/v1/sites/cliff/points").await;
    assert_eq!(points["items"].as_array().unwrap().len(), N);
    let rows = audit(&s).await;
    assert_eq!(rows[0]["action"], "group.delete", "{rows:#?}");
    assert_eq!(rows[0]["target"], "group B1");
    assert!(rows[0]["value_after"].is_null());
    let b: Value = serde_json::from_str(rows[0]["value_before"].as_str().unwrap()).unwrap();
    assert_eq!(b["points"].as_array().unwrap().len(), N - STABLE);
    // Newest first, paged.
    let ats: Vec<&str> = rows.iter().map(|r| r["at"].as_str().unwrap()).collect();
    assert!(ats.windows(2).all(|w| w[0] >= w[1]), "{ats:?}");
    assert_eq!(rows.len(), STABLE + 5, "{rows:#?}");
    let (_, first) = s.get("/api/v1/sites/cliff/audit?limit=2").await;
    let cursor = first["next_cursor"].as_str().unwrap();
    let (_, second) = s
        .get(&format!(
            "/api/v1/sites/cliff/audit?limit=2&cursor={}",
            cursor
                .replace('|', "%7C")
                .replace(':', "%3A")
                .replace('+', "%2B")
        ))
        .await;
    assert_eq!(second["items"][0]["id"], rows[2]["id"], "{second}");
    s.stop().await;
}

/// A site of the configuration file is refused (the file is applied at every start), and with
/// tokens the audit trail names the token by its hash prefix and role, never the token.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn configured_sites_are_refused_and_the_actor_is_the_tokens_name() {
    const TOKEN: &str = "admin-token-0123456789abcdef0123456789";
    let s = TestServer::start(|c| {
        c.sites
            .push(serde_json::from_value(json!({"id": "conf"})).unwrap());
        c.tokens
            .push(serde_json::from_value(json!({"token": TOKEN, "role": "admin"})).unwrap());
    })
    .await;
    let send = |method: Method, path: &str, body: Value| {
        s.client
            .request(method, s.url(path))
            .bearer_auth(TOKEN)
            .json(&body)
            .send()
    };
    let r = send(Method::PATCH, "/api/v1/sites/conf", json!({"name": "x"}))
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let b: Value = r.json().await.unwrap();
    assert_eq!(b["error"]["code"], "configured_site", "{b}");
    assert!(b["error"]["message"]
        .as_str()
        .unwrap()
        .contains("configuration file"));
    let r = send(Method::POST, "/api/v1/sites", json!({"id": "api"}))
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let r = send(
        Method::PATCH,
        "/api/v1/sites/api",
        json!({"schedule_hours": 24}),
    )
    .await
    .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let r = s
        .client
        .get(s.url("/api/v1/sites/api/audit"))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap();
    let text = r.text().await.unwrap();
    assert!(!text.contains(TOKEN), "{text}");
    let rows: Value = serde_json::from_str(&text).unwrap();
    let actor = rows["items"][0]["actor"].as_str().unwrap();
    let name = &hex_sha256(TOKEN)[..16];
    assert_eq!(actor, format!("token {name} (admin)"));
    s.stop().await;
}

fn hex_sha256(s: &str) -> String {
    use sha2::Digest;
    hex::encode(sha2::Sha256::digest(s.as_bytes()))
}

//! Issue 77 on PostgreSQL: a site retired (its open alerts resolved, uploads refused), exported
//! and deleted leaves no row of it in any table but the audit trail, which ends with the
//! deletion (the new columns and the deletion's statements on this backend's SQL).

use crate::support;

use reqwest::Method;
use serde_json::{json, Value};
use support::day;
use support::server::{snapshot, synthetic_epoch, TestServer};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_site_is_retired_exported_and_deleted_on_postgres() {
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("retire");
    let s = TestServer::start(move |c| c.database_url = Some(url)).await;
    assert_eq!(s.store.backend(), cliffwatch::store::Backend::Postgres);
    let (st, b) = s
        .post(
            "/api/v1/sites",
            &json!({"id": "cliff", "alert_rules": [
                {"level": "watch", "metric": "displacement_mm", "above": 5.0}]}),
        )
        .await;
    assert_eq!(st, 201, "{b}");
    let stable: serde_json::Map<String, Value> = (1..=6)
        .map(|i| (format!("T{i:03}"), json!({"role": "stable"})))
        .collect();
    let (st, b) = s
        .send(
            Method::PUT,
            "/api/v1/sites/cliff/points",
            Some(&Value::Object(stable)),
        )
        .await;
    assert_eq!(st, 200, "{b}");
    for k in 0..3 {
        let body = synthetic_epoch(4, 12, &day(k), 40 + k as u64, 8.0 * k as f64, 6);
        let (st, b) = s.upload("cliff", &body).await;
        assert_eq!(st, 201, "{b}");
    }
    let (_, open) = s.get("/api/v1/alerts?site=cliff&state=open").await;
    assert!(!open["items"].as_array().unwrap().is_empty(), "{open}");

    let (st, b) = s
        .post(
            "/api/v1/sites/cliff/retire",
            &json!({"reason": "netting installed"}),
        )
        .await;
    assert_eq!(st, 200, "{b}");
    let (_, open) = s.get("/api/v1/alerts?site=cliff&state=open").await;
    assert!(open["items"].as_array().unwrap().is_empty(), "{open}");
    let body = synthetic_epoch(4, 12, &day(3), 43, 24.0, 6);
    let (st, b) = s.upload("cliff", &body).await;
    assert_eq!(
        (st, b["error"]["code"].as_str()),
        (409, Some("site_retired")),
        "{b}"
    );
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(
        (st, b["error"]["code"].as_str()),
        (409, Some("not_deletable")),
        "{b}"
    );
    let (st, export) = s.get("/api/v1/sites/cliff/export").await;
    assert_eq!(st, 200, "{export}");
    assert_eq!(export["epochs"].as_array().unwrap().len(), 3);
    let (st, b) = s.send(Method::DELETE, "/api/v1/sites/cliff", None).await;
    assert_eq!(st, 204, "{b}");
    for (table, n) in snapshot(&s.store).await {
        assert_eq!(n, 0, "{table} still holds {n} rows");
    }
    let actions: Vec<String> =
        sqlx::query_scalar("SELECT action FROM audit WHERE site_id = 'cliff' ORDER BY at, id")
            .fetch_all(s.store.reader())
            .await
            .unwrap();
    assert_eq!(
        &actions[actions.len() - 3..],
        ["site.retire", "site.export", "site.delete"],
        "{actions:?}"
    );
    s.stop().await;
}

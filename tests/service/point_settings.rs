//! A point's settings (role, group, direction): what a PUT leaves out is kept, what it sets to
//! null is cleared.

use crate::support;

use serde_json::{json, Value};
use support::server::TestServer;

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
            (status, crate::support::server::checked_json(r).await)
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

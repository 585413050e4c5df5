//! Dashboard sessions on PostgreSQL with two nodes: a session signed in through one node is one
//! on the other, and signing out through either ends it on both.

use crate::support;

use cliffwatch::config::{Role, TokenConfig};
use reqwest::header;
use support::server::TestServer;

/// The status of `/` read with `cookie` through `node`, and the page's CSRF token if it is 200.
async fn home(node: &TestServer, client: &reqwest::Client, cookie: &str) -> (u16, String) {
    let r = client
        .get(node.url("/"))
        .header(header::COOKIE, cookie)
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    let page = r.text().await.unwrap();
    let csrf = page
        .split("name=\"csrf\" value=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .unwrap_or_default()
        .to_string();
    (status, csrf)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_signed_out_through_one_node_ends_on_both() {
    let cluster = support::pg::PgCluster::start();
    let url = cluster.create_database("sessions");
    let node = |url: String| {
        TestServer::start(move |c| {
            c.database_url = Some(url);
            c.tokens = vec![TokenConfig {
                token: "admin-token-3".into(),
                role: Role::Admin,
            }];
        })
    };
    let a = node(url.clone()).await;
    let b = node(url).await;
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let mut cookies = Vec::new();
    for _ in 0..2 {
        let r = client
            .post(a.url("/signin"))
            .form(&[("token", "admin-token-3"), ("next", "/")])
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 303);
        let c = r.headers()[header::SET_COOKIE].to_str().unwrap();
        cookies.push(c.split(';').next().unwrap().to_string());
    }
    assert_ne!(cookies[0], cookies[1]);
    let (st, csrf) = home(&b, &client, &cookies[0]).await;
    assert_eq!(st, 200);
    assert_eq!(csrf.len(), 32);
    let hashes = cliffwatch::store::sessions::id_hashes(b.store.reader())
        .await
        .unwrap();
    assert_eq!(hashes.len(), 2);
    for c in &cookies {
        let id = c.split_once('=').unwrap().1;
        assert!(hashes.iter().all(|h| !h.contains(id)), "no raw id stored");
    }
    let r = client
        .post(b.url("/signout"))
        .header(header::COOKIE, &cookies[0])
        .form(&[("csrf", csrf.as_str())])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    assert_eq!(home(&a, &client, &cookies[0]).await.0, 303);
    assert_eq!(home(&b, &client, &cookies[0]).await.0, 303);
    assert_eq!(home(&a, &client, &cookies[1]).await.0, 200);
    a.stop().await;
    b.stop().await;
}

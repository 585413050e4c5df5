//! Who may do what: bearer tokens and roles, host names served without tokens, the time limit
//! of a request, and the OpenAPI document's answers of authorization.

use crate::support;

use cliffwatch::config::{Role, TokenConfig};
use serde_json::{json, Value};
use support::server::{paper, TestServer, PAPER};

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
            // every role reads and asks the pre-analyses (they store nothing), except the
            // webhooks' list (their URLs are capabilities) and a site's export (recorded; it
            // opens the way to the site's deletion)
            let pre_analysis = path == "/api/v1/plan" || path == "/api/v1/sites/{site}/plan";
            if pre_analysis {
                let r = s
                    .client
                    .request(m, &url)
                    .bearer_auth("r".repeat(20))
                    .send()
                    .await
                    .unwrap();
                assert_ne!(r.status(), 403, "{method} {path} with the read token");
            } else if m != reqwest::Method::GET
                || path == "/api/v1/webhooks"
                || path.ends_with("/export")
            {
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
    let e = crate::support::unique_keys::parse_unique_keys(json).unwrap();
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
    let e: Value = crate::support::server::checked_json(r).await;
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
        let e: Value = crate::support::server::checked_json(r).await;
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

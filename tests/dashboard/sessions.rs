//! Sign-in when tokens are set: pages need a session cookie, changes a CSRF token, and each
//! role sees and may do only its own.

use crate::support;

use cliffwatch::config::{Role, TokenConfig};
use reqwest::header;
use serde_json::{json, Value};
use support::dashboard::{fill, SITE};
use support::server::TestServer;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_tokens_pages_need_a_session_and_changes_a_csrf_token() {
    let tokens = [
        ("reader-token-1", Role::Read),
        ("uploader-token-1", Role::Upload),
        ("admin-token-1", Role::Admin),
    ];
    let s = TestServer::start(|c| {
        c.tokens = tokens
            .iter()
            .map(|(t, r)| TokenConfig {
                token: t.to_string(),
                role: *r,
            })
            .collect();
        // Behind a proxy: browsers send this origin while the service sees another Host.
        c.public_url = Some("https://cliff.example".into());
    })
    .await;
    fill(&s, 6, Some("admin-token-1")).await;
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();

    // Without credentials: pages redirect to the sign-in form, data answer 401, assets are open.
    let r = client
        .get(s.url(&format!("/sites/{SITE}")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    assert_eq!(
        r.headers()[header::LOCATION],
        format!("/signin?next=%2Fsites%2F{SITE}")
    );
    let r = client
        .get(s.url(&format!("/dashboard/plot/{SITE}/T001")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);
    assert_eq!(
        client
            .get(s.url("/assets/plots.js"))
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    assert_eq!(
        client.get(s.url("/signin")).send().await.unwrap().status(),
        200
    );

    // A wrong token: 401 and no cookie.
    let r = client
        .post(s.url("/signin"))
        .form(&[("token", "guess"), ("next", "/")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);
    assert!(r.headers().get(header::SET_COOKIE).is_none());

    let sign_in = |token: &'static str| {
        let client = client.clone();
        let url = s.url("/signin");
        async move {
            let r = client
                .post(url)
                .form(&[("token", token), ("next", "/\t/evil.example/")])
                .send()
                .await
                .unwrap();
            assert_eq!(r.status(), 303);
            assert_eq!(r.headers()[header::LOCATION], "/", "no open redirect");
            let c = r.headers()[header::SET_COOKIE]
                .to_str()
                .unwrap()
                .to_string();
            assert!(
                c.contains("HttpOnly") && c.contains("SameSite=Strict") && c.contains("Secure"),
                "{c}"
            );
            assert!(!c.contains(token), "the cookie does not carry the token");
            c.split(';').next().unwrap().to_string()
        }
    };
    let reader = sign_in("reader-token-1").await;
    let uploader = sign_in("uploader-token-1").await;

    // With the reader's cookie: pages, but no acknowledgement form and no acknowledging.
    let r = client
        .get(s.url(&format!("/sites/{SITE}")))
        .header(header::COOKIE, &reader)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let page = r.text().await.unwrap();
    assert!(!page.contains("hx-post=\"/dashboard/alerts/"));
    let csrf_of = |page: &str| {
        let at = page.find("x-csrf-token").expect("csrf token in the page");
        page[at..].split("&quot;").nth(2).unwrap().to_string()
    };
    let reader_csrf = csrf_of(&page);
    let (_, open) = {
        let r = client
            .get(s.url(&format!("/api/v1/alerts?site={SITE}&state=open")))
            .bearer_auth("reader-token-1")
            .send()
            .await
            .unwrap();
        (r.status(), r.json::<Value>().await.unwrap())
    };
    let id = open["items"][0]["id"]
        .as_str()
        .expect("an open alert")
        .to_string();
    let ack = |cookie: String, csrf: Option<String>| {
        let client = client.clone();
        let url = s.url(&format!("/dashboard/alerts/{id}/ack"));
        async move {
            let mut r = client
                .post(url)
                .header(header::COOKIE, cookie)
                .header("hx-request", "true");
            if let Some(c) = csrf {
                r = r.header("x-csrf-token", c);
            }
            r.form(&[("by", "Aiko")])
                .send()
                .await
                .unwrap()
                .status()
                .as_u16()
        }
    };
    assert_eq!(
        ack(reader.clone(), Some(reader_csrf)).await,
        403,
        "read role"
    );

    // The uploader: the form is there; without or with a wrong CSRF token 403, with it 200.
    let r = client
        .get(s.url(&format!("/sites/{SITE}")))
        .header(header::COOKIE, &uploader)
        .send()
        .await
        .unwrap();
    let page = r.text().await.unwrap();
    assert!(page.contains("hx-post=\"/dashboard/alerts/"));
    let csrf = csrf_of(&page);
    assert_eq!(ack(uploader.clone(), None).await, 403);
    assert_eq!(ack(uploader.clone(), Some("0".repeat(32))).await, 403);
    assert_eq!(ack(uploader.clone(), Some(csrf.clone())).await, 200);

    // Without JavaScript the form posts itself, the token in its `csrf` field; through the
    // proxy the browser's Origin is the public URL, not the Host the service sees.
    assert!(
        page.contains(&format!("name=\"csrf\" value=\"{csrf}\"")),
        "the form carries the token"
    );
    let second = open["items"][1]["id"]
        .as_str()
        .expect("a second open alert")
        .to_string();
    let plain_ack = |csrf: &str| {
        client
            .post(s.url(&format!("/dashboard/alerts/{second}/ack")))
            .header(header::COOKIE, &uploader)
            .header(header::ORIGIN, "https://cliff.example")
            .form(&[("csrf", csrf), ("by", "Ben"), ("comment", "")])
            .send()
    };
    assert_eq!(plain_ack("0").await.unwrap().status(), 403);
    let r = plain_ack(&csrf).await.unwrap();
    assert_eq!(r.status(), 303);
    assert_eq!(r.headers()[header::LOCATION], format!("/sites/{SITE}"));
    let r = client
        .get(s.url(&format!("/api/v1/alerts?site={SITE}&state=acknowledged")))
        .bearer_auth("reader-token-1")
        .send()
        .await
        .unwrap();
    let acked: Value = r.json().await.unwrap();
    assert!(
        acked["items"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| a["id"] == json!(second) && a["acknowledged_by"] == json!("Ben")),
        "{acked}"
    );
    // Again: refused (409) with a page that says by whom, not a bare status.
    let r = plain_ack(&csrf).await.unwrap();
    assert_eq!(r.status(), 409);
    let page = r.text().await.unwrap();
    assert!(
        page.contains("<html") && page.contains("acknowledged already by Ben"),
        "{page}"
    );
    // Another origin is still refused, whatever the token.
    let r = client
        .post(s.url(&format!("/dashboard/alerts/{second}/ack")))
        .header(header::COOKIE, &uploader)
        .header(header::ORIGIN, "https://evil.example")
        .form(&[("csrf", csrf.as_str()), ("by", "Mallory")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 403);

    // Signing out needs the session's token too, so that no other page can do it.
    let sign_out = |csrf: &str| {
        client
            .post(s.url("/signout"))
            .header(header::COOKIE, &uploader)
            .form(&[("csrf", csrf)])
            .send()
    };
    assert_eq!(sign_out("").await.unwrap().status(), 403);
    let r = sign_out(&csrf).await.unwrap();
    assert_eq!(r.status(), 303);
    assert!(r.headers()[header::SET_COOKIE]
        .to_str()
        .unwrap()
        .contains("Max-Age=0"));
    // The signed-out session's cookie is cleared without the field: it has no token left to
    // carry, the session being ended in the database.
    let r = client
        .post(s.url("/signout"))
        .header(header::COOKIE, &uploader)
        .form(&[("csrf", "")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    assert!(r.headers()[header::SET_COOKIE]
        .to_str()
        .unwrap()
        .contains("Max-Age=0"));

    // A forged cookie is no session.
    // The last character changed (to '1' where it was '0', which made this test flaky).
    let last = if uploader.ends_with('0') { '1' } else { '0' };
    let forged = format!("{}{last}", &uploader[..uploader.len() - 1]);
    let r = client
        .get(s.url("/"))
        .header(header::COOKIE, forged)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    s.stop().await;
}

fn tokens_of(tokens: &[(&str, Role)]) -> Vec<TokenConfig> {
    tokens
        .iter()
        .map(|(t, r)| TokenConfig {
            token: t.to_string(),
            role: *r,
        })
        .collect()
}

fn without_redirects() -> reqwest::Client {
    reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap()
}

/// Signs in with `token`: the cookie pair `cliffwatch_session=…` the answer set.
async fn sign_in(s: &TestServer, client: &reqwest::Client, token: &str) -> String {
    let r = client
        .post(s.url("/signin"))
        .form(&[("token", token), ("next", "/")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    let c = r.headers()[header::SET_COOKIE].to_str().unwrap();
    c.split(';').next().unwrap().to_string()
}

/// The site page read with `cookie`: its status, and the session's CSRF token when it is 200.
async fn site_page(s: &TestServer, client: &reqwest::Client, cookie: &str) -> (u16, String) {
    let r = client
        .get(s.url(&format!("/sites/{SITE}")))
        .header(header::COOKIE, cookie)
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    if status != 200 {
        let to = r
            .headers()
            .get(header::LOCATION)
            .map(|l| l.to_str().unwrap().to_string())
            .unwrap_or_default();
        return (status, to);
    }
    let page = r.text().await.unwrap();
    let at = page.find("x-csrf-token").expect("csrf token in the page");
    (200, page[at..].split("&quot;").nth(2).unwrap().to_string())
}

/// The ids of `site`'s alerts in `state`, read through the API.
async fn alert_ids(s: &TestServer, state: &str) -> Vec<String> {
    let r = s
        .client
        .get(s.url(&format!("/api/v1/alerts?site={SITE}&state={state}")))
        .bearer_auth("admin-token-2")
        .send()
        .await
        .unwrap();
    let v: Value = r.json().await.unwrap();
    v["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["id"].as_str().unwrap().to_string())
        .collect()
}

/// Issue 79: a copy of a cookie taken before signing out reads nothing and acknowledges
/// nothing; two sign-ins with one token at once get two sessions that end separately; the
/// database holds no session id.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn signing_out_ends_the_session_for_every_copy_of_its_cookie() {
    let s = TestServer::start(|c| {
        c.tokens = tokens_of(&[
            ("uploader-token-2", Role::Upload),
            ("admin-token-2", Role::Admin),
        ]);
    })
    .await;
    fill(&s, 6, Some("admin-token-2")).await;
    let client = without_redirects();

    // Two sign-ins with the same token in the same second: two cookies, both live.
    let first = sign_in(&s, &client, "uploader-token-2").await;
    let second = sign_in(&s, &client, "uploader-token-2").await;
    assert_ne!(first, second);
    let (st, csrf) = site_page(&s, &client, &first).await;
    assert_eq!(st, 200);
    let (st, second_csrf) = site_page(&s, &client, &second).await;
    assert_eq!(st, 200);
    assert_ne!(csrf, second_csrf, "each session has its own CSRF token");

    // The database holds neither cookie's id, only hashes.
    let rows: Vec<(String, String, String, String, String)> =
        sqlx::query_as("SELECT id_hash, token_name, role, created_at, last_seen_at FROM sessions")
            .fetch_all(s.store.reader())
            .await
            .unwrap();
    assert_eq!(rows.len(), 2);
    for cookie in [&first, &second] {
        let id = cookie.split_once('=').unwrap().1;
        assert!(id.len() >= 32, "at least 128 bits: {id}");
        for (hash, name, role, created, seen) in &rows {
            for column in [hash, name, role, created, seen] {
                assert!(!column.contains(id), "{column} holds the id");
                assert!(
                    !column.contains("uploader-token-2"),
                    "{column} holds the token"
                );
            }
        }
    }

    // Signing out the first: its copy reads no page and acknowledges nothing.
    let copy = first.clone();
    let r = client
        .post(s.url("/signout"))
        .header(header::COOKIE, &first)
        .form(&[("csrf", csrf.as_str())])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    let (st, to) = site_page(&s, &client, &copy).await;
    assert_eq!((st, to.starts_with("/signin")), (303, true), "{to}");
    let open = alert_ids(&s, "open").await;
    let id = open.first().expect("an open alert").clone();
    let ack = |cookie: String, csrf: String, htmx: bool| {
        let mut r = client
            .post(s.url(&format!("/dashboard/alerts/{id}/ack")))
            .header(header::COOKIE, cookie);
        if htmx {
            r = r.header("hx-request", "true").header("x-csrf-token", &csrf);
        }
        r.form(&[("csrf", csrf.as_str()), ("by", "Mallory"), ("comment", "")])
            .send()
    };
    for htmx in [true, false] {
        let r = ack(copy.clone(), csrf.clone(), htmx).await.unwrap();
        assert_eq!(r.status(), 401, "htmx {htmx}");
    }
    assert!(alert_ids(&s, "open").await.contains(&id), "still open");
    assert!(!alert_ids(&s, "acknowledged").await.contains(&id));
    assert_eq!(rows_in_sessions(&s).await, 1);

    // The second session lives on until it is signed out too.
    let r = ack(second.clone(), second_csrf.clone(), true)
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(alert_ids(&s, "acknowledged").await.contains(&id));
    let r = client
        .post(s.url("/signout"))
        .header(header::COOKIE, &second)
        .form(&[("csrf", second_csrf.as_str())])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    assert_eq!(site_page(&s, &client, &second).await.0, 303);
    assert_eq!(rows_in_sessions(&s).await, 0);
    s.stop().await;
}

async fn rows_in_sessions(s: &TestServer) -> usize {
    cliffwatch::store::sessions::id_hashes(s.store.reader())
        .await
        .unwrap()
        .len()
}

/// A session ends after the idle timeout without a request, and after its lifetime however
/// active; a request within the idle timeout keeps it alive.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_and_old_sessions_end() {
    let idle = TestServer::start(|c| {
        c.tokens = tokens_of(&[("admin-token-2", Role::Admin)]);
        c.session_idle_minutes = 2.0 / 60.0;
    })
    .await;
    fill(&idle, 2, Some("admin-token-2")).await;
    let client = without_redirects();
    let cookie = sign_in(&idle, &client, "admin-token-2").await;
    for _ in 0..2 {
        tokio::time::sleep(std::time::Duration::from_millis(1200)).await;
        assert_eq!(site_page(&idle, &client, &cookie).await.0, 200, "in use");
    }
    tokio::time::sleep(std::time::Duration::from_millis(2500)).await;
    let (st, to) = site_page(&idle, &client, &cookie).await;
    assert_eq!((st, to.starts_with("/signin")), (303, true), "idle: {to}");
    idle.stop().await;

    let old = TestServer::start(|c| {
        c.tokens = tokens_of(&[("admin-token-2", Role::Admin)]);
        c.session_lifetime_hours = 2.0 / 3600.0;
    })
    .await;
    fill(&old, 2, Some("admin-token-2")).await;
    let cookie = sign_in(&old, &client, "admin-token-2").await;
    for _ in 0..2 {
        assert_eq!(site_page(&old, &client, &cookie).await.0, 200);
        tokio::time::sleep(std::time::Duration::from_millis(1100)).await;
    }
    assert_eq!(site_page(&old, &client, &cookie).await.0, 303, "too old");
    old.stop().await;
}

/// A token removed from the configuration, or given another role, ends its sessions; the other
/// tokens' sessions outlive a restart.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_removed_or_changed_token_ends_its_sessions() {
    let s = TestServer::start(|c| {
        c.tokens = tokens_of(&[
            ("uploader-token-2", Role::Upload),
            ("reader-token-2", Role::Read),
            ("admin-token-2", Role::Admin),
        ]);
    })
    .await;
    fill(&s, 2, Some("admin-token-2")).await;
    let client = without_redirects();
    let uploader = sign_in(&s, &client, "uploader-token-2").await;
    let reader = sign_in(&s, &client, "reader-token-2").await;
    let admin = sign_in(&s, &client, "admin-token-2").await;
    for c in [&uploader, &reader, &admin] {
        assert_eq!(site_page(&s, &client, c).await.0, 200);
    }
    let dir = s.stop().await;
    // The same database; the uploader's token removed, the reader's made an upload token.
    let data = dir.path().to_path_buf();
    let s = TestServer::start(move |c| {
        c.data_dir = data;
        c.tokens = tokens_of(&[
            ("reader-token-2", Role::Upload),
            ("admin-token-2", Role::Admin),
        ]);
    })
    .await;
    assert_eq!(site_page(&s, &client, &uploader).await.0, 303, "removed");
    assert_eq!(site_page(&s, &client, &reader).await.0, 303, "role changed");
    assert_eq!(site_page(&s, &client, &admin).await.0, 200, "unchanged");
    s.stop().await;
    drop(dir);
}

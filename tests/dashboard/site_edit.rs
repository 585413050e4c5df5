//! Issue 77: an administrator signs in with Chromium, edits the site's alert rules in the site
//! page's settings form (CSRF-safe, as the acknowledgement form), and reads on the pages what it
//! did: the change in the site's audit trail (who, from the page, before → after in words), the
//! re-evaluated alerts (none open any more; the alert page names the change that resolved it),
//! and the change quoted in the campaign report. A reader sees the rules but no form, and a
//! post without the session's CSRF token changes nothing.

use crate::support;

use cliffwatch::config::{Role, TokenConfig};
use reqwest::header;
use serde_json::{json, Value};
use support::dashboard::{fill, SITE};
use support::server::TestServer;

use crate::browser::Driver;

const ADMIN: &str = "admin-token-77";
const READER: &str = "reader-token-77";

/// The new rules: thresholds far above the block's 12.5 mm, so every displacement alert ends.
const RULES: &str = r#"[{"level": "watch", "metric": "displacement_mm", "above": 50, "clear_below": 40},
 {"level": "warning", "metric": "displacement_mm", "above": 100}]"#;

fn text_of(css: &str) -> String {
    format!("var e = document.querySelector('{css}'); return e ? e.innerText : ''")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_admin_edits_a_rule_in_chromium_and_reads_the_change_and_its_effect() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|c| {
        c.tokens = vec![
            TokenConfig {
                token: ADMIN.into(),
                role: Role::Admin,
            },
            TokenConfig {
                token: READER.into(),
                role: Role::Read,
            },
        ]
    })
    .await;
    fill(&s, 6, Some(ADMIN)).await;
    let (open, _) = open_alerts(&s).await;
    assert!(!open.is_empty(), "the block's points alert before the edit");

    // Signed in as a person does: the token typed into the sign-in form.
    driver.goto(&s.url("/signin")).await;
    let token = driver.element("input[name=token]").await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{token}/value"),
            json!({"text": ADMIN}),
        )
        .await;
    let button = driver.element("form.signin button").await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{button}/click"),
            json!({}),
        )
        .await;
    driver
        .wait_for("return location.pathname === '/' && document.readyState === 'complete'")
        .await;

    // The site page: open alerts, the rules in the settings form.
    driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
    let headline = driver.script(&text_of("section.headline p.what")).await;
    assert!(
        !headline.as_str().unwrap().contains("No open alert"),
        "{headline}"
    );
    let rules = driver
        .script("return document.querySelector('#settings textarea').value")
        .await;
    assert!(
        rules.as_str().unwrap().contains("\"above\": 10"),
        "the stored rules in the form: {rules}"
    );

    // The edit: the rules replaced in the textarea, then "save the settings".
    let area = driver.element("#settings textarea[name=alert_rules]").await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{area}/clear"),
            json!({}),
        )
        .await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{area}/value"),
            json!({ "text": RULES }),
        )
        .await;
    let save = driver.element("#settings button[type=submit]").await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{save}/click"),
            json!({}),
        )
        .await;

    // Back on the site page: the change at the top of its audit trail, in words.
    let audit = driver
        .wait_for(
            "var a = document.querySelector('#audit'); \
             return a && a.innerText.indexOf('above 50') >= 0 ? a.innerText : ''",
        )
        .await;
    let audit = audit.as_str().unwrap();
    let first_row = driver.script(&text_of("#audit table.audit tbody tr")).await;
    let first_row = first_row.as_str().unwrap();
    assert!(first_row.contains("site.update"), "{first_row}");
    assert!(
        first_row.contains("(admin) (page)"),
        "who and from where: {first_row}"
    );
    assert!(
        first_row.contains("warning displacement_mm above 10"),
        "before: {first_row}"
    );
    assert!(
        first_row.contains("→ alert_rules: watch displacement_mm above 50 (clear below 40); warning displacement_mm above 100"),
        "after: {first_row}"
    );
    assert!(!audit.contains(ADMIN), "never the token: {audit}");
    driver.screenshot("site-edit.png").await;

    // The alerts were re-evaluated at once: none open, the headline says so.
    let headline = driver.script(&text_of("section.headline p.what")).await;
    assert_eq!(headline, json!("No open alert."), "{headline}");
    let (after, all) = open_alerts(&s).await;
    assert!(after.is_empty(), "{after:?}");
    assert!(!all.is_empty());

    // An alert's page names the change that resolved it.
    let id = open[0]["id"].as_str().unwrap();
    driver
        .goto(&s.url(&format!("/sites/{SITE}/alerts/{id}")))
        .await;
    let body = driver.script("return document.body.innerText").await;
    let body = body.as_str().unwrap();
    assert!(
        body.contains("resolved: the site's settings were changed by token"),
        "{body}"
    );

    // The campaign report quotes the change of its period.
    driver.goto(&s.url(&format!("/sites/{SITE}/report"))).await;
    let changes = driver.script(&text_of("section.changes")).await;
    let changes = changes.as_str().unwrap();
    assert!(
        changes.contains("Changes of the settings in the period"),
        "{changes}"
    );
    assert!(
        changes.contains("warning displacement_mm above 100"),
        "{changes}"
    );

    // The API agrees: one change, from the page.
    let (_, trail) = get(&s, &format!("/api/v1/sites/{SITE}/audit"), ADMIN).await;
    let row = &trail["items"][0];
    assert_eq!(row["action"], "site.update", "{trail}");
    assert_eq!(row["source"], "page", "{row}");
    driver.quit().await;

    reader_sees_no_form_and_a_forged_post_changes_nothing(&s).await;
    s.stop().await;
}

/// A reader's page has the rules and no form; a post without the CSRF token is refused (403)
/// and the trail does not grow.
async fn reader_sees_no_form_and_a_forged_post_changes_nothing(s: &TestServer) {
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let mut cookies = vec![];
    for token in [READER, ADMIN] {
        let r = client
            .post(s.url("/signin"))
            .form(&[("token", token), ("next", "/")])
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 303);
        let c = r.headers()[header::SET_COOKIE].to_str().unwrap();
        cookies.push(c.split(';').next().unwrap().to_string());
    }
    let page = client
        .get(s.url(&format!("/sites/{SITE}")))
        .header(header::COOKIE, &cookies[0])
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(page.contains("Alert rules: "), "the reader reads the rules");
    assert!(!page.contains("save the settings"), "and has no form");
    let (_, before) = get(s, &format!("/api/v1/sites/{SITE}/audit"), ADMIN).await;
    let r = client
        .post(s.url(&format!("/dashboard/sites/{SITE}/settings")))
        .header(header::COOKIE, &cookies[1])
        .form(&[("name", "x"), ("time_zone", ""), ("alert_rules", "[]")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 403, "no CSRF token");
    let (_, after) = get(s, &format!("/api/v1/sites/{SITE}/audit"), ADMIN).await;
    assert_eq!(before, after, "nothing changed");
}

async fn get(s: &TestServer, path: &str, token: &str) -> (u16, Value) {
    let r = s
        .client
        .get(s.url(path))
        .bearer_auth(token)
        .send()
        .await
        .unwrap();
    (r.status().as_u16(), r.json().await.unwrap_or(Value::Null))
}

/// The site's alerts that are not resolved, and all of them.
async fn open_alerts(s: &TestServer) -> (Vec<Value>, Vec<Value>) {
    let (_, a) = get(s, &format!("/api/v1/alerts?site={SITE}&limit=1000"), ADMIN).await;
    let all = a["items"].as_array().unwrap().clone();
    let open = all
        .iter()
        .filter(|a| a["state"] != "resolved")
        .cloned()
        .collect();
    (open, all)
}

/// An administrator retires the site from its page: the page then says since when and why, the
/// form gives way to the export's link, and the trail records the retirement from the page.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_site_is_retired_from_its_page() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 6, None).await;
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let page = |client: reqwest::Client| {
        let url = s.url(&format!("/sites/{SITE}"));
        async move { client.get(url).send().await.unwrap().text().await.unwrap() }
    };
    let before = page(client.clone()).await;
    assert!(before.contains("retire the site"), "the form");
    let r = client
        .post(s.url(&format!("/dashboard/sites/{SITE}/retire")))
        .form(&[("reason", "   ")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422);
    let refused = r.text().await.unwrap();
    assert!(refused.contains("Site not retired"), "{refused}");
    assert!(
        refused.contains("reason: why the site is retired"),
        "{refused}"
    );
    let r = client
        .post(s.url(&format!("/dashboard/sites/{SITE}/retire")))
        .form(&[(
            "reason",
            "Block B1 fell on 2026-12-01; nothing left to watch",
        )])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 303);
    let after = page(client.clone()).await;
    assert!(after.contains("Retired on"), "the banner");
    assert!(
        after.contains("Block B1 fell on 2026-12-01; nothing left to watch"),
        "the reason"
    );
    assert!(after.contains("No open alert."), "the alerts closed");
    assert!(
        after.contains("Download the site&#39;s data (JSON)")
            || after.contains("Download the site's data (JSON)")
    );
    assert!(!after.contains("retire the site"), "no second retirement");
    assert!(
        !after.contains("save the settings"),
        "no edit of a retired site"
    );
    let sites = client
        .get(s.url("/"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(
        sites.contains("<span class=\"badge retired\">retired</span>"),
        "the sites list marks it"
    );
    let (_, trail) = s.get(&format!("/api/v1/sites/{SITE}/audit")).await;
    assert_eq!(trail["items"][0]["action"], "site.retire", "{trail}");
    assert_eq!(trail["items"][0]["source"], "page", "{trail}");
    s.stop().await;
}

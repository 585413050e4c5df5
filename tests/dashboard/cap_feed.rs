//! The public-warning feed against a real server: a site with a block that moves to alarm and
//! back, every CAP message of every alert thread valid against the OASIS CAP 1.2 schema
//! (`xmllint --schema`, vendored XSD), the threads Alert → Update → Cancel with references,
//! the site's area and time zone, the Atom feed's entries, user text escaped, and the errors.

use crate::support;

use std::path::Path;
use std::process::Command;

use serde_json::{json, Value};
use support::dashboard::{create_site_with_stable, day, name, POINTS, STABLE};
use support::server::{synthetic_epoch, TestServer};

const SITE: &str = "kamo";
const SITE_NAME: &str = "Kamo <script>alert(1)</script> & cliff";
const PUBLIC: &str = "https://cliffwatch.agency.example";
const SENDER: &str = "cliffwatch@agency.example";
const CAP: &str = "urn:oasis:names:tc:emergency:cap:1.2";
const ATOM: &str = "http://www.w3.org/2005/Atom";

/// The block's displacement per epoch (mm): through watch (5), warning (10) and alarm (20),
/// then back to rest so every alert resolves.
const BLOCK_MM: [f64; 14] = [
    0.0, 0.0, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0, 21.0, 24.0, 27.0, 0.0, 0.0, 0.0,
];

fn polygon() -> Value {
    json!([
        [35.01, 135.76],
        [35.01, 135.77],
        [35.02, 135.77],
        [35.02, 135.76],
        [35.01, 135.76]
    ])
}

async fn fill(s: &TestServer) {
    create_site_with_stable(
        s,
        json!({"id": SITE, "name": SITE_NAME, "time_zone": "Asia/Tokyo",
            "area": {"description": "Route 42 below the cliff, km 3.2–3.6 <b>", "polygon": polygon()},
            "alert_rules": [
            {"level": "watch", "metric": "displacement_mm", "above": 5.0, "clear_below": 4.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0, "clear_below": 8.0},
            {"level": "alarm", "metric": "displacement_mm", "above": 20.0, "clear_below": 16.0}]}),
    )
    .await;
    for (k, mm) in BLOCK_MM.iter().enumerate() {
        let body = synthetic_epoch(4, POINTS, &day(k), 900 + k as u64, *mm, STABLE);
        let (st, answer) = s.upload(SITE, &body).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
    }
}

async fn text(s: &TestServer, path: &str) -> (u16, String, String) {
    let r = s.client.get(s.url(path)).send().await.unwrap();
    let status = r.status().as_u16();
    let ct = r
        .headers()
        .get(reqwest::header::CONTENT_TYPE)
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    (status, ct, r.text().await.unwrap())
}

/// Validates `xml` against the vendored CAP 1.2 schema with xmllint; panics with its output.
fn validate_cap(xml: &str, dir: &Path, label: &str) {
    let file = dir.join(format!("{label}.xml"));
    std::fs::write(&file, xml).unwrap();
    let xsd = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/cap/CAP-v1.2.xsd");
    let out = Command::new("xmllint")
        .arg("--noout")
        .arg("--schema")
        .arg(&xsd)
        .arg(&file)
        .output()
        .expect("xmllint (Debian's libxml2-utils) runs; .ci/run installs it");
    assert!(
        out.status.success(),
        "{label} is not valid CAP 1.2:\n{}\n{xml}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn child<'a>(
    node: roxmltree::Node<'a, 'a>,
    ns: &str,
    name: &str,
) -> Option<roxmltree::Node<'a, 'a>> {
    node.children().find(|c| c.has_tag_name((ns, name)))
}

fn child_text<'a>(node: roxmltree::Node<'a, 'a>, ns: &str, name: &str) -> String {
    child(node, ns, name)
        .and_then(|c| c.text())
        .unwrap_or_default()
        .to_string()
}

fn xmllint_available() -> bool {
    let ok = Command::new("xmllint").arg("--version").output().is_ok();
    if !ok && std::env::var("CI").as_deref() == Ok("true") {
        panic!("xmllint (libxml2-utils) is missing under CI=true");
    }
    ok
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_cap_message_is_valid_cap_1_2_and_threads_alert_update_cancel() {
    let s = TestServer::start(|c| {
        c.cap_sender = SENDER.into();
        c.public_url = Some(PUBLIC.into());
    })
    .await;
    fill(&s).await;
    let have_xmllint = xmllint_available();
    let scratch = tempfile::tempdir().unwrap();
    // The feed and the messages are also left under target/cap-feed/ for a person to read.
    let keep = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/cap-feed");
    std::fs::create_dir_all(&keep).unwrap();

    // The feed: one entry per alert that reached warning, each linking its latest message.
    let (st, ct, feed) = text(&s, "/api/v1/cap/feed.atom").await;
    assert_eq!(st, 200, "{feed}");
    assert!(ct.starts_with("application/atom+xml"), "{ct}");
    assert!(!feed.contains("<script>"), "site name escaped in the feed");
    std::fs::write(keep.join("feed.atom"), &feed).unwrap();
    let doc = roxmltree::Document::parse(&feed).expect("the feed is XML");
    let root = doc.root_element();
    assert!(root.has_tag_name((ATOM, "feed")));
    for required in ["id", "title", "updated"] {
        assert!(
            !child_text(root, ATOM, required).is_empty(),
            "feed {required}"
        );
    }
    let entries: Vec<_> = root
        .children()
        .filter(|c| c.has_tag_name((ATOM, "entry")))
        .collect();

    let (_, alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=200"))
        .await;
    let alerts = alerts["items"].as_array().unwrap().clone();
    let block: Vec<String> = (STABLE..POINTS).map(name).collect();
    // Every block point passed 20 mm, so each has an alert that reached alarm; no stable point
    // may appear in the public feed.
    assert_eq!(
        entries.len(),
        block.len(),
        "one entry per block point:\n{feed}"
    );
    let mut updated_prev = String::from("9999");
    let mut with_onset = 0;
    for e in &entries {
        let id = child_text(*e, ATOM, "id");
        assert!(id.starts_with("urn:uuid:") && id.len() == 45, "{id}");
        let link = child(*e, ATOM, "link").expect("entry link");
        assert_eq!(link.attribute("type"), Some("application/cap+xml"));
        let href = link.attribute("href").unwrap();
        let alert_id = href
            .strip_prefix(&format!("{PUBLIC}/api/v1/cap/alerts/"))
            .and_then(|f| f.strip_suffix(".xml"))
            .unwrap_or_else(|| panic!("{href}"));
        let alert = alerts
            .iter()
            .find(|a| a["id"] == alert_id)
            .unwrap_or_else(|| panic!("entry {alert_id} is an alert of the site"));
        let point = alert["point"].as_str().unwrap();
        assert!(block.iter().any(|b| b == point), "{point} is a block point");
        assert_eq!(alert["state"], "resolved", "the block came back to rest");
        let updated = child_text(*e, ATOM, "updated");
        assert!(updated <= updated_prev, "entries newest first");
        updated_prev = updated;

        // The thread: message 1, 2, … up to the latest (the one the feed links).
        let path = href.strip_prefix(PUBLIC).unwrap();
        let (st, ct, latest) = text(&s, path).await;
        assert_eq!(st, 200, "{latest}");
        assert!(ct.starts_with("application/cap+xml"), "{ct}");
        let latest_doc = roxmltree::Document::parse(&latest).unwrap();
        let n: usize = child_text(latest_doc.root_element(), CAP, "identifier")
            .rsplit('.')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            n >= 2,
            "a thread that went public and was cancelled has ≥ 2 messages"
        );
        let mut kinds = Vec::new();
        let mut sent_prev = String::new();
        for seq in 1..=n {
            let (st, _, xml) = text(&s, &format!("/api/v1/cap/alerts/{alert_id}.{seq}.xml")).await;
            assert_eq!(st, 200, "{xml}");
            if have_xmllint {
                validate_cap(&xml, scratch.path(), &format!("{alert_id}.{seq}"));
            }
            std::fs::write(
                keep.join(format!("{}.{seq}.xml", alert_id.replace(':', "_"))),
                &xml,
            )
            .unwrap();
            assert!(
                !xml.contains("<script>") && !xml.contains("<b>"),
                "user text escaped"
            );
            let d = roxmltree::Document::parse(&xml).unwrap();
            let a = d.root_element();
            assert!(a.has_tag_name((CAP, "alert")));
            assert_eq!(
                child_text(a, CAP, "identifier"),
                format!("{alert_id}.{seq}")
            );
            assert_eq!(child_text(a, CAP, "sender"), SENDER);
            assert_eq!(child_text(a, CAP, "status"), "Actual");
            assert_eq!(child_text(a, CAP, "scope"), "Public");
            assert_eq!(child_text(a, CAP, "incidents"), alert_id);
            let sent = child_text(a, CAP, "sent");
            assert!(sent.ends_with("+00:00") && sent >= sent_prev, "{sent}");
            sent_prev = sent;
            let refs = child_text(a, CAP, "references");
            let refs: Vec<&str> = refs.split_whitespace().collect();
            assert_eq!(
                refs.len(),
                seq - 1,
                "message {seq} references the earlier ones"
            );
            for (k, r) in refs.iter().enumerate() {
                let parts: Vec<&str> = r.split(',').collect();
                assert_eq!(parts[..2], [SENDER, &format!("{alert_id}.{}", k + 1)]);
            }
            let info = child(a, CAP, "info").expect("info");
            assert_eq!(child_text(info, CAP, "category"), "Geo");
            let headline = child_text(info, CAP, "headline");
            assert!(headline.contains(SITE_NAME), "{headline}");
            assert!(headline.contains(point), "{headline}");
            assert_eq!(
                child_text(info, CAP, "web"),
                format!("{PUBLIC}/sites/{SITE}")
            );
            let area = child(info, CAP, "area").expect("area");
            assert_eq!(
                child_text(area, CAP, "areaDesc"),
                "Route 42 below the cliff, km 3.2–3.6 <b>"
            );
            assert_eq!(
                child_text(area, CAP, "polygon"),
                "35.01,135.76 35.01,135.77 35.02,135.77 35.02,135.76 35.01,135.76"
            );
            let kind = child_text(a, CAP, "msgType");
            let severity = child_text(info, CAP, "severity");
            let urgency = child_text(info, CAP, "urgency");
            let parameter = |name: &str| {
                info.children()
                    .filter(|p| p.has_tag_name((CAP, "parameter")))
                    .find(|p| child_text(*p, CAP, "valueName") == name)
                    .map(|p| child_text(p, CAP, "value"))
                    .unwrap_or_else(|| panic!("parameter {name}"))
            };
            let level = parameter("cliffwatch:level");
            // Each message tells the value of its own change (the epoch's snapshot), not today's.
            let value: f64 = parameter("cliffwatch:value")
                .strip_suffix(" mm")
                .unwrap()
                .parse()
                .unwrap();
            let kind_level = (kind.as_str(), level.as_str());
            match kind_level {
                ("Cancel", _) => {
                    assert_eq!((urgency.as_str(), severity.as_str()), ("Past", "Minor"));
                    assert!(value < 8.0, "{kind_level:?} at {value} mm");
                }
                (_, "alarm") => {
                    assert_eq!(
                        (urgency.as_str(), severity.as_str()),
                        ("Immediate", "Severe")
                    );
                    assert!(value > 20.0, "{kind_level:?} at {value} mm");
                }
                (_, "warning") => {
                    assert_eq!(
                        (urgency.as_str(), severity.as_str()),
                        ("Expected", "Moderate")
                    );
                    assert!(value > 8.0, "{kind_level:?} at {value} mm");
                }
                other => panic!("unexpected message {other:?}"),
            }
            if child(info, CAP, "onset").is_some() {
                with_onset += 1;
            }
            kinds.push((kind, level));
        }
        assert_eq!(
            kinds.last().map(|k| k.0.as_str()),
            Some("Cancel"),
            "{kinds:?}"
        );
        assert_eq!(kinds[0].0, "Alert", "{kinds:?}");
        assert!(
            kinds.iter().any(|k| k.1 == "alarm" && k.0 != "Cancel"),
            "the alarm was announced: {kinds:?}"
        );
        for w in kinds.windows(2) {
            // A Cancel is followed only by a new Alert; an Update changes the level.
            if w[0].0 == "Cancel" {
                assert_eq!(w[1].0, "Alert", "{kinds:?}");
            }
            if w[1].0 == "Update" {
                assert_ne!(w[0].1, w[1].1, "{kinds:?}");
            }
        }
        let (st, _, _) = text(&s, &format!("/api/v1/cap/alerts/{alert_id}.{}.xml", n + 1)).await;
        assert_eq!(st, 404, "no message past the thread's end");
    }
    assert_eq!(with_onset, 0, "displacement alerts carry no forecast onset");

    // The per-site feed holds the same entries; the errors are named.
    let (st, _, site_feed) = text(&s, &format!("/api/v1/cap/feed.atom?site={SITE}")).await;
    assert_eq!(st, 200);
    let d = roxmltree::Document::parse(&site_feed).unwrap();
    let ids = |root: roxmltree::Node| -> Vec<String> {
        root.children()
            .filter(|c| c.has_tag_name((ATOM, "entry")))
            .map(|e| child_text(e, ATOM, "id"))
            .collect()
    };
    assert_eq!(ids(d.root_element()), ids(root), "entry ids are stable");
    assert_eq!(text(&s, "/api/v1/cap/feed.atom?site=nowhere").await.0, 404);
    assert_eq!(text(&s, "/api/v1/cap/feed.atom?limit=0").await.0, 400);
    let (st, _, one) = text(&s, "/api/v1/cap/feed.atom?limit=1").await;
    assert_eq!(st, 200);
    assert_eq!(one.matches("<entry>").count(), 1);
    assert_eq!(text(&s, "/api/v1/cap/alerts/nope.xml").await.0, 404);
    assert_eq!(text(&s, "/api/v1/cap/alerts/nope.json").await.0, 404);

    // The site's time zone on its pages: UTC and Japan time.
    let (st, _, page) = text(&s, &format!("/sites/{SITE}")).await;
    assert_eq!(st, 200);
    assert!(
        page.contains("09:00 UTC") && page.contains("18:00 JST"),
        "times in UTC and JST"
    );
    s.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_areas_and_time_zones_are_refused_by_name() {
    let s = TestServer::start(|_| {}).await;
    let post = |body: Value| {
        let s = &s;
        async move {
            let r = s
                .client
                .post(s.url("/api/v1/sites"))
                .json(&body)
                .send()
                .await
                .unwrap();
            (r.status().as_u16(), r.text().await.unwrap())
        }
    };
    let (st, msg) = post(json!({"id": "a", "time_zone": "Mars/Olympus"})).await;
    assert_eq!(st, 422);
    assert!(msg.contains("time_zone 'Mars/Olympus'"), "{msg}");
    let open_ring = json!([[35.0, 135.0], [35.0, 135.1], [35.1, 135.1], [35.1, 135.0]]);
    let (st, msg) =
        post(json!({"id": "b", "area": {"description": "x", "polygon": open_ring}})).await;
    assert_eq!(st, 422);
    assert!(msg.contains("area.polygon"), "{msg}");
    let (st, msg) = post(json!({"id": "c", "area": {"description": "x",
        "circle": {"latitude": 35.0, "longitude": 200.0, "radius_km": 1.0}}}))
    .await;
    assert_eq!(st, 422);
    assert!(msg.contains("area.circle"), "{msg}");
    let (st, msg) = post(json!({"id": "d", "time_zone": "Europe/Zurich",
        "area": {"description": "Gotthard road", "circle": {"latitude": 46.55, "longitude": 8.56, "radius_km": 0.5}}}))
    .await;
    assert_eq!(st, 201, "{msg}");
    let (_, site) = s.get("/api/v1/sites/d").await;
    assert_eq!(site["time_zone"], "Europe/Zurich");
    assert_eq!(site["area"]["circle"]["radius_km"], 0.5);
    // No alert at all: the feed is an empty, valid Atom document.
    let (st, _, feed) = text(&s, "/api/v1/cap/feed.atom").await;
    assert_eq!(st, 200);
    let d = roxmltree::Document::parse(&feed).unwrap();
    assert!(d.root_element().has_tag_name((ATOM, "feed")));
    assert_eq!(feed.matches("<entry>").count(), 0);
    s.stop().await;
}

/// A datum alert stays internal: a stable point that moves with the block raises
/// `reference_unstable` at warning, which the API lists and the CAP feed does not carry (its
/// message is 404, no feed entry names it); the movement alerts' messages are all valid CAP 1.2,
/// and no value carries a stray space.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reference_unstable_alert_produces_no_cap_message() {
    let s = TestServer::start(|c| {
        c.cap_sender = SENDER.into();
        c.public_url = Some(PUBLIC.into());
    })
    .await;
    create_site_with_stable(
        &s,
        json!({"id": "datum", "alert_rules": [
            {"level": "watch", "metric": "displacement_mm", "above": 5.0},
            {"level": "warning", "metric": "displacement_mm", "above": 10.0}]}),
    )
    .await;
    // The last stable point moves with the block: 0, then 12 mm three times.
    for (k, mm) in [0.0, 12.0, 12.0, 12.0].iter().enumerate() {
        let body = synthetic_epoch(4, POINTS, &day(k), 700 + k as u64, *mm, STABLE - 1);
        let (st, answer) = s.upload("datum", &body).await;
        assert_eq!(st, 201, "epoch {k}: {answer}");
    }
    let (_, alerts) = s.get("/api/v1/alerts?site=datum&limit=200").await;
    let alerts = alerts["items"].as_array().unwrap().clone();
    let datum = alerts
        .iter()
        .find(|a| a["rule"] == "reference_unstable")
        .unwrap_or_else(|| panic!("a reference_unstable alert: {alerts:?}"));
    assert_eq!(datum["level"], "warning", "{datum}");
    let id = datum["id"].as_str().unwrap();
    let (st, _, body) = text(&s, &format!("/api/v1/cap/alerts/{id}.xml")).await;
    assert_eq!(st, 404, "{body}");
    assert!(body.contains("movement alerts only"), "{body}");
    let (st, _, body) = text(&s, &format!("/api/v1/cap/alerts/{id}.1.xml")).await;
    assert_eq!(st, 404, "{body}");

    let (st, _, feed) = text(&s, "/api/v1/cap/feed.atom?site=datum").await;
    assert_eq!(st, 200, "{feed}");
    assert!(
        !feed.contains("reference_unstable") && !feed.contains(id),
        "{feed}"
    );
    let doc = roxmltree::Document::parse(&feed).unwrap();
    let hrefs: Vec<String> = doc
        .root_element()
        .children()
        .filter(|c| c.has_tag_name((ATOM, "entry")))
        .filter_map(|e| {
            child(e, ATOM, "link")?
                .attribute("href")
                .map(str::to_string)
        })
        .collect();
    let movement = alerts
        .iter()
        .filter(|a| a["rule"] == "displacement_mm" && a["peak_level"] != "watch")
        .count();
    assert!(movement > 0, "{alerts:?}");
    assert_eq!(hrefs.len(), movement, "{feed}");
    let have_xmllint = xmllint_available();
    let scratch = tempfile::tempdir().unwrap();
    for (k, href) in hrefs.iter().enumerate() {
        let (st, _, xml) = text(&s, href.strip_prefix(PUBLIC).unwrap()).await;
        assert_eq!(st, 200, "{xml}");
        let d = roxmltree::Document::parse(&xml).unwrap();
        let rule = d
            .descendants()
            .filter(|n| n.has_tag_name((CAP, "parameter")))
            .find(|p| child_text(*p, CAP, "valueName") == "cliffwatch:rule")
            .map(|p| child_text(p, CAP, "value"));
        assert_eq!(rule.as_deref(), Some("displacement_mm"), "{xml}");
        for v in d.descendants().filter(|n| n.has_tag_name((CAP, "value"))) {
            let t = v.text().unwrap_or_default();
            assert_eq!(t, t.trim(), "a value with a stray space: {xml}");
        }
        if have_xmllint {
            validate_cap(&xml, scratch.path(), &format!("datum-{k}"));
        }
    }
}

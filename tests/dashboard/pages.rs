//! The dashboard's pages against a real server: a site with a moving block (16 targets, 8 stable,
//! the block moving 2.5 mm a day towards the cameras), its pages linked sites → site → point →
//! epoch, user text escaped, the plot data equal to the API's series, acknowledgement from the
//! site page and assets (the sign-in with tokens: `sessions.rs`).

use crate::support;

use reqwest::header;
use serde_json::{json, Value};
use support::dashboard::{fill, html, links, name, POINTS, SITE, STABLE};
use support::server::TestServer;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_link_down_escape_user_text_and_plot_the_api_series() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 8, None).await;

    // Sites: the site with its state, last epoch and number of points.
    let (st, sites) = html(&s, "/").await;
    assert_eq!(st, 200);
    assert!(links(&sites).contains(&format!("/sites/{SITE}")), "{sites}");
    assert!(sites.contains("Kamo &lt;script&gt;alert(1)&lt;/script&gt; &amp; cliff"));
    assert!(!sites.contains("<script>alert(1)"));
    assert!(
        sites.contains("badge warning"),
        "the block reached 17.5 mm: warning"
    );
    assert!(sites.contains(&format!(">{POINTS}</td>")));

    // Site: face plan with every point, open alerts with the form, epochs, points.
    let (st, site) = html(&s, &format!("/sites/{SITE}")).await;
    assert_eq!(st, 200);
    assert!(site.contains("<svg class=\"plan\""));
    for i in 0..POINTS {
        assert!(
            site.contains(&format!(">{}</text>", name(i))),
            "{} on the plan",
            name(i)
        );
        assert!(links(&site).contains(&format!("/sites/{SITE}/points/{}", name(i))));
    }
    assert_eq!(site.matches("pt stable").count(), STABLE);
    assert!(site.contains("vectors ×"));
    let epoch_links: Vec<String> = links(&site)
        .into_iter()
        .filter(|l| l.starts_with(&format!("/sites/{SITE}/epochs/")))
        .collect();
    assert!(epoch_links.len() >= 8, "{epoch_links:?}");
    assert!(site.contains("hx-post=\"/dashboard/alerts/"), "ack forms");

    // The alert filter: the rows shown are the API's alerts of that level and state.
    let (_, api_alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=500"))
        .await;
    let api_alerts = api_alerts["items"].as_array().unwrap().clone();
    let rank = |l: &str| ["watch", "warning", "alarm"].iter().position(|k| *k == l);
    for (query, want) in [
        (
            "",
            Box::new(|a: &Value| a["state"] != "resolved") as Box<dyn Fn(&Value) -> bool>,
        ),
        (
            "?level=warning",
            Box::new(|a: &Value| {
                a["state"] != "resolved" && rank(a["level"].as_str().unwrap()) >= rank("warning")
            }),
        ),
        ("?state=all&level=watch", Box::new(|_: &Value| true)),
        ("?state=all&level=alarm", Box::new(|_: &Value| false)),
        (
            "?state=resolved",
            Box::new(|a: &Value| a["state"] == "resolved"),
        ),
        (
            &*format!("?state=all&subject={}", name(POINTS - 1).to_lowercase()),
            Box::new(|a: &Value| a["point"] == json!(name(POINTS - 1))),
        ),
    ] {
        let (st, page) = html(&s, &format!("/sites/{SITE}{query}")).await;
        assert_eq!(st, 200, "{query}: {page}");
        let mut shown: Vec<String> = page
            .split("<tr id=\"alert-")
            .skip(1)
            .map(|r| r.split('"').next().unwrap().to_string())
            .collect();
        let mut expected: Vec<String> = api_alerts
            .iter()
            .filter(|a| want(a))
            .map(|a| a["id"].as_str().unwrap().to_string())
            .collect();
        shown.sort();
        expected.sort();
        assert_eq!(shown, expected, "alerts shown for '{query}'");
    }
    // the fill raises warnings and no alarm, so the alarm filter must empty the table
    assert!(
        api_alerts.iter().any(|a| a["level"] == "warning")
            && !api_alerts.iter().any(|a| a["level"] == "alarm"),
        "{api_alerts:?}"
    );
    for (query, named) in [
        ("?level=severe", "level 'severe'"),
        ("?state=closed", "state 'closed'"),
    ] {
        let (st, page) = html(&s, &format!("/sites/{SITE}{query}")).await;
        assert_eq!(st, 400, "{query}");
        assert!(page.contains(named), "{page}");
    }

    // Point: the plots' data source and the CSV of the same series.
    let moving = name(POINTS - 1);
    let (st, point) = html(&s, &format!("/sites/{SITE}/points/{moving}")).await;
    assert_eq!(st, 200);
    assert!(point.contains(&format!("data-src=\"/dashboard/plot/{SITE}/{moving}\"")));
    assert!(links(&point).contains(&format!(
        "/api/v1/sites/{SITE}/points/{moving}/displacements?format=csv"
    )));
    for panel in ["xyz", "d", "velocity", "inverse"] {
        assert!(
            point.contains(&format!("data-panel=\"{panel}\"")),
            "{panel}"
        );
    }

    // The plot data are the API's series (short series: nothing dropped), with the rules'
    // thresholds and the alert events.
    let (st, plot) = s
        .get(&format!("/dashboard/plot/{SITE}/{moving}?width=800"))
        .await;
    assert_eq!(st, 200, "{plot}");
    let (_, api) = s
        .get(&format!(
            "/api/v1/sites/{SITE}/points/{moving}/displacements?limit=1000"
        ))
        .await;
    let items = api["items"].as_array().unwrap();
    assert_eq!(plot["total"], json!(items.len()));
    assert_eq!(plot["t"].as_array().unwrap().len(), items.len());
    for (k, it) in items.iter().enumerate() {
        assert_eq!(plot["epoch"][k], it["epoch"]);
        for (col, field) in [
            ("dx", "dx_mm"),
            ("dz", "dz_mm"),
            ("d", "d_mm"),
            ("sd", "sigma_mm"),
            ("f_d", "f_d_mm"),
        ] {
            let (a, b) = (plot[col][k].as_f64(), it[field].as_f64());
            assert_eq!(a, b, "{col} at {k}");
        }
    }
    let levels: Vec<&str> = plot["thresholds"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["level"].as_str())
        .collect();
    assert_eq!(levels, ["watch", "warning"]);
    let events: Vec<&str> = plot["events"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["type"].as_str())
        .collect();
    assert!(events.contains(&"alert.raised"), "{events:?}");
    assert!(plot["events"][0]["t"].as_f64().unwrap() > 1.7e9);

    // Epoch: the report and a residual plot per image.
    let (st, epoch) = html(&s, &epoch_links[0]).await;
    assert_eq!(st, 200);
    assert!(epoch.contains("σ0 (mm)") && epoch.contains("iterations"));
    // The global test as the API reports it: verdict, variance factor and bounds.
    let (_, summary) = s.get(&format!("/api/v1{}", epoch_links[0])).await;
    let t = &summary["global_test"];
    let f = |k: &str| format!("{:.3}", t[k].as_f64().unwrap());
    let verdict = if t["accepted"].as_bool().unwrap() {
        "accepted"
    } else {
        "rejected"
    };
    let row = format!(
        "{verdict}: {} in [{}, {}] (99.8 %)",
        f("variance_factor"),
        f("lower"),
        f("upper")
    );
    assert!(epoch.contains(&row), "{row} not on the page");
    assert_eq!(
        epoch.matches("<svg class=\"residual\"").count(),
        4,
        "4 images"
    );

    // Campaign report: plan, a row per point, plots of the moving points, the alert history;
    // a period that ends before the movement shows no moving point.
    let (st, report) = html(&s, &format!("/sites/{SITE}/report")).await;
    assert_eq!(st, 200);
    assert!(report.contains("<svg class=\"plan\""));
    assert_eq!(
        report.matches("<figure class=\"moving\"").count(),
        (POINTS - STABLE).min(4),
        "the moving points that moved most, at most 4"
    );
    assert!(report.contains("Alert history") && report.contains("badge warning"));
    for i in 0..POINTS {
        assert!(
            report.contains(&format!(">{}</a></td>", name(i))),
            "{} in the table",
            name(i)
        );
    }
    let (st, early) = html(
        &s,
        &format!("/sites/{SITE}/report?from=2026-11-01&to=2026-11-01"),
    )
    .await;
    assert_eq!(st, 200);
    assert!(
        early.contains("No block and no point moved significantly")
            && early.contains("No alert in the period")
    );
    assert_eq!(
        html(&s, &format!("/sites/{SITE}/report?from=yesterday"))
            .await
            .0,
        400
    );

    // Unknown things are HTML 404 pages; a malformed epoch id too.
    for p in [
        "/sites/nope",
        &format!("/sites/{SITE}/points/nope"),
        &format!("/sites/{SITE}/epochs/x"),
    ] {
        let (st, body) = html(&s, p).await;
        assert_eq!(st, 404, "{p}");
        assert!(body.contains("<html"), "{p}");
    }

    // Acknowledging from the site page (htmx): the row comes back acknowledged, the API agrees.
    let (_, open) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=open"))
        .await;
    let id = open["items"][0]["id"]
        .as_str()
        .expect("an open alert")
        .to_string();
    // Even with no tokens, another site's page cannot make a browser acknowledge it.
    let host = s
        .url("")
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    for (name, value) in [
        ("origin", "http://evil.example".to_string()),
        ("origin", "null".to_string()),
        ("sec-fetch-site", "cross-site".to_string()),
    ] {
        let r = s
            .client
            .post(s.url(&format!("/dashboard/alerts/{id}/ack")))
            .header(name, value.as_str())
            .form(&[("by", "mallory")])
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 403, "{name}: {value}");
    }
    let (_, still) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=open"))
        .await;
    assert_eq!(still["items"][0]["id"], json!(id), "nothing acknowledged");
    // The service's own page (same origin) may.
    let r = s
        .client
        .post(s.url(&format!("/dashboard/alerts/{id}/ack")))
        .header("hx-request", "true")
        .header("origin", format!("http://{host}"))
        .header("sec-fetch-site", "same-origin")
        .form(&[("by", "Aiko <b>"), ("comment", "on my way")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let row = r.text().await.unwrap();
    assert!(row.contains("acknowledged by Aiko &lt;b&gt;"), "{row}");
    // A second acknowledgement does not overwrite the first: 409 naming who.
    let r = s
        .client
        .post(s.url(&format!("/api/v1/alerts/{id}/ack")))
        .json(&json!({"by": "someone else"}))
        .send()
        .await
        .unwrap();
    let st = r.status();
    let e: Value = r.json().await.unwrap();
    assert_eq!(st, 409, "{e}");
    assert_eq!(e["error"]["code"], "already_acknowledged");
    assert!(
        e["error"]["message"].as_str().unwrap().contains("Aiko <b>"),
        "{e}"
    );
    // The alert's page, linked from its row on the site page: its history, with who
    // acknowledged and their comment (user text escaped).
    let enc: String = id
        .bytes()
        .map(|b| match b {
            b if b.is_ascii_alphanumeric() || b"-._~".contains(&b) => (b as char).to_string(),
            b => format!("%{b:02X}"),
        })
        .collect();
    let alert_path = format!("/sites/{SITE}/alerts/{enc}");
    let (st, page) = html(&s, &alert_path).await;
    assert_eq!(st, 200, "{page}");
    for want in [
        "<td class=\"event\">raised</td>",
        "<td class=\"event\">acknowledged</td>",
        "Aiko &lt;b&gt;",
        "on my way",
    ] {
        assert!(page.contains(want), "{want} missing from {page}");
    }
    let (_, site_page) = html(&s, &format!("/sites/{SITE}")).await;
    assert!(site_page.contains(&alert_path), "no link to {alert_path}");
    let (st, _) = html(&s, &format!("/sites/{SITE}/alerts/nope")).await;
    assert_eq!(st, 404);
    let (_, a) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=acknowledged"))
        .await;
    assert!(a["items"]
        .as_array()
        .unwrap()
        .iter()
        .any(|x| x["id"] == json!(id)));
    let r = s
        .client
        .post(s.url(&format!("/dashboard/alerts/{id}/ack")))
        .form(&[("by", " ")])
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 422, "a name is required");

    // Assets: embedded, cached by ETag, nothing else served.
    let r = s
        .client
        .get(s.url("/assets/uPlot.iife.min.js"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let etag = r.headers()[header::ETAG].clone();
    assert!(r.bytes().await.unwrap().len() > 40_000);
    let r = s
        .client
        .get(s.url("/assets/uPlot.iife.min.js"))
        .header(header::IF_NONE_MATCH, etag)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 304);
    assert_eq!(s.get("/assets/../Cargo.toml").await.0, 404);

    // The site page lists epochs without reading their stored reports: one that is unreadable
    // does not take the page down.
    let mut tx = s.store.begin_write().await.unwrap();
    sqlx::query("UPDATE epochs SET report = '{}' WHERE id = (SELECT MAX(id) FROM epochs)")
        .execute(&mut *tx)
        .await
        .unwrap();
    tx.commit().await.unwrap();
    let (st, site) = html(&s, &format!("/sites/{SITE}")).await;
    assert_eq!(st, 200, "{site}");
    assert!(site.contains("<svg class=\"plan\""));
    s.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_series_plot_keeps_peaks_ends_and_alert_epochs() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 40, None).await;
    let moving = name(POINTS - 1);
    let (_, api) = s
        .get(&format!(
            "/api/v1/sites/{SITE}/points/{moving}/displacements?limit=1000"
        ))
        .await;
    let items = api["items"].as_array().unwrap().clone();
    // The narrowest plot (100 px) on 39 epochs keeps all; the downsampling itself is checked
    // on long series by the unit tests of `dashboard::downsample`. Here: ends and alert epochs.
    let (_, plot) = s
        .get(&format!("/dashboard/plot/{SITE}/{moving}?width=10"))
        .await;
    let epochs: Vec<i64> = plot["epoch"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e.as_i64().unwrap())
        .collect();
    assert_eq!(
        epochs.first(),
        items.first().map(|i| i["epoch"].as_i64().unwrap()).as_ref()
    );
    assert_eq!(
        epochs.last(),
        items.last().map(|i| i["epoch"].as_i64().unwrap()).as_ref()
    );
    let (_, alerts) = s
        .get(&format!("/api/v1/alerts?site={SITE}&limit=200"))
        .await;
    for a in alerts["items"].as_array().unwrap() {
        if a["point"] == json!(moving) {
            assert!(
                epochs.contains(&a["epoch"].as_i64().unwrap()),
                "alert epoch kept"
            );
        }
    }
    // The epochs the plot keeps: those of the alerts on the point or on a group it is in.
    let concerns = |a: &&Value| {
        a["point"] == json!(moving)
            || a["points"]
                .as_array()
                .is_some_and(|p| p.contains(&json!(moving)))
    };
    let want: std::collections::BTreeSet<i64> = alerts["items"]
        .as_array()
        .unwrap()
        .iter()
        .filter(concerns)
        .filter_map(|a| a["epoch"].as_i64())
        .collect();
    let of_point = |p: String| {
        let store = s.store.clone();
        async move {
            cliffwatch::store::alerts::epochs_of_point(store.reader(), SITE, &p)
                .await
                .unwrap()
                .into_iter()
                .collect::<std::collections::BTreeSet<i64>>()
        }
    };
    assert!(!want.is_empty());
    assert_eq!(of_point(moving.clone()).await, want);
    assert!(
        of_point(name(0)).await.is_empty(),
        "a stable point has no alerts"
    );
    let max_api = items
        .iter()
        .map(|i| i["d_mm"].as_f64().unwrap())
        .fold(0.0, f64::max);
    let max_plot = plot["d"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_f64)
        .fold(0.0, f64::max);
    assert_eq!(max_api, max_plot);
    s.stop().await;
}

/// A long history plotted from SQLite: see [`support::plot::long_history_plot`].
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn long_history_plot_reads_block_extremes_and_keeps_the_envelope() {
    let s = TestServer::start(|_| {}).await;
    support::plot::long_history_plot(&s.store, &s.url("")).await;
    s.stop().await;
}

/// A block accelerating towards failure (inverse-velocity law, failure on day 16): the point page
/// says its estimates are filtered, and the forecast failure time reads in UTC and the site's zone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_forecast_reads_in_utc_and_the_site_zone() {
    use support::dashboard::day;
    let s = TestServer::start(|_| {}).await;
    let r = s
        .client
        .post(s.url("/api/v1/sites"))
        .json(&json!({"id": "tf", "time_zone": "Asia/Tokyo", "model": "orthogonal"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    support::dashboard::fill_accelerating(&s, "tf").await;
    let moving = name(POINTS - 1);
    let (_, page) = html(&s, &format!("/sites/tf/points/{moving}")).await;
    assert!(
        page.contains("filtered velocity (mm/day)")
            && page.contains("filtered time to failure (h)")
            && page.contains("raw velocity (mm/day)"),
        "{page}"
    );
    // The block is not declared, so the forecast is the mean series' of the targets that move
    // together with this one, and the page names them: the other moving targets, never a
    // stable one.
    let text = support::dashboard::text_of(&page);
    let pooled = text
        .split(&format!(
            "pooled: the forecast of the mean series of {moving} with "
        ))
        .nth(1)
        .and_then(|r| {
            r.split(", which move together (not a declared block)")
                .next()
        })
        .unwrap_or_else(|| panic!("the pooled forecast named: {text}"));
    let named: Vec<&str> = pooled
        .split([',', ' '])
        .filter(|w| !w.is_empty() && *w != "and")
        .collect();
    let others: Vec<String> = (STABLE..POINTS - 1).map(name).collect();
    assert!(
        named.len() >= 2 && named.iter().all(|n| others.iter().any(|o| o == n)),
        "pooled with {named:?}, the other moving targets {others:?}"
    );
    let (_, plot) = s
        .get(&format!("/dashboard/plot/tf/{moving}?width=400"))
        .await;
    let text = plot["forecast"]["text"]
        .as_str()
        .unwrap_or_else(|| panic!("{}", plot["forecast"]));
    eprintln!("{text}");
    // the true failure (day 16, 2026-11-17 09:00 UTC) lies in the interval shown
    let truth = chrono::DateTime::parse_from_rfc3339(&day(16))
        .unwrap()
        .timestamp() as f64;
    let f = &plot["forecast"];
    assert!(
        f["lower"].as_f64().unwrap() <= truth && truth <= f["upper"].as_f64().unwrap(),
        "{f}"
    );
    assert!(
        text.starts_with("Failure likely before ")
            && text.contains("Forecast failure (filtered): ")
            && text.contains(" UTC · ")
            && text.matches("JST").count() == 4,
        "{text}"
    );
    // The bound is the last epoch plus hours + 1.645 σ, and the truth lies before it.
    let bound = f["likely_before"].as_f64().unwrap();
    assert!(bound >= f["t_f"].as_f64().unwrap() && truth <= bound, "{f}");
    s.stop().await;
}

/// An open alarm raised long ago stays on the site page (and sets the sites page's badge)
/// however many alerts were raised and resolved since: the page once read the newest 500 alerts
/// of every state and then dropped the resolved ones, and showed "No alert matches."
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_old_open_alarm_is_shown_under_many_newer_resolved_alerts() {
    let s = TestServer::start(|_| {}).await;
    s.create_site("busy").await;
    let mut tx = s.store.begin_write().await.unwrap();
    for k in 0..=600i64 {
        let (id, level, state) = if k == 0 {
            ("old-alarm".to_string(), "alarm", "open")
        } else {
            (format!("noise-{k}"), "watch", "resolved")
        };
        let t = format!("2026-01-{:02}T{:02}:00:00.000000Z", 1 + k / 24, k % 24);
        sqlx::query(
            "INSERT INTO alerts (id, site_id, point, level, rule, message, state, raised_at, updated_at) \
             VALUES ($1, 'busy', $2, $3, 'displacement_mm', 'm', $4, $5, $6)",
        )
        .bind(&id)
        .bind(if k == 0 { "T1" } else { "Noisy1" })
        .bind(level)
        .bind(state)
        .bind(&t)
        .bind(&t)
        .execute(&mut *tx)
        .await
        .unwrap();
    }
    tx.commit().await.unwrap();
    let (status, page) = html(&s, "/sites/busy").await;
    assert_eq!(status, 200);
    assert!(
        page.contains("id=\"alert-old-alarm\""),
        "the open alarm is not shown"
    );
    assert!(!page.contains("No alert matches."));
    let (_, sites) = html(&s, "/").await;
    let row = sites
        .split("<tr>")
        .find(|r| r.contains("/sites/busy\""))
        .expect("the site's row");
    assert!(row.contains("badge alarm"), "badge: {row}");

    // Every state: 601 alerts, newest first, 500 a page; the second page holds the other 101,
    // down to the old alarm, and links back to the newest.
    let ids = |page: &str| -> Vec<String> {
        page.split("id=\"alert-")
            .skip(1)
            .filter_map(|s| s.split('"').next())
            .map(str::to_string)
            .collect()
    };
    let (_, first) = html(&s, "/sites/busy?state=all").await;
    let older = links(&first)
        .into_iter()
        .find(|l| l.contains("alerts_before="))
        .expect("a link to older alerts");
    assert!(first.contains("older alerts →"));
    assert!(!first.contains("id=\"alert-old-alarm\""));
    let (st, second) = html(&s, &older.replace("&amp;", "&")).await;
    assert_eq!(st, 200, "{older}");
    let (a, b) = (ids(&first), ids(&second));
    assert_eq!((a.len(), b.len()), (500, 101), "{older}");
    assert!(b.iter().all(|id| !a.contains(id)), "pages overlap");
    assert!(b.contains(&"old-alarm".to_string()));
    assert!(!second.contains("older alerts →"));
    assert!(second.contains("← newest alerts"));
    // A filtered list pages with its filter, and its way back to the newest keeps it.
    let (_, first) = html(&s, "/sites/busy?state=resolved&level=watch&subject=NOISY").await;
    let older = links(&first)
        .into_iter()
        .find(|l| l.contains("alerts_before="))
        .expect("a link to older alerts of the filter");
    assert!(older.contains("level=watch&amp;subject=noisy"), "{older}");
    let (_, second) = html(&s, &older.replace("&amp;", "&")).await;
    assert_eq!(ids(&first).len(), 500);
    assert_eq!(ids(&second).len(), 100, "{older}");
    let newest = links(&second)
        .into_iter()
        .find(|l| l.ends_with("#alerts") && !l.contains("alerts_before="))
        .expect("the link back to the newest alerts");
    assert_eq!(
        newest,
        "/sites/busy?state=resolved&amp;level=watch&amp;subject=noisy#alerts"
    );
    let (st, bad) = html(&s, "/sites/busy?state=all&alerts_before=2026").await;
    assert_eq!(st, 400);
    assert!(
        bad.contains("alerts_before and alerts_before_id go together"),
        "{bad}"
    );
    s.stop().await;
}

/// The epochs table pages back to the first epoch: 30 a page, newest first, "older epochs →"
/// to the next page, which ends with the site's first epoch and links back to the newest; a
/// cursor that is no time is refused by name.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_epochs_table_pages_back_to_the_first_epoch() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 34, None).await;
    let (_, api) = s
        .get(&format!("/api/v1/sites/{SITE}/epochs?limit=100"))
        .await;
    let mut ids: Vec<i64> = api["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["id"].as_i64().unwrap())
        .collect();
    assert_eq!(ids.len(), 34);
    ids.sort_unstable_by(|a, b| b.cmp(a));
    // The epoch links of a page's epochs table, in the order shown.
    let epoch_links = |page: &str| -> Vec<i64> {
        let table = page.split("<section id=\"epochs\">").nth(1).unwrap();
        links(table)
            .iter()
            .filter_map(|l| l.rsplit("/epochs/").next()?.parse().ok())
            .collect()
    };
    let (st, first) = html(&s, &format!("/sites/{SITE}")).await;
    assert_eq!(st, 200);
    assert_eq!(
        epoch_links(&first),
        ids[..30],
        "the newest 30, newest first"
    );
    let older = links(&first)
        .into_iter()
        .find(|l| l.contains("epochs_before="))
        .expect("a link to older epochs");
    assert!(first.contains("older epochs →"));
    let (st, second) = html(&s, &older.replace("&amp;", "&")).await;
    assert_eq!(st, 200, "{older}");
    assert_eq!(
        epoch_links(&second),
        ids[30..],
        "the 4 oldest, down to the first"
    );
    assert!(!second.contains("older epochs →"));
    assert!(second.contains("The first epoch of the site is the last row."));
    assert!(second.contains("← newest epochs"));
    let (st, bad) = html(&s, &format!("/sites/{SITE}?epochs_before=yesterday")).await;
    assert_eq!(st, 400);
    assert!(bad.contains("epochs_before 'yesterday'"), "{bad}");
    s.stop().await;
}

//! The dashboard in a real browser: headless Chromium driven through ChromeDriver (W3C
//! WebDriver over HTTP). The point page's plots are drawn by the embedded uPlot from the
//! server's data (canvases exist, no error), and an alert is acknowledged by typing a name and
//! clicking the button of the site page (htmx), which the API then reports; the alert filter
//! swaps the alert section to the acknowledged ones. At a phone's width
//! (360 CSS px) no page scrolls sideways and the face plan's names stay readable. An epoch taken
//! from the watched directory shows each station's image with the detected targets drawn where
//! the picture has them.
//!
//! Needs `chromium` and `chromedriver` (Debian's `chromium`, `chromium-driver`; `.ci/run`
//! installs them). Under `CI=true` their absence fails the test; elsewhere it is skipped with a
//! message.

use crate::support;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use support::dashboard::{fill, name, POINTS, SITE};
use support::server::{free_port, TestServer};

const CHROMIUM: &str = "/usr/bin/chromium";
const DRIVER: &str = "/usr/bin/chromedriver";
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

pub(crate) struct Driver {
    child: Child,
    base: String,
    session: String,
    client: reqwest::Client,
    _profile: tempfile::TempDir,
}

impl Driver {
    /// Types `name` into the acknowledgement form of alert `id`'s row and clicks the button,
    /// after opening its subject's list of alerts (as a person clicks it open).
    pub(crate) async fn acknowledge_as(&self, id: &str, name: &str) {
        self.script(&format!(
            "var d = document.getElementById('alert-{id}').closest('details'); if (d) d.open = true; return true"
        ))
        .await;
        let input = self
            .element(&format!("[id=\"alert-{id}\"] input[name=by]"))
            .await;
        self.call(
            reqwest::Method::POST,
            &format!("/element/{input}/value"),
            json!({"text": name}),
        )
        .await;
        let button = self.element(&format!("[id=\"alert-{id}\"] button")).await;
        self.call(
            reqwest::Method::POST,
            &format!("/element/{button}/click"),
            json!({}),
        )
        .await;
    }

    pub(crate) async fn start() -> Option<Driver> {
        if !(Path::new(CHROMIUM).exists() && Path::new(DRIVER).exists()) {
            assert!(
                std::env::var("CI").as_deref() != Ok("true"),
                "CI=true: {CHROMIUM} and {DRIVER} are required (apt-get install chromium chromium-driver)"
            );
            eprintln!("skipped: {CHROMIUM} or {DRIVER} missing");
            return None;
        }
        let port = free_port();
        let child = Command::new(DRIVER)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts");
        let base = format!("http://127.0.0.1:{port}");
        let client = reqwest::Client::new();
        let t0 = Instant::now();
        loop {
            if let Ok(r) = client.get(format!("{base}/status")).send().await {
                if r.status().is_success() {
                    break;
                }
            }
            assert!(t0.elapsed() < Duration::from_secs(20), "chromedriver ready");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let profile = tempfile::tempdir().unwrap();
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": CHROMIUM, "args": [
                "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", "--window-size=1200,1000",
                format!("--user-data-dir={}", profile.path().display())]}}}});
        let r: Value = client
            .post(format!("{base}/session"))
            .json(&caps)
            .send()
            .await
            .unwrap()
            .json()
            .await
            .unwrap();
        let session = r["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("new session: {r}"))
            .to_string();
        Some(Driver {
            child,
            base,
            session,
            client,
            _profile: profile,
        })
    }

    pub(crate) async fn call(&self, method: reqwest::Method, path: &str, body: Value) -> Value {
        let url = format!("{}/session/{}{}", self.base, self.session, path);
        let mut req = self.client.request(method, url);
        if !body.is_null() {
            req = req.json(&body);
        }
        let r: Value = req.send().await.unwrap().json().await.unwrap();
        assert!(r["value"]["error"].is_null(), "{path}: {r}");
        r["value"].clone()
    }

    pub(crate) async fn goto(&self, url: &str) {
        self.call(reqwest::Method::POST, "/url", json!({"url": url}))
            .await;
    }

    pub(crate) async fn script(&self, script: &str) -> Value {
        self.call(
            reqwest::Method::POST,
            "/execute/sync",
            json!({"script": script, "args": []}),
        )
        .await
    }

    pub(crate) async fn element(&self, css: &str) -> String {
        let v = self
            .call(
                reqwest::Method::POST,
                "/element",
                json!({"using": "css selector", "value": css}),
            )
            .await;
        v[ELEMENT].as_str().expect("element").to_string()
    }

    /// Saves a PNG of the viewport as `name` in `$CLIFFWATCH_SCREENSHOTS` (created if missing),
    /// when that is set.
    pub(crate) async fn screenshot(&self, name: impl AsRef<Path>) {
        if let Some(dir) = std::env::var_os("CLIFFWATCH_SCREENSHOTS") {
            use base64::Engine;
            let png = self
                .call(reqwest::Method::GET, "/screenshot", Value::Null)
                .await;
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(png.as_str().unwrap())
                .unwrap();
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(Path::new(&dir).join(name), bytes).unwrap();
        }
    }

    /// Lays pages out as a phone does: 360 × 740 CSS px, device scale 2, mobile.
    /// The current page printed to an A4 PDF (WebDriver's Print Page), and its page count (the
    /// `/Type /Page` objects, whatever the writer's spacing).
    pub(crate) async fn print_a4(&self) -> (Vec<u8>, usize) {
        let pdf = self
            .call(
                reqwest::Method::POST,
                "/print",
                json!({"page": {"width": 21.0, "height": 29.7}, "background": true}),
            )
            .await;
        let pdf = {
            use base64::Engine;
            base64::engine::general_purpose::STANDARD
                .decode(pdf.as_str().unwrap())
                .unwrap()
        };
        assert!(pdf.starts_with(b"%PDF"), "a PDF");
        let text = String::from_utf8_lossy(&pdf);
        let pages = text.matches("/Type /Page\n").count()
            + text.matches("/Type /Page/").count()
            + text.matches("/Type /Page ").count()
            + text.matches("/Type/Page/").count()
            + text.matches("/Type/Page>").count()
            + text.matches("/Type /Page>").count();
        (pdf, pages)
    }

    pub(crate) async fn emulate_phone(&self) {
        self.emulate_phone_width(360).await;
    }

    /// Lays pages out as a phone `width` CSS px wide does (740 px high, device scale 2).
    pub(crate) async fn emulate_phone_width(&self, width: u32) {
        self.call(
            reqwest::Method::POST,
            "/goog/cdp/execute",
            json!({"cmd": "Emulation.setDeviceMetricsOverride", "params": {
                "width": width, "height": 740, "deviceScaleFactor": 2, "mobile": true}}),
        )
        .await;
    }

    /// Ends the WebDriver session (the browser closes).
    pub(crate) async fn quit(&self) {
        self.client
            .delete(format!("{}/session/{}", self.base, self.session))
            .send()
            .await
            .ok();
    }

    /// Polls `script` until it returns a truthy value (at most 15 s).
    pub(crate) async fn wait_for(&self, script: &str) -> Value {
        let t0 = Instant::now();
        loop {
            let v = self.script(script).await;
            if !(v.is_null() || v == json!(false) || v == json!(0) || v == json!("")) {
                return v;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(15),
                "waited for: {script}"
            );
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plots_draw_and_an_alert_is_acknowledged_in_chromium() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 8, None).await;
    let moving = name(POINTS - 1);

    // The point page: uPlot draws every panel from the server's data.
    driver
        .goto(&s.url(&format!("/sites/{SITE}/points/{moving}")))
        .await;
    let drawn = driver
        .wait_for("return document.querySelector('.plots').getAttribute('data-drawn') || document.querySelector('.plots').getAttribute('data-error')")
        .await;
    assert_eq!(drawn, json!("8"), "the 8 epochs of the series drawn");
    let canvases = driver
        .script("return document.querySelectorAll('.plots .uplot canvas').length")
        .await;
    assert!(canvases.as_u64().unwrap() >= 4, "{canvases} canvases");
    // Time reads in UTC on the plots too, as everywhere on the dashboard.
    let x_label = driver
        .script("return document.querySelector('.plots ul.legend li[data-kind=axis]').textContent")
        .await;
    assert_eq!(x_label, json!("time (UTC)"));
    let forecast = driver
        .script("return document.querySelector('.forecast').textContent")
        .await;
    assert!(
        forecast.as_str().unwrap().contains("forecast"),
        "{forecast}"
    );
    driver.screenshot("point.png").await;

    // The site page: type a name, click acknowledge; htmx swaps the row.
    driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
    let (_, open) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=open"))
        .await;
    let id = open["items"][0]["id"]
        .as_str()
        .expect("an open alert")
        .to_string();
    driver.acknowledge_as(&id, "Aiko").await;
    driver
        .wait_for(&format!(
            "var r = document.getElementById('alert-{id}'); return r && r.textContent.indexOf('acknowledged by Aiko') >= 0"
        ))
        .await;
    let (_, acked) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=acknowledged"))
        .await;
    assert!(acked["items"]
        .as_array()
        .unwrap()
        .iter()
        .any(|a| a["id"] == json!(id) && a["acknowledged_by"] == json!("Aiko")));
    driver.screenshot("site.png").await;
    // The alert's page, from the link of its row: its history ends with the acknowledgement.
    driver
        .script(&format!(
            "document.getElementById('alert-{id}').querySelector('a[title=history]').click(); return true"
        ))
        .await;
    let last = driver
        .wait_for("return location.pathname.indexOf('/alerts/') > 0 && document.querySelector('table.history tbody tr:last-child') ? document.querySelector('table.history tbody tr:last-child').textContent : null")
        .await;
    let last = last.as_str().unwrap_or_default();
    assert!(
        last.starts_with("acknowledged") && last.contains("Aiko"),
        "{last}"
    );
    // The raising event shows its epoch's observation time beside the time it was processed,
    // as the API's history gives it.
    let (_, events) = s.get(&format!("/api/v1/alerts/{id}/events")).await;
    let observed = events["items"][0]["data"]["observed_at"]
        .as_str()
        .unwrap_or_else(|| panic!("the raising event's epoch time: {events}"))
        .to_string();
    let first = driver
        .script("var r = document.querySelector('table.history tbody tr'); return [r.querySelector('td.event').textContent, r.querySelector('td.observed').textContent]")
        .await;
    let shown = format!("{} UTC", observed.replacen('T', " ", 1).get(..16).unwrap());
    assert_eq!(first[0], json!("raised"), "{first}");
    assert!(
        first[1].as_str().unwrap().starts_with(&shown),
        "{shown}: {first}"
    );
    let alert_path = driver.script("return location.pathname").await;
    let alert_path = alert_path.as_str().unwrap().to_string();
    driver.screenshot("alert.png").await;
    driver.goto(&s.url(&format!("/sites/{SITE}"))).await;

    // A colleague acknowledged another alert since the page was loaded: the click is refused
    // (409) and the page says so and by whom, instead of looking like nothing happened.
    let other = open["items"][1]["id"]
        .as_str()
        .expect("a second open alert")
        .to_string();
    let r = s
        .client
        .post(s.url(&format!("/api/v1/alerts/{other}/ack")))
        .json(&json!({"by": "Ben"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    driver.acknowledge_as(&other, "Aiko").await;
    let shown = driver
        .wait_for(&format!(
            "var e = document.querySelector('[id=\"alert-{other}\"] .form-error'); return e && e.textContent"
        ))
        .await;
    let shown = shown.as_str().unwrap_or_default().to_string();
    assert!(shown.contains("409") && shown.contains("Ben"), "{shown}");
    driver.screenshot("site-refused.png").await;
    // The alert filter: choosing a state swaps the alert section (htmx) and the address keeps it.
    driver
        .script("var s = document.querySelector('form.filters select[name=state]'); s.value = 'acknowledged'; s.dispatchEvent(new Event('change', {bubbles: true})); return true")
        .await;
    let rows = driver
        .wait_for("return location.search.indexOf('state=acknowledged') >= 0 && document.querySelector('#alerts h2').textContent == 'Acknowledged alerts' ? Array.from(document.querySelectorAll('#alerts tr[id^=alert-]')).map(function (r) { return r.id; }) : null")
        .await;
    let (_, acked) = s
        .get(&format!("/api/v1/alerts?site={SITE}&state=acknowledged"))
        .await;
    // The page groups them by subject, so the order is not the API's.
    let mut want: Vec<String> = acked["items"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| format!("alert-{}", a["id"].as_str().unwrap()))
        .collect();
    let mut rows: Vec<String> = serde_json::from_value(rows).unwrap();
    want.sort_unstable();
    rows.sort_unstable();
    assert_eq!(rows, want, "acknowledged alerts after the filter");
    assert_eq!(
        driver
            .script("return document.querySelectorAll('section#alerts').length + document.querySelectorAll('form.filters').length")
            .await,
        json!(2),
        "the section was swapped, not nested"
    );
    // The campaign report prints to a PDF of A4 pages.
    driver.goto(&s.url(&format!("/sites/{SITE}/report"))).await;
    let (pdf, pages) = driver.print_a4().await;
    let text = String::from_utf8_lossy(&pdf);
    // Every page's MediaBox is A4, 595.28 × 841.89 pt, to Chromium's rounding to its pixel grid
    // (595.92 × 841.92 or 842.88 seen).
    let boxes: Vec<Vec<f64>> = text
        .match_indices("/MediaBox [")
        .map(|(i, m)| {
            text[i + m.len()..]
                .split(']')
                .next()
                .unwrap_or("")
                .split_whitespace()
                .filter_map(|v| v.parse().ok())
                .collect()
        })
        .collect();
    assert!(!boxes.is_empty(), "a MediaBox");
    for b in &boxes {
        assert!(
            b.len() == 4 && (b[2] - 595.28).abs() < 1.5 && (b[3] - 841.89).abs() < 1.5,
            "A4 media box: {boxes:?}"
        );
    }
    if let Some(dir) = std::env::var_os("CLIFFWATCH_SCREENSHOTS") {
        std::fs::write(Path::new(&dir).join("report.pdf"), &pdf).unwrap();
        eprintln!("report: {} bytes, {pages} page objects", pdf.len());
    }
    // A phone, 360 CSS px wide: no page scrolls sideways, the plots fit, and the face plan's
    // names are drawn at a readable size.
    driver.emulate_phone().await;
    let (_, epochs) = s.get(&format!("/api/v1/sites/{SITE}/epochs")).await;
    let epoch = epochs["items"][0]["id"].as_i64().expect("an epoch id");
    for (k, path) in [
        "/".to_string(),
        format!("/sites/{SITE}"),
        format!("/sites/{SITE}/points/{moving}"),
        format!("/sites/{SITE}/epochs/{epoch}"),
        format!("/sites/{SITE}/report"),
        alert_path.clone(),
    ]
    .into_iter()
    .enumerate()
    {
        driver.goto(&s.url(&path)).await;
        if path.contains("/points/") {
            driver
                .wait_for("return document.querySelector('.plots').getAttribute('data-drawn')")
                .await;
        }
        let width = driver
            .script("return [window.innerWidth, document.documentElement.scrollWidth]")
            .await;
        let (inner, scroll) = (width[0].as_f64().unwrap(), width[1].as_f64().unwrap());
        if inner != 360.0 {
            let wide = driver
                .script("var out = []; document.querySelectorAll('body *').forEach(function (e) { var r = e.getBoundingClientRect(); if (r.right > 361 && out.length < 16) out.push(e.tagName + '.' + e.className + ' ' + Math.round(r.width)); }); return out")
                .await;
            panic!("{path}: layout viewport {width} wider than 360 px; wide elements: {wide}");
        }
        assert!(
            scroll <= inner,
            "{path} scrolls sideways at 360 px: {width}"
        );
        driver.screenshot(format!("phone-{k}.png")).await;
        if path == format!("/sites/{SITE}") {
            let label = driver
                .script("var r = document.querySelector('svg.plan text.label').getBoundingClientRect(); return [r.height, document.querySelector('svg.plan').getBoundingClientRect().width]")
                .await;
            assert!(
                label[0].as_f64().unwrap() >= 9.0,
                "plan label height {label} (CSS px) at 360 px"
            );
            assert!(label[1].as_f64().unwrap() >= 300.0, "plan width {label}");
        }
    }
    driver.quit().await;
    s.stop().await;
}

/// A watched epoch's page: the preview loads, the SVG of detections lies exactly over it, every
/// circle sits on a bright target of the picture itself, and the page fits a phone.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn watched_epoch_images_line_up_in_chromium() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let watch = tempfile::tempdir().unwrap();
    let site = watch.path().join("kamo");
    std::fs::create_dir_all(&site).unwrap();
    let dir = watch.path().to_path_buf();
    let s = TestServer::start(move |c| c.watch_dir = Some(dir)).await;
    let r = s
        .client
        .post(s.url("/api/v1/sites"))
        .json(&json!({"id": "kamo", "name": "Kamo", "model": "orthogonal"}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let epoch = support::watch::small_scene();
    support::watch::write_epoch(&site, &epoch, "e1", "2026-11-20T09:00:00Z", true, 1);
    let t0 = Instant::now();
    let id = loop {
        let (_, list) = s.get("/api/v1/sites/kamo/epochs").await;
        if let Some(id) = list["items"][0]["id"].as_i64() {
            break id;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(180),
            "no epoch from the watched folder: {:?}",
            std::fs::read_to_string(site.join(".failed/e1/error.txt"))
        );
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    driver
        .goto(&s.url(&format!("/sites/kamo/epochs/{id}")))
        .await;
    let size = driver
        .wait_for("var i = document.querySelector('.overlay img'); return i && i.complete && i.naturalWidth ? [i.naturalWidth, i.naturalHeight] : null")
        .await;
    assert_eq!(size, json!([1080, 720]), "preview loaded at full size");
    // the SVG covers the picture exactly; every circle's centre on the screen is its pixel's
    let fit = driver
        .script(
            "var f = document.querySelector('.station-image'), img = f.querySelector('img'), svg = f.querySelector('svg');
             var a = img.getBoundingClientRect(), b = svg.getBoundingClientRect();
             var c = document.createElement('canvas'); c.width = img.naturalWidth; c.height = img.naturalHeight;
             var g = c.getContext('2d'); g.drawImage(img, 0, 0);
             var px = g.getImageData(0, 0, c.width, c.height).data;
             var level = function (x, y) { return px[4 * (Math.round(y) * c.width + Math.round(x))]; };
             var off = 0, on = 0, beside = 0, n = 0;
             f.querySelectorAll('circle.target').forEach(function (e) {
               var r = e.getBoundingClientRect(), x = e.cx.baseVal.value, y = e.cy.baseVal.value;
               var sx = a.left + x / img.naturalWidth * a.width, sy = a.top + y / img.naturalHeight * a.height;
               off = Math.max(off, Math.hypot(r.left + r.width / 2 - sx, r.top + r.height / 2 - sy));
               on += level(x, y); beside += level(Math.min(x + 12, c.width - 1), y); n++;
             });
             return [Math.abs(a.left - b.left) + Math.abs(a.top - b.top) + Math.abs(a.width - b.width) + Math.abs(a.height - b.height), off, on / n, beside / n, n, a.width];",
        )
        .await;
    let v = |k: usize| fit[k].as_f64().unwrap();
    assert!(v(0) < 1.0, "SVG and picture boxes differ by {} px", v(0));
    assert!(v(1) < 1.0, "a circle {} CSS px off its pixel", v(1));
    assert!(v(4) >= 26.0, "{} circles", v(4));
    assert!(
        v(2) > v(3) + 40.0,
        "picture under the circles {} vs beside them {}",
        v(2),
        v(3)
    );
    assert!(v(5) > 600.0, "picture drawn {} px wide", v(5));
    driver.screenshot("epoch-images.png").await;

    driver.emulate_phone().await;
    driver
        .goto(&s.url(&format!("/sites/kamo/epochs/{id}")))
        .await;
    let width = driver
        .script("return [window.innerWidth, document.documentElement.scrollWidth, document.querySelector('.overlay').getBoundingClientRect().width]")
        .await;
    assert_eq!(width[0], json!(360), "{width}");
    assert!(width[1].as_f64().unwrap() <= 360.0, "{width}");
    assert!(width[2].as_f64().unwrap() >= 300.0, "{width}");
    driver.screenshot("phone-epoch-images.png").await;
    driver.quit().await;
    s.stop().await;
}

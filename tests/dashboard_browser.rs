//! The dashboard in a real browser: headless Chromium driven through ChromeDriver (W3C
//! WebDriver over HTTP). The point page's plots are drawn by the embedded uPlot from the
//! server's data (canvases exist, no error), and an alert is acknowledged by typing a name and
//! clicking the button of the site page (htmx), which the API then reports. At a phone's width
//! (360 CSS px) no page scrolls sideways and the face plan's names stay readable.
//!
//! Needs `chromium` and `chromedriver` (Debian's `chromium`, `chromium-driver`; `.ci/run`
//! installs them). Under `CI=true` their absence fails the test; elsewhere it is skipped with a
//! message.

mod dashboard_support;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use dashboard_support::service_support::{free_port, TestServer};
use dashboard_support::{fill, name, POINTS, SITE};
use serde_json::{json, Value};

const CHROMIUM: &str = "/usr/bin/chromium";
const DRIVER: &str = "/usr/bin/chromedriver";
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

struct Driver {
    child: Child,
    base: String,
    session: String,
    client: reqwest::Client,
    _profile: tempfile::TempDir,
}

impl Driver {
    async fn start() -> Option<Driver> {
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

    async fn call(&self, method: reqwest::Method, path: &str, body: Value) -> Value {
        let url = format!("{}/session/{}{}", self.base, self.session, path);
        let mut req = self.client.request(method, url);
        if !body.is_null() {
            req = req.json(&body);
        }
        let r: Value = req.send().await.unwrap().json().await.unwrap();
        assert!(r["value"]["error"].is_null(), "{path}: {r}");
        r["value"].clone()
    }

    async fn goto(&self, url: &str) {
        self.call(reqwest::Method::POST, "/url", json!({"url": url}))
            .await;
    }

    async fn script(&self, script: &str) -> Value {
        self.call(
            reqwest::Method::POST,
            "/execute/sync",
            json!({"script": script, "args": []}),
        )
        .await
    }

    async fn element(&self, css: &str) -> String {
        let v = self
            .call(
                reqwest::Method::POST,
                "/element",
                json!({"using": "css selector", "value": css}),
            )
            .await;
        v[ELEMENT].as_str().expect("element").to_string()
    }

    /// Saves a PNG of the viewport as `name` in `$CLIFFWATCH_SCREENSHOTS`, when that is set.
    async fn screenshot(&self, name: impl AsRef<Path>) {
        if let Some(dir) = std::env::var_os("CLIFFWATCH_SCREENSHOTS") {
            use base64::Engine;
            let png = self
                .call(reqwest::Method::GET, "/screenshot", Value::Null)
                .await;
            let bytes = base64::engine::general_purpose::STANDARD
                .decode(png.as_str().unwrap())
                .unwrap();
            std::fs::write(Path::new(&dir).join(name), bytes).unwrap();
        }
    }

    /// Polls `script` until it returns a truthy value (at most 15 s).
    async fn wait_for(&self, script: &str) -> Value {
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
    let input = driver
        .element(&format!("[id=\"alert-{id}\"] input[name=by]"))
        .await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{input}/value"),
            json!({"text": "Aiko"}),
        )
        .await;
    let button = driver.element(&format!("[id=\"alert-{id}\"] button")).await;
    driver
        .call(
            reqwest::Method::POST,
            &format!("/element/{button}/click"),
            json!({}),
        )
        .await;
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
    // The campaign report prints to a PDF of A4 pages.
    driver.goto(&s.url(&format!("/sites/{SITE}/report"))).await;
    let pdf = driver
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
        + text.matches("/Type/Page/").count();
    assert!(text.contains("595") && text.contains("842"), "A4 media box");
    if let Some(dir) = std::env::var_os("CLIFFWATCH_SCREENSHOTS") {
        std::fs::write(Path::new(&dir).join("report.pdf"), &pdf).unwrap();
        eprintln!("report: {} bytes, {pages} page objects", pdf.len());
    }
    // A phone, 360 CSS px wide: no page scrolls sideways, the plots fit, and the face plan's
    // names are drawn at a readable size.
    driver
        .call(
            reqwest::Method::POST,
            "/goog/cdp/execute",
            json!({"cmd": "Emulation.setDeviceMetricsOverride", "params": {
                "width": 360, "height": 740, "deviceScaleFactor": 2, "mobile": true}}),
        )
        .await;
    let (_, epochs) = s.get(&format!("/api/v1/sites/{SITE}/epochs")).await;
    let epoch = epochs["items"][0]["id"].as_i64().expect("an epoch id");
    for (k, path) in [
        "/".to_string(),
        format!("/sites/{SITE}"),
        format!("/sites/{SITE}/points/{moving}"),
        format!("/sites/{SITE}/epochs/{epoch}"),
        format!("/sites/{SITE}/report"),
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
    driver
        .client
        .delete(format!("{}/session/{}", driver.base, driver.session))
        .send()
        .await
        .ok();
    s.stop().await;
}

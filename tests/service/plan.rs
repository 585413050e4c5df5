//! Campaign design through the API (issue 78): `POST /api/v1/plan` answers what `cliffwatch
//! plan` prints and names the item of a bad plan; `POST /api/v1/sites/{site}/plan` predicts the
//! σ a site's own epoch reported (within 5 % at the same a-priori σ), and its what-ifs move the σ
//! the right way.

use crate::support;

use serde_json::{json, Value};
use support::day;
use support::server::{synthetic_epoch, TestServer};

/// A plan: four stations 100 m in front of a 20 m × 20 m face (Y towards the face), 16 targets
/// with 2 m of relief, the four corners known.
fn plan() -> Value {
    let mut targets = Vec::new();
    for r in 0..4 {
        for c in 0..4 {
            let i = r * 4 + c;
            let corner = (r == 0 || r == 3) && (c == 0 || c == 3);
            targets.push(json!({"point": format!("T{:02}", i + 1),
                "xyz": [-10.0 + 20.0 * c as f64 / 3.0, 100.0 + 2.0 * ((i * 7) % 5) as f64 / 5.0,
                        20.0 * r as f64 / 3.0],
                "known": corner}));
        }
    }
    let stations: Vec<Value> = (0..4)
        .map(|k| {
            json!({"name": format!("S{}", k + 1), "camera": "cam",
                   "position": [-25.0 + 50.0 * k as f64 / 3.0, 0.0, 5.0 + 4.0 * (k % 2) as f64],
                   "aim": [0.0, 100.0, 10.0]})
        })
        .collect();
    json!({"sigma_px": 0.25, "face_normal": [0, -1, 0],
           "cameras": [{"id": "cam", "c_mm": 100, "pixel_size_mm": 0.005,
                        "width_px": 8000, "height_px": 6000}],
           "stations": stations, "targets": targets})
}

/// The route answers the core's report exactly; bad plans get 422 naming the item.
#[tokio::test]
async fn plan_route_answers_the_report_and_names_bad_items() {
    let s = TestServer::start(|_| {}).await;
    let body = plan();
    let (status, answer) = s.post("/api/v1/plan", &body).await;
    assert_eq!(status, 200, "{answer}");
    let parsed: cliffwatch_core::plan::Plan = serde_json::from_value(body.clone()).unwrap();
    let expected = cliffwatch_core::plan::pre_analysis(&parsed).unwrap();
    let targets = answer["targets"].as_array().unwrap();
    assert_eq!(targets.len(), 16);
    for (got, want) in targets.iter().zip(&expected.targets) {
        assert_eq!(got["point"], want.point.as_str());
        let g = got["mdd_3d_mm"].as_f64().unwrap();
        assert!((g - want.mdd_3d_mm.unwrap()).abs() <= 1e-9 * g, "{got}");
    }

    let mut few_known = plan();
    for t in few_known["targets"].as_array_mut().unwrap().iter_mut() {
        t["known"] = json!(false);
    }
    let (status, e) = s.post("/api/v1/plan", &few_known).await;
    assert_eq!(status, 422, "{e}");
    assert_eq!(e["error"]["code"], "invalid_plan", "{e}");
    assert!(
        e["error"]["message"]
            .as_str()
            .unwrap()
            .contains("four known"),
        "{e}"
    );

    let mut unknown_camera = plan();
    unknown_camera["stations"][2]["camera"] = json!("nikon");
    let (status, e) = s.post("/api/v1/plan", &unknown_camera).await;
    assert_eq!(status, 422, "{e}");
    let m = e["error"]["message"].as_str().unwrap();
    assert!(m.contains("S3") && m.contains("nikon"), "{e}");

    let mut blind = plan();
    blind["stations"][1]["aim"] = json!([-25.0, -100.0, 5.0]);
    let (status, e) = s.post("/api/v1/plan", &blind).await;
    assert_eq!(status, 422, "{e}");
    assert!(
        e["error"]["message"].as_str().unwrap().contains("S2"),
        "{e}"
    );

    let (status, e) = s.post("/api/v1/plan", &json!({"sigma_px": 1})).await;
    assert_eq!(status, 422, "{e}");
}

/// σ of one image coordinate of the simulated epochs: uniform noise of ± 1 µm.
const SIGMA_MM: f64 = 0.001 / 1.732_050_807_568_877_2;

/// Site `s` with two epochs of 5 stations × 30 targets (free network), the cameras' a-priori σ
/// that of the simulated noise.
async fn site(s: &TestServer) {
    s.create_site("cliff").await;
    for k in 0..2 {
        let mut body = synthetic_epoch(5, 30, &day(k), 11 + k as u64, 0.0, 30);
        body["cameras"][0]["sigma_mm"] = json!(SIGMA_MM);
        let (status, answer) = s.upload("cliff", &body).await;
        assert_eq!(status, 201, "{answer}");
    }
}

/// Each target's σ (x, y, z in mm) in a report.
fn sigmas(report: &Value) -> Vec<(String, [f64; 3])> {
    report["targets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let s = &t["sigma_mm"];
            (
                t["point"].as_str().unwrap().to_string(),
                ["x", "y", "z"].map(|k| s[k].as_f64().unwrap()),
            )
        })
        .collect()
}

/// The site's own network, no changes: each target's predicted σ is the σ the latest epoch's
/// adjustment reported, rescaled to the a-priori σ (divided by √ of its variance factor), within
/// 5 % per component. Dropping a station raises every σ, adding one lowers them.
#[tokio::test]
async fn site_plan_predicts_the_epoch_and_what_ifs_move_it() {
    let s = TestServer::start(|_| {}).await;
    site(&s).await;
    let (status, own) = s.post("/api/v1/sites/cliff/plan", &json!({})).await;
    assert_eq!(status, 200, "{own}");
    assert_eq!(own["epoch"], 2);
    assert_eq!(own["plan"]["datum"], "free", "{}", own["plan"]);
    let vf = own["achieved"]["variance_factor"].as_f64().unwrap();
    let achieved: Vec<(String, [f64; 3])> = own["achieved"]["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let v: Vec<f64> = serde_json::from_value(p["sigma_mm"].clone()).unwrap();
            (p["point"].as_str().unwrap().to_string(), [v[0], v[1], v[2]])
        })
        .collect();
    let predicted = sigmas(&own["report"]);
    assert_eq!(predicted.len(), 30);
    let mut worst = 0.0f64;
    for (point, p) in &predicted {
        let a = &achieved.iter().find(|(q, _)| q == point).unwrap().1;
        for k in 0..3 {
            let ratio = p[k] / (a[k] / vf.sqrt());
            worst = worst.max((ratio - 1.0).abs());
        }
    }
    eprintln!(
        "site plan: largest |predicted/achieved − 1| = {worst:.2e} (variance factor {vf:.3})"
    );
    assert!(worst <= 0.05, "{worst}");

    let (status, fewer) = s
        .post(
            "/api/v1/sites/cliff/plan",
            &json!({"changes": [{"change": "drop_station", "station": "S3"}]}),
        )
        .await;
    assert_eq!(status, 200, "{fewer}");
    let (status, more) = s
        .post(
            "/api/v1/sites/cliff/plan",
            &json!({"changes": [{"change": "add_station", "name": "S9", "camera": "cam",
                                 "distance_m": 100, "direction": [0.3, -1, 0.1]}]}),
        )
        .await;
    assert_eq!(status, 200, "{more}");
    let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (own_s, fewer_s, more_s) = (predicted, sigmas(&fewer["report"]), sigmas(&more["report"]));
    let (mut grew, mut shrank) = (0, 0);
    for ((o, f), m) in own_s.iter().zip(&fewer_s).zip(&more_s) {
        assert_eq!(o.0, f.0);
        assert!(norm(&f.1) >= norm(&o.1) * (1.0 - 1e-6), "{}", o.0);
        assert!(norm(&m.1) <= norm(&o.1) * (1.0 + 1e-6), "{}", o.0);
        grew += usize::from(norm(&f.1) > 1.02 * norm(&o.1));
        shrank += usize::from(norm(&m.1) < 0.98 * norm(&o.1));
    }
    assert!(grew > 0 && shrank > 0, "{grew} {shrank}");

    // A change naming nothing of the site: 422 naming the change.
    let (status, e) = s
        .post(
            "/api/v1/sites/cliff/plan",
            &json!({"changes": [{"change": "set_c", "camera": "leica", "c_mm": 500}]}),
        )
        .await;
    assert_eq!(status, 422, "{e}");
    let m = e["error"]["message"].as_str().unwrap();
    assert!(m.contains("changes[0]") && m.contains("leica"), "{e}");
    let (status, e) = s.post("/api/v1/sites/nowhere/plan", &json!({})).await;
    assert_eq!(status, 404, "{e}");

    // The page: the site's own pre-analysis beside what it achieved, linked from the site page.
    let html = |path: &'static str| {
        let (client, url) = (s.client.clone(), s.url(path));
        async move {
            let r = client.get(url).send().await.unwrap();
            (r.status().as_u16(), r.text().await.unwrap())
        }
    };
    let (status, page) = html("/sites/cliff/plan").await;
    assert_eq!(status, 200, "{page}");
    for words in [
        "Campaign design",
        "Worst targets",
        "<svg",
        "T001",
        "a-priori scale",
    ] {
        assert!(page.contains(words), "{words}");
    }
    let (status, site_page) = html("/sites/cliff").await;
    assert_eq!(status, 200);
    assert!(site_page.contains("/sites/cliff/plan"));
}

//! The adjustments' health (issue 61, item 8): two cameras that both declare an a-priori σ of
//! 0.6 µm, where the images carry 0.577 µm and 0.987 µm. The global test fails on every epoch
//! and the site page says so, with the per-camera estimate from the variance components of the
//! last 20 epochs (a first step, since the declared ratio is wrong). A site with
//! `apriori_sigma: estimated` applies the estimate from its sixth epoch on; from the 21st the
//! applied σ is within 5 % of the simulated noise, and the global test passes at its nominal
//! rate (99.8 % two-sided: at most one failure in 20 epochs, mean variance factor 1 ± 0.1).

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use serde_json::{json, Value};

use crate::support;
use support::dashboard::html;
use support::day;
use support::server::{synthetic_epoch, TestServer};

/// The uploaded a-priori σ of both cameras, mm (too optimistic for camera B, a little
/// pessimistic for A; far more optimistic, the epoch is refused as inconsistent).
const DECLARED_MM: f64 = 0.0006;
/// Camera A's images carry the synthetic epoch's noise only: uniform ± 1 µm, σ = 1/√3 µm.
const TRUE_A_MM: f64 = 0.001 / 1.732_050_807_568_877_2;
/// Camera B's images have Gaussian noise of 0.8 µm added.
const EXTRA_B_MM: f64 = 0.0008;

fn true_b_mm() -> f64 {
    (TRUE_A_MM * TRUE_A_MM + EXTRA_B_MM * EXTRA_B_MM).sqrt()
}

/// Epoch `k`: 36 targets seen by 6 stations, the first three with camera A, the others with
/// camera B (its noise added), both declaring [`DECLARED_MM`].
fn epoch(k: usize) -> Value {
    let mut body = synthetic_epoch(6, 36, &day(k), 1000 + k as u64, 0.0, 36);
    let cam =
        |id: &str| json!({"id": id, "c_mm": 300.0, "calibrate_c": true, "sigma_mm": DECLARED_MM});
    body["cameras"] = json!([cam("A"), cam("B")]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7 + k as u64);
    let extra = Normal::new(0.0, EXTRA_B_MM).unwrap();
    for (i, im) in body["images"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .enumerate()
    {
        let b = i >= 3;
        im["camera"] = json!(if b { "B" } else { "A" });
        if b {
            for o in im["observations"].as_array_mut().unwrap() {
                for c in ["x_mm", "y_mm"] {
                    o[c] = json!(o[c].as_f64().unwrap() + extra.sample(&mut rng));
                }
            }
        }
    }
    body
}

/// The variance factor and global-test bounds of an epoch, from its report.
async fn global_test(s: &TestServer, site: &str, epoch: i64) -> (f64, f64, f64, Value) {
    let (status, r) = s.get(&format!("/api/v1/sites/{site}/epochs/{epoch}")).await;
    assert_eq!(status, 200, "{r}");
    let report = if r["report"].is_object() {
        r["report"].clone()
    } else {
        r.clone()
    };
    let vf = report["variance_factor"].as_f64().expect("variance_factor");
    let dof = report["dof"].as_i64().expect("dof");
    let t = cliffwatch_core::photogrammetry::statistics::GlobalTest::of(dof, vf);
    (vf, t.lower, t.upper, report)
}

async fn upload(s: &TestServer, site: &str, k: usize) -> i64 {
    let (status, r) = s.upload(site, &epoch(k)).await;
    assert_eq!(status, 201, "epoch {k}: {r}");
    r["epoch"]
        .as_i64()
        .or_else(|| r["id"].as_i64())
        .expect("epoch id")
}

fn within(estimate: f64, truth: f64, bound: f64) -> bool {
    (estimate / truth - 1.0).abs() <= bound
}

#[tokio::test]
async fn the_estimated_sigma_converges_and_passes_the_global_test_at_its_rate() {
    let s = TestServer::start(|_| {}).await;
    for (id, setting) in [("upload", "upload"), ("estimated", "estimated")] {
        let (status, r) = s
            .post(
                "/api/v1/sites",
                &json!({"id": id, "name": id, "model": "central", "apriori_sigma": setting}),
            )
            .await;
        assert_eq!(status, 201, "{r}");
        assert_eq!(r["apriori_sigma"], setting, "{r}");
    }

    // The uploaded σ: every epoch fails the global test, too optimistic.
    for k in 0..20 {
        let e = upload(&s, "upload", k).await;
        let (vf, _, upper, report) = global_test(&s, "upload", e).await;
        assert!(
            vf > upper,
            "epoch {k}: variance factor {vf} within the band"
        );
        assert!(report.get("apriori_sigma_estimated").is_none(), "{report}");
    }
    let sigma = cliffwatch::service::apriori_sigma::of_site(&s.store, "upload")
        .await
        .unwrap();
    let of = |cam: &str| {
        sigma
            .estimate
            .iter()
            .find(|e| e.camera == cam)
            .unwrap_or_else(|| panic!("no estimate of camera {cam}: {sigma:?}"))
            .clone()
    };
    let (a, b) = (of("A"), of("B"));
    assert_eq!((a.epochs, b.epochs), (20, 20), "{sigma:?}");
    // One step from a wrong ratio (both cameras declared alike): biased towards that ratio,
    // each within 10 % (measured +7.3 % and −5.7 %), and the page says it is a first step.
    assert!(
        within(a.sigma_mm, TRUE_A_MM, 0.10),
        "A: {} mm against {TRUE_A_MM}",
        a.sigma_mm
    );
    assert!(
        within(b.sigma_mm, true_b_mm(), 0.10),
        "B: {} mm against {}",
        b.sigma_mm,
        true_b_mm()
    );
    assert!(a.sigma_mm < b.sigma_mm, "{sigma:?}");
    assert!(sigma.first_step, "{sigma:?}");
    let (status, page) = html(&s, "/sites/upload").await;
    assert_eq!(status, 200);
    let text = support::dashboard::text_of(&page);
    assert!(
        text.contains("The global test failed on 10 of the last 10 epochs"),
        "{text}"
    );
    assert!(text.contains("too optimistic"), "{text}");
    let shown = format!("camera A {:.2} µm", a.sigma_mm * 1000.0);
    assert!(text.contains(&shown), "{shown} not in {text}");
    let used = format!("used at the last epoch: {:.2} µm", DECLARED_MM * 1000.0);
    assert!(text.contains(&used), "{used} not in {text}");
    assert!(text.contains("This is a first step"), "{text}");

    // In Chromium: the section reads at desk and phone width, no sideways scroll at 360 px.
    if let Some(driver) = crate::browser::Driver::start().await {
        driver.goto(&s.url("/sites/upload#health")).await;
        let shown = driver
            .script("return document.querySelector('#health .estimate').innerText")
            .await;
        assert!(
            shown.as_str().unwrap_or("").contains("first step"),
            "{shown}"
        );
        driver.screenshot("health-desk.png").await;
        driver.emulate_phone().await;
        driver.goto(&s.url("/sites/upload#health")).await;
        let overflow = driver
            .script("return document.documentElement.scrollWidth - window.innerWidth")
            .await;
        assert!(overflow.as_f64().unwrap() <= 0.0, "{overflow} px sideways");
        driver.screenshot("health-phone.png").await;
        driver.quit().await;
    }

    // Applied: the first epochs use the uploaded σ, then the estimate of the epochs before.
    let mut tests = Vec::new();
    for k in 0..40 {
        let e = upload(&s, "estimated", k).await;
        let (vf, lower, upper, report) = global_test(&s, "estimated", e).await;
        let applied = report.get("apriori_sigma_estimated").cloned();
        if k < cliffwatch::service::apriori_sigma::MIN_EPOCHS {
            assert!(applied.is_none(), "epoch {k}: {report}");
            assert!(vf > upper, "epoch {k}: variance factor {vf}");
            continue;
        }
        let applied = applied.unwrap_or_else(|| panic!("epoch {k}: nothing applied"));
        if k >= 20 {
            let list = applied.as_array().unwrap();
            assert_eq!(list.len(), 2, "{applied}");
            for e in list {
                let truth = if e["camera"] == "A" {
                    TRUE_A_MM
                } else {
                    true_b_mm()
                };
                let used = e["sigma_mm"].as_f64().unwrap();
                assert_eq!(e["epochs"], 20, "{e}");
                assert!(within(used, truth, 0.05), "epoch {k}: {e} against {truth}");
            }
            tests.push((vf, (lower..=upper).contains(&vf)));
        }
    }
    let failed = tests.iter().filter(|(_, ok)| !ok).count();
    let mean = tests.iter().map(|(vf, _)| vf).sum::<f64>() / tests.len() as f64;
    assert!(failed <= 1, "{failed} of {} failed: {tests:?}", tests.len());
    assert!(
        (mean - 1.0).abs() <= 0.1,
        "mean variance factor {mean}: {tests:?}"
    );
    // Converged: the last estimate is a fixed point, within 3 of its own σ of the truth.
    let last = cliffwatch::service::apriori_sigma::of_site(&s.store, "estimated")
        .await
        .unwrap();
    assert!(!last.first_step, "{last:?}");
    for e in &last.estimate {
        let truth = if e.camera == "A" {
            TRUE_A_MM
        } else {
            true_b_mm()
        };
        assert!(
            (e.sigma_mm / truth - 1.0).abs() <= 3.0 * e.relative_sigma,
            "{e:?} against {truth}"
        );
    }
    let (_, page) = html(&s, "/sites/estimated").await;
    let text = support::dashboard::text_of(&page);
    assert!(text.contains("The global test passed on"), "{text}");
    assert!(
        text.contains("The site applies it to its next epochs"),
        "{text}"
    );
    assert!(!text.contains("This is a first step"), "{text}");
    s.stop().await;
}

//! What "no alert" means, as the pages say it: the point page's "smallest movement this epoch
//! detects" equals the minimum detectable displacement computed from the API's covariance of the
//! same row (80 % power, the site's 99 % confidence), a still point reads "no movement above this
//! is seen", and the site plan's tooltip gives the same figure. (That the MDD itself is right is
//! checked against Monte Carlo in `crates/cliffwatch-core/tests/analysis/sensitivity.rs`.)

use crate::support;

use cliffwatch_core::analysis::sensitivity::{minimum_detectable, DEFAULT_POWER};
use cliffwatch_core::analysis::stats::chi2_quantile;
use nalgebra::Matrix3;
use serde_json::Value;
use support::dashboard::{fill, html, name, POINTS, SITE, STABLE};
use support::server::TestServer;

/// The worst-direction MDD (mm) of an API displacement row.
fn mdd_of(row: &Value) -> f64 {
    let f = |k: &str| row[k].as_f64().unwrap_or_else(|| panic!("{k} in {row}"));
    let cov = Matrix3::new(
        f("sigma_dx_mm").powi(2),
        f("cov_dxdy_mm2"),
        f("cov_dxdz_mm2"),
        f("cov_dxdy_mm2"),
        f("sigma_dy_mm").powi(2),
        f("cov_dydz_mm2"),
        f("cov_dxdz_mm2"),
        f("cov_dydz_mm2"),
        f("sigma_dz_mm").powi(2),
    );
    minimum_detectable(&cov, chi2_quantile(0.99, 3.0), 3, DEFAULT_POWER, None)
        .expect("a regular covariance")
        .worst_mm
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_say_how_small_a_movement_the_epoch_would_have_seen() {
    let s = TestServer::start(|_| {}).await;
    fill(&s, 5, None).await;
    let (_, site_page) = html(&s, &format!("/sites/{SITE}")).await;
    let mut still_seen = false;
    for i in [0, POINTS - 1] {
        let point = name(i);
        let (_, api) = s
            .get(&format!(
                "/api/v1/sites/{SITE}/points/{point}/displacements?limit=1000"
            ))
            .await;
        let items = api["items"].as_array().expect("items");
        let last = items
            .iter()
            .max_by_key(|r| r["epoch"].as_i64())
            .expect("a displacement row");
        let worst = mdd_of(last);
        assert!(worst > 0.05 && worst < 50.0, "{point}: MDD {worst} mm");
        let (st, page) = html(&s, &format!("/sites/{SITE}/points/{point}")).await;
        assert_eq!(st, 200);
        let shown = format!("{worst:.2} mm in the worst direction");
        assert!(page.contains(&shown), "{point}: '{shown}' not on the page");
        assert!(
            page.contains("80 % of the time, 99.0 % confidence"),
            "{point}"
        );
        let significant = last["significant"].as_bool().unwrap();
        assert_eq!(
            page.contains("no movement above this is seen"),
            !significant,
            "{point}: significant {significant}"
        );
        still_seen |= !significant;
        let role = if i < STABLE { " (stable)" } else { "" };
        // The tooltip: the name, the out-of-face component when one is drawn, the sensitivity.
        let title = site_page
            .split("<title>")
            .find(|t| {
                t.starts_with(&format!("{point}{role} "))
                    || t.starts_with(&format!("{point}{role}<"))
            })
            .and_then(|t| t.split("</title>").next())
            .unwrap_or_else(|| panic!("no tooltip of {point} on the plan"));
        assert!(
            title.ends_with(&format!(" · detects movement ≥ {worst:.1} mm")),
            "{title}"
        );
    }
    assert!(still_seen, "one of the two points is still");
}

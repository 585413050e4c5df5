//! The face plan's names in Chromium, as a reader sees them: on a desk screen and on 390 / 360 px
//! phones no two names (nor the out-of-face lines under them) that are drawn overlap, every point
//! keeps its tooltip, and when names were left out the legend says so. The site is the dashboard
//! fixture (16 targets, a block moving towards the cameras).

use crate::browser::Driver;
use crate::support;

use support::dashboard::{fill, POINTS, SITE};
use support::server::TestServer;

/// The rectangles of the plan's drawn texts and the count of point tooltips, in CSS px.
const SEEN: &str = "var r = Array.from(document.querySelectorAll('svg.plan text.label, svg.plan text.normal')).filter(function (t) { return getComputedStyle(t).display !== 'none'; }).map(function (t) { var b = t.getBoundingClientRect(); return [t.textContent, b.left, b.top, b.right, b.bottom]; }); return [r, document.querySelectorAll('svg.plan title').length, document.querySelectorAll('svg.plan text.label').length, document.querySelector('figure.plan figcaption').textContent]";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plan_names_never_overlap_on_a_desk_or_a_phone() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 6, None).await;
    let mut left_out_on_a_phone = 0;
    for width in [None, Some(390u32), Some(360)] {
        if let Some(w) = width {
            driver.emulate_phone_width(w).await;
        }
        driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
        let seen = driver.script(SEEN).await;
        let texts = seen[0].as_array().expect("texts");
        assert_eq!(seen[1].as_u64(), Some(POINTS as u64), "a tooltip per point");
        assert_eq!(seen[2].as_u64(), Some(POINTS as u64), "a name per point");
        let boxes: Vec<(String, [f64; 4])> = texts
            .iter()
            .map(|t| {
                let f = |k: usize| t[k].as_f64().unwrap();
                (t[0].as_str().unwrap().to_string(), [f(1), f(2), f(3), f(4)])
            })
            .collect();
        let names = boxes.iter().filter(|(t, _)| t.starts_with('T')).count();
        assert!(names >= 1, "{width:?}: some names drawn");
        for (i, (ta, a)) in boxes.iter().enumerate() {
            for (tb, b) in &boxes[i + 1..] {
                let meets = a[0] < b[2] - 0.5
                    && b[0] < a[2] - 0.5
                    && a[1] < b[3] - 0.5
                    && b[1] < a[3] - 0.5;
                assert!(!meets, "{width:?}: '{ta}' {a:?} overlaps '{tb}' {b:?}");
            }
        }
        let left_out = POINTS - names;
        let caption = seen[3].as_str().unwrap();
        if left_out > 0 {
            assert!(
                caption.contains("Names that would overlap are left out"),
                "{width:?}: {caption}"
            );
        }
        if width.is_some() {
            left_out_on_a_phone = left_out_on_a_phone.max(left_out);
        }
        println!("{width:?}: {names} of {POINTS} names drawn");
        let shot = width.map_or("plan-desk.png".to_string(), |w| {
            format!("plan-phone-{w}.png")
        });
        driver.screenshot(shot).await;
    }
    assert!(
        left_out_on_a_phone > 0,
        "the fixture's plan is crowded on a phone: some names give way"
    );
    driver.quit().await;
    s.stop().await;
}

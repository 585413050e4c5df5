//! The face plan's names in Chromium, as a reader sees them: on a desk screen and on 390 / 360 px
//! phones no two names (nor the out-of-face lines under them) that are drawn overlap, none is
//! drawn over another point's marker or arrow, every point
//! keeps its tooltip, and when names were left out the legend says so. The site is the dashboard
//! fixture (16 targets, a block moving towards the cameras).

use crate::browser::Driver;
use crate::support;

use support::dashboard::{fill, POINTS, SITE};
use support::server::TestServer;

/// The rectangles of the plan's drawn texts (with the index of the point's link they belong
/// to), the count of point tooltips and names, the caption, and the rectangles of the points'
/// markers and arrows (with their link's index), in CSS px.
const SEEN: &str = "var links = Array.from(document.querySelectorAll('svg.plan a')); var rect = function (e) { var b = e.getBoundingClientRect(); return [b.left, b.top, b.right, b.bottom]; }; var r = Array.from(document.querySelectorAll('svg.plan text.label, svg.plan text.normal')).filter(function (t) { return getComputedStyle(t).display !== 'none'; }).map(function (t) { return [t.textContent].concat(rect(t), [links.indexOf(t.closest('a'))]); }); var m = Array.from(document.querySelectorAll('svg.plan .pt, svg.plan line.vector')).map(function (e) { return rect(e).concat([links.indexOf(e.closest('a'))]); }); return [r, document.querySelectorAll('svg.plan title').length, document.querySelectorAll('svg.plan text.label').length, document.querySelector('figure.plan figcaption').textContent, m]";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plan_names_never_overlap_on_a_desk_or_a_phone() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 6, None).await;
    let mut left_out_on_a_phone = 0;
    let mut normals_on_the_desk = None;
    for width in [None, Some(390u32), Some(360)] {
        if let Some(w) = width {
            driver.emulate_phone_width(w).await;
        }
        driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
        let seen = driver.script(SEEN).await;
        let texts = seen[0].as_array().expect("texts");
        assert_eq!(seen[1].as_u64(), Some(POINTS as u64), "a tooltip per point");
        assert_eq!(seen[2].as_u64(), Some(POINTS as u64), "a name per point");
        let boxes: Vec<(String, [f64; 4], i64)> = texts
            .iter()
            .map(|t| {
                let f = |k: usize| t[k].as_f64().unwrap();
                let text = t[0].as_str().unwrap().to_string();
                (text, [f(1), f(2), f(3), f(4)], t[5].as_i64().unwrap())
            })
            .collect();
        let marks: Vec<([f64; 4], i64)> = seen[4]
            .as_array()
            .expect("markers")
            .iter()
            .map(|m| {
                let f = |k: usize| m[k].as_f64().unwrap();
                ([f(0), f(1), f(2), f(3)], m[4].as_i64().unwrap())
            })
            .collect();
        let meets = |a: &[f64; 4], b: &[f64; 4]| {
            a[0] < b[2] - 0.5 && b[0] < a[2] - 0.5 && a[1] < b[3] - 0.5 && b[1] < a[3] - 0.5
        };
        for (t, a, own) in &boxes {
            for (m, point) in &marks {
                assert!(
                    point == own || !meets(a, m),
                    "{width:?}: '{t}' {a:?} is drawn over the marker or arrow {m:?} of point link {point}"
                );
            }
        }
        let normals = boxes.iter().filter(|(t, _, _)| t.starts_with('⊥')).count();
        let names = boxes.iter().filter(|(t, _, _)| t.starts_with('T')).count();
        assert!(names >= 1, "{width:?}: some names drawn");
        for (i, (ta, a, _)) in boxes.iter().enumerate() {
            for (tb, b, _) in &boxes[i + 1..] {
                assert!(
                    !meets(a, b),
                    "{width:?}: '{ta}' {a:?} overlaps '{tb}' {b:?}"
                );
            }
        }
        let left_out = POINTS - names;
        let caption = seen[3].as_str().unwrap();
        if left_out > 0 || normals < normals_on_the_desk.unwrap_or(normals) {
            assert!(
                caption.contains("Names and out-of-face lines that would overlap are left out"),
                "{width:?}: {caption}"
            );
        }
        normals_on_the_desk.get_or_insert(normals);
        if width.is_some() {
            let lines_left_out = normals_on_the_desk.unwrap_or(normals) - normals;
            left_out_on_a_phone = left_out_on_a_phone.max(left_out + lines_left_out);
        }
        println!("{width:?}: {names} of {POINTS} names and {normals} out-of-face lines drawn");
        let shot = width.map_or("plan-desk.png".to_string(), |w| {
            format!("plan-phone-{w}.png")
        });
        driver.screenshot(shot).await;
    }
    assert!(
        left_out_on_a_phone > 0,
        "the fixture's plan is crowded on a phone: some names or out-of-face lines give way"
    );
    driver.quit().await;
    s.stop().await;
}

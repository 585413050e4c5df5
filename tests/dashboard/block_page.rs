//! A block's page in Chromium: reached from the site page's link, it names the block, shows its
//! latest motion, and links each member point (and only those), whose page links back to it.

use crate::browser::Driver;
use crate::dashboard_support;

use dashboard_support::service_support::TestServer;
use dashboard_support::{fill, name, SITE};
use serde_json::{json, Value};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_block_page_links_its_members_and_they_link_back() {
    let Some(driver) = Driver::start().await else {
        return;
    };
    let s = TestServer::start(|_| {}).await;
    fill(&s, 6, None).await;
    // The moving points T010 to T014 declared as block B1 (T009 and T015, T016 moving too, left out).
    let members: Vec<String> = (9..14).map(name).collect();
    let r = s
        .client
        .put(s.url(&format!("/api/v1/sites/{SITE}/groups/B1")))
        .json(&json!({"kind": "block", "points": members, "direction": [0.0, -1.0, 0.0]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let (_, motion) = s
        .get(&format!("/api/v1/sites/{SITE}/groups/B1/motion"))
        .await;
    let last: &Value = motion["items"]
        .as_array()
        .unwrap()
        .last()
        .expect("a motion");

    driver.goto(&s.url(&format!("/sites/{SITE}"))).await;
    driver
        .script("document.querySelector('p.blocks a').click(); return true")
        .await;
    driver
        .wait_for("return location.pathname.endsWith('/groups/B1')")
        .await;
    let seen = driver
        .script("return [document.querySelector('h1').textContent, Array.from(document.querySelectorAll('#members a')).map(function (a) { return [a.textContent, a.getAttribute('href')]; }), document.querySelector('table.latest').innerText]")
        .await;
    assert!(seen[0].as_str().unwrap().starts_with("Block B1"), "{seen}");
    let want: Vec<Value> = members
        .iter()
        .map(|m| json!([m, format!("/sites/{SITE}/points/{m}")]))
        .collect();
    assert_eq!(seen[1], json!(want), "the member links");
    // The latest motion as the API gives it (d ± σ, 2 decimals).
    let d = format!(
        "{:.2} ± {:.2}",
        last["d_mm"].as_f64().unwrap(),
        last["sigma_mm"].as_f64().unwrap()
    );
    assert!(seen[2].as_str().unwrap().contains(&d), "{d}: {seen}");
    driver.screenshot("block-desk.png").await;
    // A member's page links back to its block.
    driver
        .script("document.querySelector('#members a').click(); return true")
        .await;
    driver
        .wait_for(&format!(
            "return location.pathname.endsWith('/points/{}')",
            members[0]
        ))
        .await;
    let back = driver
        .script("return Array.from(document.querySelectorAll('main a')).filter(function (a) { return a.getAttribute('href').endsWith('/groups/B1'); }).length")
        .await;
    assert!(back.as_u64().unwrap() >= 1, "a link back to B1");
    driver.emulate_phone_width(360).await;
    driver
        .goto(&s.url(&format!("/sites/{SITE}/groups/B1")))
        .await;
    let width = driver
        .script("return [window.innerWidth, document.documentElement.scrollWidth]")
        .await;
    assert!(
        width[1].as_f64().unwrap() <= width[0].as_f64().unwrap(),
        "{width}"
    );
    driver.screenshot("block-phone-360.png").await;
    // An unknown block is a 404 page.
    let r = s
        .client
        .get(s.url(&format!("/sites/{SITE}/groups/nope")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    driver.quit().await;
    s.stop().await;
}

//! The site frame (issue 61, item 1): the same cliff and the same motion in a frame with Z up
//! (E, N, Up; the face looking towards −Y) and in a local frame with Y up (Z towards the
//! cameras) draw the same face plan and read the same along / height / out-of-face components,
//! and those components are the motion's (right, down the face, towards the cameras).

use serde_json::{json, Value};

use crate::support;
use support::dashboard::{create_site_with_stable, day, html, name, POINTS, STABLE};
use support::server::{synthetic_epoch_moved, TestServer};

/// The block's motion per epoch in the Z-up frame (mm): 1 right (+X), 2 towards the cameras
/// (−Y), 1.5 down (−Z).
const STEP_ZUP: [f64; 3] = [1.0, -2.0, -1.5];
const EPOCHS: usize = 4;

/// Z-up (x, y, z) → Y-up (x, z, −y): a rotation, so the same cliff in the other frame.
fn to_y_up(p: [f64; 3]) -> [f64; 3] {
    [p[0], p[2], -p[1]]
}

/// The upload with its approximations turned into the Y-up frame (the images are the same).
fn in_y_up(mut body: Value) -> Value {
    for a in body["approx"].as_array_mut().unwrap() {
        let p = to_y_up([
            a["X"].as_f64().unwrap(),
            a["Y"].as_f64().unwrap(),
            a["Z"].as_f64().unwrap(),
        ]);
        a["X"] = json!(p[0]);
        a["Y"] = json!(p[1]);
        a["Z"] = json!(p[2]);
    }
    body
}

/// The numbers in the plan's marks (circle and triangle positions, vectors) and its ⊥ labels.
fn plan_marks(page: &str) -> (Vec<f64>, Vec<String>) {
    let svg = &page[page.find("<svg class=\"plan\"").expect("a plan")..];
    let svg = &svg[..svg.find("</svg>").unwrap()];
    let mut numbers = Vec::new();
    for tag in ["<circle", "<polygon", "<line class=\"vector\""] {
        for part in svg.split(tag).skip(1) {
            let head = &part[..part.find('>').unwrap()];
            for attr in [
                "cx=\"",
                "cy=\"",
                "x1=\"",
                "y1=\"",
                "x2=\"",
                "y2=\"",
                "points=\"",
            ] {
                if let Some(i) = head.find(attr) {
                    let v = &head[i + attr.len()..];
                    let v = &v[..v.find('"').unwrap()];
                    numbers.extend(
                        v.split([',', ' '])
                            .filter(|t| !t.is_empty())
                            .map(|t| t.parse::<f64>().unwrap()),
                    );
                }
            }
        }
    }
    let normals = svg
        .split("class=\"normal")
        .skip(1)
        .map(|p| p[p.find('>').unwrap() + 1..p.find('<').unwrap()].to_string())
        .collect();
    (numbers, normals)
}

/// The point page's "in the face" row: (along, height, out) in mm.
fn face_components(page: &str) -> [f64; 3] {
    let row = &page[page
        .find("<tr class=\"face\">")
        .expect("the in-the-face row")..];
    let row = &row[row.find("<td>").unwrap() + 4..row.find("<small>").unwrap()];
    let text = row.replace("−", "-");
    let values: Vec<f64> = text
        .split(['·'])
        .map(|part| {
            part.split_whitespace()
                .next()
                .unwrap()
                .parse::<f64>()
                .unwrap_or_else(|_| panic!("'{part}' in '{text}'"))
        })
        .collect();
    [values[0], values[1], values[2]]
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_y_up_and_a_z_up_site_draw_the_same_plan_and_components() {
    let s = TestServer::start(|_| {}).await;
    create_site_with_stable(&s, json!({"id": "zup", "model": "orthogonal"})).await;
    create_site_with_stable(
        &s,
        json!({"id": "yup", "model": "orthogonal", "frame": {"up": [0, 1, 0]}}),
    )
    .await;
    for k in 0..EPOCHS {
        let shift = STEP_ZUP.map(|c| c * k as f64);
        let body = synthetic_epoch_moved(4, POINTS, &day(k), 700 + k as u64, shift, STABLE);
        let (st, answer) = s.upload("zup", &body).await;
        assert_eq!(st, 201, "zup epoch {k}: {answer}");
        let (st, answer) = s.upload("yup", &in_y_up(body)).await;
        assert_eq!(st, 201, "yup epoch {k}: {answer}");
    }
    let (_, zup) = html(&s, "/sites/zup").await;
    let (_, yup) = html(&s, "/sites/yup").await;
    assert!(
        zup.contains("Up is +Z"),
        "the Z-up site's legend names its up axis"
    );
    assert!(
        yup.contains("Up is +Y"),
        "the Y-up site's legend names its up axis"
    );
    let (marks_z, normals_z) = plan_marks(&zup);
    let (marks_y, normals_y) = plan_marks(&yup);
    assert_eq!(marks_z.len(), marks_y.len(), "the same marks");
    assert!(marks_z.len() > 2 * POINTS, "every point drawn");
    for (a, b) in marks_z.iter().zip(&marks_y) {
        assert!((a - b).abs() <= 0.25, "plan positions differ: {a} vs {b}");
    }
    assert_eq!(normals_z, normals_y, "the same out-of-face labels");
    assert!(
        !normals_z.is_empty(),
        "the block's out-of-face motion is written"
    );
    // The block's vectors point right and down (SVG y grows downwards).
    let vectors: Vec<&str> = zup.split("<line class=\"vector\"").skip(1).collect();
    assert!(
        vectors.len() >= POINTS - STABLE,
        "a vector per moving point"
    );
    let truth = {
        let t = STEP_ZUP.map(|c| c * (EPOCHS - 1) as f64);
        // along = +X, height = +Z, out = −Y for this face (it looks towards the cameras at −Y).
        [t[0], t[2], -t[1]]
    };
    // σ across the line of sight ≈ 0.25 mm an epoch, ≈ 1.5 mm in depth (out of the face);
    // the bounds are 4 σ of a difference of two epochs.
    let bound = [1.5, 1.5, 8.5];
    for i in STABLE..POINTS {
        let p = name(i);
        let (_, pz) = html(&s, &format!("/sites/zup/points/{p}")).await;
        let (_, py) = html(&s, &format!("/sites/yup/points/{p}")).await;
        let (cz, cy) = (face_components(&pz), face_components(&py));
        for k in 0..3 {
            assert!(
                (cz[k] - cy[k]).abs() <= 0.011,
                "{p}: Z-up {cz:?} vs Y-up {cy:?}"
            );
            assert!(
                (cz[k] - truth[k]).abs() <= bound[k],
                "{p}: {cz:?} against the motion {truth:?}"
            );
        }
    }
    s.stop().await;
}

/// A declared frame is checked, naming the field at fault, and nothing is stored.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_flat_or_empty_frame_is_refused() {
    let s = TestServer::start(|_| {}).await;
    for (frame, field) in [
        (json!({"up": [0, 0, 0]}), "frame.up"),
        (
            json!({"up": [0, 0, 1], "face_normal": [0, 0.05, 1]}),
            "frame.face_normal",
        ),
    ] {
        let r = s
            .client
            .post(s.url("/api/v1/sites"))
            .json(&json!({"id": "bad", "frame": frame}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 422, "{frame}");
        let body = r.text().await.unwrap();
        assert!(body.contains(field), "{body}");
    }
    let r = s
        .client
        .get(s.url("/api/v1/sites/bad"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    s.stop().await;
}

//! Webhooks: Standard Webhooks signatures (published test vector and an independent HMAC), payload shape,
//! backoff bounds, and delivery against a local receiver: same id on retries, Retry-After, 410 disables.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::IntoResponse;
use axum::routing::post;
use axum::Router;
use base64::engine::general_purpose::STANDARD;
use base64::Engine;
use chrono::{TimeZone, Utc};
use hmac::{Hmac, Mac};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sha2::Sha256;

use cliffwatch::webhooks::IncidentLink;
use cliffwatch::webhooks::{
    accepts, alertmanager_alerts, alertmanager_body, backoff_delay, deliver, message_id,
    next_retry, parse_retry_after, render, sign, verify, DeliveryOutcome, PayloadFormat,
    RetryPolicy, WebhookEndpoint, WebhookPayload,
};
use cliffwatch_core::analysis::{
    Alert, AlertEvent, AlertEventType, AlertKind, AlertLevel, AlertStatus,
};

const SECRET: &str = "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw";

#[test]
fn signature_matches_the_published_standard_webhooks_vector() {
    // Test vector of the Standard Webhooks reference libraries.
    let sig = sign(
        SECRET,
        "msg_p5jXN8AQM9LWM0D4loKWxJek",
        1614265330,
        br#"{"test": 2432232314}"#,
    )
    .expect("sign");
    assert_eq!(sig, "v1,g0hM9SsE+OTPJTGt/tmIKtSyZlE3uFJELVlNIOLJ1OE=");
    assert!(verify(
        SECRET,
        "msg_p5jXN8AQM9LWM0D4loKWxJek",
        1614265330,
        br#"{"test": 2432232314}"#,
        &format!("v1,bm9wZQ== {sig}")
    ));
    assert!(!verify(
        SECRET,
        "msg_p5jXN8AQM9LWM0D4loKWxJek",
        1614265331,
        br#"{"test": 2432232314}"#,
        &sig
    ));
    assert!(sign("whsec_not base64!", "id", 1, b"").is_err());
}

fn hmac_by_hand(secret: &str, id: &str, ts: &str, body: &[u8]) -> String {
    let key = STANDARD
        .decode(secret.trim_start_matches("whsec_"))
        .expect("b64");
    let mut m = <Hmac<Sha256> as Mac>::new_from_slice(&key).expect("key");
    m.update(format!("{id}.{ts}.").as_bytes());
    m.update(body);
    format!("v1,{}", STANDARD.encode(m.finalize().into_bytes()))
}

fn event(ty: AlertEventType, level: AlertLevel) -> AlertEvent {
    let t = Utc
        .with_ymd_and_hms(2026, 11, 21, 9, 0, 5)
        .single()
        .expect("time");
    let obs = Utc
        .with_ymd_and_hms(2026, 11, 21, 9, 0, 0)
        .single()
        .expect("time");
    AlertEvent {
        event_type: ty,
        timestamp: t,
        alert: Alert {
            id: "kamo/T103/displacement_mm/17".into(),
            site: "kamo".into(),
            point: Some("T103".into()),
            group: None,
            points: vec![],
            rule: AlertKind::DisplacementMm,
            level,
            peak_level: level,
            value: Some(12.4),
            threshold: Some(10.0),
            unit: "mm".into(),
            epoch: Some(17),
            observed_at: Some(obs),
            raised_epoch: Some(17),
            raised_observed_at: Some(obs),
            raised_at: t,
            updated_at: t,
            status: AlertStatus::Open,
            acknowledged_by: None,
            comment: None,
            message: "kamo/T103: displacement_mm 12.40 mm above 10 mm (warning)".into(),
        },
        cleared_by: None,
    }
}

#[test]
fn payload_has_the_contract_shape() {
    let p = WebhookPayload::from_event(
        &event(AlertEventType::Raised, AlertLevel::Warning),
        None,
        None,
    );
    let v: serde_json::Value = serde_json::to_value(&p).expect("json");
    assert_eq!(v["type"], "alert.raised");
    assert_eq!(v["timestamp"], "2026-11-21T09:00:05Z");
    let d = &v["data"];
    for (k, want) in [
        (
            "alert_id",
            serde_json::json!("kamo/T103/displacement_mm/17"),
        ),
        ("site", serde_json::json!("kamo")),
        ("point", serde_json::json!("T103")),
        ("level", serde_json::json!("warning")),
        ("rule", serde_json::json!("displacement_mm")),
        ("value", serde_json::json!(12.4)),
        ("threshold", serde_json::json!(10.0)),
        ("unit", serde_json::json!("mm")),
        ("epoch", serde_json::json!(17)),
        ("observed_at", serde_json::json!("2026-11-21T09:00:00Z")),
    ] {
        assert_eq!(d[k], want, "field {k}");
    }
    assert!(d["message"].is_string());
    assert!(d.get("url").is_none(), "no link without a public URL");
    assert!(d.get("incident").is_none() && d.get("incident_url").is_none());
    let linked = WebhookPayload::from_event(
        &event(AlertEventType::Raised, AlertLevel::Warning),
        Some("https://cw.example.org/"),
        None,
    );
    assert_eq!(
        linked.data.url.as_deref(),
        Some("https://cw.example.org/sites/kamo/alerts/kamo%2FT103%2Fdisplacement_mm%2F17")
    );
    // In an incident (T103 in block B1): its id and page beside the alert's.
    let b1 = IncidentLink {
        key: "block:B1".into(),
        page: "/sites/kamo/groups/B1".into(),
    };
    let in_block = WebhookPayload::from_event(
        &event(AlertEventType::Raised, AlertLevel::Warning),
        Some("https://cw.example.org/"),
        Some(&b1),
    );
    assert_eq!(in_block.data.incident.as_deref(), Some("block:B1"));
    assert_eq!(
        in_block.data.incident_url.as_deref(),
        Some("https://cw.example.org/sites/kamo/groups/B1")
    );
    assert_eq!(in_block.data.url, linked.data.url);
    // Site-level: point null, points listed.
    let mut e = event(AlertEventType::Raised, AlertLevel::Warning);
    e.alert.point = None;
    e.alert.points = vec!["R3".into()];
    e.alert.rule = AlertKind::ReferenceUnstable;
    let v = serde_json::to_value(WebhookPayload::from_event(&e, None, None)).expect("json");
    assert!(v["data"]["point"].is_null());
    assert_eq!(v["data"]["points"], serde_json::json!(["R3"]));
    assert_eq!(v["data"]["rule"], "reference_unstable");
    // Alertmanager body.
    let am = serde_json::to_value(alertmanager_body(
        &event(AlertEventType::Resolved, AlertLevel::Watch),
        "ops",
        Some("https://cw.example.org"),
        None,
    ))
    .expect("json");
    assert_eq!(am["version"], "4");
    assert_eq!(am["status"], "resolved");
    let a = &am["alerts"][0];
    assert_eq!(a["labels"]["severity"], "watch");
    assert_eq!(a["labels"]["point"], "T103");
    // Alertmanager's fingerprint (a hash of the labels, 16 hex digits), not cliffwatch's id.
    let labels: std::collections::BTreeMap<String, String> =
        serde_json::from_value(a["labels"].clone()).unwrap();
    assert_eq!(a["fingerprint"], cliffwatch::webhooks::fingerprint(&labels));
    assert_eq!(a["fingerprint"].as_str().unwrap().len(), 16);
    assert_eq!(
        a["generatorURL"],
        "https://cw.example.org/sites/kamo/alerts/kamo%2FT103%2Fdisplacement_mm%2F17"
    );
    assert_eq!(am["externalURL"], "https://cw.example.org");
    // In an incident, Alertmanager's link opens the incident's page and names it.
    let am = serde_json::to_value(alertmanager_body(
        &event(AlertEventType::Raised, AlertLevel::Watch),
        "ops",
        Some("https://cw.example.org"),
        Some(&b1),
    ))
    .expect("json");
    let a = &am["alerts"][0];
    assert_eq!(
        a["generatorURL"],
        "https://cw.example.org/sites/kamo/groups/B1"
    );
    assert_eq!(a["annotations"]["incident"], "block:B1");
    let v2 = serde_json::to_value(alertmanager_alerts(
        &event(AlertEventType::Raised, AlertLevel::Watch),
        Some("https://cw.example.org"),
        Some(&b1),
        chrono::Duration::seconds(240),
    ))
    .expect("json");
    assert_eq!(
        v2[0]["generatorURL"],
        "https://cw.example.org/sites/kamo/groups/B1"
    );
}

#[test]
fn endpoints_filter_by_minimum_level() {
    let ep = |min| WebhookEndpoint {
        id: "e".into(),
        url: "http://x".into(),
        secret: SECRET.into(),
        min_level: min,
        format: PayloadFormat::Standard,
        enabled: true,
    };
    let watch = event(AlertEventType::Raised, AlertLevel::Watch);
    assert!(accepts(&ep(None), &watch));
    assert!(!accepts(&ep(Some(AlertLevel::Warning)), &watch));
    assert!(accepts(
        &ep(Some(AlertLevel::Warning)),
        &event(AlertEventType::Raised, AlertLevel::Alarm)
    ));
    // De-escalated to watch after peaking at warning: still delivered to a warning endpoint.
    let mut de = event(AlertEventType::Deescalated, AlertLevel::Watch);
    de.alert.peak_level = AlertLevel::Warning;
    assert!(accepts(&ep(Some(AlertLevel::Warning)), &de));
    let mut off = ep(None);
    off.enabled = false;
    assert!(!accepts(&off, &watch));
    // The id is deterministic per event and differs between events.
    assert_eq!(message_id(&watch), message_id(&watch.clone()));
    assert_ne!(message_id(&watch), message_id(&de));
    // Two escalations of one alert to the same level within one second are two messages (an
    // alert that de-escalates and escalates back quickly must not lose the second).
    let first = event(AlertEventType::Escalated, AlertLevel::Alarm);
    let mut again = first.clone();
    again.timestamp += chrono::Duration::milliseconds(300);
    assert_eq!(
        again.timestamp.timestamp(),
        first.timestamp.timestamp(),
        "the same second"
    );
    assert_ne!(message_id(&first), message_id(&again));
}

#[test]
fn backoff_stays_within_its_bounds() {
    let policy = RetryPolicy {
        base_seconds: 2.0,
        max_delay_seconds: 600.0,
        max_attempts: 10,
        max_retry_after_seconds: 3600.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for attempt in 0..40u32 {
        let d = (2.0 * 2f64.powi(attempt as i32)).min(600.0);
        for _ in 0..200 {
            let s = backoff_delay(&policy, attempt, &mut rng).as_secs_f64();
            assert!(
                s >= 0.5 * d - 1e-9 && s <= d + 1e-9,
                "attempt {attempt}: {s} outside [{}, {d}]",
                d / 2.0
            );
        }
    }
    assert_eq!(next_retry(&policy, 10, None, &mut rng), None);
    assert_eq!(
        next_retry(&policy, 3, Some(Duration::from_secs(120)), &mut rng),
        Some(Duration::from_secs(120))
    );
    assert_eq!(
        next_retry(&policy, 3, Some(Duration::from_secs(99_999)), &mut rng),
        Some(Duration::from_secs(3600))
    );
    // A shorter Retry-After never shortens the backoff (retry number 2: d = 8 s).
    for ra in [0, 1, 3] {
        let wait = next_retry(&policy, 3, Some(Duration::from_secs(ra)), &mut rng)
            .expect("within the limit")
            .as_secs_f64();
        assert!((4.0..=8.0).contains(&wait), "Retry-After {ra}: {wait} s");
    }
    // A receiver answering `Retry-After: 1` to every attempt: under the default policy the
    // message is still retried for at least 45 h before it is given up.
    let default = RetryPolicy::default();
    let mut total = 0.0;
    let mut made = 1;
    while let Some(wait) = next_retry(&default, made, Some(Duration::from_secs(1)), &mut rng) {
        total += wait.as_secs_f64();
        made += 1;
    }
    assert_eq!(made, default.max_attempts);
    assert!(total >= 45.0 * 3600.0, "given up after {total} s");
    let now = Utc
        .with_ymd_and_hms(2015, 10, 21, 7, 28, 0)
        .single()
        .expect("time");
    assert_eq!(
        parse_retry_after("120", now),
        Some(Duration::from_secs(120))
    );
    assert_eq!(
        parse_retry_after("Wed, 21 Oct 2015 07:30:00 GMT", now),
        Some(Duration::from_secs(120))
    );
    assert_eq!(parse_retry_after("soon", now), None);
}

/// Statuses (and Retry-After) to answer, in order.
type Script = Vec<(u16, Option<&'static str>)>;

#[derive(Clone, Default)]
struct Receiver {
    /// Statuses to answer in order (then 200).
    script: Arc<Mutex<Script>>,
    /// (webhook-id, verified, body) of every request.
    got: Arc<Mutex<Vec<(String, bool, serde_json::Value)>>>,
}

async fn hook(
    State(r): State<Receiver>,
    headers: HeaderMap,
    body: axum::body::Bytes,
) -> impl IntoResponse {
    let h = |k: &str| {
        headers
            .get(k)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string()
    };
    let (id, ts, sig) = (
        h("webhook-id"),
        h("webhook-timestamp"),
        h("webhook-signature"),
    );
    let ok = sig
        .split(' ')
        .any(|s| s == hmac_by_hand(SECRET, &id, &ts, &body));
    let json = serde_json::from_slice(&body).unwrap_or(serde_json::Value::Null);
    r.got.lock().expect("lock").push((id, ok, json));
    let next = {
        let mut s = r.script.lock().expect("lock");
        if s.is_empty() {
            (200, None)
        } else {
            s.remove(0)
        }
    };
    let mut resp = StatusCode::from_u16(next.0)
        .expect("status")
        .into_response();
    if let Some(ra) = next.1 {
        resp.headers_mut()
            .insert("retry-after", ra.parse().expect("header"));
    }
    resp
}

async fn start(script: Script) -> (String, Receiver) {
    let r = Receiver {
        script: Arc::new(Mutex::new(script)),
        ..Default::default()
    };
    let app = Router::new()
        .route("/hook", post(hook))
        .with_state(r.clone());
    (format!("http://{}/hook", serve(app).await), r)
}

/// Serves `app` on a free loopback port; its address.
async fn serve(app: Router) -> std::net::SocketAddr {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let addr = listener.local_addr().expect("addr");
    tokio::spawn(async move {
        let _ = axum::serve(listener, app).await;
    });
    addr
}

#[tokio::test]
async fn retries_reuse_the_id_honour_retry_after_and_410_disables() {
    let (url, rx) = start(vec![(503, None), (429, Some("1")), (500, None)]).await;
    let client = cliffwatch::webhooks::client(Duration::from_secs(5)).expect("client");
    let ev = event(AlertEventType::Raised, AlertLevel::Warning);
    let body = serde_json::to_vec(&WebhookPayload::from_event(&ev, None, None)).expect("body");
    let id = message_id(&ev);
    let policy = RetryPolicy {
        base_seconds: 0.01,
        max_delay_seconds: 0.05,
        max_attempts: 6,
        max_retry_after_seconds: 2.0,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut outcomes = vec![];
    let mut attempts = 0;
    loop {
        let out = deliver(&client, &url, SECRET, &id, &body, Utc::now()).await;
        attempts += 1;
        outcomes.push(out.clone());
        match out {
            DeliveryOutcome::Retry { retry_after, .. } => {
                let wait = next_retry(&policy, attempts, retry_after, &mut rng)
                    .expect("within the attempt limit");
                if retry_after.is_some() {
                    assert_eq!(wait, Duration::from_secs(1), "Retry-After honoured");
                }
                tokio::time::sleep(wait).await;
            }
            _ => break,
        }
    }
    assert_eq!(
        outcomes.last(),
        Some(&DeliveryOutcome::Delivered { status: 200 })
    );
    assert!(
        matches!(outcomes[1], DeliveryOutcome::Retry { status: Some(429), retry_after: Some(d), .. } if d == Duration::from_secs(1))
    );
    let got = rx.got.lock().expect("lock").clone();
    assert_eq!(got.len(), 4);
    assert!(
        got.iter().all(|(gid, ok, _)| gid == &id && *ok),
        "same id, valid signature on every attempt"
    );
    assert_eq!(got[3].2["data"]["alert_id"], "kamo/T103/displacement_mm/17");

    // 410 Gone: the endpoint is to be disabled; 404 (a proxy or a deploy in between): retried.
    let (url, _rx) = start(vec![(410, None)]).await;
    assert_eq!(
        deliver(&client, &url, SECRET, &id, &body, Utc::now()).await,
        DeliveryOutcome::Gone
    );
    let (url, _rx) = start(vec![(404, None)]).await;
    assert!(matches!(
        deliver(&client, &url, SECRET, &id, &body, Utc::now()).await,
        DeliveryOutcome::Retry {
            status: Some(404),
            ..
        }
    ));
    // Nobody listening: transient.
    let dead = "http://127.0.0.1:9/hook";
    assert!(matches!(
        deliver(&client, dead, SECRET, &id, &body, Utc::now()).await,
        DeliveryOutcome::Retry { status: None, .. }
    ));
}

/// The Alertmanager API v2 body of an event (`postableAlerts` in Alertmanager's OpenAPI
/// spec): a JSON array of `{labels, annotations, startsAt, endsAt, generatorURL}`, label and
/// annotation values strings, times RFC 3339, `generatorURL` the alert's dashboard page. Each
/// level is its own Alertmanager alert (severity is a label): every level up to the current one
/// fires, held a few periods (not a year); a resolution ends every level at its time.
#[test]
fn alertmanager_v2_body_has_the_postable_alerts_shape() {
    use serde_json::Value;
    use std::collections::BTreeSet;
    let raised = event(AlertEventType::Raised, AlertLevel::Warning);
    let hold = chrono::Duration::seconds(240);
    let body = serde_json::to_value(alertmanager_alerts(
        &raised,
        Some("https://cw.example.org/"),
        None,
        hold,
    ))
    .unwrap();
    let alerts = body.as_array().expect("the body is a JSON array");
    assert_eq!(alerts.len(), 2, "watch and warning: {body}");
    let time = |v: &Value| {
        chrono::DateTime::parse_from_rfc3339(v.as_str().expect("a string"))
            .expect("RFC 3339")
            .to_utc()
    };
    let mut firing = vec![];
    for a in alerts {
        let o = a.as_object().expect("an object");
        let keys: BTreeSet<&str> = o.keys().map(String::as_str).collect();
        assert_eq!(
            keys,
            BTreeSet::from([
                "annotations",
                "endsAt",
                "generatorURL",
                "labels",
                "startsAt"
            ])
        );
        for m in ["labels", "annotations"] {
            let map = o[m].as_object().expect("a label set");
            assert!(map.values().all(Value::is_string), "{m}: {map:?}");
        }
        let url = reqwest::Url::parse(o["generatorURL"].as_str().unwrap()).expect("a URI");
        assert_eq!(url.scheme(), "https");
        assert_eq!(
            url.path(),
            "/sites/kamo/alerts/kamo%2FT103%2Fdisplacement_mm%2F17"
        );
        let l = &o["labels"];
        assert_eq!(l["alertname"], "cliffwatch_displacement_mm");
        assert_eq!(l["site"], "kamo");
        assert_eq!(l["point"], "T103");
        assert_eq!(l["rule"], "displacement_mm");
        let n = &o["annotations"];
        assert_eq!(n["alert_id"], raised.alert.id.as_str());
        assert_eq!(n["value"], "12.4");
        assert_eq!(n["threshold"], "10");
        assert_eq!(n["unit"], "mm");
        assert_eq!(n["level"], "warning");
        assert_eq!(n["summary"], raised.alert.message.as_str());
        assert_eq!(time(&o["startsAt"]), raised.alert.raised_at);
        assert_eq!(time(&o["endsAt"]), raised.timestamp + hold);
        firing.push(l["severity"].as_str().unwrap().to_string());
    }
    assert_eq!(firing, ["watch", "warning"]);

    // Resolution ends every level reached at the event time; without a public URL there is no
    // generatorURL.
    let resolved = event(AlertEventType::Resolved, AlertLevel::Warning);
    let body = serde_json::to_value(alertmanager_alerts(&resolved, None, None, hold)).unwrap();
    assert_eq!(body.as_array().unwrap().len(), 2);
    for a in body.as_array().unwrap() {
        assert_eq!(time(&a["endsAt"]), resolved.timestamp);
        assert!(a.get("generatorURL").is_none());
    }
}

/// The format names are the serde names (what `POST /api/v1/webhooks` and `[[webhooks]]` take and
/// the database stores), and [`render`] gives each endpoint the body of its format.
#[test]
fn each_format_renders_its_body() {
    let names: Vec<&str> = PayloadFormat::ALL.iter().map(|f| f.as_str()).collect();
    assert_eq!(
        names,
        ["standard", "alertmanager_webhook", "alertmanager_api_v2"]
    );
    for &f in PayloadFormat::ALL {
        assert_eq!(serde_json::to_value(f).unwrap(), f.as_str());
        assert_eq!(
            serde_json::from_value::<PayloadFormat>(f.as_str().into()).unwrap(),
            f
        );
        assert_eq!(f.as_str().parse::<PayloadFormat>(), Ok(f));
    }
    assert!("alertmanager".parse::<PayloadFormat>().is_err());
    assert!(serde_json::from_value::<PayloadFormat>("alertmanager".into()).is_err());
    assert_eq!(PayloadFormat::default(), PayloadFormat::Standard);

    let ev = event(AlertEventType::Raised, AlertLevel::Warning);
    let ep = |format| WebhookEndpoint {
        id: "ops".into(),
        url: "http://x".into(),
        secret: SECRET.into(),
        min_level: None,
        format,
        enabled: true,
    };
    let body = |f| -> serde_json::Value {
        serde_json::from_str(&render(&ev, &ep(f), None, None).expect("render")).expect("json")
    };
    let standard = body(PayloadFormat::Standard);
    assert_eq!(
        standard,
        serde_json::to_value(WebhookPayload::from_event(&ev, None, None)).unwrap()
    );
    let v4 = body(PayloadFormat::AlertmanagerWebhook);
    assert_eq!(v4["version"], "4");
    assert_eq!(v4["receiver"], "ops");
    assert_eq!(v4["status"], "firing");
    assert_eq!(v4["alerts"][0]["labels"]["severity"], "warning");
    let v2 = body(PayloadFormat::AlertmanagerApiV2);
    let hold = chrono::Duration::seconds(4 * cliffwatch::webhooks::DEFAULT_RESEND_SECS);
    assert_eq!(
        v2,
        serde_json::to_value(alertmanager_alerts(&ev, None, None, hold)).unwrap()
    );
    assert_eq!(v2.as_array().map(Vec::len), Some(2));
}

/// A receiver answering 301 to the POST: the redirect is not followed (a followed 301 turns the
/// POST into a body-less GET whose 200 would count as delivered); the attempt is retried and its
/// reason names where the redirect pointed.
#[tokio::test]
async fn a_redirect_is_not_followed_and_is_retried() {
    let followed = Arc::new(Mutex::new(0usize));
    let count = followed.clone();
    let app = Router::new()
        .route(
            "/old",
            post(|| async { (StatusCode::MOVED_PERMANENTLY, [("location", "/new")]) }),
        )
        .route(
            "/new",
            axum::routing::any(move || {
                *count.lock().expect("lock") += 1;
                async { StatusCode::OK }
            }),
        );
    let addr = serve(app).await;
    let client = cliffwatch::webhooks::client(Duration::from_secs(5)).expect("client");
    let ev = event(AlertEventType::Raised, AlertLevel::Alarm);
    let body = serde_json::to_vec(&WebhookPayload::from_event(&ev, None, None)).expect("body");
    let out = deliver(
        &client,
        &format!("http://{addr}/old"),
        SECRET,
        &message_id(&ev),
        &body,
        Utc::now(),
    )
    .await;
    match out {
        DeliveryOutcome::Retry {
            status: Some(301),
            reason,
            ..
        } => assert!(reason.contains("redirect to /new not followed"), "{reason}"),
        other => panic!("a 301 is retried, not {other:?}"),
    }
    assert_eq!(
        *followed.lock().expect("lock"),
        0,
        "the redirect was followed"
    );
}

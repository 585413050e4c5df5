//! The OpenAPI document as the contract: health, metrics and request ids, every contract endpoint
//! described with schemas, answers conforming to them, the upload form's bounds equal to the core's.

use crate::support;

use serde_json::{json, Value};
use support::server::{paper, TestServer, PAPER};

#[tokio::test]
async fn health_metrics_openapi_and_request_ids() {
    let s = TestServer::start(|_| {}).await;
    assert_eq!(s.get("/healthz").await.0, 200);
    assert_eq!(s.get("/readyz").await.0, 200);
    let (status, doc) = s.get("/api/v1/openapi.json").await;
    assert_eq!(status, 200);
    for path in [
        "/api/v1/sites/{site}/epochs",
        "/api/v1/sites/{site}/points/{point}/displacements",
        "/api/v1/alerts/{id}/ack",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path}");
    }
    let r = s.client.get(s.url("/metrics")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers().contains_key("x-request-id"));
    assert!(r.text().await.unwrap().contains("# TYPE"));
    let (status, e) = s.get("/api/v1/sites/none").await;
    assert_eq!(status, 404);
    assert_eq!(e["error"]["code"], "not_found");
    let (status, alerts) = s.get("/api/v1/alerts?state=open").await;
    assert_eq!(status, 200);
    assert_eq!(alerts, json!({"items": [], "next_cursor": null}));
    assert_eq!(
        s.client
            .post(s.url("/api/v1/alerts/x/ack"))
            .json(&json!({"by": "me"}))
            .send()
            .await
            .unwrap()
            .status(),
        404
    );
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/hook", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let (_, hooks) = s.get("/api/v1/webhooks").await;
    assert_eq!(hooks["items"].as_array().unwrap().len(), 1);
    assert!(hooks["items"][0].get("secret").is_none());
    assert_eq!(hooks["items"][0]["format"], "standard");
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/am", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", "format": "alertmanager_api_v2"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let created: Value = crate::support::server::checked_json(r).await;
    assert_eq!(created["format"], "alertmanager_api_v2");
    let r = s.client.post(s.url("/api/v1/webhooks")).json(&json!({"url": "http://127.0.0.1:9/am", "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", "format": "prometheus"})).send().await.unwrap();
    assert_eq!(r.status(), 422);
    let e: Value = crate::support::server::checked_json(r).await;
    assert!(
        e["error"]["message"].as_str().unwrap().contains("format"),
        "{e}"
    );
    let (_, hooks) = s.get("/api/v1/webhooks").await;
    assert_eq!(hooks["items"].as_array().unwrap().len(), 2);
    // A secret whose base64 does not decode would fail every delivery: refused at creation, and
    // the document's pattern says which secrets are taken.
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let pattern = doc["components"]["schemas"]["NewWebhook"]["properties"]["secret"]["pattern"]
        .as_str()
        .expect("the secret's pattern");
    let pattern = regex::Regex::new(pattern).unwrap();
    for (secret, want) in [
        ("whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", 201),
        ("whsec_Y2xpZmZ3YXRjaC1hbS13ZWJob29rLXY0", 201),
        ("whsec_YWJj", 201),
        ("whsec_YWJjZA==", 201),
        ("whsec_YWJjZGU=", 201),
        ("whsec_abcdef", 422),
        ("whsec_not base64!", 422),
        ("whsec_YWJjZB==", 422),
        ("whsec_YQ==", 422),
        ("MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw", 422),
    ] {
        let r = s
            .client
            .post(s.url("/api/v1/webhooks"))
            .json(&json!({"url": "http://127.0.0.1:9/h", "secret": secret}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), want, "{secret}");
        assert_eq!(pattern.is_match(secret), want == 201, "pattern on {secret}");
    }
    // A URL that does not parse, or names no host, could never be delivered to.
    for url in ["http://[", "https://", "http:///path", "ftp://a.example/h"] {
        let r = s
            .client
            .post(s.url("/api/v1/webhooks"))
            .json(&json!({"url": url, "secret": "whsec_MfKQ9r8GKYqrTwjUPD8ILPZIo2LaLaSw"}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 422, "{url}");
    }
    s.stop().await;
}

/// Follows `$ref`s of the OpenAPI document to the schema itself.
fn resolve<'a>(doc: &'a Value, schema: &'a Value) -> &'a Value {
    match schema["$ref"].as_str() {
        Some(r) => {
            let name = r.trim_start_matches("#/components/schemas/");
            resolve(doc, &doc["components"]["schemas"][name])
        }
        None => schema,
    }
}

/// The property names of an object schema (through `$ref` and `allOf`).
fn properties(doc: &Value, schema: &Value) -> Vec<String> {
    let s = resolve(doc, schema);
    let mut names: Vec<String> = s["properties"]
        .as_object()
        .map(|p| p.keys().cloned().collect())
        .unwrap_or_default();
    for part in s["allOf"].as_array().into_iter().flatten() {
        names.extend(properties(doc, part));
    }
    names
}

/// Checks `value` against `schema` of the OpenAPI document (3.1: `$ref`, `allOf`, `oneOf`,
/// `anyOf`, `type` as a name or a list, `enum`, `properties`, `required`, `items`); an object
/// member the schema does not name is an error too. Appends what does not conform to `errors`.
fn conforms(doc: &Value, schema: &Value, value: &Value, at: &str, errors: &mut Vec<String>) {
    let s = resolve(doc, schema);
    if let Some(parts) = s["allOf"].as_array() {
        // members are checked against the union of the parts' properties below
        for part in parts {
            let part = resolve(doc, part);
            for name in part["required"].as_array().into_iter().flatten() {
                if value.get(name.as_str().unwrap()).is_none() {
                    errors.push(format!("{at}: required member {name} missing"));
                }
            }
        }
    }
    for key in ["oneOf", "anyOf"] {
        if let Some(alternatives) = s[key].as_array() {
            let fits = alternatives.iter().any(|a| {
                let mut e = Vec::new();
                conforms(doc, a, value, at, &mut e);
                e.is_empty()
            });
            if !fits {
                errors.push(format!("{at}: {value} fits none of {key}"));
            }
            return;
        }
    }
    let type_ok = |t: &str| match t {
        "null" => value.is_null(),
        "boolean" => value.is_boolean(),
        "string" => value.is_string(),
        "integer" => value.is_i64() || value.is_u64(),
        "number" => value.is_number(),
        "array" => value.is_array(),
        "object" => value.is_object(),
        _ => true,
    };
    let types: Vec<&str> = match &s["type"] {
        Value::String(t) => vec![t.as_str()],
        Value::Array(ts) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    if !types.is_empty() && !types.iter().any(|t| type_ok(t)) {
        errors.push(format!("{at}: {value} is not {types:?}"));
        return;
    }
    if let Some(allowed) = s["enum"].as_array() {
        if !allowed.contains(value) {
            errors.push(format!("{at}: {value} not in {allowed:?}"));
        }
    }
    if let (Some(items), Some(values)) = (s.get("items"), value.as_array()) {
        for (k, v) in values.iter().enumerate() {
            conforms(doc, items, v, &format!("{at}[{k}]"), errors);
        }
    }
    if let Some(members) = value.as_object() {
        let names = properties(doc, s);
        if names.is_empty() {
            return; // a free-form object
        }
        for name in s["required"].as_array().into_iter().flatten() {
            if !members.contains_key(name.as_str().unwrap()) {
                errors.push(format!("{at}: required member {name} missing"));
            }
        }
        for (name, v) in members {
            let Some(member_schema) = member_schema(doc, s, name) else {
                errors.push(format!("{at}: member '{name}' is not in the schema"));
                continue;
            };
            conforms(doc, member_schema, v, &format!("{at}.{name}"), errors);
        }
    }
}

/// The schema of member `name` of an object schema (through `$ref` and `allOf`).
fn member_schema<'a>(doc: &'a Value, schema: &'a Value, name: &str) -> Option<&'a Value> {
    let s = resolve(doc, schema);
    if let Some(m) = s["properties"].get(name) {
        return Some(m);
    }
    s["allOf"]
        .as_array()
        .into_iter()
        .flatten()
        .find_map(|part| member_schema(doc, part, name))
}

#[tokio::test]
async fn epoch_summaries_and_errors_conform_to_their_schemas() {
    let s = TestServer::start(|_| {}).await;
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let schema = |name: &str| json!({ "$ref": format!("#/components/schemas/{name}") });
    s.create_site("paper").await;
    // an epoch with a blunder, so that `dropped` and the residuals' `w` are filled
    let mut body = paper(PAPER[3]);
    let blunder = &mut body["images"][0]["observations"][3]["x_mm"];
    *blunder = json!(blunder.as_f64().unwrap() + 0.05);
    let (status, created) = s.upload("paper", &body).await;
    assert_eq!(status, 201, "{created}");
    assert!(
        !created["dropped"].as_array().unwrap().is_empty(),
        "the blunder is dropped: {}",
        created["dropped"]
    );
    // The epoch list counts them (the site page's column) without reading the report.
    let n_dropped = json!(created["dropped"].as_array().unwrap().len());
    assert_eq!(created["dropped_observations"], n_dropped);
    let (status, list) = s.get("/api/v1/sites/paper/epochs").await;
    assert_eq!(status, 200);
    assert_eq!(
        list["items"][0]["dropped_observations"], n_dropped,
        "{list}"
    );
    let (status, full) = s.get("/api/v1/sites/paper/epochs/1").await;
    assert_eq!(status, 200);
    assert!(!full["residuals"].as_array().unwrap().is_empty());
    assert!(created.get("residuals").is_none(), "detail view only");
    // The global test: the reported variance factor against χ²(r)/r bounds around 1, 0.1 % in
    // each tail; the paper's noise matches its a-priori σ, so it is accepted.
    let t = &full["global_test"];
    let (lower, upper, vf) = (
        t["lower"].as_f64().unwrap(),
        t["upper"].as_f64().unwrap(),
        t["variance_factor"].as_f64().unwrap(),
    );
    assert_eq!(vf, full["variance_factor"].as_f64().unwrap());
    assert!(lower < 1.0 && 1.0 < upper, "{t}");
    assert_eq!(t["accepted"], json!((lower..=upper).contains(&vf)), "{t}");
    assert_eq!(t["accepted"], json!(true), "{t}");
    assert_eq!(t["confidence"], json!(0.998));
    let (status, missing) = s.get("/api/v1/sites/paper/epochs/9").await;
    assert_eq!(status, 404);
    let (status, healthy) = s.get("/healthz").await;
    assert_eq!(status, 200);
    let mut errors = Vec::new();
    conforms(
        &doc,
        &schema("EpochSummary"),
        &created,
        "upload",
        &mut errors,
    );
    conforms(&doc, &schema("EpochSummary"), &full, "epoch", &mut errors);
    conforms(&doc, &schema("ErrorBody"), &missing, "404", &mut errors);
    conforms(&doc, &schema("Status"), &healthy, "healthz", &mut errors);
    assert!(errors.is_empty(), "{errors:#?}");
    // the checker itself: a wrong type, an unknown member and a missing one are caught
    let mut wrong = full.clone();
    wrong["cameras"][0]["c_mm"] = json!("300");
    wrong["points"][0]["extra"] = json!(1);
    wrong["images"][0].as_object_mut().unwrap().remove("rms_mm");
    let mut errors = Vec::new();
    conforms(&doc, &schema("EpochSummary"), &wrong, "epoch", &mut errors);
    assert_eq!(errors.len(), 3, "{errors:#?}");
    s.stop().await;
}

/// Every `pattern` in the document (schemas and parameters), recursively.
fn patterns(v: &Value, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                match (k.as_str(), x) {
                    ("pattern", Value::String(p)) => out.push(p.clone()),
                    _ => patterns(x, out),
                }
            }
        }
        Value::Array(a) => a.iter().for_each(|x| patterns(x, out)),
        _ => {}
    }
}

#[tokio::test]
async fn upload_form_bounds_in_the_document_are_the_cores_limits() {
    use cliffwatch_core::photogrammetry::input::epoch::{
        MAX_IMAGE_COORDINATE, MAX_OBJECT_COORDINATE_M,
    };
    let s = TestServer::start(|_| {}).await;
    let (_, doc) = s.get("/api/v1/openapi.json").await;
    let schemas = &doc["components"]["schemas"];
    let bounds: [(&str, &[&str], f64); 3] = [
        (
            "ObservationInput",
            &["x_mm", "y_mm", "col", "row"],
            MAX_IMAGE_COORDINATE,
        ),
        ("ControlInput", &["X", "Y", "Z"], MAX_OBJECT_COORDINATE_M),
        ("ApproxInput", &["X", "Y", "Z"], MAX_OBJECT_COORDINATE_M),
    ];
    for (schema, fields, limit) in bounds {
        for field in fields {
            let p = &schemas[schema]["properties"][field];
            assert_eq!(p["maximum"].as_f64(), Some(limit), "{schema}.{field}: {p}");
            assert_eq!(p["minimum"].as_f64(), Some(-limit), "{schema}.{field}: {p}");
        }
    }
    // one identifier rule everywhere: every identifier pattern of the document (the other
    // patterns are cursors, URLs, secrets, …) is the core's rule, which refuses what it refuses
    let mut found = Vec::new();
    patterns(&doc, &mut found);
    let identifiers: Vec<&String> = found.iter().filter(|p| p.contains("A-Za-z0-9._")).collect();
    assert!(identifiers.len() >= 5, "{found:?}");
    assert!(
        identifiers.iter().all(|p| *p == "^[A-Za-z0-9._-]{1,64}$"),
        "{identifiers:?}"
    );
    use cliffwatch_core::photogrammetry::input::epoch::is_valid_identifier as valid;
    assert!(valid(&"a".repeat(64)) && valid("T-1.b_2"));
    assert!(!valid(&"a".repeat(65)) && !valid("") && !valid("a b") && !valid("é"));
    s.stop().await;
}

#[tokio::test]
async fn openapi_describes_every_contract_endpoint_with_schemas() {
    let s = TestServer::start(|_| {}).await;
    let (status, doc) = s.get("/api/v1/openapi.json").await;
    assert_eq!(status, 200);
    // (method, path, success status, list endpoint, request body)
    let endpoints = [
        ("get", "/healthz", "200", false, false),
        ("get", "/readyz", "200", false, false),
        ("get", "/metrics", "200", false, false),
        ("post", "/api/v1/sites", "201", false, true),
        ("get", "/api/v1/sites", "200", true, false),
        ("get", "/api/v1/sites/{site}", "200", false, false),
        ("post", "/api/v1/sites/{site}/epochs", "201", false, true),
        ("get", "/api/v1/sites/{site}/epochs", "200", true, false),
        (
            "get",
            "/api/v1/sites/{site}/epochs/{epoch}",
            "200",
            false,
            false,
        ),
        ("put", "/api/v1/sites/{site}/reference", "200", false, true),
        ("get", "/api/v1/sites/{site}/points", "200", true, false),
        (
            "put",
            "/api/v1/sites/{site}/points/{point}",
            "200",
            false,
            true,
        ),
        (
            "get",
            "/api/v1/sites/{site}/points/{point}/displacements",
            "200",
            true,
            false,
        ),
        ("get", "/api/v1/alerts", "200", true, false),
        ("post", "/api/v1/alerts/{id}/ack", "200", false, true),
        ("post", "/api/v1/webhooks", "201", false, true),
        ("get", "/api/v1/webhooks", "200", true, false),
    ];
    for (method, path, ok, list, request) in endpoints {
        let op = &doc["paths"][path][method];
        assert!(op.is_object(), "{method} {path} missing");
        let content = &op["responses"][ok]["content"];
        let (media, body) = content
            .as_object()
            .and_then(|c| c.iter().next())
            .unwrap_or_else(|| panic!("{method} {path}: no {ok} response schema"));
        let schema = &body["schema"];
        assert!(
            schema.is_object(),
            "{method} {path}: {media} without schema"
        );
        if media == "application/json" {
            let props = properties(&doc, schema);
            assert!(!props.is_empty(), "{method} {path}: no properties");
            if list {
                assert!(
                    props.contains(&"items".to_string())
                        && props.contains(&"next_cursor".to_string()),
                    "{method} {path}: not the list shape: {props:?}"
                );
                let item = &resolve(&doc, schema)["properties"]["items"]["items"];
                assert!(
                    !properties(&doc, item).is_empty(),
                    "{method} {path}: list items without a schema"
                );
            }
        }
        if request {
            assert!(
                op["requestBody"]["content"]["application/json"]["schema"].is_object(),
                "{method} {path}: no request schema"
            );
        }
        // every error answer names the error body
        for (code, r) in op["responses"].as_object().unwrap() {
            if code.starts_with('4') || code.starts_with('5') {
                assert!(
                    r["content"]["application/json"]["schema"].is_object(),
                    "{method} {path} {code}: no error schema"
                );
            }
        }
    }
    // the webhook schemas name the body formats
    for name in ["NewWebhook", "Webhook"] {
        let format = &doc["components"]["schemas"][name]["properties"]["format"];
        assert_eq!(
            format["enum"],
            json!(["standard", "alertmanager_webhook", "alertmanager_api_v2"]),
            "{name}.format: {format}"
        );
    }
    // the documented upload form names every field the paper epochs use
    let form = &doc["paths"]["/api/v1/sites/{site}/epochs"]["post"]["requestBody"]["content"]
        ["application/json"]["schema"];
    let epoch = paper(PAPER[0]);
    let top = properties(&doc, form);
    let form = resolve(&doc, form);
    for (key, value) in epoch.as_object().unwrap() {
        assert!(top.contains(key), "upload form lacks '{key}'");
        if let Some(first) = value.as_array().and_then(|a| a.first()) {
            let item = &form["properties"][key]["items"];
            let names = properties(&doc, item);
            for k in first.as_object().unwrap().keys() {
                assert!(names.contains(k), "upload form: {key} lacks '{k}'");
            }
        }
    }
    // null where the document allows it, and only there: the schema is that of the types that
    // read the form (a hand-written copy once documented null for fields the server refused)
    let camera = resolve(&doc, &form["properties"]["cameras"]["items"]).clone();
    let nullable = |schema: &Value, field: &str| {
        schema["properties"][field]["type"]
            .as_array()
            .is_some_and(|t| t.contains(&json!("null")))
    };
    s.create_site("n").await;
    for (k, (field, on_camera)) in [
        ("label", false),
        ("control", false),
        ("calibrate_c", true),
        ("k1", true),
        ("sigma_mm", true),
    ]
    .into_iter()
    .enumerate()
    {
        let mut body = paper(PAPER[0]);
        body["observed_at"] = json!(format!("2026-02-0{}T00:00:00Z", k + 1));
        if on_camera {
            body["cameras"][0][field] = Value::Null;
        } else {
            body[field] = Value::Null;
        }
        let documented = nullable(if on_camera { &camera } else { form }, field);
        let (status, answer) = s.upload("n", &body).await;
        assert_eq!(
            status == 201,
            documented,
            "{field}: null documented {documented}, answered {status} {answer}"
        );
    }
    // the bounds the core checks are in the document: c_mm in (0, 100 m], the distortion terms
    // within ±1000, calibrate's names
    let c = &camera["properties"];
    assert_eq!(c["c_mm"]["exclusiveMinimum"], json!(0));
    assert_eq!(c["c_mm"]["maximum"], json!(100_000));
    assert_eq!(c["k1"]["maximum"], json!(1000));
    assert_eq!(
        c["calibrate"]["items"]["enum"],
        json!(cliffwatch_core::photogrammetry::model::camera::INTERIOR_NAMES)
    );
    for (k, (field, value)) in [("c_mm", json!(0.0)), ("k1", json!(1000.5))]
        .into_iter()
        .enumerate()
    {
        let mut body = paper(PAPER[0]);
        body["observed_at"] = json!(format!("2026-03-0{}T00:00:00Z", k + 1));
        body["cameras"][0][field] = value;
        assert_eq!(s.upload("n", &body).await.0, 422, "{field}");
    }
    s.stop().await;
}

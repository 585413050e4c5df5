//! The machine-readable description: `GET /api/v1/openapi.json` (utoipa).

use axum::response::IntoResponse;
use utoipa::OpenApi;

/// The OpenAPI document of the v1 API.
#[derive(OpenApi)]
#[openapi(
    info(title = "cliffwatch", description = "Rock-cliff movement monitoring: epochs, adjustments, displacements, alerts (docs/api.md)"),
    paths(
        super::health::healthz, super::health::readyz, super::health::metrics,
        super::sites::create, super::sites::list, super::sites::get_one, super::sites::set_reference,
        super::sites::update, super::sites::audit, super::groups::delete,
        super::site_lifecycle::retire, super::site_lifecycle::export, super::site_lifecycle::delete,
        super::epochs::upload, super::epochs::list, super::epochs::get_one,
        super::plan::plan, super::plan::site_plan,
        super::points::list, super::points::update, super::points::update_many, super::points::displacements,
        super::groups::put, super::groups::list, super::groups::get_one, super::groups::motion,
        super::alerts::list, super::alerts::acknowledge, super::alerts::events,
        super::incidents::list, super::incidents::acknowledge, super::cap::feed, super::cap::message,
        super::webhooks::create, super::webhooks::list, super::webhooks::delete, super::webhooks::test,
    ),
    components(schemas(
        crate::store::sites::NewSite, crate::store::sites::Site, crate::store::points::PointSettings,
        crate::store::points::Point, crate::store::displacements::Displacement, crate::store::alerts::Alert,
        crate::store::webhooks::NewWebhook, crate::store::webhooks::Webhook, crate::store::epochs::EpochListItem,
        super::sites::ReferenceBody, super::alerts::AckBody, super::incidents::IncidentList, super::sites::AuditPage, super::points::UpdatedPoints, crate::store::audit::AuditEntry,
        super::site_lifecycle::RetireBody, crate::service::site_lifecycle::SiteExport,
        crate::service::incidents::Incident, crate::service::incidents::IncidentForecast, super::alerts::AlertHistory, super::points::PointItem,
        crate::webhooks::WebhookPayload, crate::webhooks::WebhookData, super::webhooks::WebhookTest,
        super::schemas::ErrorBody, super::schemas::ErrorDetail, super::schemas::Status,
        cliffwatch_core::photogrammetry::EpochInput, cliffwatch_core::photogrammetry::input::epoch::CameraInput,
        cliffwatch_core::photogrammetry::input::epoch::ImageInput, cliffwatch_core::photogrammetry::input::epoch::ObservationInput,
        cliffwatch_core::photogrammetry::input::epoch::ControlInput, cliffwatch_core::photogrammetry::input::epoch::ApproxInput,
        super::schemas::EpochSummary, super::schemas::EpochHead, super::groups::GroupBody, super::groups::Group,
        cliffwatch_core::analysis::alerts::AlertRule, cliffwatch_core::analysis::alerts::AlertLevel,
        cliffwatch_core::analysis::alerts::Metric, cliffwatch_core::analysis::alerts::Source,
        crate::cap::SiteArea, crate::cap::Circle,
        cliffwatch_core::plan::Plan, cliffwatch_core::plan::PlanReport, cliffwatch_core::plan::PlanChange,
        super::plan::WhatIf, crate::service::plan::SitePlan,
    )),
    modifiers(&BearerAuth, &CommonErrors)
)]
pub struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The answers every handler can give before its own code runs, added where an operation does not
/// list them: 400 (a query or path value that does not parse, a body that is not JSON, a bad
/// cursor) on every operation with parameters or a body, 415 (a body that is not
/// `application/json`), 413 (a body over the size limit) and 422 (JSON not of the schema) on every
/// operation with a body; 401 and 403 ([`crate::http::auth::authorize`]) with the bearer token as an
/// alternative to none on every operation that needs a role; 408 (the request timeout) and 500
/// (a failure of the database or a task) on every operation.
struct CommonErrors;

impl utoipa::Modify for CommonErrors {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::{ContentBuilder, Ref, ResponseBuilder};
        let error = |what: &str| {
            ResponseBuilder::new()
                .description(what)
                .content(
                    "application/json",
                    ContentBuilder::new()
                        .schema(Some(Ref::from_schema_name("ErrorBody")))
                        .build(),
                )
                .build()
        };
        use axum::http::Method;
        use utoipa::openapi::security::SecurityRequirement;
        for (path, item) in openapi.paths.paths.iter_mut() {
            for (method, op) in [
                (Method::GET, &mut item.get),
                (Method::PUT, &mut item.put),
                (Method::POST, &mut item.post),
                (Method::DELETE, &mut item.delete),
                (Method::PATCH, &mut item.patch),
            ]
            .into_iter()
            .filter_map(|(m, op)| Some((m, op.as_mut()?)))
            {
                if let Some(role) = crate::http::auth::required_role(&method, path) {
                    // no token at all while the server has none configured
                    op.security = Some(vec![
                        SecurityRequirement::default(),
                        SecurityRequirement::new("bearer", Vec::<String>::new()),
                    ]);
                    let responses = &mut op.responses.responses;
                    responses.entry("401".into()).or_insert_with(|| {
                        error(
                            "the server has tokens and the request carries none, or an unknown one",
                        )
                        .into()
                    });
                    // only changes are checked for their origin
                    let mut forbidden = vec![];
                    if role > crate::config::Role::Read {
                        forbidden.push(format!(
                            "the token's role is below {}",
                            format!("{role:?}").to_lowercase()
                        ));
                    }
                    if method != Method::GET {
                        forbidden.push(
                            "a browser sent the change from another site's page (Origin / \
                             Sec-Fetch-Site)"
                                .into(),
                        );
                    }
                    forbidden.push(
                        "the server has no tokens and the Host header names neither a loopback \
                         name nor public_url's host"
                            .into(),
                    );
                    responses
                        .entry("403".into())
                        .or_insert_with(|| error(&forbidden.join("; or ")).into());
                }
                for p in op.parameters.iter_mut().flatten() {
                    match p.name.as_str() {
                        "cursor" => p.schema = Some(cursor_schema()),
                        "from" | "to" => p.schema = Some(time_bound_schema()),
                        "observed_at" => p.schema = Some(date_time_schema()),
                        "format" => p.schema = Some(series_format_schema()),
                        _ => {}
                    }
                }
                let has_params = op.parameters.as_ref().is_some_and(|p| !p.is_empty());
                let has_body = op.request_body.is_some();
                let responses = &mut op.responses.responses;
                if has_params || has_body {
                    responses.entry("400".into()).or_insert_with(|| {
                        error("a path or query value, the body or the cursor does not parse").into()
                    });
                }
                if has_body {
                    responses.entry("422".into()).or_insert_with(|| {
                        error("the body is JSON but not of the schema (the field is named)").into()
                    });
                    responses
                        .entry("413".into())
                        .or_insert_with(|| error("the body is over the size limit").into());
                    responses
                        .entry("415".into())
                        .or_insert_with(|| error("the body is not application/json").into());
                }
                responses.entry("408".into()).or_insert_with(|| {
                    error("no answer within the request timeout (`request_timeout_secs`)").into()
                });
                responses.entry("500".into()).or_insert_with(|| {
                    error("a failure of the database or of a task; details in the server log")
                        .into()
                });
            }
        }
    }
}

/// The page cursor: unpadded base64url ([`super::list::decode`] decodes every string of this
/// form, and answers 400 unless the listing gave it).
fn cursor_schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
    use utoipa::openapi::schema::{ObjectBuilder, Type};
    ObjectBuilder::new()
        .schema_type(Type::String)
        .pattern(Some(super::list::CURSOR_PATTERN))
        .description(Some(
            "opaque: the next_cursor of the previous page of the same listing (a cursor of \
             another listing is a 400)",
        ))
        .into()
}

/// A series' time bound: an RFC 3339 time or a date (`from`: its start, `to`: its end).
fn time_bound_schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
    use utoipa::openapi::schema::{AnyOfBuilder, KnownFormat, ObjectBuilder, SchemaFormat, Type};
    let with = |f: KnownFormat| {
        ObjectBuilder::new()
            .schema_type(Type::String)
            .format(Some(SchemaFormat::KnownFormat(f)))
    };
    AnyOfBuilder::new()
        .item(with(KnownFormat::Date))
        .item(with(KnownFormat::DateTime))
        .description(Some("an RFC 3339 time or a date (UTC)"))
        .into()
}

/// An RFC 3339 time.
fn date_time_schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
    use utoipa::openapi::schema::{KnownFormat, ObjectBuilder, SchemaFormat, Type};
    ObjectBuilder::new()
        .schema_type(Type::String)
        .format(Some(SchemaFormat::KnownFormat(KnownFormat::DateTime)))
        .description(Some(
            "RFC 3339 time of the epoch (CSV uploads only, required there)",
        ))
        .into()
}

/// `json` (default) or `csv`.
fn series_format_schema() -> utoipa::openapi::RefOr<utoipa::openapi::schema::Schema> {
    use utoipa::openapi::schema::{ObjectBuilder, Type};
    ObjectBuilder::new()
        .schema_type(Type::String)
        .enum_values(Some(["json", "csv"]))
        .description(Some("json (default) or csv"))
        .into()
}

/// The served document: [`ApiDoc`] with the constraints utoipa's derive cannot state.
pub fn document() -> serde_json::Value {
    let mut doc = serde_json::to_value(ApiDoc::openapi()).unwrap_or_default();
    let schemas = &mut doc["components"]["schemas"];
    // A rule has exactly one numeric threshold: `above` or `below` (AlertRule::validate).
    if let Some(rule) = schemas.get_mut("AlertRule") {
        let only =
            |k: &str| serde_json::json!({"required": [k], "properties": {k: {"type": "number"}}});
        rule["oneOf"] = serde_json::json!([only("above"), only("below")]);
    }
    // Members of a group are point identifiers.
    if let Some(items) = schemas
        .get_mut("GroupBody")
        .and_then(|s| s["properties"]["points"].get_mut("items"))
    {
        items["pattern"] = serde_json::json!("^[A-Za-z0-9._-]{1,64}$");
    }
    // A warning area: a [latitude, longitude] pair in range, a description not only blanks.
    if let Some(area) = schemas.get_mut("SiteArea") {
        area["properties"]["polygon"]["items"] = serde_json::json!({
            "type": "array", "minItems": 2, "maxItems": 2,
            "prefixItems": [
                {"type": "number", "minimum": -90, "maximum": 90},
                {"type": "number", "minimum": -180, "maximum": 180}
            ]
        });
        area["properties"]["description"]["pattern"] = serde_json::json!("\\S");
    }
    // A site's time zone is an IANA name the server knows.
    if let Some(zone) = schemas
        .get_mut("NewSite")
        .and_then(|s| s["properties"].get_mut("time_zone"))
    {
        let mut names: Vec<serde_json::Value> = chrono_tz::TZ_VARIANTS
            .iter()
            .map(|z| serde_json::json!(z.name()))
            .collect();
        names.push(serde_json::Value::Null);
        zone["enum"] = serde_json::Value::Array(names);
    }
    // A direction of interest is three numbers, not all zero.
    for (schema, field) in [("GroupBody", "direction"), ("PointSettings", "direction")] {
        if let Some(d) = schemas
            .get_mut(schema)
            .and_then(|s| s["properties"].get_mut(field))
        {
            d["not"] = serde_json::json!({"type": "array", "items": {"const": 0}});
        }
    }
    doc
}

/// `GET /api/v1/openapi.json`.
pub async fn openapi_json() -> impl IntoResponse {
    axum::Json(document())
}

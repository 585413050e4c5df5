//! The machine-readable description: `GET /api/v1/openapi.json` (utoipa).

use axum::response::IntoResponse;
use utoipa::OpenApi;

/// The OpenAPI document of the v1 API.
#[derive(OpenApi)]
#[openapi(
    info(title = "cliffwatch", description = "Rock-cliff movement monitoring: epochs, adjustments, displacements, alerts (docs/api-contract.md)"),
    paths(
        super::health::healthz, super::health::readyz, super::health::metrics,
        super::sites::create, super::sites::list, super::sites::get_one, super::sites::set_reference,
        super::epochs::upload, super::epochs::list, super::epochs::get_one,
        super::points::list, super::points::update, super::points::displacements,
        super::groups::put, super::groups::list, super::groups::get_one, super::groups::motion,
        super::alerts::list, super::alerts::acknowledge,
        super::webhooks::create, super::webhooks::list, super::webhooks::delete,
    ),
    components(schemas(
        crate::store::sites::NewSite, crate::store::sites::Site, crate::store::points::PointSettings,
        crate::store::points::Point, crate::store::displacements::Displacement, crate::store::alerts::Alert,
        crate::store::webhooks::NewWebhook, crate::store::webhooks::Webhook, crate::store::epochs::EpochListItem,
        super::sites::ReferenceBody, super::alerts::AckBody, super::points::PointItem,
        super::schemas::ErrorBody, super::schemas::ErrorDetail, super::schemas::Status,
        super::schemas::UploadForm, super::schemas::CameraForm, super::schemas::ImageForm,
        super::schemas::ObservationForm, super::schemas::ControlForm, super::schemas::ApproxForm,
        super::schemas::EpochSummary, super::groups::GroupBody, super::groups::Group,
    )),
    modifiers(&BearerAuth)
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

/// `GET /api/v1/openapi.json`.
pub async fn openapi_json() -> impl IntoResponse {
    axum::Json(ApiDoc::openapi())
}

//! `GET /api/openapi.json`: the API's OpenAPI 3.1 document. The routes, request and response
//! schemas come from the handlers' `#[utoipa::path]` and the types' `ToSchema` derives (the
//! types the server actually parses and answers with); what a derive cannot say is added
//! here from the same sources the server checks against: each number's range and each
//! integrator's defaults from the spec (`spec::rules`, `spec::describe`), and the built-in
//! scene names from the catalogue.

use serde_json::{Value, json};
use utoipa::OpenApi;
use utoipa::openapi::extensions::Extensions;
use utoipa::openapi::schema::{Object, Schema};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::openapi::{OpenApi as Document, RefOr};

use crate::spec::{RULES, Range, SPEC_VERSION, default_text, defaults_by_integrator};

#[derive(OpenApi)]
#[openapi(
    info(
        title = "photonbox",
        description = "A photon-mapping render server: submit a scene and its parameters as a \
                       job, follow it, fetch its images. Every `/api` route but this document \
                       needs `Authorization: Bearer TOKEN`; errors are JSON naming the field.",
    ),
    modifiers(&BearerToken),
    components(schemas(crate::spec::SpecForm))
)]
struct ApiDoc;

struct BearerToken;

impl utoipa::Modify for BearerToken {
    fn modify(&self, doc: &mut Document) {
        doc.components
            .get_or_insert_with(Default::default)
            .add_security_scheme(
                "bearer",
                SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
            );
    }
}

/// The document before the routes add their paths.
pub fn base() -> Document {
    ApiDoc::openapi()
}

/// The document with what derives cannot say: the spec's ranges and defaults, and the
/// built-in scenes' names.
pub fn complete(mut doc: Document, scene_names: &[String]) -> Document {
    if let Some(params) = schema_mut(&mut doc, "Params") {
        describe_params(params);
    }
    if let Some(request) = schema_mut(&mut doc, "JobRequest")
        && let Some(name) = property_mut(request, "scene_name")
    {
        let mut names: Vec<Value> = scene_names.iter().map(|n| json!(n)).collect();
        names.push(Value::Null);
        name.enum_values = Some(names);
    }
    doc
}

/// Ranges, defaults and the integrators' full defaults on the spec's form.
fn describe_params(params: &mut Object) {
    for rule in RULES {
        let Some(p) = property_mut(params, rule.field) else {
            continue;
        };
        match rule.range {
            Range::Int { min, max } => {
                p.minimum = Some(min.into());
                p.maximum = Some(max.into());
            }
            Range::OpenUnit => {
                p.exclusive_minimum = Some(0.0.into());
                p.exclusive_maximum = Some(1.0.into());
            }
            Range::Positive => p.exclusive_minimum = Some(0.0.into()),
            Range::Span { lo, hi } => {
                p.minimum = Some(lo.into());
                p.maximum = Some(hi.into());
            }
        }
    }
    let fields: Vec<String> = params.properties.keys().cloned().collect();
    for field in fields {
        if let (Some(text), Some(p)) = (default_text(&field), property_mut(params, &field)) {
            let d = p.description.take().unwrap_or_default();
            p.description = Some(format!("{d} Default: {text}.").trim().to_string());
        }
    }
    if let Some(seed) = property_mut(params, "seed") {
        seed.maximum = Some(u64::MAX.into());
    }
    if let Some(version) = property_mut(params, "version") {
        (version.minimum, version.maximum) = (Some(SPEC_VERSION.into()), Some(SPEC_VERSION.into()));
    }
    let defaults: serde_json::Map<String, Value> = defaults_by_integrator()
        .into_iter()
        .map(|(name, form)| (name.to_string(), Value::Object(form)))
        .collect();
    let mut ext = Extensions::default();
    ext.insert("x-defaults".into(), Value::Object(defaults));
    params
        .extensions
        .get_or_insert_with(Default::default)
        .merge(ext);
}

fn schema_mut<'a>(doc: &'a mut Document, name: &str) -> Option<&'a mut Object> {
    match doc.components.as_mut()?.schemas.get_mut(name)? {
        RefOr::T(Schema::Object(o)) => Some(o),
        _ => None,
    }
}

fn property_mut<'a>(o: &'a mut Object, name: &str) -> Option<&'a mut Object> {
    match o.properties.get_mut(name)? {
        RefOr::T(Schema::Object(p)) => Some(p),
        _ => None,
    }
}

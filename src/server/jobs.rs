//! What a job is at the API's edge: the request body, and the job's spec as the server
//! validates, stores and runs it. The scene it renders: `scenes.rs`; limits and estimates:
//! `needs.rs`; result files: `results.rs`.

use serde::Deserialize;
use serde_json::Value;

use super::error::ApiError;
use crate::spec::RenderSpec;
use crate::spec::SpecForm;

/// `POST /api/jobs` body: a scene (uploaded, or a built-in one by name) and its params.
#[derive(Deserialize, utoipa::ToSchema, Debug)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    /// A scene of your own (the scene format: README.md, "Scenes"); or give `scene_name`.
    #[schema(value_type = Option<Object>)]
    pub scene: Option<Value>,
    /// A built-in scene (`GET /api/scenes`); or give `scene`.
    pub scene_name: Option<String>,
    /// The render's parameters (defaults by integrator).
    #[serde(default)]
    #[schema(value_type = Option<crate::spec::SpecForm>)]
    pub params: Option<Value>,
    /// Whether other users may see the job (they cannot cancel or delete it).
    #[serde(default)]
    pub public: bool,
}

/// A job's validated spec: what renders, and what the server does with the image.
#[derive(Clone, Debug)]
pub struct JobSpec {
    pub render: RenderSpec,
    /// PNG exposure in stops.
    pub exposure: f32,
    /// The job whose EXR the result is measured against.
    pub reference_job: Option<i64>,
}

impl JobSpec {
    /// Validate a request's `params`, naming the first problem's path under `params`.
    pub fn from_form(form: &SpecForm) -> Result<JobSpec, ApiError> {
        let render = form
            .to_spec(form.reference_job.is_some())
            .map_err(|e| ApiError::invalid(e.json_path("params"), e.message))?;
        Ok(JobSpec {
            render,
            exposure: form.exposure.unwrap_or(0.0),
            reference_job: form.reference_job,
        })
    }

    /// The form the spec is stored in and shown as: every field its integrator reads.
    pub fn to_form(&self) -> SpecForm {
        SpecForm {
            exposure: Some(self.exposure),
            reference_job: self.reference_job,
            ..SpecForm::of(&self.render)
        }
    }

    /// A stored spec (the text of [`JobSpec::to_form`], or the params as submitted before
    /// specs were stored whole: the defaults fill them in the same way).
    pub fn from_stored(text: &str) -> Result<JobSpec, String> {
        let form: SpecForm = serde_json::from_str(text).map_err(|e| format!("params: {e}"))?;
        JobSpec::from_form(&form).map_err(|e| e.message)
    }
}

/// Deserialize `value` as `T`, naming the JSON path of the first problem under `prefix`.
pub fn from_json<T: serde::de::DeserializeOwned>(
    value: Value,
    prefix: &str,
) -> Result<T, ApiError> {
    serde_path_to_error::deserialize(value).map_err(|e| {
        let inner = e.path().to_string();
        let path = match (prefix.is_empty(), inner.as_str()) {
            (true, ".") => "body".to_string(),
            (true, p) => p.to_string(),
            (false, ".") => prefix.to_string(),
            (false, p) => format!("{prefix}.{p}"),
        };
        ApiError::invalid(path, e.into_inner().to_string())
    })
}

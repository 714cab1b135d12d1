//! What the API answers, as types: serialized once at the edge, and described by the same
//! derive in the OpenAPI document (`openapi.rs`), so that the document cannot drift from the
//! answers. A job's spec and stats are stored as the JSON text they were serialized to once
//! (by the submit handler and the runner) and embedded here as they are.

use serde::Serialize;
use serde_json::value::RawValue;

use super::store::{JobRow, Status};

/// An error: what is wrong and the field, header or limit it concerns.
#[derive(Serialize, utoipa::ToSchema)]
pub struct ErrorBody {
    pub error: String,
    /// A JSON path into the request (`params.k`, `scene.objects[3].radius`), a header
    /// (`header.Authorization`), a limit (`limits.max_queued_per_user`), or null.
    pub path: Option<String>,
    /// Internal errors only: quote it to the operator, who finds the detail in the log.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub request_id: Option<String>,
}

/// Where a job's resources are.
#[derive(Serialize, utoipa::ToSchema)]
pub struct JobLinks {
    #[serde(rename = "self")]
    pub self_: String,
    pub png: String,
    pub exr: String,
    pub events: String,
}

impl JobLinks {
    pub fn of(id: i64) -> JobLinks {
        let base = format!("/api/jobs/{id}");
        JobLinks {
            png: format!("{base}/image.png"),
            exr: format!("{base}/image.exr"),
            events: format!("{base}/events"),
            self_: base,
        }
    }
}

/// A job as the API shows it.
#[derive(Serialize, utoipa::ToSchema)]
pub struct JobView {
    pub id: i64,
    /// The owner's user name.
    pub owner: String,
    /// Whether the requesting user owns it.
    pub mine: bool,
    pub public: bool,
    /// The built-in scene's name, or the name given in an uploaded scene.
    pub scene: Option<String>,
    /// The job's spec: every field its integrator reads, defaults filled in.
    #[schema(value_type = crate::spec::SpecForm)]
    pub params: Box<RawValue>,
    pub status: Status,
    /// A queued job's place in the scheduler's order (0: next).
    pub queue_position: Option<usize>,
    /// 0..1, monotone while the job runs.
    pub progress: f64,
    /// The phase running (`photon_trace`, `build_maps`, `precompute`, `render`, `passes`).
    pub phase: Option<&'static str>,
    pub eta_seconds: Option<f64>,
    /// Unix seconds.
    pub created: f64,
    pub started: Option<f64>,
    pub finished: Option<f64>,
    /// Why the job failed.
    pub error: Option<String>,
    /// A finished job's STATS.json (times, photon counts, effects and why, radii, errors
    /// against a reference, `ppm` passes) with `cache` and `ppm_state`.
    #[schema(value_type = Option<Object>)]
    pub stats: Option<Box<RawValue>>,
    /// What the server planned for (the memory budget admits by it).
    pub memory_estimate_bytes: u64,
    pub links: JobLinks,
}

/// Stored JSON text, embedded as it is (`null` if it is not JSON: a store edited by hand).
pub fn raw(text: &str) -> Box<RawValue> {
    RawValue::from_string(text.to_string())
        .unwrap_or_else(|_| RawValue::from_string("null".into()).expect("null is JSON"))
}

impl JobView {
    pub fn of(row: &JobRow, snap: &super::state::Snapshot, owner: String, mine: bool) -> JobView {
        JobView {
            id: row.id,
            owner,
            mine,
            public: row.public,
            scene: row.scene_name.clone(),
            params: raw(&row.params_json),
            status: row.status,
            queue_position: None,
            progress: snap.progress,
            phase: snap.phase,
            eta_seconds: snap.eta_seconds,
            created: row.created,
            started: row.started,
            finished: row.finished,
            error: row.error.clone(),
            stats: row.stats_json.as_deref().map(raw),
            memory_estimate_bytes: row.memory_bytes,
            links: JobLinks::of(row.id),
        }
    }
}

#[derive(Serialize, utoipa::ToSchema)]
pub struct JobList {
    /// Your jobs and the public ones (an admin: every job), newest first.
    pub jobs: Vec<JobView>,
}

/// A job accepted (202): committed to the store and queued.
#[derive(Serialize, utoipa::ToSchema)]
pub struct Submitted {
    pub id: i64,
    pub status: Status,
    pub links: SelfLink,
}

#[derive(Serialize, utoipa::ToSchema)]
pub struct SelfLink {
    #[serde(rename = "self")]
    pub self_: String,
}

/// What became of a job that was asked to stop.
#[derive(Serialize, utoipa::ToSchema)]
pub struct Stopped {
    pub id: i64,
    /// `cancelled`, or `running` if it had not stopped within 5 s (it stops soon after).
    pub status: Status,
}

#[derive(Serialize, utoipa::ToSchema)]
pub struct SceneEntry {
    pub name: String,
    pub description: Option<String>,
}

#[derive(Serialize, utoipa::ToSchema)]
pub struct SceneList {
    pub scenes: Vec<SceneEntry>,
}

/// The user a token belongs to.
#[derive(Serialize, utoipa::ToSchema)]
pub struct Me {
    pub id: i64,
    pub name: String,
    /// Admins see and may cancel every job.
    pub admin: bool,
}

/// The error answers of every route that takes a token. (This and [`JobErrors`] describe
/// what `ApiError` answers, for the document: no handler builds them.)
#[derive(utoipa::IntoResponses)]
#[allow(dead_code)]
pub enum AuthErrors {
    /// No or an unknown token.
    #[response(status = 401)]
    Unauthorized(ErrorBody),
}

/// The error answers of a route about one job.
#[derive(utoipa::IntoResponses)]
#[allow(dead_code)]
pub enum JobErrors {
    /// No or an unknown token.
    #[response(status = 401)]
    Unauthorized(ErrorBody),
    /// No such job that you may see.
    #[response(status = 404)]
    NotFound(ErrorBody),
}

/// A job's path parameter.
#[derive(utoipa::IntoParams)]
#[into_params(parameter_in = Path)]
pub struct JobPath {
    /// The job's id.
    pub id: i64,
}

/// A job's image files: the PNG (8-bit sRGB at its exposure) and the EXR (linear radiance,
/// 32-bit float).
#[derive(utoipa::ToSchema)]
pub enum ImageFile {
    #[schema(rename = "image.png")]
    Png,
    #[schema(rename = "image.exr")]
    Exr,
}

impl ImageFile {
    pub fn parse(name: &str) -> Option<ImageFile> {
        match name {
            "image.png" => Some(ImageFile::Png),
            "image.exr" => Some(ImageFile::Exr),
            _ => None,
        }
    }

    /// The result file's extension and content type.
    pub fn ext_and_type(&self) -> (&'static str, &'static str) {
        match self {
            ImageFile::Png => ("png", "image/png"),
            ImageFile::Exr => ("exr", "image/x-exr"),
        }
    }
}

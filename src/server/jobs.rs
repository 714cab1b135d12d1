//! What a job is: the request body, its parameters (the CLI's names in snake_case), the
//! limits a job must respect, the memory it will need, and the photon-map cache key.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::error::ApiError;
use crate::render::photon::PhotonParams;
use crate::render::scene::{SceneDesc, ShapeDesc};
use crate::render::{EffectSwitches, IntegratorKind, PhotonStore, RenderParams};

/// `POST /api/jobs` body.
#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    pub scene: Option<Value>,
    pub scene_name: Option<String>,
    #[serde(default)]
    pub params: Option<Value>,
    #[serde(default)]
    pub public: bool,
}

/// A job's parameters as JSON: every field optional, defaults as on the CLI.
#[derive(Deserialize, Serialize, Debug, Default, Clone, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ParamsJson {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub integrator: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub photons: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caustic_photons: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub k: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub photon_store: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gather_rays: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alpha: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_depth: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// PNG exposure in stops.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exposure: Option<f32>,
    /// Effects to switch off, e.g. `{"caustics": false}`; unnamed ones stay on.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub effects: Option<EffectsJson>,
    /// A finished job (same width and height) whose EXR this job is measured against.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_job: Option<i64>,
}

/// `params.effects`: each effect on (true, the default) or off.
#[derive(Deserialize, Serialize, Debug, Default, Clone, Copy, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EffectsJson {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_light: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caustics: Option<bool>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffuse_interreflection: Option<bool>,
}

impl EffectsJson {
    fn switches(&self) -> EffectSwitches {
        EffectSwitches {
            direct_light: self.direct_light.unwrap_or(true),
            caustics: self.caustics.unwrap_or(true),
            diffuse_interreflection: self.diffuse_interreflection.unwrap_or(true),
        }
    }
}

/// Validated parameters of a job.
#[derive(Clone, Debug)]
pub struct JobParams {
    pub render: RenderParams,
    pub exposure: f32,
    /// The job whose EXR the result is measured against.
    pub reference_job: Option<i64>,
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

impl ParamsJson {
    pub fn to_params(&self) -> Result<JobParams, ApiError> {
        let integrator = match self.integrator.as_deref() {
            None | Some("photon") => IntegratorKind::Photon,
            Some("raytrace") => IntegratorKind::Raytrace,
            Some("ppm") => IntegratorKind::Ppm,
            Some(other) => {
                return Err(ApiError::invalid(
                    "params.integrator",
                    format!("unknown integrator {other:?}: expected raytrace, photon or ppm"),
                ));
            }
        };
        let d = if integrator == IntegratorKind::Ppm {
            RenderParams::ppm_defaults()
        } else {
            RenderParams::default()
        };
        let photon_store = match self.photon_store.as_deref() {
            None | Some("indirect") => PhotonStore::Indirect,
            Some("all") => PhotonStore::All,
            Some("direct_only") => PhotonStore::DirectOnly,
            Some(other) => {
                return Err(ApiError::invalid(
                    "params.photon_store",
                    format!(
                        "unknown photon store {other:?}: expected indirect, all or direct_only"
                    ),
                ));
            }
        };
        let exposure = self.exposure.unwrap_or(0.0);
        if !exposure.is_finite() || exposure.abs() > 64.0 {
            return Err(ApiError::invalid(
                "params.exposure",
                "must be a finite number of stops in -64..=64",
            ));
        }
        let render = RenderParams {
            integrator,
            photons: self.photons.unwrap_or(d.photons),
            caustic_photons: self.caustic_photons.unwrap_or(d.caustic_photons),
            k: self.k.unwrap_or(d.k),
            photon_store,
            gather_rays: self.gather_rays.unwrap_or(d.gather_rays),
            spp: self.spp.unwrap_or(d.spp),
            max_depth: self.max_depth.unwrap_or(d.max_depth),
            seed: self.seed.unwrap_or(d.seed),
            width: self.width,
            height: self.height,
            iterations: self.iterations.unwrap_or(d.iterations),
            alpha: self.alpha.unwrap_or(d.alpha),
            radius: self.radius,
            aim_caustics: true,
            effects: self.effects.unwrap_or_default().switches(),
        };
        render
            .validate()
            .map_err(|e| ApiError::invalid(format!("params.{}", e.field), e.message))?;
        Ok(JobParams {
            render,
            exposure,
            reference_job: self.reference_job,
        })
    }
}

/// Server limits on what one job may ask for (flags of `photonbox serve`).
#[derive(Clone, Debug)]
pub struct Limits {
    pub body_bytes: usize,
    pub max_pixels: u64,
    pub max_photons: u64,
    pub max_k: usize,
    pub max_iterations: u32,
    pub max_triangles: usize,
    pub max_queued_per_user: usize,
    /// Memory all running renders together may use.
    pub memory_bytes: u64,
    /// Most work units ([`JobNeeds::work`]) one job may ask for.
    pub max_work: f64,
    /// Disk one user's uploaded scenes and result files may take.
    pub storage_bytes_per_user: u64,
}

impl Limits {
    pub const DEFAULT: Limits = Limits {
        body_bytes: 16 << 20,
        max_pixels: 4096 * 4096,
        max_photons: 50_000_000,
        max_k: 1000,
        max_iterations: 100_000,
        max_triangles: 2_000_000,
        max_queued_per_user: 32,
        memory_bytes: 8 << 30,
        // About 10^12 rays: days of this 2-core machine; a typical final render is 10^9.
        max_work: 1e12,
        storage_bytes_per_user: 2 << 30,
    };
}

impl Default for Limits {
    fn default() -> Limits {
        Limits::DEFAULT
    }
}

/// What a job needs, checked against the limits before it is accepted.
pub struct JobNeeds {
    pub pixels: u64,
    pub triangles: usize,
    pub memory_bytes: u64,
    /// The job's work in ray-sized units: every camera sample and final-gather ray, every
    /// emitted photon, and (for `photon`) each k-NN neighbour of the irradiance precompute,
    /// times the passes of a progressive job. An upper guide, not a prediction of seconds:
    /// it bounds what one job may take from the box, whatever its parameters.
    pub work: f64,
    /// An upper estimate of the job's result files: the EXR (f32 RGBA), the PNG, and a
    /// progressive job's state (the f64 sum image).
    pub result_bytes: u64,
}

impl JobNeeds {
    /// An upper estimate of a render's peak memory: photons while traced and in their
    /// kd-trees (a global photon path stores at most a few photons: 3 per emitted photon
    /// bounds the built-in scenes' 1.35 with room), the irradiance cache, the film, the BVH.
    pub fn estimate(desc: &SceneDesc, p: &RenderParams) -> JobNeeds {
        let width = p.width.unwrap_or(desc.camera.width) as u64;
        let height = p.height.unwrap_or(desc.camera.height) as u64;
        let pixels = width * height;
        let triangles: usize = desc
            .objects
            .iter()
            .map(|o| match &o.shape {
                ShapeDesc::Mesh(m) => m.triangles.len(),
                _ => 1,
            })
            .sum();
        let photon_bytes = 32u64;
        let (global, caustic) = match p.integrator {
            IntegratorKind::Raytrace => (0, 0),
            // ppm: one pass's maps at a time, whatever the number of passes.
            IntegratorKind::Photon | IntegratorKind::Ppm => (p.photons * 3, p.caustic_photons),
        };
        // Traced photons are gathered in per-chunk buffers, then copied into the map.
        let maps = (global + caustic) * photon_bytes * 2;
        let irradiance = global / 4 * 64;
        // The camera pass's tiles and image, the images' encodings (PNG, EXR); a progressive
        // job adds its f64 sum, a pass's image and the saved state. Measured on the largest
        // images the test limits accept (tests/server/memory.rs): 36 and 75 bytes a pixel.
        let film = pixels * 48
            + if p.integrator == IntegratorKind::Ppm {
                pixels * 48
            } else {
                0
            };
        // Measured on the largest mesh the test limits accept (tests/server/memory.rs): the
        // scene's parsed JSON and description, primitives, the BVH's build, all alive at
        // once in the submit handler and the job's start, about 900 bytes a triangle.
        let geometry = triangles as u64 * 1200;
        JobNeeds {
            pixels,
            triangles,
            memory_bytes: maps + irradiance + film + geometry + (16 << 20),
            work: Self::work(pixels, p),
            result_bytes: pixels * 20
                + if p.integrator == IntegratorKind::Ppm {
                    pixels * 24
                } else {
                    0
                }
                + (64 << 10),
        }
    }

    fn work(pixels: u64, p: &RenderParams) -> f64 {
        let camera = pixels as f64 * p.spp as f64 * (1.0 + p.gather_rays as f64);
        let photons = match p.integrator {
            IntegratorKind::Raytrace => 0.0,
            IntegratorKind::Photon | IntegratorKind::Ppm => (p.photons + p.caustic_photons) as f64,
        };
        match p.integrator {
            IntegratorKind::Ppm => (camera + photons) * p.iterations as f64,
            IntegratorKind::Photon => camera + photons + p.photons as f64 / 4.0 * p.k as f64,
            IntegratorKind::Raytrace => camera,
        }
    }

    pub fn check(&self, p: &RenderParams, limits: &Limits) -> Result<(), ApiError> {
        // (field, what the job asks, the limit, what is counted)
        let counts: [(&str, u64, u64, &str); 6] = [
            (
                "params.width",
                self.pixels,
                limits.max_pixels,
                "pixels (width*height)",
            ),
            ("params.photons", p.photons, limits.max_photons, "photons"),
            (
                "params.caustic_photons",
                p.caustic_photons,
                limits.max_photons,
                "photons",
            ),
            (
                "params.k",
                p.k as u64,
                limits.max_k as u64,
                "neighbours (k)",
            ),
            (
                "params.iterations",
                p.iterations as u64,
                limits.max_iterations as u64,
                "passes",
            ),
            (
                "scene.objects",
                self.triangles as u64,
                limits.max_triangles as u64,
                "triangles",
            ),
        ];
        for (field, n, limit, what) in counts {
            if n > limit {
                return Err(ApiError::invalid(
                    field,
                    format!("{n} {what} exceed the limit of {limit}"),
                ));
            }
        }
        if self.work > limits.max_work {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "this job is an estimated {:.3e} ray samples of work (pixels x spp x (1 + \
                     gather_rays), photons, passes), more than the server's limit of {:.3e} \
                     (fewer samples, gather rays, pixels, photons or passes would fit)",
                    self.work, limits.max_work
                ),
            ));
        }
        if self.memory_bytes > limits.memory_bytes {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "this job needs an estimated {} MiB, more than the server's memory budget of {} MiB \
                     (fewer photons or pixels would fit)",
                    self.memory_bytes >> 20,
                    limits.memory_bytes >> 20
                ),
            ));
        }
        Ok(())
    }
}

/// The built-in scenes (`scenes/*.json`).
pub struct SceneCatalog {
    pub dir: PathBuf,
}

impl SceneCatalog {
    /// (name, description) of every built-in scene, sorted by name.
    pub fn list(&self) -> Vec<(String, Option<String>)> {
        let mut out = Vec::new();
        let Ok(entries) = std::fs::read_dir(&self.dir) else {
            return out;
        };
        for e in entries.flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "json")
                && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
            {
                let description = std::fs::read_to_string(&path)
                    .ok()
                    .and_then(|t| serde_json::from_str::<Value>(&t).ok())
                    .and_then(|v| v.get("description")?.as_str().map(str::to_string));
                out.push((stem.to_string(), description));
            }
        }
        out.sort();
        out
    }

    /// The path of a built-in scene, if `name` is one (names are plain file stems).
    pub fn path(&self, name: &str) -> Option<PathBuf> {
        let plain = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
        let p = self.dir.join(format!("{name}.json"));
        (plain && p.is_file()).then_some(p)
    }

    pub fn json(&self, name: &str) -> Option<Value> {
        let text = std::fs::read_to_string(self.path(name)?).ok()?;
        serde_json::from_str(&text).ok()
    }
}

/// The scene of a job: parsed and validated, with the texts the job is keyed by. Texts, not
/// the parsed JSON: a `serde_json::Value` of a large mesh takes about ten times its text,
/// and the render would carry it to the end.
pub struct ResolvedScene {
    pub desc: SceneDesc,
    /// The scene's JSON as compact text, keys sorted (serde_json's maps are): canonical. An
    /// uploaded scene is stored as it; a progressive job's state is fingerprinted by it.
    pub text: String,
    /// The SHA-256 of the same text without `camera`, `name` and `description`: what the
    /// photon-map cache key is made from ([`cache_key`]).
    pub without_camera: String,
    pub name: Option<String>,
}

/// `value`'s canonical text, and a hash of that text without the keys that do not shape
/// photon maps.
fn canonical_texts(value: &mut Value) -> (String, String) {
    let text = value.to_string();
    let mut taken = Vec::new();
    if let Some(obj) = value.as_object_mut() {
        for key in ["camera", "name", "description"] {
            if let Some(v) = obj.remove(key) {
                taken.push((key, v));
            }
        }
    }
    let without_camera = super::auth::sha256_hex(value.to_string().as_bytes());
    if let Some(obj) = value.as_object_mut() {
        for (key, v) in taken {
            obj.insert(key.to_string(), v);
        }
    }
    (text, without_camera)
}

/// Resolve a job's scene: a built-in by name, or an uploaded one (which may not reference
/// files: `obj` meshes are for built-in scenes).
pub fn resolve_scene(
    catalog: &SceneCatalog,
    scene: Option<Value>,
    scene_name: Option<&str>,
) -> Result<ResolvedScene, ApiError> {
    match (scene, scene_name) {
        (Some(_), Some(_)) => Err(ApiError::invalid(
            "scene_name",
            "give either scene or scene_name, not both",
        )),
        (None, None) => Err(ApiError::invalid(
            "scene",
            "missing: give a scene object or a built-in scene_name",
        )),
        (None, Some(name)) => {
            let path = catalog.path(name).ok_or_else(|| {
                ApiError::invalid("scene_name", format!("no built-in scene named {name:?}"))
            })?;
            let internal = |e: &dyn std::fmt::Display| {
                ApiError::internal(format!("built-in scene {name}: {e}"))
            };
            let text = std::fs::read_to_string(&path).map_err(|e| internal(&e))?;
            let mut json: Value = serde_json::from_str(&text).map_err(|e| internal(&e))?;
            let (text, without_camera) = canonical_texts(&mut json);
            let desc = SceneDesc::from_value(json, path.parent()).map_err(|e| internal(&e))?;
            Ok(ResolvedScene {
                desc,
                text,
                without_camera,
                name: Some(name.to_string()),
            })
        }
        (Some(mut value), None) => {
            let (text, without_camera) = canonical_texts(&mut value);
            let desc = SceneDesc::from_value(value, None)
                .map_err(|e| ApiError::invalid(scene_path(&e.path), e.message))?;
            let name = desc.name.clone();
            Ok(ResolvedScene {
                desc,
                text,
                without_camera,
                name,
            })
        }
    }
}

/// A scene error's path as a path into the request body.
fn scene_path(p: &str) -> String {
    if p == "scene" || p.starts_with("scene.") {
        p.to_string()
    } else {
        format!("scene.{p}")
    }
}

/// The photon-map cache key: a content hash of the scene without its camera, the
/// parameters that shape the maps, and the renderer's version.
pub fn cache_key(scene: &ResolvedScene, photon_params: &PhotonParams) -> String {
    let text = format!(
        "photonbox {}\n{}\n{:?}",
        env!("CARGO_PKG_VERSION"),
        scene.without_camera,
        photon_params
    );
    super::auth::sha256_hex(text.as_bytes())
}

/// Where a job's result files live: `png` and `exr` (the final image, or the latest
/// preview), and `ppmstate` (a progressive job's running state, while it may resume).
pub fn result_path(data: &Path, id: i64, ext: &str) -> PathBuf {
    data.join("results").join(format!("{id}.{ext}"))
}

/// Result files of jobs the store does not hold (it lost rows, or was replaced) are moved
/// to `results/orphaned/` and said loudly: never served as another job's, never deleted.
pub fn set_aside_orphans(data: &Path, ids: &std::collections::HashSet<i64>) {
    let dir = data.join("results");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    let mut moved = 0;
    // One folder a start, so that an earlier start's orphans are never overwritten.
    let orphaned = dir
        .join("orphaned")
        .join(format!("{:.0}", super::store::now() * 1e3));
    for e in entries.flatten() {
        let path = e.path();
        if !path.is_file() {
            continue;
        }
        let id = path
            .file_stem()
            .and_then(|s| s.to_str())
            .and_then(|s| s.parse::<i64>().ok());
        if id.is_none_or(|id| ids.contains(&id)) {
            continue; // not a result file (temporaries), or a known job's
        }
        let to = orphaned.join(e.file_name());
        match std::fs::create_dir_all(&orphaned).and_then(|_| std::fs::rename(&path, &to)) {
            Ok(()) => moved += 1,
            Err(err) => tracing::error!("setting aside {}: {err}", path.display()),
        }
    }
    if moved > 0 {
        tracing::error!(
            "the store and the data folder disagree: {moved} result files belong to no job in \
             the store (it lost rows?); moved to {}",
            orphaned.display()
        );
    }
}

/// Bytes a job's result files take on disk now.
pub fn result_bytes(data: &Path, id: i64) -> u64 {
    ["png", "exr", "ppmstate"]
        .iter()
        .filter_map(|ext| std::fs::metadata(result_path(data, id, ext)).ok())
        .map(|m| m.len())
        .sum()
}

/// Remove a job's result files (`which`: extensions, see [`result_path`]); missing ones are
/// fine.
pub fn remove_results(data: &Path, id: i64, which: &[&str]) {
    for ext in which {
        let _ = std::fs::remove_file(result_path(data, id, ext));
    }
}

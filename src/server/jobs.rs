//! What a job is: the request body, its parameters (the CLI's names in snake_case), the scene
//! it renders and the photon-map cache key. Limits and estimates: `needs.rs`; result files:
//! `results.rs`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::error::ApiError;
use crate::render::photon::PhotonParams;
use crate::render::scene::SceneDesc;
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

/// The built-in scenes (`scenes/*.json`), read once at start: the handlers that list and
/// show them never touch the file system.
pub struct SceneCatalog {
    dir: PathBuf,
    /// By name: the scene's JSON (None if it does not parse: it is listed, and refused when
    /// a job names it, with the reason).
    scenes: std::collections::BTreeMap<String, Option<Value>>,
}

impl SceneCatalog {
    pub fn load(dir: PathBuf) -> SceneCatalog {
        let mut scenes = std::collections::BTreeMap::new();
        for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "json")
                && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
                && plain_name(stem)
            {
                let json = std::fs::read_to_string(&path)
                    .ok()
                    .and_then(|t| serde_json::from_str::<Value>(&t).ok());
                scenes.insert(stem.to_string(), json);
            }
        }
        SceneCatalog { dir, scenes }
    }

    /// (name, description) of every built-in scene, sorted by name.
    pub fn list(&self) -> Vec<(String, Option<String>)> {
        self.scenes
            .iter()
            .map(|(name, json)| {
                let description = json
                    .as_ref()
                    .and_then(|v| v.get("description")?.as_str().map(str::to_string));
                (name.clone(), description)
            })
            .collect()
    }

    /// The path of a built-in scene, if `name` is one.
    pub fn path(&self, name: &str) -> Option<PathBuf> {
        self.scenes
            .contains_key(name)
            .then(|| self.dir.join(format!("{name}.json")))
    }

    pub fn json(&self, name: &str) -> Option<Value> {
        self.scenes.get(name)?.clone()
    }
}

/// Built-in scene names are plain file stems.
fn plain_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
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
            // Catalogued at start (its OBJ meshes are read from its folder now).
            let mut json = catalog
                .json(name)
                .ok_or_else(|| internal(&"not valid JSON"))?;
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

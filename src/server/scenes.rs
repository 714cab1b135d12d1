//! The scene a job renders: a built-in one (`scenes/*.json`, read, parsed and validated
//! once at start, so that no handler and no job reads a file for it) or an uploaded one
//! (validated at submit, its canonical text kept in the store). Either way, the job carries
//! the texts it is keyed by: its canonical text (a progressive job's state is fingerprinted
//! by it) and a hash of that text without the camera (the photon-map cache's key).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::Value;

use crate::render::SceneDesc;

/// Why a job's scene cannot be had: the path into the request that names the problem, or
/// an operator's problem (a built-in scene that does not load).
#[derive(Debug)]
pub enum SceneRefError {
    Invalid { path: String, message: String },
    Internal(String),
}

impl std::fmt::Display for SceneRefError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            SceneRefError::Invalid { path, message } => write!(f, "{path}: {message}"),
            SceneRefError::Internal(m) => f.write_str(m),
        }
    }
}

/// The scene of a job: parsed and validated, with the texts the job is keyed by. Texts, not
/// the parsed JSON: a `serde_json::Value` of a large mesh takes about ten times its text,
/// and the render would carry it to the end.
#[derive(Clone)]
pub struct ResolvedScene {
    pub desc: Arc<SceneDesc>,
    /// The scene's JSON as compact text, keys sorted (serde_json's maps are): canonical.
    pub text: Arc<str>,
    /// The SHA-256 of the same text without `camera`, `name` and `description`: what the
    /// photon-map cache key is made from (`cache::cache_key`).
    pub without_camera: String,
    pub name: Option<String>,
}

/// A built-in scene as catalogued at start.
struct Builtin {
    /// The file's JSON, served by `GET /api/scenes/{name}`.
    json: Value,
    /// The scene, or why it does not load (it is listed, and refused when a job names it).
    scene: Result<ResolvedScene, String>,
}

/// The built-in scenes, by name.
pub struct SceneCatalog {
    scenes: BTreeMap<String, Option<Builtin>>,
}

impl SceneCatalog {
    /// Read, parse and validate every `*.json` in `dir` (their OBJ meshes from `dir` too).
    pub fn load(dir: PathBuf) -> SceneCatalog {
        let mut scenes = BTreeMap::new();
        for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "json")
                && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
                && plain_name(stem)
            {
                scenes.insert(stem.to_string(), Builtin::read(&path, stem));
            }
        }
        SceneCatalog { scenes }
    }

    /// (name, description) of every built-in scene, sorted by name.
    pub fn list(&self) -> Vec<(String, Option<String>)> {
        self.scenes
            .iter()
            .map(|(name, b)| {
                let description = b
                    .as_ref()
                    .and_then(|b| b.json.get("description")?.as_str().map(str::to_string));
                (name.clone(), description)
            })
            .collect()
    }

    pub fn names(&self) -> Vec<String> {
        self.scenes.keys().cloned().collect()
    }

    /// The JSON of a built-in scene.
    pub fn json(&self, name: &str) -> Option<&Value> {
        Some(&self.scenes.get(name)?.as_ref()?.json)
    }

    /// A built-in scene, resolved.
    pub fn resolve(&self, name: &str) -> Result<ResolvedScene, SceneRefError> {
        match self.scenes.get(name) {
            None => Err(SceneRefError::Invalid {
                path: "scene_name".into(),
                message: format!("no built-in scene named {name:?}"),
            }),
            Some(None) => Err(SceneRefError::Internal(format!(
                "built-in scene {name}: not valid JSON"
            ))),
            Some(Some(b)) => b
                .scene
                .clone()
                .map_err(|e| SceneRefError::Internal(format!("built-in scene {name}: {e}"))),
        }
    }
}

impl Builtin {
    fn read(path: &Path, name: &str) -> Option<Builtin> {
        let text = std::fs::read_to_string(path).ok()?;
        let json: Value = serde_json::from_str(&text).ok()?;
        let mut value = json.clone();
        let (text, without_camera) = canonical_texts(&mut value);
        let scene = SceneDesc::from_value(value, path.parent())
            .map(|desc| ResolvedScene {
                desc: Arc::new(desc),
                text: text.into(),
                without_camera,
                name: Some(name.to_string()),
            })
            .map_err(|e| e.to_string());
        if let Err(e) = &scene {
            tracing::error!("built-in scene {}: {e}", path.display());
        }
        Some(Builtin { json, scene })
    }
}

/// Built-in scene names are plain file stems.
fn plain_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
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

/// An uploaded scene (which may not reference files: `obj` meshes are for built-in
/// scenes), validated, every error naming its path in the request (`scene.objects[3]...`).
pub fn resolve_uploaded(mut value: Value) -> Result<ResolvedScene, SceneRefError> {
    let (text, without_camera) = canonical_texts(&mut value);
    let desc = SceneDesc::from_value(value, None).map_err(|e| SceneRefError::Invalid {
        path: scene_path(&e.path),
        message: e.message,
    })?;
    let name = desc.name.clone();
    Ok(ResolvedScene {
        desc: Arc::new(desc),
        text: text.into(),
        without_camera,
        name,
    })
}

/// The scene of a request: exactly one of `scene` and `scene_name`.
pub fn resolve_request(
    catalog: &SceneCatalog,
    scene: Option<Value>,
    scene_name: Option<&str>,
) -> Result<ResolvedScene, SceneRefError> {
    let invalid = |path: &str, message: &str| SceneRefError::Invalid {
        path: path.into(),
        message: message.into(),
    };
    match (scene, scene_name) {
        (Some(_), Some(_)) => Err(invalid(
            "scene_name",
            "give either scene or scene_name, not both",
        )),
        (None, None) => Err(invalid(
            "scene",
            "missing: give a scene object or a built-in scene_name",
        )),
        (None, Some(name)) => catalog.resolve(name),
        (Some(value), None) => resolve_uploaded(value),
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

//! JSON text -> validated scene description, with every error naming its JSON path
//! (`objects[3].radius: expected a number`): the tagged unions dispatched by hand, typed
//! values made from JSON, OBJ files read. What makes a typed value valid is in `checks.rs`.

use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::de::DeserializeOwned;
use serde_json::Value;

use super::checks::{
    check_camera, check_mesh, check_phong, color, non_degenerate_pair, positive, reflectance,
};
use super::format::*;
use super::{LightDesc, MeshData, ObjectDesc, SceneDesc, SceneError, ShapeDesc};
use crate::render::material::Material;

pub(super) fn err(path: impl Into<String>, message: impl Into<String>) -> SceneError {
    SceneError {
        path: path.into(),
        message: message.into(),
    }
}

/// Join a parent path and a serde_path_to_error path ("." is the root).
fn join(prefix: &str, inner: &str) -> String {
    match (prefix.is_empty(), inner == "." || inner.is_empty()) {
        (true, true) => "scene".to_string(),
        (true, false) => inner.to_string(),
        (false, true) => prefix.to_string(),
        (false, false) => format!("{prefix}.{inner}"),
    }
}

/// Deserialize `value` as `T`, reporting errors with their full path under `prefix`.
fn typed<T: DeserializeOwned>(value: Value, prefix: &str) -> Result<T, SceneError> {
    serde_path_to_error::deserialize::<_, T>(value).map_err(|e| {
        let path = join(prefix, &e.path().to_string());
        err(path, e.into_inner().to_string())
    })
}

/// Split a tagged object into its `type` and the remaining fields.
fn tagged(value: Value, path: &str, allowed: &[&str]) -> Result<(String, Value), SceneError> {
    let Value::Object(mut map) = value else {
        return Err(err(path, "expected an object"));
    };
    let expected = allowed.join(", ");
    let tag = match map.remove("type") {
        Some(Value::String(s)) if allowed.contains(&s.as_str()) => s,
        Some(Value::String(s)) => {
            return Err(err(
                format!("{path}.type"),
                format!("unknown type \"{s}\" (expected one of: {expected})"),
            ));
        }
        Some(_) => {
            return Err(err(
                format!("{path}.type"),
                format!("expected a string (one of: {expected})"),
            ));
        }
        None => {
            return Err(err(
                format!("{path}.type"),
                format!("missing (expected one of: {expected})"),
            ));
        }
    };
    Ok((tag, Value::Object(map)))
}

pub(super) fn dvec(v: V3) -> DVec3 {
    DVec3::from_array(v.0)
}

pub(super) fn parse(text: &str, base_dir: Option<&Path>) -> Result<SceneDesc, SceneError> {
    let value: Value =
        serde_json::from_str(text).map_err(|e| err("scene", format!("invalid JSON: {e}")))?;
    parse_value(value, base_dir)
}

pub(super) fn parse_value(value: Value, base_dir: Option<&Path>) -> Result<SceneDesc, SceneError> {
    if !value.is_object() {
        return Err(err("scene", "expected a JSON object"));
    }
    let file: SceneFile = typed(value, "")?;
    let camera = check_camera(file.camera)?;

    let mut materials = Vec::new();
    let mut material_names = Vec::new();
    for (name, v) in file.materials {
        let path = format!("materials.{name}");
        materials.push(parse_material(v, &path)?);
        material_names.push(name);
    }

    let mut objects = Vec::new();
    for (i, v) in file.objects.into_iter().enumerate() {
        let path = format!("objects[{i}]");
        objects.push(parse_object(v, &path, &material_names, base_dir)?);
    }
    let mut lights = Vec::new();
    for (i, v) in file.lights.into_iter().enumerate() {
        lights.push(parse_light(v, &format!("lights[{i}]"))?);
    }
    Ok(SceneDesc {
        name: file.name,
        description: file.description,
        camera,
        materials,
        material_names,
        objects,
        lights,
    })
}

fn parse_material(v: Value, path: &str) -> Result<Material, SceneError> {
    let (tag, v) = tagged(v, path, &["diffuse", "mirror", "dielectric", "phong"])?;
    Ok(match tag.as_str() {
        "diffuse" => {
            let d: DiffuseDef = typed(v, path)?;
            Material::Diffuse {
                albedo: reflectance(d.albedo, format!("{path}.albedo"))?,
            }
        }
        "mirror" => {
            let d: MirrorDef = typed(v, path)?;
            Material::Mirror {
                reflectance: reflectance(d.reflectance, format!("{path}.reflectance"))?,
            }
        }
        "dielectric" => {
            let d: DielectricDef = typed(v, path)?;
            Material::Dielectric {
                ior: positive(d.ior, format!("{path}.ior"))? as f32,
            }
        }
        _ => {
            let d: PhongDef = typed(v, path)?;
            let diffuse = color(d.diffuse, format!("{path}.diffuse"))?;
            let specular = color(d.specular, format!("{path}.specular"))?;
            let exponent = d.exponent.0;
            check_phong(diffuse, specular, exponent, path)?;
            Material::Phong {
                diffuse,
                specular,
                exponent: exponent as f32,
            }
        }
    })
}

fn material_index(name: &str, names: &[String], path: &str) -> Result<u32, SceneError> {
    names
        .iter()
        .position(|n| n == name)
        .map(|i| i as u32)
        .ok_or_else(|| {
            err(
                format!("{path}.material"),
                format!(
                    "unknown material \"{name}\" (defined: {})",
                    names.join(", ")
                ),
            )
        })
}

fn parse_object(
    v: Value,
    path: &str,
    names: &[String],
    base_dir: Option<&Path>,
) -> Result<ObjectDesc, SceneError> {
    let (tag, v) = tagged(v, path, &["sphere", "quad", "mesh"])?;
    match tag.as_str() {
        "sphere" => {
            let d: SphereDef = typed(v, path)?;
            Ok(ObjectDesc {
                material: material_index(&d.material, names, path)?,
                shape: ShapeDesc::Sphere {
                    center: dvec(d.center),
                    radius: positive(d.radius, format!("{path}.radius"))?,
                },
            })
        }
        "quad" => {
            let d: QuadDef = typed(v, path)?;
            let (u, w) = (dvec(d.edge_u), dvec(d.edge_v));
            non_degenerate_pair(u, w, path, "quad: edge_u and edge_v are zero or parallel")?;
            Ok(ObjectDesc {
                material: material_index(&d.material, names, path)?,
                shape: ShapeDesc::Quad {
                    corner: dvec(d.corner),
                    edge_u: u,
                    edge_v: w,
                },
            })
        }
        _ => {
            let d: MeshDef = typed(v, path)?;
            let material = material_index(&d.material, names, path)?;
            let mesh = match (d.obj, d.positions, d.triangles) {
                (Some(obj), None, None) => load_obj(&obj, path, base_dir)?,
                (None, Some(p), Some(t)) => MeshData {
                    positions: p.into_iter().map(dvec).collect(),
                    triangles: t,
                },
                _ => {
                    return Err(err(
                        path,
                        "a mesh needs either \"obj\" or both \"positions\" and \"triangles\"",
                    ));
                }
            };
            check_mesh(&mesh, path)?;
            Ok(ObjectDesc {
                material,
                shape: ShapeDesc::Mesh(mesh),
            })
        }
    }
}

/// Load a Wavefront OBJ file given relative to the scene's folder; it may not leave it.
fn load_obj(rel: &str, path: &str, base_dir: Option<&Path>) -> Result<MeshData, SceneError> {
    let opath = format!("{path}.obj");
    let Some(base) = base_dir else {
        return Err(err(opath, "obj files need a scene loaded from a folder"));
    };
    let rel_path = Path::new(rel);
    if rel_path.is_absolute() {
        return Err(err(opath, "must be a path relative to the scene's folder"));
    }
    let base = base
        .canonicalize()
        .map_err(|e| err(&opath, format!("cannot resolve the scene folder: {e}")))?;
    let full: PathBuf = base
        .join(rel_path)
        .canonicalize()
        .map_err(|e| err(&opath, format!("cannot read \"{rel}\": {e}")))?;
    if !full.starts_with(&base) {
        return Err(err(
            opath,
            format!("\"{rel}\" is outside the scene's folder"),
        ));
    }
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let file = std::fs::File::open(&full)
        .map_err(|e| err(&opath, format!("cannot read \"{rel}\": {e}")))?;
    // Material libraries (`mtllib`) are never opened: they could name any file, and the
    // scene's materials come from its JSON.
    let no_materials = |_: &Path| -> tobj::MTLLoadResult { Ok((Vec::new(), Default::default())) };
    let (models, _) = tobj::load_obj_buf(&mut std::io::BufReader::new(file), &opts, no_materials)
        .map_err(|e| err(&opath, format!("cannot load \"{rel}\": {e}")))?;
    let mut mesh = MeshData {
        positions: Vec::new(),
        triangles: Vec::new(),
    };
    for m in models {
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(
            m.mesh
                .positions
                .chunks_exact(3)
                .map(|p| DVec3::new(p[0], p[1], p[2])),
        );
        mesh.triangles.extend(
            m.mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }
    if mesh
        .positions
        .iter()
        .any(|p| !p.is_finite() || !(p.as_vec3().is_finite()))
    {
        return Err(err(
            opath,
            format!("\"{rel}\" has non-finite vertex positions"),
        ));
    }
    Ok(mesh)
}

fn parse_light(v: Value, path: &str) -> Result<LightDesc, SceneError> {
    let (tag, v) = tagged(v, path, &["point", "sphere", "quad"])?;
    match tag.as_str() {
        "point" => {
            let d: PointLightDef = typed(v, path)?;
            Ok(LightDesc::Point {
                position: dvec(d.position),
                power: color(d.power, format!("{path}.power"))?,
            })
        }
        "sphere" => {
            let d: SphereLightDef = typed(v, path)?;
            Ok(LightDesc::Sphere {
                center: dvec(d.center),
                radius: positive(d.radius, format!("{path}.radius"))?,
                radiance: color(d.radiance, format!("{path}.radiance"))?,
            })
        }
        _ => {
            let d: QuadLightDef = typed(v, path)?;
            let (u, w) = (dvec(d.edge_u), dvec(d.edge_v));
            non_degenerate_pair(
                u,
                w,
                path,
                "quad light: edge_u and edge_v are zero or parallel",
            )?;
            Ok(LightDesc::Quad {
                corner: dvec(d.corner),
                edge_u: u,
                edge_v: w,
                radiance: color(d.radiance, format!("{path}.radiance"))?,
            })
        }
    }
}

//! Scenes: the JSON format (`format`), its validation (`load`, with the semantic checks in
//! `checks`), and the immutable [`Scene`] the renderer reads.
//!
//! The loader works in f64 and hands the engine f32 coordinates relative to the centre of the
//! scene's bounds. With no absolute epsilon anywhere (see `geometry`), this makes an image
//! independent of where the scene sits in space and of its scale.

mod build;
mod checks;
mod enclosure;
mod format;
mod load;

use std::path::Path;

use glam::{DVec3, Vec3A};
use serde_json::Value;

pub use format::CameraDef;

use crate::render::camera::Camera;
use crate::render::control::{Cancelled, Control};
use crate::render::geometry::{Accel, Hit, PrimHit, PrimId, Ray, Surface};
use crate::render::light::Light;
use crate::render::material::Material;
use crate::render::math::Rgb;

/// A scene the loader rejected: the JSON path of the offending value and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {}", one_line(.path), one_line(.message))]
pub struct SceneError {
    pub path: String,
    pub message: String,
}

/// Control characters escaped (`\n`, `\u{1b}`), so that an error quoting a name from the
/// scene file (a material called "a\nb") stays one line (found by tests/parser_fuzz.rs).
fn one_line(s: &str) -> String {
    s.chars()
        .flat_map(|c| {
            if c.is_control() {
                c.escape_default().collect::<Vec<_>>()
            } else {
                vec![c]
            }
        })
        .collect()
}

/// A validated scene in world coordinates (f64), as the JSON describes it.
#[derive(Debug)]
pub struct SceneDesc {
    pub name: Option<String>,
    pub description: Option<String>,
    pub camera: CameraDef,
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    pub objects: Vec<ObjectDesc>,
    pub lights: Vec<LightDesc>,
}

#[derive(Debug)]
pub struct ObjectDesc {
    pub material: u32,
    pub shape: ShapeDesc,
}

#[derive(Debug)]
pub enum ShapeDesc {
    Sphere {
        center: DVec3,
        radius: f64,
    },
    Quad {
        corner: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
    },
    Mesh(MeshData),
}

#[derive(Debug)]
pub struct MeshData {
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

#[derive(Debug)]
pub enum LightDesc {
    Point {
        position: DVec3,
        power: Rgb,
    },
    Sphere {
        center: DVec3,
        radius: f64,
        radiance: Rgb,
    },
    Quad {
        corner: DVec3,
        edge_u: DVec3,
        edge_v: DVec3,
        radiance: Rgb,
    },
}

impl SceneDesc {
    pub fn parse(text: &str, base_dir: Option<&Path>) -> Result<SceneDesc, SceneError> {
        load::parse(text, base_dir)
    }

    pub fn from_value(value: Value, base_dir: Option<&Path>) -> Result<SceneDesc, SceneError> {
        load::parse_value(value, base_dir)
    }

    /// Read and parse a scene file; `obj` paths resolve against its folder.
    pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
        Ok(SceneDesc::load_with_source(path)?.0)
    }

    /// [`SceneDesc::load`], also returning the file's text (which identifies the scene).
    pub fn load_with_source(path: &Path) -> Result<(SceneDesc, String), SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            path: "scene".into(),
            message: format!("cannot read {}: {e}", path.display()),
        })?;
        let dir = path.parent().map(|d| {
            if d.as_os_str().is_empty() {
                Path::new(".")
            } else {
                d
            }
        });
        Ok((load::parse(&text, dir)?, text))
    }

    /// Axis-aligned bounds of the objects, and of the lights too if `with_lights` (the
    /// camera excluded).
    fn bounds(&self, with_lights: bool) -> Option<(DVec3, DVec3)> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut add = |p: DVec3| {
            lo = lo.min(p);
            hi = hi.max(p);
        };
        let add_quad = |c: DVec3, u: DVec3, v: DVec3, add: &mut dyn FnMut(DVec3)| {
            for p in [c, c + u, c + v, c + u + v] {
                add(p);
            }
        };
        for o in &self.objects {
            match &o.shape {
                ShapeDesc::Sphere { center, radius } => {
                    add(*center - *radius);
                    add(*center + *radius);
                }
                ShapeDesc::Quad {
                    corner,
                    edge_u,
                    edge_v,
                } => add_quad(*corner, *edge_u, *edge_v, &mut add),
                ShapeDesc::Mesh(m) => m.positions.iter().for_each(|p| add(*p)),
            }
        }
        for l in self.lights.iter().filter(|_| with_lights) {
            match l {
                LightDesc::Point { position, .. } => add(*position),
                LightDesc::Sphere { center, radius, .. } => {
                    add(*center - *radius);
                    add(*center + *radius);
                }
                LightDesc::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    ..
                } => add_quad(*corner, *edge_u, *edge_v, &mut add),
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }
}

/// The immutable scene the renderer reads: f32 geometry relative to `frame_origin`, a BVH,
/// materials and lights. Shared between threads by reference.
pub struct Scene {
    pub name: Option<String>,
    pub camera: Camera,
    pub materials: Vec<Material>,
    pub material_names: Vec<String>,
    pub lights: Vec<Light>,
    pub accel: Accel,
    /// World position of the engine frame's origin (the centre of the scene bounds).
    pub frame_origin: DVec3,
    /// Bounds of objects and lights in the engine frame.
    pub bounds_min: Vec3A,
    pub bounds_max: Vec3A,
    /// Diagonal of the objects' bounds (of everything, if there are no objects): the scene's
    /// own length scale, which search radii are fractions of. Lights are left out so that a
    /// distant light does not widen every photon search.
    pub geometry_extent: f32,
    pub triangle_count: usize,
    /// Bounds of the specular objects, which caustic photons are aimed at.
    pub caustic_targets: crate::render::photon::CausticTargets,
    /// For each light, the closed opaque object (index into the scene's `objects`) that
    /// shuts it in while the camera is outside, if any: such a light emits no photons.
    pub shut_in: Vec<Option<usize>>,
}

impl Scene {
    pub fn parse(text: &str, base_dir: Option<&Path>) -> Result<Scene, SceneError> {
        Ok(Scene::build(&SceneDesc::parse(text, base_dir)?))
    }

    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Ok(Scene::build(&SceneDesc::load(path)?))
    }

    /// [`Scene::load`], also returning the file's text (which identifies the scene).
    pub fn load_with_source(path: &Path) -> Result<(Scene, String), SceneError> {
        let (desc, text) = SceneDesc::load_with_source(path)?;
        Ok((Scene::build(&desc), text))
    }

    /// [`Scene::build_with`] with no progress or cancel hooks.
    pub fn build(desc: &SceneDesc) -> Scene {
        match Scene::build_with(desc, &Control::none()) {
            Ok(scene) => scene,
            Err(Cancelled) => unreachable!("no cancel flag"),
        }
    }

    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.accel.intersect(ray)
    }

    /// The primitives up to four rays meet first (None: an idle lane), for
    /// [`Scene::hit_point`]: [`Scene::intersect`] four at a time.
    #[inline]
    pub fn closest4(&self, rays: [Option<&Ray>; 4]) -> [Option<PrimHit>; 4] {
        self.accel.closest4(rays)
    }

    /// The full hit (surface point with its error bound) of `ray`'s closest primitive `c`.
    #[inline]
    pub fn hit_point(&self, ray: &Ray, c: PrimHit) -> Hit {
        self.accel.hit_point(ray, c)
    }

    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.accel.occluded(ray)
    }

    #[inline]
    pub fn surface(&self, prim: PrimId) -> Surface {
        self.accel.prims()[prim as usize].surface
    }

    /// Whether `p`, on primitive `prim`, lies within `r` of its edges (`Shape::near_boundary`).
    pub fn near_boundary(&self, prim: PrimId, p: Vec3A, r: f32) -> bool {
        self.accel.prims()[prim as usize].shape.near_boundary(p, r)
    }

    /// The scene's length scale (see `geometry_extent`).
    pub fn extent(&self) -> f32 {
        self.geometry_extent
    }
}

//! [`Scene::build_with`]: a validated description -> the immutable [`Scene`] (recentring,
//! primitives, BVH, lights, camera, caustic targets, lights shut in).

use glam::{DVec3, Vec3A};

use super::{LightDesc, Scene, SceneDesc, ShapeDesc, enclosure};
use crate::render::camera::Camera;
use crate::render::control::{Cancelled, Control, Phase, Tracker};
use crate::render::geometry::{Accel, NO_PRIM, PrimId, Primitive, Shape, Surface};
use crate::render::light::Light;
use crate::render::photon::CausticTargets;

/// Progress units of the stages after the primitives: BVH, lights, caustic targets,
/// enclosure.
const STAGES: u64 = 4;

/// A point in the engine frame: f32 coordinates relative to `origin`, the centre of the
/// objects' bounds.
fn to_local(origin: DVec3) -> impl Fn(DVec3) -> Vec3A {
    move |p: DVec3| (p - origin).as_vec3a()
}

/// A vector (an edge) in the engine frame: no shift, only f32.
fn vec(v: DVec3) -> Vec3A {
    v.as_vec3a()
}

impl Scene {
    /// Build the scene, reporting [`Phase::BuildScene`] progress (one unit a stage, and the
    /// primitives a unit an object) and checking `control`'s cancel flag between stages and
    /// objects: a scene of a million triangles takes seconds, and a server job cancelled
    /// while it loads must stop there. Every stage is O(n log n) in the scene's size
    /// (the BVH whatever the geometry's shape: `geometry/degenerate.rs`).
    pub fn build_with(desc: &SceneDesc, control: &Control) -> Result<Scene, Cancelled> {
        control.check()?;
        let tracker = control.tracker(Phase::BuildScene, desc.objects.len() as u64 + STAGES);
        let (lo, hi) = desc.bounds(true).unwrap_or((DVec3::ZERO, DVec3::ZERO));
        // The objects' bounds (everything's, if there are none) give the scene's length
        // scale and the engine frame's centre. Not the lights': a distant light (a sun at
        // 1e9) must not move the origin away from the geometry, where f32 would leave the
        // scene units apart (found by tests/parser_fuzz.rs).
        let (geo_lo, geo_hi) = desc.bounds(false).unwrap_or((lo, hi));
        let geometry_extent = (geo_hi - geo_lo).length() as f32;
        let origin = (geo_lo + geo_hi) * 0.5;
        let local = to_local(origin);

        let (mut prims, triangle_count) = object_primitives(desc, origin, control, &tracker)?;
        push_light_primitives(desc, origin, &mut prims);
        control.check()?;
        let accel = Accel::build(prims);
        tracker.advance(1);
        control.check()?;
        let lights = lights(desc, origin, &accel);
        tracker.advance(1);
        control.check()?;
        let camera = camera(desc, origin, geometry_extent);
        let caustic_targets = CausticTargets::from_desc(desc, origin);
        tracker.advance(1);
        let shut_in = enclosure::shut_lights(desc, control)?;
        tracker.finish();
        Ok(Scene {
            name: desc.name.clone(),
            camera,
            materials: desc.materials.clone(),
            material_names: desc.material_names.clone(),
            lights,
            accel,
            frame_origin: origin,
            bounds_min: local(lo),
            bounds_max: local(hi),
            geometry_extent,
            triangle_count,
            caustic_targets,
            shut_in,
        })
    }
}

/// The objects' primitives in the engine frame centred on `origin`, in the order of
/// `desc.objects` (a mesh's triangles in its order), and how many are triangles. A unit of
/// progress and a cancel check an object.
fn object_primitives(
    desc: &SceneDesc,
    origin: DVec3,
    control: &Control,
    tracker: &Tracker,
) -> Result<(Vec<Primitive>, usize), Cancelled> {
    let local = to_local(origin);
    let mut prims = Vec::new();
    let mut triangle_count = 0;
    for o in &desc.objects {
        control.check()?;
        tracker.advance(1);
        let surface = Surface::Material(o.material);
        match &o.shape {
            ShapeDesc::Sphere { center, radius } => {
                prims.push(sphere(origin, *center, *radius, surface))
            }
            ShapeDesc::Quad {
                corner,
                edge_u,
                edge_v,
            } => prims.push(quad(origin, *corner, *edge_u, *edge_v, surface)),
            ShapeDesc::Mesh(m) => {
                let pos: Vec<Vec3A> = m.positions.iter().map(|p| local(*p)).collect();
                triangle_count += m.triangles.len();
                prims.extend(m.triangles.iter().map(|t| Primitive {
                    shape: Shape::Triangle {
                        p0: pos[t[0] as usize],
                        p1: pos[t[1] as usize],
                        p2: pos[t[2] as usize],
                    },
                    surface,
                }));
            }
        }
    }
    Ok((prims, triangle_count))
}

/// The area lights' shapes, after the objects: what a ray hits when it sees a light.
fn push_light_primitives(desc: &SceneDesc, origin: DVec3, prims: &mut Vec<Primitive>) {
    for (i, l) in desc.lights.iter().enumerate() {
        let surface = Surface::Light(i as u32);
        match l {
            LightDesc::Point { .. } => {}
            LightDesc::Sphere { center, radius, .. } => {
                prims.push(sphere(origin, *center, *radius, surface))
            }
            LightDesc::Quad {
                corner,
                edge_u,
                edge_v,
                ..
            } => prims.push(quad(origin, *corner, *edge_u, *edge_v, surface)),
        }
    }
}

/// A sphere's primitive in the engine frame.
fn sphere(origin: DVec3, center: DVec3, radius: f64, surface: Surface) -> Primitive {
    Primitive {
        shape: Shape::Sphere {
            center: to_local(origin)(center),
            radius: radius as f32,
        },
        surface,
    }
}

/// A quad's primitive in the engine frame.
fn quad(origin: DVec3, corner: DVec3, edge_u: DVec3, edge_v: DVec3, surface: Surface) -> Primitive {
    Primitive {
        shape: Shape::quad(to_local(origin)(corner), vec(edge_u), vec(edge_v)),
        surface,
    }
}

/// The lights in the engine frame, each area light with the id of its primitive in `accel`.
fn lights(desc: &SceneDesc, origin: DVec3, accel: &Accel) -> Vec<Light> {
    let local = to_local(origin);
    let mut light_prims = vec![NO_PRIM; desc.lights.len()];
    for (id, p) in accel.prims().iter().enumerate() {
        if let Surface::Light(l) = p.surface {
            light_prims[l as usize] = id as PrimId;
        }
    }
    let prim_of_light = |i: usize| light_prims[i];
    desc.lights
        .iter()
        .enumerate()
        .map(|(i, l)| match l {
            LightDesc::Point { position, power } => Light::Point {
                position: local(*position),
                power: *power,
            },
            LightDesc::Sphere {
                center,
                radius,
                radiance,
            } => Light::Sphere {
                center: local(*center),
                radius: *radius as f32,
                radiance: *radiance,
                prim: prim_of_light(i),
            },
            LightDesc::Quad {
                corner,
                edge_u,
                edge_v,
                radiance,
            } => {
                let c = vec(*edge_u).cross(vec(*edge_v));
                Light::Quad {
                    corner: local(*corner),
                    edge_u: vec(*edge_u),
                    edge_v: vec(*edge_v),
                    n: c.normalize(),
                    area: c.length(),
                    radiance: *radiance,
                    prim: prim_of_light(i),
                }
            }
        })
        .collect()
}

/// The camera in the engine frame, its view direction found in f64.
fn camera(desc: &SceneDesc, origin: DVec3, geometry_extent: f32) -> Camera {
    let local = to_local(origin);
    let c = &desc.camera;
    // The view direction in f64: a camera 1e-3 from what it looks at, 1e5 from the
    // origin, still has one. The point looked at is placed at the position's own scale.
    let position = DVec3::from_array(c.position.0);
    let forward = (DVec3::from_array(c.look_at.0) - position).normalize();
    let reach = (position - origin).length() + geometry_extent as f64 + 1.0;
    Camera::new(
        local(position),
        local(position + forward * reach),
        DVec3::from_array(c.up.0).as_vec3a(),
        c.fov.0 as f32,
        c.width,
        c.height,
    )
}

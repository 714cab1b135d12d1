//! Lights shut inside a closed opaque object that the camera is outside of. Nothing such a
//! light emits can reach what the camera sees, so it emits no photons (issue 5: "no photons
//! from a light that cannot reach anything the camera can see").
//!
//! Closed objects are spheres and watertight meshes (every edge shared by exactly two
//! triangles, in opposite directions), of any material but glass, which lets light out. A
//! box of six quads is not recognised (quads are open surfaces), nor are meshes whose
//! vertices are not shared between faces: the test errs on the side of emitting photons.
//! Answers are exact in f64 with margins, and a point whose parity rays disagree counts as
//! neither inside nor outside, so a doubtful case never switches a light off.

use std::collections::HashMap;

use glam::DVec3;

use super::{LightDesc, MeshData, SceneDesc, ShapeDesc};
use crate::render::control::{Cancelled, Control};
use crate::render::material::Material;

/// Relative margin within which a point counts as on a sphere (neither inside nor out).
const SPHERE_MARGIN: f64 = 1e-9;

/// Tests the analysis may take in all (about half a second): one per (light, object) pair,
/// and three per triangle for a point-in-mesh test. A scene of a few megabytes could
/// otherwise ask for lights x triangles of them (100,000 point lights in a mesh of 80,000
/// triangles: minutes) or lights x objects (70,000 of each: seconds). Past it, a light is
/// not looked for any further, the side this analysis errs on (it emits photons); the
/// count, not a clock, decides, so the answer is the same on every run.
const PARITY_BUDGET: u64 = 1 << 26;

/// For each light, the index of a closed opaque object that holds it while the camera is
/// outside, if any. The cancel flag is checked for each (light, object) pair.
pub fn shut_lights(desc: &SceneDesc, control: &Control) -> Result<Vec<Option<usize>>, Cancelled> {
    let camera = DVec3::from_array(desc.camera.position.0);
    let mut meshes = MeshTests {
        camera,
        known: HashMap::new(),
        spent: 0,
    };
    let mut shut = Vec::with_capacity(desc.lights.len());
    for light in &desc.lights {
        let mut holder = None;
        for (i, o) in desc.objects.iter().enumerate() {
            control.check()?;
            if meshes.spent >= PARITY_BUDGET {
                break;
            }
            meshes.spent += 1;
            if matches!(
                desc.materials[o.material as usize],
                Material::Dielectric { .. }
            ) {
                continue;
            }
            let holds = match (&o.shape, light) {
                (ShapeDesc::Sphere { center, radius }, _) => {
                    sphere_holds(*center, *radius, light)
                        && sphere_side(*center, *radius, camera) == Some(false)
                }
                (ShapeDesc::Mesh(m), LightDesc::Point { position, .. }) => {
                    meshes.holds(i, m, *position)
                }
                _ => false,
            };
            if holds {
                holder = Some(i);
                break;
            }
        }
        shut.push(holder);
    }
    Ok(shut)
}

/// Point-in-mesh tests, with what each mesh's tests share worked out once: its bounds, and
/// whether it can hold a light away from the camera at all (watertight, the camera
/// outside).
struct MeshTests {
    camera: DVec3,
    /// Per object index: the mesh's bounds, and whether it can shut a light in.
    known: HashMap<usize, ((DVec3, DVec3), bool)>,
    /// Tests done so far (pairs and triangles), against [`PARITY_BUDGET`].
    spent: u64,
}

impl MeshTests {
    /// Whether mesh `m` (object `i`) holds point `p` while the camera is outside it.
    fn holds(&mut self, i: usize, m: &MeshData, p: DVec3) -> bool {
        let cost = 3 * m.triangles.len() as u64;
        let (camera, spent) = (self.camera, &mut self.spent);
        let &mut (bounds, can_shut) = self.known.entry(i).or_insert_with(|| {
            let bounds = mesh_bounds(m);
            *spent += cost;
            // Cheap tests first: the watertightness check reads every edge.
            let can = mesh_side(m, bounds, camera) == Some(false) && is_watertight(m);
            (bounds, can)
        });
        if !can_shut || !within(bounds, p) || self.spent + cost > PARITY_BUDGET {
            return false;
        }
        self.spent += cost;
        mesh_side(m, bounds, p) == Some(true)
    }
}

/// Some(true) strictly inside the sphere, Some(false) strictly outside, None on it.
fn sphere_side(center: DVec3, radius: f64, p: DVec3) -> Option<bool> {
    let d = (p - center).length();
    if d < radius * (1.0 - SPHERE_MARGIN) {
        Some(true)
    } else if d > radius * (1.0 + SPHERE_MARGIN) {
        Some(false)
    } else {
        None
    }
}

/// The whole light strictly inside the sphere (spheres are convex: for a quad light, its
/// corners suffice).
fn sphere_holds(center: DVec3, radius: f64, light: &LightDesc) -> bool {
    let inside = |p: DVec3, r: f64| sphere_side(center, radius - r, p) == Some(true);
    match light {
        LightDesc::Point { position, .. } => inside(*position, 0.0),
        LightDesc::Sphere {
            center: c,
            radius: r,
            ..
        } => inside(*c, *r),
        LightDesc::Quad {
            corner,
            edge_u,
            edge_v,
            ..
        } => [
            *corner,
            *corner + *edge_u,
            *corner + *edge_v,
            *corner + *edge_u + *edge_v,
        ]
        .into_iter()
        .all(|p| inside(p, 0.0)),
    }
}

/// Every directed edge (a, b) has exactly one twin (b, a): a closed, consistently oriented
/// surface.
fn is_watertight(m: &MeshData) -> bool {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(m.triangles.len() * 3);
    for t in &m.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a, b)).or_default() += 1;
        }
    }
    edges
        .iter()
        .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}

/// Inside by the parity of crossings along three unrelated directions: Some(true) or
/// Some(false) when all three agree, None when they do not (a ray through an edge, a
/// point on the surface, an open mesh).
fn mesh_side(m: &MeshData, bounds: (DVec3, DVec3), p: DVec3) -> Option<bool> {
    const DIRS: [DVec3; 3] = [
        DVec3::new(0.5773, 0.6143, 0.5381),
        DVec3::new(-0.7072, 0.1211, 0.6966),
        DVec3::new(0.1830, -0.9511, 0.2487),
    ];
    if !within(bounds, p) {
        return Some(false);
    }
    let odd = |d: DVec3| {
        m.triangles
            .iter()
            .filter(|t| {
                let v = |i: usize| m.positions[t[i] as usize];
                crosses(p, d, v(0), v(1), v(2))
            })
            .count()
            % 2
            == 1
    };
    let first = odd(DIRS[0]);
    DIRS[1..].iter().all(|&d| odd(d) == first).then_some(first)
}

/// The smallest box around the mesh's vertices.
fn mesh_bounds(m: &MeshData) -> (DVec3, DVec3) {
    m.positions
        .iter()
        .fold((DVec3::MAX, DVec3::MIN), |(lo, hi), q| {
            (lo.min(*q), hi.max(*q))
        })
}

/// `p` within the box (its faces included).
fn within((lo, hi): (DVec3, DVec3), p: DVec3) -> bool {
    !(p.cmplt(lo).any() || p.cmpgt(hi).any())
}

/// The ray p + t d, t > 0, crosses triangle (a, b, c) (Moller and Trumbore 1997).
fn crosses(p: DVec3, d: DVec3, a: DVec3, b: DVec3, c: DVec3) -> bool {
    let (e1, e2) = (b - a, c - a);
    let q = d.cross(e2);
    let det = e1.dot(q);
    if det.abs() < 1e-300 {
        return false;
    }
    let s = p - a;
    let u = s.dot(q) / det;
    let r = s.cross(e1);
    let v = d.dot(r) / det;
    let t = e2.dot(r) / det;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0
}

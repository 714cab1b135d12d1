//! Caustic photons aimed at what can make caustics. A caustic path starts light -> specular,
//! so a photon matters to the caustic map only if its first ray meets a mirror or glass
//! object. Jensen (2001, section 5.2.1) keeps a "projection map" of the directions toward
//! specular objects; we use the equivalent in closed form: the cones that the objects'
//! bounding spheres subtend from the emission point. A direction is drawn from one cone
//! (each with probability 1/N), and the photon is weighted by the light's own direction pdf
//! over the mixture pdf of all cones containing the direction. No direction that can reach a
//! specular object has pdf 0 (the spheres bound the objects), so the caustic map stays
//! unbiased: as bright as with blind emission, with far more of its photons stored.

use glam::{DVec3, Vec2, Vec3A};

use crate::render::math::Frame;
use crate::render::sampling::{uniform_cone, uniform_sphere};
use crate::render::scene::{SceneDesc, ShapeDesc};

/// Bounding spheres of the scene's specular objects (engine frame).
#[derive(Clone, Debug, Default)]
pub struct CausticTargets {
    spheres: Vec<(Vec3A, f32)>,
}

/// A sampled direction toward the targets and its mixture pdf (per steradian).
#[derive(Clone, Copy, Debug)]
pub struct TargetedDirection {
    pub dir: Vec3A,
    pub pdf: f32,
}

/// Relative margin on the bounding spheres against f32 rounding at their rims.
const MARGIN: f64 = 1e-4;

/// More specular objects than this are aimed at as one: the sphere bounding all their
/// spheres. Each photon's pdf reads every target, so thousands of mirror triangles (each
/// its own object) would make tracing cost photons x objects; one bound keeps it O(1) and
/// still covers every direction toward a specular object, so the map stays unbiased.
const MAX_TARGETS: usize = 32;

/// Relative slack on the squared radii when culling photons that cannot meet a target.
const CULL_SLACK: f32 = 1e-3;

impl CausticTargets {
    /// Bounding spheres of the objects whose material is specular, `origin` being the
    /// engine frame's origin in world coordinates.
    pub fn from_desc(desc: &SceneDesc, origin: DVec3) -> CausticTargets {
        let mut spheres = Vec::new();
        for o in &desc.objects {
            if !desc.materials[o.material as usize].is_specular() {
                continue;
            }
            let (c, r) = match &o.shape {
                ShapeDesc::Sphere { center, radius } => (*center, *radius),
                ShapeDesc::Quad {
                    corner,
                    edge_u,
                    edge_v,
                } => {
                    let c = *corner + (*edge_u + *edge_v) * 0.5;
                    let r = (*edge_u + *edge_v)
                        .length()
                        .max((*edge_u - *edge_v).length())
                        * 0.5;
                    (c, r)
                }
                ShapeDesc::Mesh(m) => {
                    let lo = m.positions.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
                    let hi = m
                        .positions
                        .iter()
                        .fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
                    let c = (lo + hi) * 0.5;
                    let r = m
                        .positions
                        .iter()
                        .map(|p| (*p - c).length())
                        .fold(0.0, f64::max);
                    (c, r)
                }
            };
            let r = r * (1.0 + MARGIN) + MARGIN * (c - origin).abs().max_element();
            spheres.push(((c - origin).as_vec3a(), r as f32));
        }
        if spheres.len() > MAX_TARGETS {
            spheres = vec![bounding_sphere(&spheres)];
        }
        CausticTargets { spheres }
    }

    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    pub fn len(&self) -> usize {
        self.spheres.len()
    }

    /// The cone toward target `j` from `p`: (axis, 1 - cos of its half-angle), or the whole
    /// sphere (`None`) when `p` is inside the target's bound.
    #[inline]
    fn cone(&self, j: usize, p: Vec3A) -> Option<(Vec3A, f32)> {
        let (c, r) = self.spheres[j];
        let d = c - p;
        let d2 = d.length_squared();
        let r2 = r * r;
        if d2 <= r2 {
            return None;
        }
        let sin2 = r2 / d2;
        // 1 - cos = sin^2 / (1 + cos): keeps precision for small, distant targets.
        let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).sqrt());
        Some((d / d2.sqrt(), one_minus_cos))
    }

    /// Solid-angle pdf of the mixture at direction `dir` from `p`.
    pub fn pdf(&self, p: Vec3A, dir: Vec3A) -> f32 {
        let mut sum = 0.0;
        for j in 0..self.spheres.len() {
            sum += match self.cone(j, p) {
                None => 0.25 * std::f32::consts::FRAC_1_PI,
                Some((axis, omc)) if 1.0 - axis.dot(dir) <= omc => {
                    1.0 / (std::f32::consts::TAU * omc)
                }
                Some(_) => 0.0,
            };
        }
        sum / self.spheres.len() as f32
    }

    /// Whether a ray from `o` along unit `dir` may meet a specular object: false only if it
    /// misses every bounding sphere. A blindly emitted caustic photon that cannot meet one
    /// first ends, unstored, at its first (non-specular) hit, so it is left untraced: the
    /// caustic map is bit for bit what tracing it would give. (Blind emission is the seed's
    /// workload; at n = 100k on scene (1) about 95% of its photons are such.)
    #[inline]
    pub fn may_reach(&self, o: Vec3A, dir: Vec3A) -> bool {
        self.spheres.iter().any(|&(c, r)| {
            let to_c = c - o;
            // Extra slack for the rounding of these few operations.
            let r2 = r * r * (1.0 + CULL_SLACK);
            if to_c.length_squared() <= r2 {
                return true;
            }
            let along = to_c.dot(dir);
            along > 0.0 && (to_c - dir * along).length_squared() <= r2
        })
    }

    /// A direction from `p` toward one target picked by `u_pick` (uniformly), with its pdf.
    pub fn sample(&self, p: Vec3A, u_pick: f32, u: Vec2) -> TargetedDirection {
        let n = self.spheres.len();
        let j = ((u_pick * n as f32) as usize).min(n - 1);
        let dir = match self.cone(j, p) {
            None => uniform_sphere(u),
            Some((axis, omc)) => Frame::from_normal(axis).to_world(uniform_cone(u, omc)),
        };
        TargetedDirection {
            dir,
            pdf: self.pdf(p, dir),
        }
    }
}

/// A sphere holding all of `spheres` (centred on their boxes' centre; not the smallest).
fn bounding_sphere(spheres: &[(Vec3A, f32)]) -> (Vec3A, f32) {
    let (lo, hi) = spheres.iter().fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(c, r)| (lo.min(c - r), hi.max(c + r)),
    );
    let c = (lo + hi) * 0.5;
    let r = spheres
        .iter()
        .map(|&(ci, ri)| (ci - c).length() + ri)
        .fold(0.0f32, f32::max);
    (c, r * (1.0 + MARGIN as f32))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream};

    fn targets(spheres: &[(Vec3A, f32)]) -> CausticTargets {
        CausticTargets {
            spheres: spheres.to_vec(),
        }
    }

    #[test]
    fn many_targets_become_one_bound_holding_them_all() {
        let many: Vec<(Vec3A, f32)> = (0..100)
            .map(|i| (Vec3A::new(i as f32, (i % 3) as f32, 0.0), 0.25))
            .collect();
        let (c, r) = bounding_sphere(&many);
        for &(ci, ri) in &many {
            assert!((ci - c).length() + ri <= r, "{ci} {ri} outside {c} {r}");
        }
        assert!(r < 51.0, "{r}");
    }

    /// E[1 / pdf] over the mixture's samples is the solid angle of the union of the cones:
    /// for two disjoint cones, the sum of theirs.
    #[test]
    fn weights_integrate_to_the_covered_solid_angle() {
        let t = targets(&[
            (Vec3A::new(0.0, 0.0, 5.0), 1.0),
            (Vec3A::new(4.0, 0.0, 0.0), 0.5),
        ]);
        let solid = |d: f32, r: f32| {
            let s2 = (r / d).powi(2);
            std::f64::consts::TAU * (s2 / (1.0 + (1.0 - s2).sqrt())) as f64
        };
        let want = solid(5.0, 1.0) + solid(4.0, 0.5);
        let mut s = Sampler::new(1, Stream::Camera, 0);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let td = t.sample(Vec3A::ZERO, s.next_f32(), s.next_2d());
            assert!(td.pdf > 0.0);
            sum += 1.0 / td.pdf as f64;
        }
        let got = sum / n as f64;
        assert!((got / want - 1.0).abs() < 0.01, "{got} vs {want}");
    }

    /// Overlapping cones: the mixture pdf counts both, so the estimate is still the union's
    /// solid angle (here one cone inside the other: the larger one's).
    #[test]
    fn overlapping_cones_are_not_counted_twice() {
        let t = targets(&[
            (Vec3A::new(0.0, 0.0, 5.0), 2.0),
            (Vec3A::new(0.0, 0.0, 5.0), 0.5),
        ]);
        let s2 = (2.0f64 / 5.0).powi(2);
        let want = std::f64::consts::TAU * s2 / (1.0 + (1.0 - s2).sqrt());
        let mut s = Sampler::new(2, Stream::Camera, 0);
        let n = 200_000;
        let sum: f64 = (0..n)
            .map(|_| 1.0 / t.sample(Vec3A::ZERO, s.next_f32(), s.next_2d()).pdf as f64)
            .sum();
        let got = sum / n as f64;
        assert!((got / want - 1.0).abs() < 0.01, "{got} vs {want}");
    }

    /// No ray that meets a specular object is culled, whatever its origin (outside, near the
    /// rim, inside the bound), and most rays that miss are.
    #[test]
    fn culling_keeps_every_ray_that_meets_a_target() {
        use crate::render::geometry::{Ray, Shape};
        use crate::render::scene::SceneDesc;
        let json = serde_json::json!({
            "camera": {"position": [0, 1, 4], "look_at": [0, 1, 0], "up": [0, 1, 0], "fov": 40,
                       "width": 8, "height": 8},
            "materials": {"glass": {"type": "dielectric", "ior": 1.5},
                          "mirror": {"type": "mirror", "reflectance": [1, 1, 1]}},
            "objects": [
                {"type": "sphere", "material": "glass", "center": [0.3, 0.4, -0.2], "radius": 0.3},
                {"type": "quad", "material": "mirror", "corner": [-1, 0, -1],
                 "edge_u": [0.5, 0, 0], "edge_v": [0, 0.8, 0.1]}
            ],
            "lights": []
        });
        let desc = SceneDesc::parse(&json.to_string(), None).expect("a valid scene");
        let t = CausticTargets::from_desc(&desc, DVec3::ZERO);
        let shapes = [
            Shape::Sphere {
                center: Vec3A::new(0.3, 0.4, -0.2),
                radius: 0.3,
            },
            Shape::quad(
                Vec3A::new(-1.0, 0.0, -1.0),
                Vec3A::new(0.5, 0.0, 0.0),
                Vec3A::new(0.0, 0.8, 0.1),
            ),
        ];
        let mut s = Sampler::new(3, Stream::Camera, 0);
        let (mut hits, mut culled_misses, mut misses) = (0, 0, 0);
        for i in 0..200_000 {
            // Origins in and around the targets, some right on the sphere's rim.
            let o = if i % 4 == 0 {
                Vec3A::new(0.3, 0.4, -0.2) + uniform_sphere(s.next_2d()) * 0.3
            } else {
                Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32()) * 3.0 - Vec3A::splat(1.5)
            };
            let d = uniform_sphere(s.next_2d());
            let ray = Ray::new(o, d);
            let hit = shapes.iter().any(|sh| sh.intersect(&ray, 7).is_some());
            let reach = t.may_reach(o, d);
            if hit {
                hits += 1;
                assert!(
                    reach,
                    "ray {i} from {o} along {d} meets a target but was culled"
                );
            } else {
                misses += 1;
                culled_misses += (!reach) as u32;
            }
        }
        assert!(hits > 10_000, "{hits}");
        assert!(
            culled_misses as f64 > 0.5 * misses as f64,
            "{culled_misses} of {misses}"
        );
    }

    #[test]
    fn inside_a_bound_every_direction_is_possible() {
        let t = targets(&[(Vec3A::ZERO, 1.0)]);
        let td = t.sample(Vec3A::new(0.1, 0.0, 0.0), 0.3, Vec2::new(0.2, 0.7));
        assert!((td.pdf - 0.25 / std::f32::consts::PI).abs() < 1e-7);
    }
}

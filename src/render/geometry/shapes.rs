//! The closed set of shapes: sphere, quad (parallelogram) and triangle, with ray
//! intersection and a conservative error bound for every hit point. The sphere and quad
//! tests are here; the watertight triangle test, with its own arithmetic, in `triangle.rs`.

use glam::Vec3A;
use obvhs::aabb::Aabb;

use super::triangle::intersect_triangle;
use super::{PrimId, Ray, SurfacePoint};
use crate::render::math::gamma;

#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Sphere {
        center: Vec3A,
        radius: f32,
    },
    /// corner + s * edge_u + t * edge_v for s, t in [0, 1]; normal along cross(edge_u, edge_v).
    Quad {
        corner: Vec3A,
        edge_u: Vec3A,
        edge_v: Vec3A,
        /// Unit normal.
        n: Vec3A,
        /// With w = cross(edge_u, edge_v) / |cross(edge_u, edge_v)|^2, a point corner + rel
        /// of the plane has s = rel . cross(edge_v, w) and t = rel . cross(w, edge_u): the
        /// scalar triple products of RTOW's quad test, folded into two precomputed vectors.
        su: Vec3A,
        sv: Vec3A,
        /// n . corner: the plane's offset.
        plane: f32,
    },
    /// Counter-clockwise seen from the side the normal points to.
    Triangle {
        p0: Vec3A,
        p1: Vec3A,
        p2: Vec3A,
    },
}

/// What a primitive's surface does to light: scatter by a material, or emit (and absorb)
/// as a light's surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Surface {
    Material(u32),
    Light(u32),
}

#[derive(Clone, Copy, Debug)]
pub struct Primitive {
    pub shape: Shape,
    pub surface: Surface,
}

/// Where along the ray a shape was hit, plus the shape's own parameters of the hit.
#[derive(Clone, Copy, Debug)]
pub struct ShapeHit {
    pub t: f32,
    pub uv: [f32; 2],
}

impl Shape {
    pub fn quad(corner: Vec3A, edge_u: Vec3A, edge_v: Vec3A) -> Shape {
        let c = edge_u.cross(edge_v);
        let w = c / c.length_squared();
        let n = c.normalize();
        Shape::Quad {
            corner,
            edge_u,
            edge_v,
            n,
            su: edge_v.cross(w),
            sv: w.cross(edge_u),
            plane: n.dot(corner),
        }
    }

    /// Whether `p`, a point of this shape, lies within `r` of the shape's boundary, where a
    /// disc of radius `r` about it may reach past the surface: a quad's edges. A sphere has
    /// none; a triangle's edges are taken as shared with its mesh's neighbours.
    pub fn near_boundary(&self, p: Vec3A, r: f32) -> bool {
        match *self {
            // s and t grow by |su| and |sv| per unit of distance from the edges s = 0, t = 0.
            Shape::Quad { corner, su, sv, .. } => {
                let (s, t) = ((p - corner).dot(su), (p - corner).dot(sv));
                s.min(1.0 - s) < r * su.length() || t.min(1.0 - t) < r * sv.length()
            }
            Shape::Sphere { .. } | Shape::Triangle { .. } => false,
        }
    }

    pub fn bounds(&self) -> Aabb {
        match *self {
            Shape::Sphere { center, radius } => Aabb {
                min: center - Vec3A::splat(radius),
                max: center + Vec3A::splat(radius),
            },
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
                ..
            } => {
                let pts = [
                    corner,
                    corner + edge_u,
                    corner + edge_v,
                    corner + edge_u + edge_v,
                ];
                points_bounds(&pts)
            }
            Shape::Triangle { p0, p1, p2 } => points_bounds(&[p0, p1, p2]),
        }
    }

    /// The nearest hit in (0, ray.t_max), if any. `me` is this shape's id, compared against
    /// the ray's origin primitive to rule out self-intersection exactly (see module docs).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, me: PrimId) -> Option<ShapeHit> {
        if ray.target_prim == me {
            return None;
        }
        let from_me = ray.origin_prim == me;
        match *self {
            Shape::Sphere { center, radius } => intersect_sphere(center, radius, ray, from_me),
            Shape::Quad {
                corner,
                n,
                su,
                sv,
                plane,
                ..
            } => {
                if from_me {
                    return None;
                }
                intersect_quad(corner, n, su, sv, plane, ray)
            }
            Shape::Triangle { p0, p1, p2 } => {
                if from_me {
                    return None;
                }
                intersect_triangle(p0, p1, p2, ray)
            }
        }
    }

    /// The surface point of a hit found by [`Shape::intersect`], with its error bound.
    pub fn surface_point(&self, ray: &Ray, hit: &ShapeHit, prim: PrimId) -> SurfacePoint {
        match *self {
            Shape::Sphere { center, radius } => {
                // Re-project onto the sphere (pbrt-v4 6.8.5): the point is then exact to a few
                // ulps whatever the error of t.
                let local = ray.at(hit.t) - center;
                let local = local * (radius / local.length());
                let p = center + local;
                let p_error = gamma(5) * local.abs() + gamma(1) * p.abs();
                SurfacePoint {
                    p,
                    p_error,
                    n: local / radius,
                    prim,
                }
            }
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
                n,
                ..
            } => {
                let [s, t] = hit.uv;
                let (a, b) = (s * edge_u, t * edge_v);
                SurfacePoint {
                    p: corner + a + b,
                    p_error: gamma(4) * (corner.abs() + a.abs() + b.abs()),
                    n,
                    prim,
                }
            }
            Shape::Triangle { p0, p1, p2 } => {
                let [b1, b2] = hit.uv;
                let b0 = 1.0 - b1 - b2;
                let (a, b, c) = (b0 * p0, b1 * p1, b2 * p2);
                SurfacePoint {
                    p: a + b + c,
                    p_error: gamma(7) * (a.abs() + b.abs() + c.abs()),
                    n: (p1 - p0).cross(p2 - p0).normalize(),
                    prim,
                }
            }
        }
    }
}

fn points_bounds(pts: &[Vec3A]) -> Aabb {
    let mut min = Vec3A::splat(f32::INFINITY);
    let mut max = Vec3A::splat(f32::NEG_INFINITY);
    for p in pts {
        min = min.min(*p);
        max = max.max(*p);
    }
    Aabb { min, max }
}

/// Ray-sphere with the numerically careful discriminant of Haines et al., "Precision
/// Improvements for Ray/Sphere Intersection" (Ray Tracing Gems, ch. 7): b^2 - c is computed
/// as r^2 - |f - b d|^2, which stays accurate for spheres tiny or huge relative to their
/// distance. A ray leaving this sphere's own surface either goes outward (no hit possible:
/// the sphere is convex) or inward (only the far root is real).
#[inline]
fn intersect_sphere(center: Vec3A, radius: f32, ray: &Ray, from_me: bool) -> Option<ShapeHit> {
    let f = ray.o - center;
    let b = f.dot(ray.d);
    let r2 = radius * radius;
    let c = f.length_squared() - r2;
    // Leaving the sphere it starts on, or starting outside and moving away: no hit.
    if (from_me || c > 0.0) && b >= 0.0 {
        return None;
    }
    let l2 = (f - b * ray.d).length_squared();
    if l2 > r2 {
        return None;
    }
    let l = l2.sqrt();
    let disc = (radius - l) * (radius + l);
    let q = -b - disc.sqrt().copysign(b);
    let (t0, t1) = if q == 0.0 {
        (0.0, 0.0)
    } else {
        let (a, bb) = (c / q, q);
        if a < bb { (a, bb) } else { (bb, a) }
    };
    let t = if from_me {
        t1
    } else if t0 > 0.0 {
        t0
    } else {
        t1
    };
    (t > 0.0 && t < ray.t_max).then_some(ShapeHit { t, uv: [0.0, 0.0] })
}

#[inline]
fn intersect_quad(
    corner: Vec3A,
    n: Vec3A,
    su: Vec3A,
    sv: Vec3A,
    plane: f32,
    ray: &Ray,
) -> Option<ShapeHit> {
    let denom = n.dot(ray.d);
    if denom == 0.0 {
        return None;
    }
    let t = (plane - n.dot(ray.o)) / denom;
    if !(t > 0.0 && t < ray.t_max) {
        return None;
    }
    let rel = ray.at(t) - corner;
    let s = rel.dot(su);
    let v = rel.dot(sv);
    ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&v)).then_some(ShapeHit { t, uv: [s, v] })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::geometry::NO_PRIM;

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3A::from(o), Vec3A::from(d).normalize())
    }

    #[test]
    fn sphere_hits_near_side_from_outside_and_far_side_from_inside() {
        let s = Shape::Sphere {
            center: Vec3A::ZERO,
            radius: 1.0,
        };
        let h = s
            .intersect(&ray([0.0, 0.0, 5.0], [0.0, 0.0, -1.0]), 0)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-6);
        let h = s
            .intersect(&ray([0.0, 0.0, 0.5], [0.0, 0.0, -1.0]), 0)
            .unwrap();
        assert!((h.t - 1.5).abs() < 1e-6);
        assert!(
            s.intersect(&ray([0.0, 2.0, 5.0], [0.0, 0.0, -1.0]), 0)
                .is_none()
        );
    }

    #[test]
    fn sphere_tiny_and_huge_hit_points_lie_on_the_surface() {
        for &(r, dist) in &[(1e-3f32, 10.0f32), (1e4, 3e4)] {
            let s = Shape::Sphere {
                center: Vec3A::new(0.3 * r, 0.0, 0.0),
                radius: r,
            };
            let rr = ray([0.0, 0.1 * r, dist], [0.0, 0.0, -1.0]);
            let h = s.intersect(&rr, 0).unwrap();
            let sp = s.surface_point(&rr, &h, 0);
            let err = ((sp.p - Vec3A::new(0.3 * r, 0.0, 0.0)).length() - r).abs();
            assert!(
                err <= 4.0 * sp.p_error.max_element(),
                "radius {r}: off by {err}"
            );
        }
    }

    #[test]
    fn quad_bounds_and_parameters() {
        let q = Shape::quad(
            Vec3A::new(-1.0, 0.0, -1.0),
            Vec3A::new(2.0, 0.0, 0.0),
            Vec3A::new(0.0, 0.0, 2.0),
        );
        let r = ray([0.5, 3.0, 0.5], [0.0, -1.0, 0.0]);
        let h = q.intersect(&r, 0).unwrap();
        assert!((h.t - 3.0).abs() < 1e-6);
        assert!((h.uv[0] - 0.75).abs() < 1e-6 && (h.uv[1] - 0.75).abs() < 1e-6);
        let sp = q.surface_point(&r, &h, 0);
        assert!((sp.n - Vec3A::new(0.0, -1.0, 0.0)).length() < 1e-6);
        assert!(
            q.intersect(&ray([1.5, 3.0, 0.5], [0.0, -1.0, 0.0]), 0)
                .is_none()
        );
    }

    #[test]
    fn triangles_sharing_an_edge_are_watertight() {
        // Two triangles forming the unit square in z = 0; shoot rays exactly at the diagonal.
        let t1 = Shape::Triangle {
            p0: Vec3A::new(0.0, 0.0, 0.0),
            p1: Vec3A::new(1.0, 0.0, 0.0),
            p2: Vec3A::new(1.0, 1.0, 0.0),
        };
        let t2 = Shape::Triangle {
            p0: Vec3A::new(0.0, 0.0, 0.0),
            p1: Vec3A::new(1.0, 1.0, 0.0),
            p2: Vec3A::new(0.0, 1.0, 0.0),
        };
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            let r = ray([x, x, 1.0], [0.0, 0.0, -1.0]);
            assert!(
                t1.intersect(&r, 0).is_some() || t2.intersect(&r, 1).is_some(),
                "leak at {x}"
            );
        }
    }

    #[test]
    fn a_ray_never_hits_the_planar_primitive_it_leaves() {
        let q = Shape::quad(Vec3A::ZERO, Vec3A::X, Vec3A::Z);
        let mut r = ray([0.5, 0.0, 0.5], [0.0, 1.0, 0.0]);
        r.origin_prim = 3;
        assert!(q.intersect(&r, 3).is_none());
        r.origin_prim = NO_PRIM;
        r.o.y = -1.0;
        assert!(q.intersect(&r, 3).is_some());
    }

    /// A parallelogram's points within r of an edge, by their distance across it (not along
    /// its parameters); a sphere has no edge.
    #[test]
    fn near_boundary_is_the_distance_to_a_quads_edges() {
        let q = Shape::quad(
            Vec3A::ZERO,
            Vec3A::new(4.0, 0.0, 0.0),
            Vec3A::new(1.0, 2.0, 0.0),
        );
        let near = |x, y| q.near_boundary(Vec3A::new(x, y, 0.0), 0.3);
        assert!(!near(2.5, 1.0));
        // The slanted edge x = y / 2: 0.25 across at (0.75, 1) is 0.224 away.
        assert!(near(0.75, 1.0) && !near(0.9, 1.0));
        assert!(near(2.5, 0.29) && !near(2.5, 0.31));
        assert!(near(2.5, 1.71) && !near(2.5, 1.69));
        let sphere = Shape::Sphere {
            center: Vec3A::ZERO,
            radius: 1.0,
        };
        assert!(!sphere.near_boundary(Vec3A::X, 10.0));
    }
}

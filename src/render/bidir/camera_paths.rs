//! Camera subpaths: one per pixel sample, each joined to the light subpath of the same index
//! (connections), to the lights (next-event estimation, and lights it reaches), and to
//! every light vertex within the merge radius (merging), each contribution weighted by its
//! technique's share (`weights.rs`).

use glam::Vec3A;

use super::Iteration;
use super::effects::Shows;
use super::light_paths::LightPaths;
use super::vertex::{LightVertex, Mis, Roulette, Walk};
use super::weights::Technique;
use crate::render::film::CameraPaths;
use crate::render::geometry::{Hit, Ray, Surface, SurfacePoint, spawn_ray_to};
use crate::render::material::{Material, Transport};
use crate::render::math::Rgb;
use crate::render::photon::RangeGrid;
use crate::render::sampling::{Sampler, Stream};

/// One iteration's camera pass: its light subpaths, and their vertices in a grid for
/// merging, built for the iteration's merge radius.
pub(super) struct CameraPass<'a> {
    pub it: &'a Iteration<'a>,
    pub lights: &'a LightPaths,
    pub grid: Option<&'a RangeGrid<LightVertex>>,
}

/// A non-specular camera vertex where techniques join.
struct Vertex<'v> {
    sp: &'v SurfacePoint,
    wo: Vec3A,
    m: &'v Material,
    mis: Mis,
    len: u32,
    /// The camera subpath's first non-specular vertex: what it shows is decided here.
    first: bool,
    /// The probability that the camera subpath goes on from here ([`Walk::survival`]).
    survive: f32,
}

impl CameraPaths for CameraPass<'_> {
    type Scratch = ();
    type Extra = ();

    /// The pixel's point of its own Sobol sequence at this iteration (`render/qmc`): one
    /// sample a pixel per iteration, so only the pixel names it.
    fn sampler(&self, pixel: u64, _: [u32; 2], _: u32) -> Sampler {
        self.it.sampler(Stream::Camera, pixel)
    }

    fn radiance(&self, ray: &Ray, pixel: u64, _: [u32; 2], s: &mut Sampler, _: &mut ()) -> Rgb {
        let it = self.it;
        let camera = &it.camera;
        let cos = camera.forward().dot(ray.d);
        let plane = camera.image_plane_distance() / cos;
        // The camera ray's solid-angle density (a pixel has unit area on the image plane).
        let camera_pdf = plane * plane / cos;
        let mis = Mis {
            d_vcm: it.factors.light_paths / camera_pdf,
            d_vc: 0.0,
            d_vm: 0.0,
        };
        let mut walk = Walk::start(*ray, Rgb::ONE, mis);
        if it.modes == super::Modes::Pt {
            walk.roulette = Roulette::Throughput;
        }
        let mut l = Rgb::ZERO;
        while let Some(hit) = it.scene.intersect(&walk.ray) {
            let wo = -walk.ray.d;
            let prev = walk.ray.o;
            walk.arrive(hit.t, hit.point.n.dot(wo));
            let mi = match it.scene.surface(hit.point.prim) {
                Surface::Light(li) => {
                    l += walk.throughput * self.reached_light(li as usize, &hit, wo, prev, &walk);
                    break;
                }
                Surface::Material(mi) => mi,
            };
            if walk.len > it.max_depth {
                break;
            }
            let m = &it.scene.materials[mi as usize];
            let survive = walk.survival(m);
            if !m.is_specular() {
                if it.modes == super::Modes::Lt {
                    break; // the light subpaths carry what a diffuse point shows
                }
                if walk.first_non_specular == 0 {
                    walk.first_non_specular = walk.len;
                }
                let v = Vertex {
                    sp: &hit.point,
                    wo,
                    m,
                    mis: walk.mis,
                    len: walk.len,
                    first: walk.first_non_specular == walk.len,
                    survive,
                };
                l += walk.throughput * self.at_vertex(&v, pixel as usize, s);
            }
            let scatter = (&mut *s, Transport::Radiance);
            if !walk.scatter_at((m, survive), &hit.point, wo, scatter, &it.factors) {
                break;
            }
        }
        l
    }
}

impl CameraPass<'_> {
    /// What a camera vertex gathers: next-event estimation, connections to its light
    /// subpath, and merging.
    fn at_vertex(&self, v: &Vertex, pixel: usize, s: &mut Sampler) -> Rgb {
        let modes = self.it.modes;
        let mut l = Rgb::ZERO;
        let effects = self.it.effects;
        let u = (s.next_f32(), s.next_2d());
        let direct = if v.first {
            Shows::Direct
        } else {
            Shows::Indirect
        };
        if modes.nee() && direct.shown(effects) {
            l += self.next_event(v, u);
        }
        if modes.connects() && Shows::Indirect.shown(effects) {
            for x in self.lights.of_path(pixel) {
                if x.len + v.len <= self.it.max_depth {
                    l += self.connect(v, x);
                }
            }
        }
        if let Some(grid) = self.grid {
            l += self.merge(v, grid) * self.it.factors.vm_normalization;
        }
        l
    }

    /// Emission of the light the path reached (from `prev`), weighted.
    fn reached_light(&self, li: usize, hit: &Hit, wo: Vec3A, prev: Vec3A, walk: &Walk) -> Rgb {
        let it = self.it;
        let light = &it.scene.lights[li];
        let radiance = light.emitted(hit.point.n, wo);
        if radiance == Rgb::ZERO || walk.len > it.max_depth + 1 {
            return Rgb::ZERO;
        }
        let shows = match walk.first_non_specular {
            0 => Shows::Light,
            first => Shows::at_light_side(walk.len - 1 - first, walk.non_specular > 1),
        };
        if !shows.shown(it.effects) {
            return Rgb::ZERO;
        }
        let pick = it.picker.probability(li);
        let p = hit.point.p;
        let w = it.weight(Technique::Hit {
            camera: &walk.mis,
            len: walk.len,
            specular: walk.specular,
            direct_pdf_area: light.direct_pdf_area(p, hit.point.n, prev) * pick,
            emission_pdf: light.emission_pdf(hit.point.n, wo) * pick,
        });
        radiance * w
    }

    /// Next-event estimation: a light sampled directly.
    fn next_event(&self, v: &Vertex, (u_light, u): (f32, glam::Vec2)) -> Rgb {
        let it = self.it;
        if !(it.picker.total > 0.0) {
            return Rgb::ZERO;
        }
        let (li, pick) = it.picker.pick(u_light);
        let Some(d) = it.scene.lights[li].direct(v.sp.p, u) else {
            return Rgb::ZERO;
        };
        let f = v.m.eval(v.wo, d.wi, v.sp.n);
        if f == Rgb::ZERO {
            return Rgb::ZERO;
        }
        let survive = v.survive;
        let bsdf_pdf = if d.delta {
            0.0
        } else {
            v.m.pdf(v.wo, d.wi, v.sp.n) * survive
        };
        let cos_camera = v.sp.n.dot(d.wi).abs();
        let w = it.weight(Technique::Nee {
            camera: &v.mis,
            bsdf_pdf,
            bsdf_rev_pdf: v.m.pdf(d.wi, v.wo, v.sp.n) * survive,
            direct_pdf: d.direct_pdf * pick,
            emission_pdf: d.emission_pdf * pick,
            cos_camera,
            cos_light: d.cos_light,
        });
        let c = d.radiance * f * (w * cos_camera / (pick * d.direct_pdf));
        if c == Rgb::ZERO || !self.visible(v.sp, d.target, d.prim) {
            return Rgb::ZERO;
        }
        c
    }

    /// A connection to light vertex `x` (its throughput included).
    fn connect(&self, v: &Vertex, x: &LightVertex) -> Rgb {
        let it = self.it;
        let to_light = x.sp.p - v.sp.p;
        let dist2 = to_light.length_squared();
        if !(dist2 > 0.0) {
            return Rgb::ZERO;
        }
        let d = to_light / dist2.sqrt();
        let f_camera = v.m.eval(v.wo, d, v.sp.n);
        let xm = &it.scene.materials[x.material as usize];
        let f_light = xm.eval(x.wo, -d, x.sp.n);
        if f_camera == Rgb::ZERO || f_light == Rgb::ZERO {
            return Rgb::ZERO;
        }
        let (cos_camera, cos_light) = (v.sp.n.dot(d).abs(), x.sp.n.dot(d).abs());
        let (survive_camera, survive_light) = (v.survive, xm.continuation());
        let w = it.weight(Technique::Connect {
            camera: &v.mis,
            light: x,
            camera_pdf_area: v.m.pdf(v.wo, d, v.sp.n) * survive_camera * cos_light / dist2,
            camera_rev_pdf: v.m.pdf(d, v.wo, v.sp.n) * survive_camera,
            light_pdf_area: xm.pdf(x.wo, -d, x.sp.n) * survive_light * cos_camera / dist2,
            light_rev_pdf: xm.pdf(-d, x.wo, x.sp.n) * survive_light,
        });
        let c = f_camera * f_light * x.throughput * (w * cos_camera * cos_light / dist2);
        if c == Rgb::ZERO || !self.visible(v.sp, x.sp.p, x.sp.prim) {
            return Rgb::ZERO;
        }
        c
    }

    /// Merging: every light vertex within the radius, as if it had arrived here (before the
    /// normalisation by the disc and the light path count).
    fn merge(&self, v: &Vertex, grid: &RangeGrid<LightVertex>) -> Rgb {
        let it = self.it;
        let survive = v.survive;
        let mut sum = Rgb::ZERO;
        grid.within(v.sp.p, &mut |x: &LightVertex, _| {
            if x.len + v.len > it.max_depth + 1 {
                return;
            }
            let shows = match v.first {
                true => Shows::at_light_side(x.len - 1, x.non_specular_before),
                false => Shows::Indirect,
            };
            if !shows.shown(it.effects) {
                return;
            }
            let f = v.m.eval(v.wo, x.wo, v.sp.n);
            if f == Rgb::ZERO {
                return;
            }
            let xm = &it.scene.materials[x.material as usize];
            let w = it.weight(Technique::Merge {
                camera: &v.mis,
                light: x,
                camera_pdf: v.m.pdf(v.wo, x.wo, v.sp.n) * survive,
                camera_rev_pdf: v.m.pdf(x.wo, v.wo, v.sp.n) * xm.continuation(),
            });
            sum += f * x.throughput * w;
        });
        sum
    }

    /// Whether nothing lies between a surface point and `target` (on primitive `prim`).
    fn visible(&self, from: &SurfacePoint, target: Vec3A, prim: u32) -> bool {
        spawn_ray_to(from, target, prim).is_some_and(|(ray, _, _)| !self.it.scene.occluded(&ray))
    }
}

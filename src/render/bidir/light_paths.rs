//! An iteration's light subpaths: one per camera sample, traced in parallel chunks, each
//! path's random numbers from (seed, light paths, its index, the iteration) alone. Their non-specular
//! vertices are kept, in path order, for connections and merging; each is also connected to
//! the camera (light tracing), the contributions splatted onto an image in path order, so
//! that the result does not depend on the thread count.

use rayon::prelude::*;

use super::Iteration;
use super::effects::Shows;
use super::vertex::{LightVertex, Mis, Walk};
use super::weights::Technique;
use crate::render::control::{Cancelled, Control};
use crate::render::film::Image;
use crate::render::geometry::{NO_PRIM, Surface, spawn_ray_to};
use crate::render::material::Transport;
use crate::render::math::Rgb;
use crate::render::sampling::{Sampler, Stream};

/// Light subpaths per parallel work item.
const CHUNK: usize = 1024;

/// The light subpaths of one iteration.
pub(super) struct LightPaths {
    /// Every kept vertex, path by path.
    pub vertices: Vec<LightVertex>,
    /// Path i's vertices are `vertices[ends[i - 1]..ends[i]]`.
    pub ends: Vec<u32>,
    /// Light tracing: each vertex's contribution through the camera, per pixel.
    pub splats: Image,
    /// Splats dropped as non-finite.
    pub nonfinite: u64,
}

impl LightPaths {
    /// No light subpaths (an integrator that traces none).
    pub fn empty(camera: &crate::render::camera::Camera) -> LightPaths {
        LightPaths {
            vertices: Vec::new(),
            ends: Vec::new(),
            splats: Image::new(camera.width, camera.height),
            nonfinite: 0,
        }
    }

    /// The vertices of light path `i` (none for a path index beyond the traced ones).
    pub fn of_path(&self, i: usize) -> &[LightVertex] {
        let Some(&end) = self.ends.get(i) else {
            return &[];
        };
        let start = if i == 0 { 0 } else { self.ends[i - 1] as usize };
        &self.vertices[start..end as usize]
    }
}

/// One chunk's paths: their vertices, path ends (relative), and splats in order.
struct Chunk {
    vertices: Vec<LightVertex>,
    counts: Vec<u32>,
    splats: Vec<(u32, Rgb)>,
}

/// Trace `it.paths` light subpaths.
pub(super) fn trace_light_paths(
    it: &Iteration,
    control: &Control,
) -> Result<LightPaths, Cancelled> {
    let n = it.paths as usize;
    let chunks: Vec<Chunk> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            control.check()?;
            let mut chunk = Chunk {
                vertices: Vec::new(),
                counts: Vec::with_capacity(CHUNK),
                splats: Vec::new(),
            };
            for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                let before = chunk.vertices.len();
                trace_one(it, i as u64, &mut chunk);
                chunk.counts.push((chunk.vertices.len() - before) as u32);
            }
            Ok(chunk)
        })
        .collect::<Result<_, Cancelled>>()?;
    let camera = &it.camera;
    let mut paths = LightPaths {
        vertices: Vec::with_capacity(chunks.iter().map(|c| c.vertices.len()).sum()),
        ends: Vec::with_capacity(n),
        splats: Image::new(camera.width, camera.height),
        nonfinite: 0,
    };
    for chunk in chunks {
        for count in chunk.counts {
            let end = paths.ends.last().copied().unwrap_or(0) + count;
            paths.ends.push(end);
        }
        paths.vertices.extend(chunk.vertices);
        for (pixel, c) in chunk.splats {
            if c.is_finite() {
                let px = &mut paths.splats.pixels[pixel as usize];
                *px = (Rgb::from_array(*px) + c).to_array();
            } else {
                paths.nonfinite += 1;
            }
        }
    }
    Ok(paths)
}

/// Where a light path left its light: the light, its selection probability, the point and
/// its normal (for the direct technique's density, known at the first hit).
struct Origin<'a> {
    light: &'a crate::render::light::Light,
    pick: f32,
    p: glam::Vec3A,
    n: glam::Vec3A,
}

/// Trace light path `index` into `out`.
fn trace_one(it: &Iteration, index: u64, out: &mut Chunk) {
    if !(it.picker.total > 0.0) {
        return;
    }
    let mut s = it.sampler(Stream::LightPaths, index);
    let (li, pick) = it.picker.pick(s.next_f32());
    let light = &it.scene.lights[li];
    let Some(e) = light.emit(s.next_2d(), s.next_2d()) else {
        return;
    };
    let emission_pdf = e.emission_pdf * pick;
    let d_vc = if e.delta {
        0.0
    } else {
        e.cos_light / emission_pdf
    };
    let mis = Mis {
        // Completed at the first hit, where a sphere light's direct density is known.
        d_vcm: 1.0 / emission_pdf,
        d_vc,
        d_vm: d_vc * it.factors.vc,
    };
    let mut walk = Walk::start(e.ray, e.weight / pick, mis);
    let origin = Origin {
        light,
        pick,
        p: e.p,
        n: e.n,
    };
    while step(it, &origin, &mut walk, &mut s, out) {}
}

/// One vertex of a light path: keep it and connect it to the camera if it is not
/// specular, then scatter on. False when the path ends.
fn step(
    it: &Iteration,
    origin: &Origin,
    walk: &mut Walk,
    s: &mut Sampler,
    out: &mut Chunk,
) -> bool {
    let scene = it.scene;
    let Some(hit) = scene.intersect(&walk.ray) else {
        return false;
    };
    let Surface::Material(mi) = scene.surface(hit.point.prim) else {
        return false; // lights do not reflect
    };
    let wo = -walk.ray.d;
    if walk.len == 0 {
        // eq. 31: the direct technique's area density of the light point, from here.
        let direct = origin
            .light
            .direct_pdf_area(origin.p, origin.n, hit.point.p);
        walk.mis.d_vcm *= direct * origin.pick;
    }
    walk.arrive(hit.t, hit.point.n.dot(wo));
    let m = &scene.materials[mi as usize];
    if !m.is_specular() {
        let v = LightVertex {
            sp: hit.point,
            wo,
            throughput: walk.throughput,
            material: mi,
            len: walk.len,
            non_specular_before: walk.non_specular > 0,
            mis: walk.mis,
        };
        if it.modes.keep_light_vertices() {
            out.vertices.push(v);
        }
        if it.modes.light_tracing() && v.len <= it.max_depth {
            connect_to_camera(it, &v, out);
        }
    }
    if walk.len >= it.max_depth {
        return false;
    }
    let (survive, scatter) = (walk.survival(m), (s, Transport::Importance));
    walk.scatter_at((m, survive), &hit.point, wo, scatter, &it.factors)
}

/// Light tracing: light vertex `v` seen by the camera, splatted onto the pixel it projects
/// to (the camera's importance, on an image plane where a pixel has unit area).
fn connect_to_camera(it: &Iteration, v: &LightVertex, out: &mut Chunk) {
    let camera = &it.camera;
    let Some(raster) = camera.raster(v.sp.p) else {
        return;
    };
    let to_camera = camera.position - v.sp.p;
    let dist2 = to_camera.length_squared();
    let dir = to_camera / dist2.sqrt();
    let m = &it.scene.materials[v.material as usize];
    let f = m.eval(v.wo, dir, v.sp.n);
    if f == Rgb::ZERO {
        return;
    }
    let shows = Shows::at_light_side(v.len - 1, v.non_specular_before);
    if !shows.shown(it.effects) {
        return;
    }
    let cos_camera = camera.forward().dot(-dir);
    let cos_surface = v.sp.n.dot(dir).abs();
    let plane = camera.image_plane_distance() / cos_camera;
    // Image plane area to the surface's area around the vertex.
    let image_to_surface = plane * plane / cos_camera * cos_surface / dist2;
    let w = it.weight(Technique::LightTrace {
        vertex: v,
        camera_pdf_area: image_to_surface,
        rev_pdf: m.pdf(dir, v.wo, v.sp.n) * m.continuation(),
    });
    let c = v.throughput * f * (w * image_to_surface / it.factors.light_paths);
    if c == Rgb::ZERO {
        return;
    }
    let Some((ray, _, _)) = spawn_ray_to(&v.sp, camera.position, NO_PRIM) else {
        return;
    };
    if it.scene.occluded(&ray) {
        return;
    }
    let (x, y) = (raster.x as u32, raster.y as u32);
    out.splats.push((y * camera.width + x, c));
}

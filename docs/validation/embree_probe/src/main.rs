//! Embree 3 (Debian's libembree3) against photonbox's `Accel` (obvhs's wide BVH and our
//! watertight triangle test) on the same triangles and the same million rays, one thread:
//! half from points on the triangles, half from points in a box 1.5 times the mesh's, in
//! uniform directions, a quarter with a finite t_max. Prints ns per closest-hit and per
//! occlusion query, how many answers agree, and a hash of Embree's hit primitives (to
//! compare builds under EMBREE_CFG=threads=1, threads=2, ...).
use std::ffi::c_void;
use std::path::Path;
use std::time::Instant;

use glam::Vec3A;
use photonbox::render::Scene;
use photonbox::render::geometry::{Accel, Primitive, Ray, Shape};
use photonbox::render::sampling::{Sampler, Stream, uniform_sphere};

// Embree 3's single-ray structs (rtcore_ray.h) and intersection context (rtcore_common.h,
// RTC_MAX_INSTANCE_LEVEL_COUNT 1, no minimum width), field for field.

#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct RTCRay {
    ox: f32,
    oy: f32,
    oz: f32,
    tnear: f32,
    dx: f32,
    dy: f32,
    dz: f32,
    time: f32,
    tfar: f32,
    mask: u32,
    id: u32,
    flags: u32,
}
#[repr(C, align(16))]
#[derive(Clone, Copy, Default)]
struct RTCHit {
    ngx: f32,
    ngy: f32,
    ngz: f32,
    u: f32,
    v: f32,
    prim: u32,
    geom: u32,
    inst: u32,
}
#[repr(C)]
#[derive(Clone, Copy, Default)]
struct RTCRayHit {
    ray: RTCRay,
    hit: RTCHit,
}
#[repr(C)]
struct Ctx {
    flags: u32,
    filter: *const c_void,
    inst: u32,
}

unsafe extern "C" {
    fn rtcNewDevice(cfg: *const i8) -> *mut c_void;
    fn rtcNewScene(d: *mut c_void) -> *mut c_void;
    fn rtcNewGeometry(d: *mut c_void, t: u32) -> *mut c_void;
    fn rtcSetNewGeometryBuffer(
        g: *mut c_void,
        t: u32,
        slot: u32,
        f: u32,
        stride: usize,
        n: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(g: *mut c_void);
    fn rtcAttachGeometry(s: *mut c_void, g: *mut c_void) -> u32;
    fn rtcCommitScene(s: *mut c_void);
    fn rtcIntersect1(s: *mut c_void, c: *mut Ctx, r: *mut RTCRayHit);
    fn rtcOccluded1(s: *mut c_void, c: *mut Ctx, r: *mut RTCRay);
}

const RAYS: usize = 1_000_000;

/// The scene's triangles, as primitives for our `Accel` and as corners for Embree.
fn load_triangles(path: &str) -> (Vec<Primitive>, Vec<[Vec3A; 3]>) {
    let scene = Scene::load(Path::new(path)).expect("the scene loads");
    let prims: Vec<Primitive> = scene
        .accel
        .prims()
        .iter()
        .copied()
        .filter(|p| matches!(p.shape, Shape::Triangle { .. }))
        .collect();
    let tris = prims
        .iter()
        .map(|p| match p.shape {
            Shape::Triangle { p0, p1, p2 } => [p0, p1, p2],
            _ => unreachable!("filtered"),
        })
        .collect();
    (prims, tris)
}

/// An Embree scene of the triangles, on a device configured by EMBREE_CFG.
fn build_embree(tris: &[[Vec3A; 3]]) -> *mut c_void {
    let cfg = std::ffi::CString::new(std::env::var("EMBREE_CFG").unwrap_or_default()).unwrap();
    // SAFETY: Embree's C API as documented; the buffers are written within their sizes.
    unsafe {
        let device = rtcNewDevice(cfg.as_ptr());
        let scene = rtcNewScene(device);
        let g = rtcNewGeometry(device, 0);
        let v = rtcSetNewGeometryBuffer(g, 1, 0, 0x9003, 12, tris.len() * 3) as *mut f32;
        let ix = rtcSetNewGeometryBuffer(g, 0, 0, 0x5003, 12, tris.len()) as *mut u32;
        for (i, t) in tris.iter().enumerate() {
            for (k, p) in t.iter().enumerate() {
                for (c, x) in p.to_array().into_iter().enumerate() {
                    *v.add(9 * i + 3 * k + c) = x;
                }
                *ix.add(3 * i + k) = (3 * i + k) as u32;
            }
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene, g);
        let t0 = Instant::now();
        rtcCommitScene(scene);
        println!("embree build {:.3} s", t0.elapsed().as_secs_f64());
        scene
    }
}

/// Half the rays from points on random triangles, half from points in a box 1.5 times the
/// mesh's, in uniform directions; every fourth with a finite t_max.
fn probe_rays(tris: &[[Vec3A; 3]]) -> (Vec<Ray>, f32) {
    let (mut lo, mut hi) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
    for p in tris.iter().flatten() {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let (centre, ext) = ((lo + hi) * 0.5, hi - lo);
    let mut s = Sampler::new(7, Stream::Camera, 0);
    let rays = (0..RAYS)
        .map(|i| {
            let o = if i % 2 == 0 {
                let t = &tris[(s.next_f32() * tris.len() as f32) as usize % tris.len()];
                let (a, b) = s.next_2d().into();
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
            } else {
                let u = Vec3A::new(s.next_f32(), s.next_f32(), s.next_f32());
                centre + (u - 0.5) * ext * 1.5
            };
            let d = uniform_sphere(s.next_2d());
            let mut ray = Ray::new(o + d * 1e-3 * ext.length(), d);
            if i % 4 == 3 {
                ray.t_max = s.next_f32() * ext.length();
            }
            ray
        })
        .collect();
    (rays, ext.length())
}

fn rtc_ray(r: &Ray, tfar: f32) -> RTCRay {
    RTCRay {
        ox: r.o.x,
        oy: r.o.y,
        oz: r.o.z,
        dx: r.d.x,
        dy: r.d.y,
        dz: r.d.z,
        tfar,
        mask: u32::MAX,
        ..Default::default()
    }
}

fn context() -> Ctx {
    Ctx {
        flags: 0,
        filter: std::ptr::null(),
        inst: u32::MAX,
    }
}

/// Seconds for every ray's closest hit by each (ours, Embree's); prints how many answers
/// agree and a hash of Embree's hit primitives.
fn time_closest(accel: &Accel, scene: *mut c_void, rays: &[Ray]) -> [f64; 2] {
    let t0 = Instant::now();
    let found: Vec<_> = rays
        .iter()
        .map(|r| accel.closest4([Some(r), None, None, None])[0])
        .collect();
    let ours_s = t0.elapsed().as_secs_f64();
    let ours: Vec<_> = rays
        .iter()
        .zip(&found)
        .map(|(r, c)| c.map(|c| accel.hit_point(r, c).t))
        .collect();
    let mut ctx = context();
    let mut prim_hash = 0u64;
    let t0 = Instant::now();
    let theirs: Vec<_> = rays
        .iter()
        .map(|r| {
            let hit = RTCHit {
                geom: u32::MAX,
                ..Default::default()
            };
            let mut rh = RTCRayHit {
                ray: rtc_ray(r, r.t_max),
                hit,
            };
            // SAFETY: a committed scene, a context and ray-hit of Embree's layout.
            unsafe { rtcIntersect1(scene, &mut ctx, &mut rh) };
            prim_hash = prim_hash.wrapping_mul(31).wrapping_add(rh.hit.prim as u64);
            (rh.hit.geom != u32::MAX).then_some(rh.ray.tfar)
        })
        .collect();
    let embree_s = t0.elapsed().as_secs_f64();
    let agree = ours.iter().zip(&theirs).filter(|(a, b)| match (a, b) {
        (Some(a), Some(b)) => (*a - *b).abs() <= 1e-4 * a.abs().max(1e-3),
        (None, None) => true,
        _ => false,
    });
    let hits = ours.iter().filter(|h| h.is_some()).count();
    println!(
        "  closest: agree {} of {RAYS}, {hits} hits, Embree's primitives {prim_hash:x}",
        agree.count()
    );
    [ours_s, embree_s]
}

/// Seconds for every ray's occlusion test by each (ours, Embree's), t_max cut to `reach`.
fn time_occluded(accel: &Accel, scene: *mut c_void, rays: &[Ray], reach: f32) -> [f64; 2] {
    let t0 = Instant::now();
    let ours = rays
        .iter()
        .filter(|r| {
            accel.occluded(&Ray {
                t_max: r.t_max.min(reach),
                ..**r
            })
        })
        .count();
    let ours_s = t0.elapsed().as_secs_f64();
    let mut ctx = context();
    let t0 = Instant::now();
    let theirs = rays
        .iter()
        .filter(|r| {
            let mut ray = rtc_ray(r, r.t_max.min(reach));
            // SAFETY: as in time_closest.
            unsafe { rtcOccluded1(scene, &mut ctx, &mut ray) };
            ray.tfar == f32::NEG_INFINITY
        })
        .count();
    let embree_s = t0.elapsed().as_secs_f64();
    println!("  occluded: {ours} (ours) and {theirs} (Embree) of {RAYS}");
    [ours_s, embree_s]
}

fn main() {
    let default = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../scenes/knot.json");
    let path = std::env::args().nth(1).unwrap_or(default.into());
    let (prims, tris) = load_triangles(&path);
    println!("{} triangles", tris.len());
    let t0 = Instant::now();
    let accel = Accel::build(prims);
    println!("obvhs build {:.3} s", t0.elapsed().as_secs_f64());
    let scene = build_embree(&tris);
    let (rays, extent) = probe_rays(&tris);
    let ns = |s: f64| s * 1e9 / RAYS as f64;
    for round in 0..3 {
        println!("round {round}");
        let [c_ours, c_embree] = time_closest(&accel, scene, &rays);
        let [o_ours, o_embree] = time_occluded(&accel, scene, &rays, 0.3 * extent);
        println!(
            "  ns a ray: closest {:.1} (ours) {:.1} (Embree), ours/Embree {:.2}; \
             occluded {:.1} {:.1}, {:.2}",
            ns(c_ours),
            ns(c_embree),
            c_ours / c_embree,
            ns(o_ours),
            ns(o_embree),
            o_ours / o_embree
        );
    }
}

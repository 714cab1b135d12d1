//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod glass_sphere;

use photonbox::render::{Control, Image, RenderOutput, Scene, render};
use photonbox::spec::RenderSpec;

/// A floor lit by a point light and by the bright patch the light throws on a wall close
/// behind it: indirect light that final gathering must find (24x24 pixels).
pub const WALL_PATCH: &str = r#"{
  "camera": {"position": [0, 3, -4], "look_at": [0, 0, 1], "up": [0, 1, 0], "fov": 50,
             "width": 24, "height": 24},
  "materials": {"white": {"type": "diffuse", "albedo": [0.8, 0.8, 0.8]}},
  "objects": [
    {"type": "quad", "material": "white", "corner": [-3, 0, -3], "edge_u": [0, 0, 6], "edge_v": [6, 0, 0]},
    {"type": "quad", "material": "white", "corner": [-3, 0, 2], "edge_u": [6, 0, 0], "edge_v": [0, 4, 0]}
  ],
  "lights": [{"type": "point", "position": [0, 1, 1.5], "power": [100, 100, 100]}]
}"#;

/// Parse a scene from JSON text (no folder: no OBJ files).
pub fn scene(json: &str) -> Scene {
    Scene::parse(json, None).unwrap_or_else(|e| panic!("test scene does not parse: {e}"))
}

/// Render on the current thread pool, with no progress or cancel hooks; every pixel must be
/// finite and no sample dropped as non-finite.
pub fn render_checked(scene: &Scene, params: &RenderSpec) -> RenderOutput {
    let out = render(scene, params, &Control::none()).expect("not cancelled");
    assert_all_finite(&out.image);
    assert_eq!(
        out.stats.nonfinite_samples, 0,
        "non-finite samples were dropped"
    );
    out
}

/// [`render_checked`]'s image.
pub fn render_image(scene: &Scene, params: &RenderSpec) -> Image {
    render_checked(scene, params).image
}

pub fn assert_all_finite(img: &Image) {
    let bad = img
        .pixels
        .iter()
        .flatten()
        .filter(|c| !c.is_finite())
        .count();
    assert_eq!(bad, 0, "{bad} non-finite pixel channels");
}

/// Relative difference a/b - 1.
pub fn rel(a: f64, b: f64) -> f64 {
    a / b - 1.0
}

/// The same scene scaled by `s` about the origin and then moved by `t`: points are
/// transformed, edge vectors and radii scaled, point-light power multiplied by s^2 (so that
/// every radiance stays the same), area-light radiance kept.
pub fn transform_scene(json: &str, s: f64, t: [f64; 3]) -> String {
    use serde_json::{Value, json};
    let mut v: Value = serde_json::from_str(json).unwrap();
    let coords = |x: &Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect()
    };
    let point = |x: &Value| -> Value {
        let a = coords(x);
        json!([a[0] * s + t[0], a[1] * s + t[1], a[2] * s + t[2]])
    };
    let vector = |x: &Value| -> Value {
        let a = coords(x);
        json!([a[0] * s, a[1] * s, a[2] * s])
    };
    for key in ["position", "look_at"] {
        v["camera"][key] = point(&v["camera"][key]);
    }
    for list in ["objects", "lights"] {
        for o in v[list].as_array_mut().unwrap() {
            for key in ["center", "corner", "position"] {
                if o.get(key).is_some() {
                    o[key] = point(&o[key]);
                }
            }
            for key in ["edge_u", "edge_v"] {
                if o.get(key).is_some() {
                    o[key] = vector(&o[key]);
                }
            }
            if let Some(r) = o.get("radius").and_then(Value::as_f64) {
                o["radius"] = json!(r * s);
            }
            if let Some(p) = o.get_mut("positions").and_then(Value::as_array_mut) {
                for q in p.iter_mut() {
                    *q = point(q);
                }
            }
            if let Some(p) = o.get("power") {
                // vector() scales once; twice is s^2.
                o["power"] = vector(&vector(p));
            }
        }
    }
    v.to_string()
}

/// An analytic image: each pixel the mean of `f(origin, direction)` (world coordinates, f64)
/// over an 8x8 grid of camera rays through it, matching the box filter; None where `f` is
/// None for any of them (a pixel the analytic answer does not fully cover).
pub fn analytic_pixels(
    scene: &Scene,
    f: impl Fn(glam::DVec3, glam::DVec3) -> Option<f64>,
) -> Vec<Option<f64>> {
    let cam = &scene.camera;
    let mut out = Vec::with_capacity((cam.width * cam.height) as usize);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let mut sum = Some(0.0);
            for j in 0..8 {
                for i in 0..8 {
                    let r = cam.ray(
                        x as f32 + (i as f32 + 0.5) / 8.0,
                        y as f32 + (j as f32 + 0.5) / 8.0,
                    );
                    let o = r.o.as_dvec3() + scene.frame_origin;
                    let v = f(o, r.d.as_dvec3().normalize());
                    sum = sum.zip(v).map(|(a, b)| a + b);
                }
            }
            out.push(sum.map(|s| s / 64.0));
        }
    }
    out
}

/// Nearest hit distance of the ray o + t d (d unit) with a sphere, t > 0.
pub fn ray_sphere(o: glam::DVec3, d: glam::DVec3, c: glam::DVec3, r: f64) -> Option<f64> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    [-b - s, -b + s].into_iter().find(|&t| t > 0.0)
}

/// Radiance of a Lambertian point x (normal n, facing the viewer) lit by an unoccluded
/// point light: albedo/pi * P/(4 pi) * max(cos, 0) / d^2.
pub fn point_lit(
    x: glam::DVec3,
    n: glam::DVec3,
    light: glam::DVec3,
    power: f64,
    albedo: f64,
) -> f64 {
    let to = light - x;
    let d2 = to.length_squared();
    let cos = (n.dot(to) / d2.sqrt()).max(0.0);
    albedo / std::f64::consts::PI * power / (4.0 * std::f64::consts::PI) * cos / d2
}

/// Check `got` (channel 0) against the covered analytic pixels: each within `pixel_tol` of
/// max(want, `floor_frac` * peak) (the floor lets sampling noise at silhouettes and terminators
/// pass, not a speckle of acne), and their mean within `mean_tol` (where acne that darkens a
/// small fraction of samples shows). Returns (worst pixel error, mean error, pixels compared).
pub fn check_against(
    label: &str,
    got: &Image,
    want: &[Option<f64>],
    pixel_tol: f64,
    floor_frac: f64,
    mean_tol: f64,
) -> (f64, f64, usize) {
    let peak = want.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
    let floor = floor_frac * peak;
    let (mut worst, mut at, mut n) = (0.0f64, 0, 0);
    let (mut sum_got, mut sum_want) = (0.0, 0.0);
    for (i, (g, w)) in got.pixels.iter().zip(want).enumerate() {
        if let Some(w) = w {
            let g = g[0] as f64;
            let e = (g - w).abs() / w.max(floor);
            if e > worst {
                (worst, at) = (e, i);
            }
            sum_got += g;
            sum_want += w;
            n += 1;
        }
    }
    let mean_err = sum_got / sum_want - 1.0;
    let (x, y) = (at as u32 % got.width, at as u32 / got.width);
    eprintln!(
        "{label}: {n} pixels, mean {mean_err:+.5}, worst {worst:.5} at ({x}, {y}): {} against {:?}",
        got.pixels[at][0], want[at]
    );
    assert!(n > 0, "{label}: no pixel compared");
    assert!(worst < pixel_tol, "{label}: worst pixel error {worst}");
    assert!(mean_err.abs() < mean_tol, "{label}: mean error {mean_err}");
    (worst, mean_err, n)
}

/// Unpolarized Fresnel reflectance, written out independently of the renderer's.
pub fn fresnel(cos_i: f64, n_i: f64, n_t: f64) -> f64 {
    let sin_t = n_i / n_t * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n_i * cos_i - n_t * cos_t) / (n_i * cos_i + n_t * cos_t);
    let rp = (n_t * cos_i - n_i * cos_t) / (n_t * cos_i + n_i * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// proptest's configuration with `default` cases unless PROPTEST_CASES says otherwise
/// (`ProptestConfig::with_cases` alone would ignore the variable).
pub fn proptest_config(default: u32) -> proptest::prelude::ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default);
    proptest::prelude::ProptestConfig::with_cases(cases)
}

/// The job of `params` (the server's parameter names, as `--flags`) on the scene the
/// server and farm tests submit, by `photonbox render` on one thread: its EXR's bytes, the
/// ones every front end must serve for the same job.
pub fn render_exr_by_cli(params: &serde_json::Value) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("one.exr");
    let mut cmd = render_command(params, dir.path());
    cmd.arg("--exr").arg(&exr);
    run_render(cmd);
    std::fs::read(&exr).unwrap()
}

/// `photonbox render` of `params` on the server tests' scene, on one thread, its PNG in
/// `dir`: more flags may follow.
pub fn render_command(params: &serde_json::Value, dir: &std::path::Path) -> std::process::Command {
    let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_photonbox"));
    cmd.arg("render")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/cornell_mirror_glass.json"
        ))
        .arg("-o")
        .arg(dir.join("one.png"))
        .args(["--threads", "1"]);
    for (k, v) in params.as_object().unwrap() {
        let v = v.as_str().map_or(v.to_string(), str::to_string);
        cmd.arg(format!("--{}", k.replace('_', "-"))).arg(v);
    }
    cmd
}

/// Run a render command to its successful end.
pub fn run_render(mut cmd: std::process::Command) {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

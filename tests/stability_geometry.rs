//! Numerical stability, geometry (issue 5): no self-intersection at grazing angles or on
//! tiny and huge spheres, no light leaks, images independent of scale and position,
//! coincident faces, lights lying on surfaces. Every image is checked finite with no
//! dropped sample (`common::render_image`), and against an analytic answer where one exists.

mod common;

use common::{
    analytic_pixels, check_against, point_lit, ray_sphere, render_image, scene, transform_scene,
};
use glam::DVec3;
use photonbox::render::accuracy::compare;
use photonbox::render::photon::PhotonStore;
use photonbox::spec::{PhotonMapping, RenderSpec};

fn raytrace(spp: u32) -> RenderSpec {
    RenderSpec::raytrace(spp)
}

/// A floor of albedo 0.5 under a point light, seen from `camera` looking at `look_at`.
fn floor_scene(light: [f64; 3], camera: [f64; 3], look_at: [f64; 3], extra: &str) -> String {
    format!(
        r#"{{
        "camera": {{"position": {camera:?}, "look_at": {look_at:?}, "up": [0, 1, 0], "fov": 60,
                    "width": 48, "height": 48}},
        "materials": {{"floor": {{"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
                      "red": {{"type": "diffuse", "albedo": [0.5, 0, 0]}}}},
        "objects": [{{"type": "quad", "material": "floor", "corner": [-50, 0, -50],
                      "edge_u": [0, 0, 100], "edge_v": [100, 0, 0]}}{extra}],
        "lights": [{{"type": "point", "position": {light:?}, "power": [100, 100, 100]}}]
    }}"#
    )
}

/// The analytic floor: radiance of y = 0 inside |x|, |z| < 50 under the light.
/// Pixels with a hit farther than `reach` from the camera, or nearer than `foot` to the
/// point under the light, are left out.
fn floor_analytic(
    s: &photonbox::render::Scene,
    light: [f64; 3],
    reach: f64,
    foot: f64,
) -> Vec<Option<f64>> {
    let l = DVec3::from_array(light);
    analytic_pixels(s, |o, d| {
        let t = -o.y / d.y;
        let x = o + d * t;
        let near_foot = (x - DVec3::new(l.x, 0.0, l.z)).length() < foot;
        (t > 0.0 && (x - o).length() < reach && x.x.abs() < 50.0 && x.z.abs() < 50.0 && !near_foot)
            .then(|| point_lit(x, DVec3::Y, l, 100.0, 0.5))
    })
}

/// Light skimming the floor: shadow rays leave the floor at a few degrees.
#[test]
fn floor_lit_at_grazing_angles_has_no_acne() {
    // Outside 0.3 of its foot, the light arrives at under 4 degrees from the floor.
    let light = [0.0, 0.02, 0.0];
    let s = scene(&floor_scene(light, [0.0, 3.0, 0.01], [0.0, 0.0, 0.0], ""));
    let want = floor_analytic(&s, light, 1e9, 0.3);
    let got = render_image(&s, &raytrace(256));
    let (_, _, n) = check_against("grazing light", &got, &want, 0.05, 0.0, 0.002);
    assert!(n > 2000);
}

/// The camera skimming the floor: its rays hit the floor at a fraction of a degree.
#[test]
fn floor_seen_at_grazing_angles_has_no_acne() {
    // A high light: smooth radiance, so that the pixels' long footprints average well.
    let light = [0.0, 20.0, 0.0];
    let s = scene(&floor_scene(light, [0.0, 0.05, 6.0], [0.0, 0.0, -6.0], ""));
    let want = floor_analytic(&s, light, 30.0, 0.0);
    let got = render_image(&s, &raytrace(256));
    let (_, _, n) = check_against("grazing view", &got, &want, 0.02, 0.0, 0.002);
    assert!(n > 300, "{n} pixels compared");
}

/// A lone diffuse sphere under a point light: the analytic lit half, and exactly nothing
/// on the other half (no light leaks through the surface).
fn check_sphere(radius: f64) {
    let json = format!(
        r#"{{
        "camera": {{"position": [0, 0, {cz}], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 40,
                    "width": 48, "height": 48}},
        "materials": {{"m": {{"type": "diffuse", "albedo": [0.8, 0.8, 0.8]}}}},
        "objects": [{{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": {radius}}}],
        "lights": [{{"type": "point", "position": [{lx}, {lx}, {lx}], "power": [{p}, {p}, {p}]}}]
    }}"#,
        cz = 4.0 * radius,
        lx = 2.0 * radius,
        p = 100.0 * radius * radius,
    );
    let s = scene(&json);
    let light = DVec3::splat(2.0 * radius);
    let want = analytic_pixels(&s, |o, d| {
        let t = ray_sphere(o, d, DVec3::ZERO, radius)?;
        let x = o + d * t;
        Some(point_lit(
            x,
            x / radius,
            light,
            100.0 * radius * radius,
            0.8,
        ))
    });
    let got = render_image(&s, &raytrace(256));
    let label = format!("sphere r = {radius:e}");
    let (_, _, n) = check_against(&label, &got, &want, 0.1, 0.05, 0.002);
    // Pixels well inside the shadowed half (cos < -0.05 all over): exactly black.
    let deep_dark = analytic_pixels(&s, |o, d| {
        let x = o + d * ray_sphere(o, d, DVec3::ZERO, radius)?;
        let cos = (x / radius).dot((light - x).normalize());
        (cos < -0.05).then_some(0.0)
    });
    let dark: Vec<f32> = got
        .pixels
        .iter()
        .zip(&deep_dark)
        .filter(|(_, w)| w.is_some())
        .map(|(g, _)| g[0])
        .collect();
    assert!(
        n > 500 && dark.len() > 100,
        "{n} pixels, {} dark",
        dark.len()
    );
    assert!(
        dark.iter().all(|&v| v == 0.0),
        "light leaked to the dark side"
    );
}

#[test]
fn tiny_sphere_has_no_acne_or_leak() {
    check_sphere(1e-3);
}

#[test]
fn huge_sphere_has_no_acne_or_leak() {
    check_sphere(1e4);
}

/// The seed's scene (1), photon mode: scaled (light power by s^2) and moved, it renders the
/// same image within noise, channel by channel and block by block. (Also a regression: the
/// caustic occupancy grid once indexed out of bounds at some scales.)
#[test]
fn images_do_not_depend_on_scale_or_position() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json");
    let json = std::fs::read_to_string(path).unwrap();
    let params = RenderSpec {
        width: Some(64),
        height: Some(64),
        ..RenderSpec::photon(PhotonMapping {
            photons: 100_000,
            caustic_photons: 100_000,
            gather_rays: 0,
            spp: 2,
            ..PhotonMapping::PHOTON
        })
    };
    let original = render_image(&scene(&json), &params);
    let base = original.mean_rgb(0, 0, 64, 64);
    for (s, t) in [
        (5.0, [0.0; 3]),
        (1e-3, [0.0; 3]),
        (1e4, [0.0; 3]),
        (1.0, [1e5, -1e5, 1e5]),
        (1.0, [1e5, -3e4, 2e5]),
        (1e-3, [1e5, -1e5, 1e5]),
    ] {
        let moved = render_image(&scene(&transform_scene(&json, s, t)), &params);
        let e = compare(&moved, &original).unwrap();
        eprintln!(
            "scale {s:e}, moved {t:?}: mean_ratio {:.5}, block_err {:.5}",
            e.mean_ratio, e.block_err
        );
        assert!(
            (e.mean_ratio - 1.0).abs() < 0.01,
            "scale {s}, moved {t:?}: {e:?}"
        );
        assert!(e.block_err < 0.03, "scale {s}, moved {t:?}: {e:?}");
        let m = moved.mean_rgb(0, 0, 64, 64);
        for c in 0..3 {
            let r = m[c] / base[c] - 1.0;
            assert!(
                r.abs() < 0.01,
                "scale {s}, moved {t:?}: channel {c} off by {r:+.4}"
            );
        }
    }
}

/// Two coincident floors (z-fighting): whichever a ray hits, the other must not shadow it.
#[test]
fn coincident_faces_do_not_shadow_each_other() {
    let twin = r#", {"type": "quad", "material": "red", "corner": [-50, 0, -50],
                     "edge_u": [0, 0, 100], "edge_v": [100, 0, 0]}"#;
    let light = [0.3, 1.0, -0.2];
    let s = scene(&floor_scene(light, [0.0, 3.0, 0.01], [0.0, 0.0, 0.0], twin));
    let want = floor_analytic(&s, light, 1e9, 0.0);
    // Both materials have the red albedo 0.5: the red channel is the analytic answer.
    let got = render_image(&s, &raytrace(256));
    check_against("coincident faces", &got, &want, 0.01, 0.0, 0.002);
    let photons = RenderSpec::photon(PhotonMapping {
        photon_store: PhotonStore::DirectOnly,
        photons: 400_000,
        k: 50,
        spp: 1,
        ..PhotonMapping::PHOTON
    });
    let got = render_image(&s, &photons);
    let mean = |v: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = v.fold((0.0, 0), |(s, n), x| (s + x, n + 1));
        sum / n as f64
    };
    let (g, w) = (
        mean(&mut got.pixels.iter().map(|p| p[0] as f64)),
        mean(&mut want.iter().map(|w| w.unwrap())),
    );
    eprintln!("coincident faces, photons: mean {g:.5} vs {w:.5}");
    assert!((g / w - 1.0).abs() < 0.03, "{g} vs {w}");
}

/// A point light exactly on the floor grazes it (zero radiance there) and lights a sphere
/// above as if the floor were not there; a quad light lying on the floor does the same.
#[test]
fn lights_lying_on_a_surface() {
    let ball = r#", {"type": "sphere", "material": "floor", "center": [0, 1, 0], "radius": 0.5}"#;
    let light = [0.0, 0.0, 0.0];
    let s = scene(&floor_scene(light, [0.0, 1.0, 3.0], [0.0, 0.6, 0.0], ball));
    let l = DVec3::from_array(light);
    let want = analytic_pixels(&s, |o, d| {
        let t_ball = ray_sphere(o, d, DVec3::Y, 0.5);
        let t_floor = (-o.y / d.y > 0.0).then_some(-o.y / d.y);
        match (t_ball, t_floor) {
            (Some(t), f) if f.is_none_or(|f| t < f) => {
                let x = o + d * t;
                Some(point_lit(x, (x - DVec3::Y) / 0.5, l, 100.0, 0.5))
            }
            (_, Some(_)) => Some(0.0),
            _ => None,
        }
    });
    let got = render_image(&s, &raytrace(256));
    // The sphere's lit cap is a steep gradient over a few pixels: the mean carries the check.
    let (_, _, n) = check_against("point light on the floor", &got, &want, 0.6, 0.05, 0.01);
    assert!(n > 1000);
    let floor_lit = got
        .pixels
        .iter()
        .zip(&want)
        .filter(|(g, w)| **w == Some(0.0) && g[0] != 0.0)
        .count();
    assert_eq!(floor_lit, 0, "pixels of the grazed floor received light");

    // A quad light on the floor, facing up, under the same sphere: the floor changes nothing
    // the sphere receives.
    let quad_light = |with_floor: bool| {
        let j = floor_scene(light, [0.0, 1.0, 3.0], [0.0, 0.6, 0.0], ball).replace(
            r#"{"type": "point", "position": [0.0, 0.0, 0.0], "power": [100, 100, 100]}"#,
            r#"{"type": "quad", "corner": [-0.5, 0, -0.5], "edge_u": [0, 0, 1], "edge_v": [1, 0, 0],
                "radiance": [5, 5, 5]}"#,
        );
        let j = if with_floor {
            j
        } else {
            j.replace("[-50, 0, -50]", "[-50, -9, -50]")
        };
        render_image(&scene(&j), &raytrace(16))
    };
    let (a, b) = (quad_light(true), quad_light(false));
    let sphere = analytic_pixels(&s, |o, d| ray_sphere(o, d, DVec3::Y, 0.5).map(|_| 1.0));
    let mut compared = 0;
    for ((pa, pb), on) in a.pixels.iter().zip(&b.pixels).zip(&sphere) {
        if on.is_some() {
            compared += 1;
            assert!(
                (pa[0] - pb[0]).abs() <= 1e-4 * pb[0].max(1e-3),
                "{pa:?} vs {pb:?}"
            );
        }
    }
    assert!(
        compared > 100 && b.pixels.iter().any(|p| p[0] > 0.1),
        "{compared}"
    );
}

//! Radiance against closed-form answers (issue 2, acceptance 1 a-c).

mod common;

use std::f64::consts::PI;

use common::glass_sphere::exits;
use common::{analytic_pixels, point_lit, rel, render_image, scene};
use glam::DVec3;
use photonbox::render::photon::PhotonStore;
use photonbox::render::{Control, Scene, trace_maps};
use photonbox::spec::{PhotonMapping, RenderSpec};

/// (a) A point light over a large diffuse floor seen from straight above.
fn floor_scene(power: f64, albedo: f64) -> String {
    format!(
        r#"{{
        "camera": {{"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov": 60,
                    "width": 64, "height": 64}},
        "materials": {{"floor": {{"type": "diffuse", "albedo": [{albedo}, {albedo}, {albedo}]}}}},
        "objects": [{{"type": "quad", "material": "floor", "corner": [-50, 0, -50],
                      "edge_u": [0, 0, 100], "edge_v": [100, 0, 0]}}],
        "lights": [{{"type": "point", "position": [0.3, 1, -0.2], "power": [{power}, {power}, {power}]}}]
    }}"#
    )
}

/// The analytic radiance L = albedo/pi * P/(4 pi) * cos(theta) / d^2, averaged over each
/// pixel like the box filter (`common::analytic_pixels`), for the scene above.
fn floor_analytic(scene: &Scene, power: f64, albedo: f64) -> Vec<f64> {
    let light = DVec3::new(0.3, 1.0, -0.2);
    analytic_pixels(scene, |o, d| {
        let hit = o + d * (-o.y / d.y);
        Some(point_lit(hit, DVec3::Y, light, power, albedo))
    })
    .into_iter()
    .map(|v| v.expect("every camera ray meets the floor"))
    .collect()
}

fn channel0(img: &photonbox::render::Image) -> Vec<f64> {
    img.pixels.iter().map(|p| p[0] as f64).collect()
}

fn region_mean(v: &[f64], w: usize, x0: usize, x1: usize) -> f64 {
    let mut s = 0.0;
    for y in x0..x1 {
        for x in x0..x1 {
            s += v[y * w + x];
        }
    }
    s / ((x1 - x0) * (x1 - x0)) as f64
}

#[test]
fn point_light_over_floor_raytrace_within_1_percent_per_pixel() {
    let (power, albedo) = (50.0, 0.6);
    let s = scene(&floor_scene(power, albedo));
    let want = floor_analytic(&s, power, albedo);
    let params = RenderSpec::raytrace(256);
    let got = channel0(&render_image(&s, &params));
    let worst = got
        .iter()
        .zip(&want)
        .map(|(g, w)| rel(*g, *w).abs())
        .fold(0.0, f64::max);
    eprintln!("raytrace floor: worst pixel {worst:.5}");
    assert!(worst < 0.01, "worst per-pixel relative error {worst:.4}");
    let m = rel(region_mean(&got, 64, 0, 64), region_mean(&want, 64, 0, 64));
    assert!(m.abs() < 0.002, "image mean off by {m:.4}");
}

#[test]
fn point_light_over_floor_direct_photons_within_3_percent() {
    let (power, albedo) = (50.0, 0.6);
    let s = scene(&floor_scene(power, albedo));
    let want = floor_analytic(&s, power, albedo);
    let params = RenderSpec::photon(PhotonMapping {
        photon_store: PhotonStore::DirectOnly,
        photons: 1_000_000,
        k: 50,
        spp: 1,
        ..PhotonMapping::PHOTON
    });
    let got = channel0(&render_image(&s, &params));
    // The central region (the light's foot and its surroundings) and four off-centre ones.
    for (x0, x1) in [(16, 48), (0, 16), (48, 64), (24, 40)] {
        let m = rel(
            region_mean(&got, 64, x0, x1),
            region_mean(&want, 64, x0, x1),
        );
        eprintln!("direct_only floor: region {x0}..{x1} {m:+.5}");
        assert!(m.abs() < 0.03, "region {x0}..{x1}: mean off by {m:.4}");
    }
}

/// (b) A closed diffuse sphere lit from its centre: every point sees the same radiance,
/// L = (a/pi) P/(4 pi R^2) / (1 - a), all bounces included.
fn closed_sphere(albedo: f64, radius: f64, power: f64) -> String {
    format!(
        r#"{{
        "camera": {{"position": [0, {y}, {z}], "look_at": [0, {ly}, {lz}], "up": [0, 1, 0],
                    "fov": 70, "width": 48, "height": 48}},
        "materials": {{"wall": {{"type": "diffuse", "albedo": [{albedo}, {albedo}, {albedo}]}}}},
        "objects": [{{"type": "sphere", "material": "wall", "center": [0, 0, 0], "radius": {radius}}}],
        "lights": [{{"type": "point", "position": [0, 0, 0], "power": [{power}, {power}, {power}]}}]
    }}"#,
        y = 0.2 * radius,
        z = 0.3 * radius,
        ly = -0.5 * radius,
        lz = -radius,
    )
}

/// The image mean within 2%, and each 12x12-pixel block (a different patch of the sphere)
/// within `block_tol`, which allows for the photon map's noise.
fn check_closed_sphere(params: RenderSpec, block_tol: f64) {
    let (a, r, p) = (0.5, 2.0, 10.0);
    let want = (a / PI) * p / (4.0 * PI * r * r) / (1.0 - a);
    let s = scene(&closed_sphere(a, r, p));
    let img = render_image(&s, &params);
    let mean = img.mean_rgb(0, 0, 48, 48)[0];
    let p = params.photon_mapping().expect("photon mapping");
    eprintln!(
        "closed sphere {:?} G={}: mean {:+.5}",
        p.photon_store,
        p.gather_rays,
        rel(mean, want)
    );
    assert!(
        rel(mean, want).abs() < 0.02,
        "{params:?}: mean {mean:.5} vs {want:.5} ({:+.4})",
        rel(mean, want)
    );
    for by in 0..4 {
        for bx in 0..4 {
            let m = img.mean_rgb(bx * 12, by * 12, bx * 12 + 12, by * 12 + 12)[0];
            eprintln!("  block ({bx}, {by}) {:+.5}", rel(m, want));
            assert!(
                rel(m, want).abs() < block_tol,
                "{params:?}: block ({bx}, {by}) mean {m:.5} vs {want:.5} ({:+.4})",
                rel(m, want)
            );
        }
    }
}

#[test]
fn closed_sphere_photon_indirect_within_2_percent() {
    check_closed_sphere(
        RenderSpec::photon(PhotonMapping {
            photons: 200_000,
            k: 100,
            gather_rays: 0,
            spp: 1,
            ..PhotonMapping::PHOTON
        }),
        0.04,
    );
}

#[test]
fn closed_sphere_photon_all_within_2_percent() {
    check_closed_sphere(
        RenderSpec::photon(PhotonMapping {
            photon_store: PhotonStore::All,
            photons: 400_000,
            k: 100,
            gather_rays: 0,
            spp: 1,
            ..PhotonMapping::PHOTON
        }),
        0.06,
    );
}

#[test]
fn closed_sphere_final_gather_within_2_percent() {
    check_closed_sphere(
        RenderSpec::photon(PhotonMapping {
            photons: 100_000,
            k: 50,
            gather_rays: 16,
            spp: 1,
            ..PhotonMapping::PHOTON
        }),
        0.04,
    );
}

/// Fraction of a point light's power that a glass sphere sends down to an infinite floor:
/// every exit of each ray of the light's cone through the sphere (`common::glass_sphere`),
/// integrated over the cone.
fn glass_sphere_floor_fraction(d: f64, r: f64, ior: f64) -> f64 {
    let alpha_max = (r / d).asin();
    let steps = 20_000;
    let da = alpha_max / steps as f64;
    (0..steps)
        .map(|s| {
            let alpha = (s as f64 + 0.5) * da;
            let down: f64 = exits(d, r, ior, alpha)
                .iter()
                .filter(|e| e.dir.y < 0.0)
                .map(|e| e.w)
                .sum();
            // Solid-angle weight of this ring of the cone, as a fraction of the full sphere.
            down * 2.0 * PI * alpha.sin() * da / (4.0 * PI)
        })
        .sum()
}

/// (c) A glass sphere transmits the expected fraction of the light's power to the floor.
#[test]
fn glass_sphere_sends_fresnel_fraction_of_power_to_floor() {
    check_glass_sphere(1.5);
}

/// Issue 5's extreme index: more reflection at each interface, more internal bounces.
#[test]
fn glass_sphere_of_ior_4_sends_fresnel_fraction_of_power_to_floor() {
    check_glass_sphere(4.0);
}

fn check_glass_sphere(ior: f64) {
    let (d, r, power) = (2.5, 1.0, 100.0);
    let json = format!(
        r#"{{
        "camera": {{"position": [0, 0, 8], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 40,
                    "width": 8, "height": 8}},
        "materials": {{"glass": {{"type": "dielectric", "ior": {ior}}},
                       "floor": {{"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}}}},
        "objects": [
            {{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": {r}}},
            {{"type": "quad", "material": "floor", "corner": [-500, -1.5, -500],
              "edge_u": [0, 0, 1000], "edge_v": [1000, 0, 0]}}
        ],
        "lights": [{{"type": "point", "position": [0, {d}, 0], "power": [{power}, {power}, {power}]}}]
    }}"#
    );
    let s = scene(&json);
    let params = RenderSpec {
        max_depth: 64,
        ..RenderSpec::photon(PhotonMapping {
            caustic_photons: 2_000_000,
            photons: 1000,
            ..PhotonMapping::PHOTON
        })
    };
    let maps = trace_maps(&s, &params, &Control::none()).unwrap();
    let caustic = maps
        .caustic
        .as_ref()
        .expect("the scene has glass: a caustic map is built");
    let got = caustic.total_power()[0];
    let want = power * glass_sphere_floor_fraction(d, r, ior);
    eprintln!("glass sphere, ior {ior}: caustic power {got:.5} W, expected {want:.5} W");
    assert!(
        rel(got, want).abs() < 0.02,
        "caustic power on the floor {got:.4} W, expected {want:.4} W ({:+.4})",
        rel(got, want)
    );
}

/// A photon carries flux (power / emitted): doubling the photon count leaves the image's
/// brightness unchanged.
#[test]
fn doubling_photons_leaves_brightness_unchanged() {
    let s = scene(&floor_scene(50.0, 0.6));
    let mean = |photons| {
        let params = RenderSpec::photon(PhotonMapping {
            photon_store: PhotonStore::DirectOnly,
            photons,
            spp: 1,
            ..PhotonMapping::PHOTON
        });
        render_image(&s, &params).mean_rgb(0, 0, 64, 64)[1]
    };
    let (a, b) = (mean(300_000), mean(600_000));
    eprintln!("doubling photons: {a:.5} -> {b:.5}");
    assert!(rel(b, a).abs() < 0.02, "{a} vs {b}");
}

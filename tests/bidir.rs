//! The bidirectional family (issue 20): `pt`, `lt`, `bdpt` and `vcm`, each alone against
//! closed-form radiance, and against each other where every technique can carry the scene's
//! light. (That the weights of the techniques add up to one, so that a broken weight fails
//! these, is `src/render/bidir/tests.rs`.)

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::glass_sphere::{exits, landing_x, share_of_circle_in_square as share};
use common::{analytic_pixels, point_lit, rel, render_checked, scene};
use glam::DVec3;
use photonbox::render::Scene;
use photonbox::render::accuracy::compare;
use photonbox::spec::{Integrator, Merging, Passes, PhotonMapping, Progressive, RenderSpec, Stop};

/// Every integrator of the family, with `passes` passes of one sample per pixel.
fn family(passes: u32) -> [(&'static str, RenderSpec); 4] {
    let p = Passes {
        spp: 1,
        stop: Stop::after(passes),
    };
    let vcm = Merging {
        passes: p.clone(),
        ..Merging::DEFAULT
    };
    [
        ("pt", RenderSpec::new(Integrator::Pt(p.clone()))),
        ("lt", RenderSpec::new(Integrator::Lt(p.clone()))),
        ("bdpt", RenderSpec::new(Integrator::Bdpt(p))),
        ("vcm", RenderSpec::new(Integrator::Vcm(vcm))),
    ]
}

/// A closed diffuse sphere lit from its centre by a point light: every point sees
/// L = (a/pi) P/(4 pi R^2) / (1 - a), every bounce included (a furnace: the sum of a
/// geometric series of bounces, which a missing or doubled technique puts off).
const CLOSED_SPHERE: &str = r#"{
    "camera": {"position": [0, 0.4, 0.6], "look_at": [0, -1, -2], "up": [0, 1, 0], "fov": 70,
               "width": 32, "height": 32},
    "materials": {"wall": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "objects": [{"type": "sphere", "material": "wall", "center": [0, 0, 0], "radius": 2}],
    "lights": [{"type": "point", "position": [0, 0, 0], "power": [10, 10, 10]}]
}"#;

#[test]
fn every_technique_renders_the_closed_sphere_within_half_a_percent() {
    let want = (0.5 / PI) * 10.0 / (4.0 * PI * 4.0) / 0.5;
    let s = scene(CLOSED_SPHERE);
    for (name, spec) in family(256) {
        let img = render_checked(&s, &spec).image;
        let mean = img.mean_rgb(0, 0, 32, 32)[0];
        eprintln!("closed sphere, {name}: mean {:+.5}", rel(mean, want));
        assert!(
            rel(mean, want).abs() < 0.005,
            "{name}: mean {mean:.5} vs {want:.5}"
        );
    }
}

/// The closed sphere lit by a large sphere light at its centre instead (radius r = R/2,
/// radiance 1): the wall sees the light over a cone of sin^2 = s = (r/R)^2 and the wall over
/// the rest, so L = a (pi s + pi (1 - s) L) / pi, L = a s / (1 - a (1 - s)). Camera paths
/// reach the light here, so a path tracer's two techniques (next-event estimation and
/// hitting the light) share every path, and their weights must add up to one at every
/// bounce: with `pt`'s roulette (which spares the first bounces) weighed wrong in either,
/// the sum is off by several percent (+8.6% with next-event estimation weighing the
/// material's own survival probability).
const CLOSED_SPHERE_AREA_LIGHT: &str = r#"{
    "camera": {"position": [0, 0, 1.4], "look_at": [0, 0, 3], "up": [0, 1, 0], "fov": 70,
               "width": 32, "height": 32},
    "materials": {"wall": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "objects": [{"type": "sphere", "material": "wall", "center": [0, 0, 0], "radius": 2}],
    "lights": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "radiance": [1, 1, 1]}]
}"#;

/// The integrators whose next-event estimation is weighed against hitting the light. (Light
/// tracing onto a camera this close to the wall needs thousands of passes to settle, and
/// vcm's merging adds a blur of its own: both are checked on the point-lit sphere above.)
#[test]
fn pt_and_bdpt_render_the_closed_sphere_around_a_sphere_light_within_half_a_percent() {
    let (a, s2) = (0.5, 0.25);
    let want = a * s2 / (1.0 - a * (1.0 - s2));
    let s = scene(CLOSED_SPHERE_AREA_LIGHT);
    let weighed = |name: &str| name == "pt" || name == "bdpt";
    for (name, spec) in family(256).into_iter().filter(|(n, _)| weighed(n)) {
        let mean = render_checked(&s, &spec).image.mean_rgb(0, 0, 32, 32)[0];
        within_half_a_percent(&format!("closed sphere, sphere light, {name}"), mean, want);
    }
}

/// A point light over a large diffuse floor seen from above: direct light only.
const FLOOR: &str = r#"{
    "camera": {"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov": 60,
               "width": 32, "height": 32},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.6, 0.6, 0.6]}},
    "objects": [{"type": "quad", "material": "floor", "corner": [-50, 0, -50],
                 "edge_u": [0, 0, 100], "edge_v": [100, 0, 0]}],
    "lights": [{"type": "point", "position": [0.3, 1, -0.2], "power": [50, 50, 50]}]
}"#;

#[test]
fn every_technique_renders_the_lit_floor_within_1_percent_per_region() {
    let s = scene(FLOOR);
    let light = DVec3::new(0.3, 1.0, -0.2);
    let want: Vec<f64> = analytic_pixels(&s, |o, d| {
        let hit = o + d * (-o.y / d.y);
        Some(point_lit(hit, DVec3::Y, light, 50.0, 0.6))
    })
    .into_iter()
    .map(|v| v.unwrap())
    .collect();
    let region = |v: &[f64], x0: usize, y0: usize| {
        let mut sum = 0.0;
        for y in y0..y0 + 8 {
            for x in x0..x0 + 8 {
                sum += v[y * 32 + x];
            }
        }
        sum / 64.0
    };
    // vcm at 4096 passes: merging blurs the light's peak under it (region (12, 12)), a
    // bias that falls as passes^(alpha - 1): -1.0% at 1024 passes, -0.7% at 4096.
    let [pt, lt, bdpt, _] = family(1024);
    let [.., vcm] = family(4096);
    for (name, spec) in [pt, lt, bdpt, vcm] {
        let img = render_checked(&s, &spec).image;
        let got: Vec<f64> = img.pixels.iter().map(|p| p[0] as f64).collect();
        for (x0, y0) in [(0, 0), (12, 12), (24, 8), (8, 24)] {
            let e = rel(region(&got, x0, y0), region(&want, x0, y0));
            assert!(e.abs() < 0.01, "{name}, region ({x0}, {y0}): {e:+.4}");
        }
    }
}

/// A box with a sphere light, a glass sphere and a mirror: every technique but light tracing
/// (which cannot show what the camera sees through glass) carries every path; with an area
/// light, path tracing reaches the caustics too. The family must agree.
const GLASS_BOX: &str = r#"{
    "camera": {"position": [0, 1, 3.2], "look_at": [0, 0.9, 0], "up": [0, 1, 0], "fov": 45,
               "width": 32, "height": 32},
    "materials": {"white": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "red": {"type": "diffuse", "albedo": [0.7, 0.2, 0.2]},
                  "glass": {"type": "dielectric", "ior": 1.5},
                  "mirror": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]}},
    "objects": [
        {"type": "quad", "material": "white", "corner": [-1, 0, 1], "edge_u": [2, 0, 0], "edge_v": [0, 0, -2]},
        {"type": "quad", "material": "white", "corner": [-1, 2, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "white", "corner": [-1, 0, -1], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0]},
        {"type": "quad", "material": "red", "corner": [-1, 0, 1], "edge_u": [0, 0, -2], "edge_v": [0, 2, 0]},
        {"type": "quad", "material": "white", "corner": [1, 0, -1], "edge_u": [0, 0, 2], "edge_v": [0, 2, 0]},
        {"type": "sphere", "material": "glass", "center": [-0.4, 0.4, 0], "radius": 0.4},
        {"type": "sphere", "material": "mirror", "center": [0.5, 0.3, -0.4], "radius": 0.3}],
    "lights": [{"type": "sphere", "center": [0, 1.6, 0], "radius": 0.15, "radiance": [20, 20, 20]}]
}"#;

#[test]
fn path_tracing_bdpt_and_vcm_agree_where_each_carries_every_path() {
    let s = scene(GLASS_BOX);
    let [pt, _, bdpt, vcm] = family(256);
    let mean = |spec: &RenderSpec| {
        let img = render_checked(&s, spec).image;
        let m = img.mean_rgb(0, 0, 32, 32);
        (m[0] + m[1] + m[2]) / 3.0
    };
    let (a, b, c) = (mean(&pt.1), mean(&bdpt.1), mean(&vcm.1));
    eprintln!(
        "glass box: pt {a:.5}, bdpt {b:.5} ({:+.4}), vcm {c:.5} ({:+.4})",
        rel(b, a),
        rel(c, a)
    );
    assert!(rel(b, a).abs() < 0.02, "bdpt {b} vs pt {a}");
    assert!(rel(c, a).abs() < 0.02, "vcm {c} vs pt {a}");
}

/// A box lit only off its back wall: a quad light 2 cm from the wall, facing it. What the
/// camera sees is lit by the bright patch the light makes there, which path tracing finds
/// by chance and bidirectional connections directly (at equal time, 128x128, 3 s, pt's
/// relmse between two seeds is 11x bdpt's). A final gather finds the patch by chance too,
/// and reads it well since shadow rays sample the rectangle by solid angle.
const WALL_WASH: &str = r#"{
    "camera": {"position": [0, 1, 3.9], "look_at": [0, 1, 0], "up": [0, 1, 0], "fov": 37,
               "width": 32, "height": 32},
    "materials": {"white": {"type": "diffuse", "albedo": [0.75, 0.75, 0.75]}},
    "objects": [
        {"type": "quad", "material": "white", "corner": [-1, 0, -1], "edge_u": [0, 0, 2],
         "edge_v": [2, 0, 0]},
        {"type": "quad", "material": "white", "corner": [-1, 2, -1], "edge_u": [2, 0, 0],
         "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "white", "corner": [-1, 0, -1], "edge_u": [2, 0, 0],
         "edge_v": [0, 2, 0]},
        {"type": "quad", "material": "white", "corner": [-1, 0, -1], "edge_u": [0, 2, 0],
         "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "white", "corner": [1, 0, -1], "edge_u": [0, 0, 2],
         "edge_v": [0, 2, 0]}
    ],
    "lights": [{"type": "quad", "corner": [-0.5, 0.6, -0.98], "edge_u": [0, 0.8, 0],
                "edge_v": [1, 0, 0], "radiance": [20, 20, 20]}]
}"#;

/// `WALL_WASH` with a parallelogram light (its edges at 68 degrees), which shadow rays
/// sample by area: a final gather that lands on the patch weighs a sample by up to
/// L A / d^2, thousands of times its mean. At 128x128, 6 s, gathering's relmse between two
/// seeds was 2.3 against bdpt's 0.0041.
fn skewed_wall_wash() -> String {
    let skewed = WALL_WASH.replace(
        r#""edge_v": [1, 0, 0], "radiance""#,
        r#""edge_v": [1, 0.4, 0], "radiance""#,
    );
    assert_ne!(skewed, WALL_WASH);
    skewed
}

/// Final gathering next to a rectangular light facing a wall: its shadow rays sample the
/// light by solid angle, so a gather ray that lands on the bright patch brings back at most
/// 2 pi L. Between two seeds, 64x64, 4 passes of 4 samples and 8 gather rays: relmse 0.07;
/// with the light sampled by area, 158 (fireflies all over the room).
#[test]
fn gathering_next_to_a_light_facing_a_wall_has_no_fireflies() {
    let s = scene(&WALL_WASH.replace(
        r#""width": 32, "height": 32"#,
        r#""width": 64, "height": 64"#,
    ));
    let render = |seed| {
        let mut spec = RenderSpec::ppm(Progressive {
            pass: PhotonMapping {
                gather_rays: 8,
                spp: 4,
                ..PhotonMapping::PPM_PASS
            },
            stop: Stop::after(4),
            ..Progressive::DEFAULT
        });
        spec.seed = seed;
        render_checked(&s, &spec).image
    };
    let relmse = compare(&render(1), &render(2)).unwrap().relmse;
    eprintln!("gathering next to the light, between seeds: relmse {relmse:.4}");
    assert!(relmse < 0.2, "relmse {relmse:.4} between seeds: fireflies");
}

/// `auto` (issue 20, the default integrator): a room without mirror or glass gets ppm with
/// final gathering or bdpt by pilot renders (pt against bdpt, then where pt does poorly
/// gathering against bdpt: ppm where the light shines into the room, under a point light or
/// an area light, and where a point light's hot spot lights it; bdpt where a light washes
/// a wall, a rectangle's or a parallelogram's), and one with glass is rendered by vcm;
/// the choice is exactly that integrator (the same bytes) and `effects.integrator` says
/// which and why.
#[test]
fn auto_gathers_in_an_open_room_connects_off_a_washed_wall_and_merges_behind_glass() {
    let passes = Passes {
        spp: 1,
        stop: Stop::after(2),
    };
    let vcm = Merging {
        passes: passes.clone(),
        ..Merging::DEFAULT
    };
    // auto.rs, `GatherShape`: 4 gather rays at 2 samples a pixel where the pilot's first
    // stage found that a camera path's bounce finds the light, 8 at 1 where it did not;
    // the gathers smoothed within 5 global radii (`GATHER_SMOOTHING`); 2 shadow rays a
    // sample to each area light (`SHADOW_RAYS`).
    let gathering = |gather_rays, spp| {
        Integrator::Ppm(Progressive {
            pass: PhotonMapping {
                gather_rays,
                spp,
                shadow_rays: 2,
                ..PhotonMapping::PPM_PASS
            },
            gather_smoothing: 5.0,
            stop: passes.stop.clone(),
            ..Progressive::DEFAULT
        })
    };
    let skewed = skewed_wall_wash();
    // A point light 25 cm under the ceiling: pt finds its hot spot poorly, gather rays well.
    let hot_spot = Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cornell_spheres.json"
    )))
    .expect("scenes/cornell_spheres.json");
    // Every room at 32x32 (the test scenes' own size; cornell_spheres' is 384x384).
    let at_32 = |integrator| RenderSpec {
        width: Some(32),
        height: Some(32),
        ..RenderSpec::new(integrator)
    };
    for (s, chosen, explicit) in [
        (scene(CLOSED_SPHERE), "ppm", gathering(4, 2)),
        (scene(CLOSED_SPHERE_AREA_LIGHT), "ppm", gathering(4, 2)),
        (hot_spot, "ppm", gathering(8, 1)),
        (scene(WALL_WASH), "bdpt", Integrator::Bdpt(passes.clone())),
        (scene(&skewed), "bdpt", Integrator::Bdpt(passes.clone())),
        (scene(GLASS_BOX), "vcm", Integrator::Vcm(vcm)),
    ] {
        let auto = render_checked(&s, &at_32(Integrator::Auto(passes.clone())));
        let why = &auto.stats.effects["integrator"];
        assert_eq!(why.how, format!("auto chose {chosen}"), "{why:?}");
        assert!(!why.reason.is_empty());
        let direct = render_checked(&s, &at_32(explicit));
        assert!(
            auto.image.pixels == direct.image.pixels,
            "auto's {chosen} image differs from {chosen}'s: {why:?}"
        );
    }
}

/// Under a short time limit alone, auto renders a scene with glass as one photon render
/// sized to the budget (the same bytes as that photon render asked for by name); with a
/// pass count it keeps to vcm's converging passes; a point-lit diffuse room keeps ppm with
/// final gathering whatever the budget.
#[test]
fn auto_takes_a_photon_render_for_a_short_budget_on_glass() {
    let timed = |seconds: f64| Passes {
        spp: 1,
        stop: Stop {
            iterations: None,
            time_limit: Some(seconds),
            target_error: None,
        },
    };
    let glass = scene(GLASS_BOX);
    let auto = render_checked(&glass, &RenderSpec::new(Integrator::Auto(timed(1.0))));
    let why = &auto.stats.effects["integrator"];
    assert_eq!(why.how, "auto chose photon", "{why:?}");
    // 32x32 pixels: half a second holds the ladder's fifth rung (auto.rs).
    let photon = PhotonMapping {
        photons: 400_000,
        caustic_photons: 400_000,
        gather_rays: 16,
        spp: 4,
        ..PhotonMapping::PHOTON
    };
    assert!(
        why.reason
            .contains("400000 photons a map, 16 gather rays, 4 spp"),
        "{why:?}"
    );
    let direct = render_checked(&glass, &RenderSpec::new(Integrator::Photon(photon)));
    assert!(auto.image.pixels == direct.image.pixels);

    // A pass count with the time limit: vcm's converging passes.
    let long = render_checked(
        &glass,
        &RenderSpec::new(Integrator::Auto(Passes {
            spp: 1,
            stop: Stop {
                iterations: Some(2),
                time_limit: Some(1.0),
                target_error: None,
            },
        })),
    );
    assert_eq!(long.stats.effects["integrator"].how, "auto chose vcm");
    let room = scene(CLOSED_SPHERE);
    let diffuse = render_checked(&room, &RenderSpec::new(Integrator::Auto(timed(0.5))));
    assert_eq!(diffuse.stats.effects["integrator"].how, "auto chose ppm");
}

/// Asserts that `got` is within 0.5% of `want`, printing both.
fn within_half_a_percent(label: &str, got: f64, want: f64) {
    eprintln!("{label}: {got:.5} vs {want:.5} ({:+.5})", rel(got, want));
    assert!(
        rel(got, want).abs() < 0.005,
        "{label}: {got:.5} vs {want:.5}"
    );
}

/// Each technique with `passes` passes, following up to 64 bounces (a glass sphere holds
/// light for many internal reflections at a high index).
fn deep_family(passes: u32) -> [(&'static str, RenderSpec); 4] {
    family(passes).map(|(name, spec)| {
        (
            name,
            RenderSpec {
                max_depth: 64,
                ..spec
            },
        )
    })
}

/// A camera looks through a glass sphere (the image inside its outline) at a large quad
/// light behind it, radiance 1: a pixel shows the share of its rays that reach the light
/// after every reflection and refraction, each weighted by the exact Fresnel reflectance.
fn seen_through_glass(ior: f64) -> String {
    format!(
        r#"{{
        "camera": {{"position": [0, 0, 4], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 20,
                    "width": 32, "height": 32}},
        "materials": {{"glass": {{"type": "dielectric", "ior": {ior}}}}},
        "objects": [{{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1}}],
        "lights": [{{"type": "quad", "corner": [-1000, -1000, -1.5], "edge_u": [2000, 0, 0],
                     "edge_v": [0, 2000, 0], "radiance": [1, 1, 1]}}]
    }}"#
    )
}

/// [`seen_through_glass`]'s image mean: the share over the image plane, ring by ring about
/// the axis (a pixel's value is the mean over its square of the image plane).
fn seen_through_glass_mean(ior: f64) -> f64 {
    let t = 10f64.to_radians().tan();
    let rho_max = t * 2f64.sqrt();
    let steps = 20_000;
    let dr = rho_max / steps as f64;
    let sum: f64 = (0..steps)
        .map(|k| {
            let rho = (k as f64 + 0.5) * dr;
            let reach: f64 = exits(4.0, 1.0, ior, rho.atan())
                .iter()
                .filter_map(|e| landing_x(e, -1.5).map(|x| e.w * share(x.abs(), 1000.0)))
                .sum();
            reach * share(rho, t) * 2.0 * PI * rho * dr
        })
        .sum();
    sum / (2.0 * t).powi(2)
}

/// The glass sphere's Fresnel share, seen through it (issue 20, acceptance 1): every
/// technique carries these paths as a camera path through specular vertices to the light, and
/// each must give the closed form (0.917 at index 1.5, 0.502 at index 4, against 1 for a
/// sphere that did not reflect).
#[test]
fn every_technique_sees_the_fresnel_share_through_a_glass_sphere() {
    for ior in [1.5, 4.0] {
        let s = scene(&seen_through_glass(ior));
        let want = seen_through_glass_mean(ior);
        for (name, spec) in deep_family(400) {
            let got = render_checked(&s, &spec).image.mean_rgb(0, 0, 32, 32)[0];
            within_half_a_percent(&format!("seen through glass {ior}, {name}"), got, want);
        }
    }
}

/// A point light over a glass sphere over a dark diffuse floor (albedo 0.01, so that light
/// the floor sends back through the sphere adds under 0.1%), the floor seen straight down
/// from between the sphere and the floor, a vertical field of view of `fov` degrees: at 80
/// the view lies inside the sphere's shadow (only light through the glass), at 120 it takes
/// in the whole shadow and the lit floor around it.
const CAUSTIC_D: f64 = 2.5;
const CAUSTIC_FLOOR: f64 = -3.0;
const CAUSTIC_CAMERA: f64 = -1.1;
const CAUSTIC_ALBEDO: f64 = 0.01;

fn caustic_floor(ior: f64, pixels: u32, fov: f64) -> String {
    format!(
        r#"{{
        "camera": {{"position": [0, {CAUSTIC_CAMERA}, 0], "look_at": [0, {CAUSTIC_FLOOR}, 0],
                    "up": [0, 0, -1], "fov": {fov}, "width": {pixels}, "height": {pixels}}},
        "materials": {{"glass": {{"type": "dielectric", "ior": {ior}}},
                       "floor": {{"type": "diffuse", "albedo": [{a}, {a}, {a}]}}}},
        "objects": [
            {{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1}},
            {{"type": "quad", "material": "floor", "corner": [-500, {CAUSTIC_FLOOR}, -500],
              "edge_u": [0, 0, 1000], "edge_v": [1000, 0, 0]}}
        ],
        "lights": [{{"type": "point", "position": [0, {CAUSTIC_D}, 0], "power": [100, 100, 100]}}]
    }}"#,
        a = CAUSTIC_ALBEDO
    )
}

/// Half the width of the square of floor [`caustic_floor`]'s camera sees at `fov` degrees.
fn caustic_view(fov: f64) -> f64 {
    (CAUSTIC_CAMERA - CAUSTIC_FLOOR) * (fov / 2.0).to_radians().tan()
}

/// The power (W) on the square of floor [`caustic_floor`]'s camera sees, read from its
/// image: a diffuse floor's radiance is albedo/pi times its irradiance, and the square is
/// parallel to the image plane, so the image's mean is the square's.
fn caustic_floor_seen(image: &photonbox::render::Image, half_width: f64) -> f64 {
    let mean = image.mean_rgb(0, 0, image.width, image.height)[0];
    PI / CAUSTIC_ALBEDO * mean * (2.0 * half_width).powi(2)
}

/// The power (W) reaching the square of floor [`caustic_floor`]'s camera sees: what falls on
/// it directly (none inside the sphere's shadow; where the square holds the whole shadow,
/// its solid angle from the light less the sphere's cone), and every exit of each ray of the
/// cone that lands in it.
fn caustic_floor_power(ior: f64, half_width: f64) -> f64 {
    let (power, h) = (100.0, CAUSTIC_D - CAUSTIC_FLOOR);
    let alpha_max = (1.0 / CAUSTIC_D).asin();
    let shadow = h * alpha_max.tan();
    let direct = if half_width * 2f64.sqrt() < shadow {
        0.0
    } else {
        assert!(half_width > shadow, "the view cuts the shadow's edge");
        let s2 = half_width * half_width;
        let square = 4.0 * (s2 / (s2 + h * h)).asin();
        let cone = 2.0 * PI * (1.0 - alpha_max.cos());
        power * (square - cone) / (4.0 * PI)
    };
    let steps = 100_000;
    let da = alpha_max / steps as f64;
    let through: f64 = (0..steps)
        .map(|k| {
            let alpha = (k as f64 + 0.5) * da;
            let landed: f64 = exits(CAUSTIC_D, 1.0, ior, alpha)
                .iter()
                .filter_map(|e| {
                    landing_x(e, CAUSTIC_FLOOR).map(|x| e.w * share(x.abs(), half_width))
                })
                .sum();
            landed * alpha.sin() * da / 2.0
        })
        .sum();
    direct + power * through
}

/// The glass sphere's Fresnel share as a caustic on the floor (issue 20, acceptance 1): the
/// power the floor receives inside the sphere's shadow, read from the image, against the
/// closed form. `pt` is not among them:
/// a point light behind glass is reached by no camera path (it is seen through the sphere
/// above).
#[test]
fn light_tracing_bdpt_and_vcm_carry_the_fresnel_share_to_the_floor() {
    let half_width = caustic_view(80.0);
    for ior in [1.5, 4.0] {
        let s = scene(&caustic_floor(ior, 128, 80.0));
        let want = caustic_floor_power(ior, half_width);
        // vcm's merges of this concentrated caustic are noisier than the light tracer's
        // splats (at 200 passes two seeds read -0.3% and -0.8% at index 4): four times the
        // passes.
        let [_, lt, bdpt, _] = deep_family(200);
        let [.., vcm] = deep_family(800);
        for (name, spec) in [lt, bdpt, vcm] {
            let got = caustic_floor_seen(&render_checked(&s, &spec).image, half_width);
            within_half_a_percent(&format!("caustic floor {ior}, {name} (W)"), got, want);
        }
    }
}

/// vcm's automatic merge radius follows what the camera sees (`bidir/radius.rs`): on the
/// caustic floor at 32x32 (1,024 light paths an iteration, most of them landing on the open
/// floor out of view) the radius from the light vertices alone was about 1.9 and the floor's
/// power came out 1.0% low after 2,000 passes (the merges blurred the view); with the
/// camera's side measured too it is 0.94, and -0.16%.
#[test]
fn vcm_s_automatic_radius_keeps_an_open_floor_at_low_resolution_within_half_a_percent() {
    let half_width = caustic_view(120.0);
    let s = scene(&caustic_floor(1.5, 32, 120.0));
    let want = caustic_floor_power(1.5, half_width);
    let [.., (_, vcm)] = deep_family(2000);
    let out = render_checked(&s, &vcm);
    let got = caustic_floor_seen(&out.image, half_width);
    let r0 = out.stats.ppm.as_ref().map(|p| p.radius_initial_global);
    within_half_a_percent(
        &format!("open floor at 32x32, vcm, radius {r0:?} (W)"),
        got,
        want,
    );
}

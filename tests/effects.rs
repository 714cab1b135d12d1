//! Effects analysis and switches (issue 5): a job simulates only what its scene calls for
//! and what it asks for, and says why in its stats.

mod common;

use common::{render_checked, scene};
use photonbox::render::{Control, Scene, render};
use photonbox::spec::{EffectSwitches, Integrator, Passes, PhotonMapping, RenderSpec, Stop};

fn scene_file(name: &str) -> Scene {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    Scene::load(&path).unwrap()
}

fn small(effects: EffectSwitches) -> RenderSpec {
    RenderSpec {
        width: Some(48),
        height: Some(48),
        effects,
        ..RenderSpec::photon(PhotonMapping {
            photons: 100_000,
            caustic_photons: 100_000,
            k: 30,
            gather_rays: 0,
            spp: 2,
            ..PhotonMapping::PHOTON
        })
    }
}

fn only(name: &str) -> EffectSwitches {
    EffectSwitches {
        direct_light: name == "direct_light",
        caustics: name == "caustics",
        diffuse_interreflection: name == "diffuse_interreflection",
    }
}

fn mean(img: &photonbox::render::Image) -> [f64; 3] {
    let mut m = [0.0; 3];
    for p in &img.pixels {
        for c in 0..3 {
            m[c] += p[c] as f64 / img.pixels.len() as f64;
        }
    }
    m
}

/// Each effect alone, summed, is the whole image: the switches split the light between
/// them without loss or double counting. Off, caustics trace no photons.
#[test]
fn the_effects_switched_on_one_at_a_time_add_up_to_the_full_image() {
    let s = scene_file("cornell_mirror_glass.json");
    let full = render(&s, &small(EffectSwitches::ALL_ON), &Control::none()).unwrap();
    let mut sum = [0.0; 3];
    for name in ["direct_light", "caustics", "diffuse_interreflection"] {
        let out = render_checked(&s, &small(only(name)));
        let m = mean(&out.image);
        eprintln!("{name}: mean {m:?}");
        assert!(m[0] > 1e-3, "{name} alone lights the box: {m:?}");
        for c in 0..3 {
            sum[c] += m[c];
        }
        for other in ["direct_light", "caustics", "diffuse_interreflection"] {
            let e = &out.stats.effects[other];
            assert_eq!(
                e.simulated,
                other == name,
                "{other} with only {name}: {e:?}"
            );
            if other != name {
                assert!(e.reason.contains("switched off"), "{e:?}");
            }
        }
        let caustic_emitted = out.stats.photons.caustic_emitted;
        assert_eq!(caustic_emitted > 0, name == "caustics", "{name}");
        let global_emitted = out.stats.photons.global_emitted;
        assert_eq!(
            global_emitted > 0,
            name == "diffuse_interreflection",
            "{name}"
        );
    }
    let m = mean(&full.image);
    eprintln!("full {m:?}, sum of the parts {sum:?}");
    for c in 0..3 {
        assert!((sum[c] / m[c] - 1.0).abs() < 0.003, "{sum:?} vs {m:?}");
    }
}

/// The same switches through the CLI's flags reach STATS.json.
#[test]
fn cli_no_caustics_traces_no_caustic_photons() {
    let dir = tempfile::tempdir().unwrap();
    let stats = dir.path().join("s.json");
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/glass_orange.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_photonbox"))
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(dir.path().join("a.png"))
        .arg("--stats")
        .arg(&stats)
        .args(["--integrator", "photon", "--width", "16", "--height", "16"])
        .args(["--photons", "5000"])
        .args(["--no-caustics", "--no-indirect"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(&stats).unwrap()).unwrap();
    assert_eq!(s["photons"]["caustic_emitted"], 0);
    assert_eq!(s["photons"]["global_emitted"], 0);
    assert_eq!(s["effects"]["caustics"]["simulated"], false);
    assert_eq!(s["effects"]["diffuse_interreflection"]["simulated"], false);
    assert_eq!(s["effects"]["direct_light"]["simulated"], true);
}

/// A floor under a point light, and a second light inside a closed object.
fn shut_scene(shell: &str, camera: [f64; 3]) -> String {
    let [cx, cy, cz] = camera;
    format!(
        r#"{{
        "camera": {{"position": [{cx}, {cy}, {cz}], "look_at": [0, 0.5, 0], "up": [0, 1, 0],
                    "fov": 50, "width": 32, "height": 32}},
        "materials": {{"white": {{"type": "diffuse", "albedo": [0.7, 0.7, 0.7]}},
                      "glass": {{"type": "dielectric", "ior": 1.5}}}},
        "objects": [
            {{"type": "quad", "material": "white", "corner": [-5, 0, -5],
              "edge_u": [0, 0, 10], "edge_v": [10, 0, 0]}},
            {shell}
        ],
        "lights": [
            {{"type": "point", "position": [1, 2, 1], "power": [40, 40, 40]}},
            {{"type": "point", "position": [0, 0.5, 0], "power": [900, 900, 900]}}
        ]
    }}"#
    )
}

const OUTSIDE: [f64; 3] = [0.0, 1.0, 3.0];

const SPHERE: &str =
    r#"{"type": "sphere", "material": "white", "center": [0, 0.5, 0], "radius": 0.3}"#;

/// A closed cube around (0, 0.5, 0), side 0.6, outward faces, shared vertices.
fn cube(material: &str) -> String {
    let mut p = vec![];
    for i in 0..8 {
        let c = |bit: i32| if i & bit != 0 { 0.3 } else { -0.3 };
        p.push(format!("[{}, {}, {}]", c(1), 0.5 + c(2), c(4)));
    }
    let t = "[0,2,3],[0,3,1],[4,5,7],[4,7,6],[0,1,5],[0,5,4],[2,6,7],[2,7,3],[0,4,6],[0,6,2],[1,3,7],[1,7,5]";
    format!(
        r#"{{"type": "mesh", "material": "{material}", "positions": [{}], "triangles": [{t}]}}"#,
        p.join(",")
    )
}

#[test]
fn a_light_shut_in_a_closed_object_emits_no_photons() {
    let params = RenderSpec::photon(PhotonMapping {
        photons: 50_000,
        caustic_photons: 0,
        k: 20,
        gather_rays: 0,
        spp: 1,
        ..PhotonMapping::PHOTON
    });
    for shell in [SPHERE.to_string(), cube("white")] {
        let s = scene(&shut_scene(&shell, OUTSIDE));
        assert_eq!(s.shut_in, vec![None, Some(1)], "{shell}");
        let out = render(&s, &params, &Control::none()).unwrap();
        let e = &out.stats.effects["lights[1]"];
        assert!(!e.simulated && e.reason.contains("objects[1]"), "{e:?}");
        assert!(out.stats.effects["lights[0]"].simulated);
        // Every stored photon came from light 0: the same as without the shut light.
        let without = shut_scene(&shell, OUTSIDE).replace("900, 900, 900", "0, 0, 0");
        let reference = render(&scene(&without), &params, &Control::none()).unwrap();
        assert_eq!(
            out.stats.photons.global_stored,
            reference.stats.photons.global_stored
        );
        let (a, b) = (mean(&out.image), mean(&reference.image));
        assert!((a[0] / b[0] - 1.0).abs() < 1e-3, "{a:?} vs {b:?}");
    }
    // Not shut: the camera inside the shell, or a glass shell, or a cube with a face missing.
    let inside = scene(&shut_scene(SPHERE, [0.0, 0.6, 0.1]));
    assert_eq!(inside.shut_in, vec![None, None]);
    let glass = scene(&shut_scene(&SPHERE.replace("white", "glass"), OUTSIDE));
    assert_eq!(glass.shut_in, vec![None, None]);
    let open = cube("white").replace(",[1,3,7],[1,7,5]", "");
    assert_eq!(scene(&shut_scene(&open, OUTSIDE)).shut_in, vec![None, None]);
}

/// The only light shut in: no photons at all, and a black, finite image.
#[test]
fn with_every_light_shut_in_nothing_is_traced_and_the_image_is_black() {
    let json = shut_scene(SPHERE, OUTSIDE).replace("40, 40, 40", "0, 0, 0");
    let s = scene(&json);
    let params = RenderSpec::photon(PhotonMapping {
        photons: 10_000,
        caustic_photons: 10_000,
        k: 500,
        spp: 1,
        ..PhotonMapping::PHOTON
    });
    let out = render_checked(&s, &params);
    assert_eq!(out.stats.photons.global_emitted, 0);
    assert_eq!(out.stats.photons.global_stored, 0);
    assert!(out.image.pixels.iter().all(|p| p.iter().all(|c| *c == 0.0)));
}

/// A closed bipyramid around (0, 0.5, 0) of 2n triangles: a ring of n vertices at height
/// 0.5, an apex above and one below, shared vertices, faces outward.
fn bipyramid(n: usize) -> String {
    let mut p = vec!["[0, 0.8, 0]".to_string(), "[0, 0.2, 0]".to_string()];
    for i in 0..n {
        let a = std::f64::consts::TAU * i as f64 / n as f64;
        p.push(format!("[{:.9}, 0.5, {:.9}]", 0.3 * a.cos(), 0.3 * a.sin()));
    }
    let ring = |i: usize| 2 + i % n;
    let t: Vec<String> = (0..n)
        .flat_map(|i| {
            [
                format!("[0,{},{}]", ring(i + 1), ring(i)),
                format!("[1,{},{}]", ring(i), ring(i + 1)),
            ]
        })
        .collect();
    format!(
        r#"{{"type": "mesh", "material": "white", "positions": [{}], "triangles": [{}]}}"#,
        p.join(","),
        t.join(",")
    )
}

/// Looking for point lights in meshes reads every triangle for every light: a scene of a few
/// megabytes (many lights in a large mesh) would ask for minutes of it. The tests stop at a
/// budget: the lights tested before it are found shut in, those after are taken to emit
/// (the side the analysis errs on), the same on every run.
#[test]
fn looking_for_lights_in_a_large_mesh_stops_at_a_budget() {
    let lights: Vec<String> = (0..400)
        .map(|i| {
            let (x, z) = (0.0001 * (i % 20) as f64, 0.0001 * (i / 20) as f64);
            format!(r#"{{"type": "point", "position": [{x}, 0.47, {z}], "power": [1, 1, 1]}}"#)
        })
        .collect();
    let json = shut_scene(&bipyramid(40_960), OUTSIDE).replace(
        r#""lights": ["#,
        &format!(r#""lights": [{},"#, lights.join(",")),
    );
    let s = scene(&json);
    assert_eq!(s.shut_in.len(), 402);
    let shut = s.shut_in.iter().take_while(|h| **h == Some(1)).count();
    // 81,920 triangles: a few hundred lights' tests, then none (the last light of
    // shut_scene is in the bipyramid too).
    assert!((100..400).contains(&shut), "{shut} lights found shut in");
    assert!(s.shut_in[shut..].iter().all(Option::is_none));
    assert_eq!(scene(&json).shut_in, s.shut_in);
}

/// Light tracing cannot show what the camera sees in a mirror or through glass (it joins
/// light vertices to the camera directly): its stats say so, where the scene has them, and
/// path tracing's do not.
#[test]
fn light_tracing_says_the_camera_sees_no_mirror_or_glass() {
    let s = scene_file("cornell_mirror_glass.json");
    let passes = Passes {
        spp: 1,
        stop: Stop::after(1),
    };
    let spec = |integrator| RenderSpec {
        width: Some(8),
        height: Some(8),
        ..RenderSpec::new(integrator)
    };
    let lt = render(&s, &spec(Integrator::Lt(passes.clone())), &Control::none()).unwrap();
    for name in ["specular_reflection", "refraction"] {
        let e = &lt.stats.effects[name];
        assert_eq!(e.how, "on light paths only", "{name}");
        assert!(e.reason.contains("stays black"), "{name}: {e:?}");
    }
    let pt = render(&s, &spec(Integrator::Pt(passes)), &Control::none()).unwrap();
    assert!(pt.stats.effects["refraction"].how.starts_with("ray traced"));
    let diffuse = render(
        &scene_file("cornell.json"),
        &spec(Integrator::Lt(Passes {
            spp: 1,
            stop: Stop::after(1),
        })),
        &Control::none(),
    )
    .unwrap();
    assert_eq!(diffuse.stats.effects["refraction"].how, "none");
}

/// The same budget bounds lights x objects: thousands of lights over thousands of small
/// spheres stop being looked for once it is spent, so a light shut in a sphere is found
/// when it comes first and taken to emit when it comes last.
#[test]
fn looking_for_lights_among_many_objects_stops_at_the_budget_too() {
    let n = 9_000;
    let mut objects = vec![SPHERE.to_string()];
    objects.extend((1..n).map(|i| {
        let x = 100.0 + (i % 100) as f64;
        let z = (i / 100) as f64;
        format!(
            r#"{{"type": "sphere", "material": "white", "center": [{x}, 0, {z}], "radius": 0.1}}"#
        )
    }));
    let shut = r#"{"type": "point", "position": [0, 0.5, 0], "power": [1, 1, 1]}"#;
    let mut lights = vec![shut.to_string()];
    lights.extend((1..n - 1).map(|i| {
        format!(
            r#"{{"type": "point", "position": [-50, 1, {}], "power": [1, 1, 1]}}"#,
            i % 97
        )
    }));
    lights.push(shut.to_string());
    let json = format!(
        r#"{{"camera": {{"position": [0, 1, 3], "look_at": [0, 0.5, 0], "up": [0, 1, 0],
                       "fov": 50, "width": 8, "height": 8}},
             "materials": {{"white": {{"type": "diffuse", "albedo": [0.7, 0.7, 0.7]}}}},
             "objects": [{}], "lights": [{}]}}"#,
        objects.join(","),
        lights.join(",")
    );
    let s = scene(&json);
    assert_eq!(s.shut_in.len(), n);
    assert_eq!(s.shut_in[0], Some(0));
    assert_eq!(s.shut_in[n - 1], None, "the last light was looked for");
}

//! The `photonbox render` command line: outputs, stats, determinism across thread counts,
//! and bad input (issue 2, acceptance 3 and 6).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn photonbox() -> Command {
    Command::new(env!("CARGO_BIN_EXE_photonbox"))
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn run(args: &[&str]) -> Output {
    photonbox().args(args).output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn render_writes_png_exr_and_stats() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("out.png");
    let exr = dir.path().join("out.exr");
    let stats = dir.path().join("stats.json");
    let scene = repo("scenes/cornell_mirror_glass.json");
    let o = run(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--exr",
        exr.to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
        "--width",
        "40",
        "--height",
        "30",
        "--integrator",
        "photon",
        "--photons",
        "20000",
        "--caustic-photons",
        "20000",
        "--spp",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (40, 30));
    let hdr = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!(hdr.dimensions(), (40, 30));
    assert!(hdr.pixels().flat_map(|p| p.0).all(f32::is_finite));
    assert!(hdr.pixels().map(|p| p.0[0]).sum::<f32>() > 0.0);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for key in ["photon_trace", "build_maps", "render", "total"] {
        assert!(s["times"][key].as_f64().unwrap() >= 0.0, "times.{key}");
    }
    assert_eq!(s["photons"]["global_emitted"], 20000);
    assert_eq!(s["photons"]["caustic_emitted"], 20000);
    assert!(s["photons"]["global_stored"].as_u64().unwrap() > 0);
    assert!(s["photons"]["caustic_stored"].as_u64().unwrap() > 0);
    let bpp = s["photons"]["bytes_per_photon"].as_f64().unwrap();
    assert!(
        (24.0..=32.0).contains(&bpp),
        "{bpp} bytes per stored photon"
    );
    assert_eq!(s["effects"]["caustics"]["simulated"], true);
    assert_eq!(s["nonfinite_samples"], 0);
    assert!(s["radius"]["caustic_max"].as_f64().unwrap() > 0.0);
}

/// Acceptance 3: the same scene, parameters and seed give the same EXR bytes with 1 and 2
/// threads (final gathering on, so every phase runs).
#[test]
fn exr_is_bit_identical_with_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scene = repo("scenes/cornell_mirror_glass.json");
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let exr = dir.path().join(format!("t{threads}.exr"));
        let png = dir.path().join(format!("t{threads}.png"));
        let o = run(&[
            "render",
            scene.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--exr",
            exr.to_str().unwrap(),
            "--width",
            "48",
            "--height",
            "48",
            "--integrator",
            "photon",
            "--photons",
            "50000",
            "--caustic-photons",
            "50000",
            "--gather-rays",
            "4",
            "--spp",
            "2",
            "--threads",
            threads,
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        outputs.push(std::fs::read(&exr).unwrap());
    }
    assert!(outputs[0].len() > 1000);
    assert!(
        outputs[0] == outputs[1],
        "EXR bytes differ between 1 and 2 threads"
    );
}

/// Acceptance 6: bad input is a one-line error naming the JSON path, exit code 2.
fn expect_bad_scene(json: &str, extra_files: &[(&str, &str)], expect_in_message: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("scenes");
    std::fs::create_dir(&sub).unwrap();
    let scene = sub.join("s.json");
    std::fs::write(&scene, json).unwrap();
    for (name, text) in extra_files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let png = dir.path().join("o.png");
    let o = run(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "exit code for {json}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for needle in expect_in_message {
        assert!(
            err.contains(needle),
            "error {err:?} should contain {needle:?}"
        );
    }
    assert!(!png.exists(), "no output on bad input");
}

const CAMERA: &str = r#""camera": {"position": [0, 1, 4], "look_at": [0, 1, 0], "up": [0, 1, 0], "fov": 40, "width": 8, "height": 8}"#;
const LIGHTS: &str =
    r#""lights": [{"type": "point", "position": [0, 2, 0], "power": [10, 10, 10]}]"#;
const MATS: &str = r#""materials": {"white": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}}"#;

fn with_objects(objects: &str) -> String {
    format!("{{{CAMERA}, {MATS}, \"objects\": [{objects}], {LIGHTS}}}")
}

#[test]
fn malformed_json() {
    expect_bad_scene("{\"camera\": ", &[], &["invalid JSON", "line 1"]);
}

#[test]
fn unknown_key_names_its_path() {
    expect_bad_scene(
        &with_objects(
            r#"{"type": "sphere", "material": "white", "center": [0,0,0], "radius": 1, "radus": 2}"#,
        ),
        &[],
        &["objects[0]", "radus"],
    );
    expect_bad_scene(
        &format!("{{{CAMERA}, {MATS}, \"objects\": [], {LIGHTS}, \"extra\": 1}}"),
        &[],
        &["extra"],
    );
}

#[test]
fn wrong_type_names_its_path() {
    expect_bad_scene(
        &with_objects(
            r#"{"type": "quad", "material": "white", "corner": [0,0,0], "edge_u": [1,0,0], "edge_v": [0,0,1]},
               {"type": "sphere", "material": "white", "center": [0,0,0], "radius": "big"}"#,
        ),
        &[],
        &["objects[1].radius", "expected a number"],
    );
    expect_bad_scene(
        &with_objects(r#"{"type": "sphere", "material": "white", "center": [0,0], "radius": 1}"#),
        &[],
        &["objects[0].center"],
    );
    expect_bad_scene(
        &with_objects(r#"{"type": "cube", "material": "white"}"#),
        &[],
        &["objects[0].type", "cube"],
    );
}

#[test]
fn negative_radius_and_degenerate_geometry() {
    expect_bad_scene(
        &with_objects(
            r#"{"type": "sphere", "material": "white", "center": [0,0,0], "radius": -1}"#,
        ),
        &[],
        &["objects[0].radius", "> 0"],
    );
    expect_bad_scene(
        &with_objects(
            r#"{"type": "quad", "material": "white", "corner": [0,0,0], "edge_u": [1,0,0], "edge_v": [2,0,0]}"#,
        ),
        &[],
        &["objects[0]", "degenerate"],
    );
    expect_bad_scene(
        &with_objects(
            r#"{"type": "mesh", "material": "white", "positions": [[0,0,0],[1,0,0],[0,1,0],[2,0,0]],
                "triangles": [[0,1,2],[0,1,3]]}"#,
        ),
        &[],
        &["objects[0].triangles[1]", "degenerate"],
    );
    expect_bad_scene(
        &with_objects(
            r#"{"type": "mesh", "material": "white", "positions": [[0,0,0],[1,0,0],[0,1,0]], "triangles": [[0,1,7]]}"#,
        ),
        &[],
        &["objects[0].triangles[0]", "out of range"],
    );
    expect_bad_scene(
        &format!(
            "{{{CAMERA}, {MATS}, \"objects\": [], \"lights\": [{{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 0, \"radiance\": [1,1,1]}}]}}"
        ),
        &[],
        &["lights[0].radius"],
    );
    // A number too large for any float is malformed JSON.
    expect_bad_scene(
        &with_objects(
            r#"{"type": "sphere", "material": "white", "center": [0,0,0], "radius": 1e999}"#,
        ),
        &[],
        &["invalid JSON"],
    );
}

#[test]
fn energy_creating_colours_huge_numbers_and_images_are_refused() {
    expect_bad_scene(
        &format!(
            r#"{{{CAMERA}, "materials": {{"w": {{"type": "diffuse", "albedo": [200, 30, 30]}}}}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["materials.w.albedo", "at most 1", "255"],
    );
    expect_bad_scene(
        &format!(
            r#"{{{CAMERA}, "materials": {{"m": {{"type": "mirror", "reflectance": [1.2, 1, 1]}}}}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["materials.m.reflectance"],
    );
    expect_bad_scene(
        &with_objects(
            r#"{"type": "sphere", "material": "white", "center": [1e20, 0, 0], "radius": 1}"#,
        ),
        &[],
        &["objects[0].center", "magnitude"],
    );
    expect_bad_scene(
        &format!(
            r#"{{"camera": {{"position": [0,1,4], "look_at": [0,1,0], "up": [0,1,0], "fov": 40, "width": 100000, "height": 8}}, {MATS}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["camera.width", "16384"],
    );
}

/// An OBJ file's material library is never opened (it could name any file, or a device
/// that never ends).
#[test]
fn obj_material_libraries_are_not_opened() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "mtllib /dev/zero\nmtllib ../../../etc/passwd\nv -1 0 -1\nv 1 0 -1\nv 0 0 1\nf 1 3 2\n",
    )
    .unwrap();
    let scene = dir.path().join("s.json");
    std::fs::write(
        &scene,
        with_objects(r#"{"type": "mesh", "material": "white", "obj": "tri.obj"}"#),
    )
    .unwrap();
    let png = dir.path().join("o.png");
    let o = run(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--integrator",
        "photon",
        "--photons",
        "1000",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(png.exists());
}

#[test]
fn unknown_material_names_its_path() {
    expect_bad_scene(
        &with_objects(
            r#"{"type": "sphere", "material": "chrome", "center": [0,0,0], "radius": 1}"#,
        ),
        &[],
        &["objects[0].material", "chrome", "white"],
    );
}

#[test]
fn obj_outside_the_scene_folder_is_refused() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    expect_bad_scene(
        &with_objects(r#"{"type": "mesh", "material": "white", "obj": "../outside.obj"}"#),
        &[("outside.obj", tri)],
        &["objects[0].obj", "outside"],
    );
    expect_bad_scene(
        &with_objects(r#"{"type": "mesh", "material": "white", "obj": "/etc/passwd"}"#),
        &[],
        &["objects[0].obj", "relative"],
    );
    expect_bad_scene(
        &with_objects(r#"{"type": "mesh", "material": "white", "obj": "missing.obj"}"#),
        &[],
        &["objects[0].obj", "missing.obj"],
    );
}

#[test]
fn camera_and_materials_are_checked() {
    expect_bad_scene(
        &format!(
            r#"{{"camera": {{"position": [0,1,4], "look_at": [0,1,4], "up": [0,1,0], "fov": 40, "width": 8, "height": 8}}, {MATS}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["camera.look_at"],
    );
    expect_bad_scene(
        &format!(
            r#"{{{CAMERA}, "materials": {{"p": {{"type": "phong", "diffuse": [0.6,0.6,0.6], "specular": [0.6,0.6,0.6], "exponent": 10}}}}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["materials.p", "energy"],
    );
    expect_bad_scene(
        &format!(
            r#"{{{CAMERA}, "materials": {{"g": {{"type": "dielectric"}}}}, "objects": [], {LIGHTS}}}"#
        ),
        &[],
        &["materials.g", "ior"],
    );
}

#[test]
fn bad_flags_exit_2() {
    let scene = repo("scenes/cornell.json");
    for args in [
        vec!["--k", "0"],
        vec!["--width", "0"],
        vec!["--spp", "0"],
        vec!["--integrator", "ppm", "--alpha", "1.5"],
        vec!["--integrator", "ppm", "--radius", "-1"],
        vec!["--integrator", "photon", "--iterations", "3"],
        vec!["--photons", "1000"],
        vec!["--integrator", "pathtracer"],
        vec!["--photon-store", "some"],
        vec!["--threads", "0"],
    ] {
        let mut all = vec![
            "render",
            scene.to_str().unwrap(),
            "-o",
            "/nonexistent/x.png",
        ];
        all.extend(args.iter().copied());
        let o = run(&all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let o = run(&["render", "/no/such/scene.json", "-o", "/tmp/x.png"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read"));
}

//! Every built-in scene parses and renders a finite, non-black image; the mesh scene has
//! at least 100k triangles (issue 2: scenes/).

mod common;

use std::path::Path;

use photonbox::render::{Control, Scene, render};
use photonbox::spec::RenderSpec;

fn scene_files() -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    v.sort();
    v
}

#[test]
fn every_scene_renders_finite_and_lit() {
    let files = scene_files();
    assert!(
        files.len() >= 6,
        "the seed's four scenes, the Cornell box and a mesh scene"
    );
    for path in files {
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for integrator in ["raytrace", "photon"] {
            let params = RenderSpec {
                width: Some(32),
                height: Some(32),
                ..RenderSpec::raytrace(1)
            };
            let out = render(&scene, &params, &Control::none()).unwrap();
            let px = &out.image.pixels;
            assert!(
                px.iter().flatten().all(|c| c.is_finite() && *c >= 0.0),
                "{}: non-finite or negative pixels",
                path.display()
            );
            let mean: f64 = px
                .iter()
                .map(|p| p[0] as f64 + p[1] as f64 + p[2] as f64)
                .sum::<f64>()
                / px.len() as f64;
            assert!(mean > 1e-3, "{} ({integrator}) is black", path.display());
            assert_eq!(out.stats.nonfinite_samples, 0);
        }
    }
}

#[test]
fn the_mesh_scene_has_at_least_100k_triangles() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/knot.json");
    let scene = Scene::load(&path).unwrap();
    assert!(
        scene.triangle_count >= 100_000,
        "{} triangles",
        scene.triangle_count
    );
}

//! Degenerate geometry (many copies of one triangle, many overlapping triangles) must not
//! make scene building super-linear: its cost is compared with the same number of distinct
//! triangles of the same size, built in the same run (no absolute times).

use std::time::{Duration, Instant};

use photonbox::render::{Control, Scene, SceneDesc, render};
use photonbox::spec::{PhotonMapping, RenderSpec};
use serde_json::json;

/// Triangles per scene: enough that a quadratic build is many times a linear one.
const N: usize = 20_000;

/// A scene of one diffuse mesh, a ceiling light and a camera looking at the mesh.
fn scene_desc(positions: Vec<[f64; 3]>, triangles: Vec<[u32; 3]>) -> SceneDesc {
    let v = json!({
        "camera": {"position": [0.5, 0.5, -3.0], "look_at": [0.5, 0.5, 0.0], "up": [0, 1, 0],
                   "fov": 40, "width": 16, "height": 16},
        "materials": {"white": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
        "objects": [{"type": "mesh", "material": "white", "positions": positions,
                     "triangles": triangles}],
        "lights": [{"type": "point", "position": [0.5, 0.5, -1.0], "power": [10, 10, 10]}]
    });
    SceneDesc::from_value(v, None).expect("test scene is valid")
}

/// The triangle of side `s` with its corner at `c`, in the z = 0 plane.
fn triangle(c: [f64; 3], s: f64) -> [[f64; 3]; 3] {
    [c, [c[0] + s, c[1], c[2]], [c[0], c[1] + s, c[2]]]
}

fn mesh(tris: impl Iterator<Item = [[f64; 3]; 3]>) -> SceneDesc {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for t in tris {
        let i = positions.len() as u32;
        positions.extend(t);
        triangles.push([i, i + 1, i + 2]);
    }
    scene_desc(positions, triangles)
}

const SIDE: f64 = 1e-3;

/// N distinct triangles of side SIDE on a grid over the unit square.
fn distinct(n: usize) -> SceneDesc {
    let m = (n as f64).sqrt().ceil() as usize;
    mesh((0..n).map(|i| {
        let (x, y) = ((i % m) as f64 / m as f64, (i / m) as f64 / m as f64);
        triangle([x, y, 0.0], SIDE)
    }))
}

/// N copies of one triangle of side SIDE (a triangle soup's duplicates, each with its own
/// vertices, as an OBJ export gives them).
fn identical(n: usize) -> SceneDesc {
    copies(n, SIDE)
}

/// N copies of the triangle of side `s` with its corner at the middle of the view.
fn copies(n: usize, s: f64) -> SceneDesc {
    mesh((0..n).map(|_| triangle([0.5 - s / 3.0, 0.5 - s / 3.0, 0.0], s)))
}

/// N triangles about one centroid, each a little larger than the last (from SIDE to twice
/// SIDE): every one overlaps all the others and their boxes nest, but none is a copy.
fn overlapping(n: usize) -> SceneDesc {
    mesh((0..n).map(|i| {
        let s = SIDE * (1.0 + i as f64 / n as f64);
        triangle([0.5 - s / 3.0, 0.5 - s / 3.0, 0.0], s)
    }))
}

/// A fan of N slivers about one vertex, each reaching a little farther than the last:
/// distinct centroids along a line, boxes nested.
fn fan(n: usize) -> SceneDesc {
    mesh((0..n).map(|i| {
        let r = SIDE * (1.0 + i as f64 / n as f64);
        [
            [0.5, 0.5, 0.0],
            [0.5 + r, 0.5 + r * 0.5, 0.0],
            [0.5 + r, 0.5 + r * 0.51, 0.0],
        ]
    }))
}

/// The least of a few builds' times (denoised against the other processes on the machine).
fn build_time(desc: &SceneDesc) -> Duration {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            let scene = Scene::build(desc);
            let dt = t.elapsed();
            assert!(scene.triangle_count >= 2_000);
            dt
        })
        .min()
        .unwrap()
}

fn assert_like_distinct(name: &str, desc: SceneDesc) {
    assert!(Scene::build(&desc).accel.built_top_down(), "{name}: PLOC");
    let base = build_time(&distinct(N));
    let t = build_time(&desc);
    let ratio = t.as_secs_f64() / base.as_secs_f64();
    eprintln!("{name}: {t:?} against {base:?} for distinct triangles: ratio {ratio:.2}");
    assert!(
        ratio < 5.0,
        "{name}: {ratio:.1}x the build time of distinct triangles"
    );
}

#[test]
fn identical_triangles_build_about_as_fast_as_distinct_ones() {
    assert_like_distinct("identical", identical(N));
}

#[test]
fn a_fan_of_nested_slivers_builds_about_as_fast_as_distinct_triangles() {
    assert_like_distinct("fan", fan(N));
}

#[test]
fn overlapping_triangles_build_about_as_fast_as_distinct_ones() {
    assert_like_distinct("overlapping", overlapping(N));
}

/// Ordinary geometry keeps the PLOC build (and so its BVH and images, bit for bit): the
/// distinct triangles and every scene shipped.
#[test]
fn ordinary_scenes_keep_the_ploc_build() {
    assert!(!Scene::build(&distinct(N)).accel.built_top_down());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut seen = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "json") {
            let scene = Scene::load(&path).unwrap();
            assert!(!scene.accel.built_top_down(), "{}", path.display());
            seen += 1;
        }
    }
    assert!(seen >= 5, "{seen} scenes");
}

/// The top-down BVH finds the same hits: 2,000 copies of a triangle render the image of 17
/// copies (a PLOC BVH; 16 or fewer are tested one by one), bit for bit.
#[test]
fn copies_render_the_same_image_with_either_build() {
    let params = RenderSpec::photon(PhotonMapping {
        photons: 20_000,
        caustic_photons: 0,
        gather_rays: 4,
        spp: 2,
        ..PhotonMapping::PHOTON
    });
    let few = Scene::build(&copies(17, 0.5));
    let many = Scene::build(&copies(2_000, 0.5));
    assert!(!few.accel.built_top_down() && many.accel.built_top_down());
    let a = render(&few, &params, &Control::none()).unwrap().image;
    let b = render(&many, &params, &Control::none()).unwrap().image;
    let lit = a.pixels.iter().filter(|p| p[0] > 0.0).count();
    assert!(lit > 0, "the triangle is seen and lit");
    assert_eq!(a, b);
}

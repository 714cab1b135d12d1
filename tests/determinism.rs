//! The same scene, parameters and seed give bit-identical images whatever the thread count
//! (issue 2, acceptance 3), across integrators, photon-store modes, final gathering, glossy
//! rays, area lights and the BVH path. tests/cli.rs checks the EXR bytes end to end.

use std::path::Path;

use photonbox::render::photon::PhotonStore;
use photonbox::render::{Control, IntegratorKind, RenderParams, Scene, render};

fn render_with_threads(scene: &Scene, params: &RenderParams, threads: usize) -> Vec<[f32; 3]> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        render(scene, params, &Control::none())
            .unwrap()
            .image
            .pixels
    })
}

fn check(scene_file: &str, params: RenderParams) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(scene_file);
    let scene = Scene::load(&path).unwrap();
    let one = render_with_threads(&scene, &params, 1);
    let two = render_with_threads(&scene, &params, 2);
    let three = render_with_threads(&scene, &params, 3);
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&one) == bits(&two),
        "{scene_file} {params:?}: 1 vs 2 threads differ"
    );
    assert!(
        bits(&one) == bits(&three),
        "{scene_file} {params:?}: 1 vs 3 threads differ"
    );
    assert!(one.iter().flatten().any(|c| *c > 0.0));
}

fn small() -> RenderParams {
    RenderParams {
        photons: 30_000,
        caustic_photons: 30_000,
        spp: 2,
        width: Some(48),
        height: Some(40),
        ..RenderParams::default()
    }
}

#[test]
fn photon_map_without_gathering() {
    for k in [1, 50] {
        check(
            "cornell_mirror_glass.json",
            RenderParams {
                k,
                gather_rays: 0,
                ..small()
            },
        );
    }
}

#[test]
fn final_gathering_and_store_modes() {
    for store in [
        PhotonStore::Indirect,
        PhotonStore::All,
        PhotonStore::DirectOnly,
    ] {
        check(
            "glass_orange.json",
            RenderParams {
                photon_store: store,
                gather_rays: 3,
                ..small()
            },
        );
    }
}

#[test]
fn raytrace_glossy_area_light_and_mesh() {
    check(
        "phong_spheres.json",
        RenderParams {
            integrator: IntegratorKind::Raytrace,
            ..small()
        },
    );
    check("phong_spheres.json", small());
    check("cornell.json", small());
    check(
        "knot.json",
        RenderParams {
            gather_rays: 1,
            ..small()
        },
    );
}

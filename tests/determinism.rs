//! The same scene, parameters and seed give bit-identical images whatever the thread count
//! (issue 2, acceptance 3), across integrators, photon-store modes, final gathering, glossy
//! rays, area lights and the BVH path. tests/cli.rs checks the EXR bytes end to end.

use std::path::Path;

use photonbox::render::photon::PhotonStore;
use photonbox::render::{Control, Scene, render};
use photonbox::spec::{PhotonMapping, RenderSpec};

fn render_with_threads(scene: &Scene, params: &RenderSpec, threads: usize) -> Vec<[f32; 3]> {
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

fn check(scene_file: &str, params: RenderSpec) {
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

/// `photon` at 48x40 with `p`'s settings.
fn small(p: PhotonMapping) -> RenderSpec {
    RenderSpec {
        width: Some(48),
        height: Some(40),
        ..RenderSpec::photon(p)
    }
}

const SMALL: PhotonMapping = PhotonMapping {
    photons: 30_000,
    caustic_photons: 30_000,
    spp: 2,
    ..PhotonMapping::PHOTON
};

#[test]
fn photon_map_without_gathering() {
    for k in [1, 50] {
        check(
            "cornell_mirror_glass.json",
            small(PhotonMapping {
                k,
                gather_rays: 0,
                ..SMALL
            }),
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
            small(PhotonMapping {
                photon_store: store,
                gather_rays: 3,
                ..SMALL
            }),
        );
    }
}

#[test]
fn raytrace_glossy_area_light_and_mesh() {
    check(
        "phong_spheres.json",
        RenderSpec {
            width: Some(48),
            height: Some(40),
            ..RenderSpec::raytrace(2)
        },
    );
    check("phong_spheres.json", small(SMALL));
    check("cornell.json", small(SMALL));
    check(
        "knot.json",
        small(PhotonMapping {
            gather_rays: 1,
            ..SMALL
        }),
    );
}

#[test]
fn bidirectional_integrators() {
    use photonbox::spec::{Integrator, Merging, Passes, Stop};
    let passes = Passes {
        spp: 2,
        stop: Stop::after(2),
    };
    for integrator in [
        Integrator::Pt(passes.clone()),
        Integrator::Lt(passes.clone()),
        Integrator::Bdpt(passes.clone()),
        Integrator::Vcm(Merging {
            passes: passes.clone(),
            ..Merging::DEFAULT
        }),
    ] {
        let spec = RenderSpec {
            width: Some(48),
            height: Some(40),
            ..RenderSpec::new(integrator)
        };
        check("cornell_mirror_glass.json", spec.clone());
        check("phong_spheres.json", spec);
    }
}

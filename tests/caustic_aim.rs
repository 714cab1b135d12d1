//! Caustic photons aimed at the specular objects (issue 5, acceptance 1): far more of them
//! are stored per emitted photon than with blind emission, and the caustic's flux is the same.

mod common;

use photonbox::render::Control;
use photonbox::render::photon::{PhotonParams, PhotonStore, build_photon_maps};

/// A glass sphere and a small mirror over a floor, lit by a point light and a quad light.
const SCENE: &str = r#"{
    "camera": {"position": [0, 2, 4], "look_at": [0, 0.5, 0], "up": [0, 1, 0], "fov": 45,
               "width": 32, "height": 32},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "glass": {"type": "dielectric", "ior": 1.5},
                  "mirror": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]}},
    "objects": [{"type": "quad", "material": "floor", "corner": [-5, 0, 5],
                 "edge_u": [10, 0, 0], "edge_v": [0, 0, -10]},
                {"type": "sphere", "material": "glass", "center": [0, 0.6, 0], "radius": 0.5},
                {"type": "quad", "material": "mirror", "corner": [1.5, 0.2, -1],
                 "edge_u": [0, 0, 0.6], "edge_v": [0, 0.6, 0]}],
    "lights": [{"type": "point", "position": [0, 3, 0], "power": [200, 200, 200]},
               {"type": "quad", "corner": [-0.5, 3.5, -0.5], "edge_u": [1, 0, 0],
                "edge_v": [0, 0, 1], "radiance": [5, 5, 5]}]
}"#;

fn caustic(aim: bool, emitted: u64) -> (u64, f64) {
    let scene = common::scene(SCENE);
    let params = PhotonParams {
        global_photons: 0,
        caustic_photons: emitted,
        store: PhotonStore::Indirect,
        max_depth: 32,
        seed: 5,
        aim_caustics: aim,
        dark_lights: vec![],
    };
    let maps = build_photon_maps(&scene, &params, &Control::none()).unwrap();
    let map = maps.caustic.expect("a caustic map");
    assert_eq!(map.emitted, emitted);
    let total = map.total_power();
    assert!(total.iter().all(|c| c.is_finite()));
    (map.len() as u64, total[1])
}

#[test]
fn aimed_caustic_photons_store_more_and_carry_the_same_flux() {
    let (blind_n, blind_flux) = caustic(false, 2_000_000);
    let (aimed_n, aimed_flux) = caustic(true, 200_000);
    let blind_rate = blind_n as f64 / 2e6;
    let aimed_rate = aimed_n as f64 / 2e5;
    eprintln!(
        "stored per emitted: blind {blind_rate:.5} ({blind_n}), aimed {aimed_rate:.5} ({aimed_n}); \
         caustic flux: blind {blind_flux:.4} W, aimed {aimed_flux:.4} W"
    );
    assert!(
        aimed_rate >= 10.0 * blind_rate,
        "{aimed_rate} vs {blind_rate}"
    );
    // Both are estimates of the same flux; the blind one has ~15k photons (1% noise).
    assert!(
        (aimed_flux / blind_flux - 1.0).abs() < 0.03,
        "aimed {aimed_flux} W vs blind {blind_flux} W"
    );
}

/// No specular surface: no caustic photon is traced at all.
#[test]
fn a_diffuse_only_scene_traces_no_caustic_photons() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_spheres.json");
    let scene = photonbox::render::Scene::load(&path).unwrap();
    let params = photonbox::spec::RenderSpec {
        width: Some(16),
        height: Some(16),
        ..photonbox::spec::RenderSpec::photon(photonbox::spec::PhotonMapping {
            photons: 20_000,
            caustic_photons: 20_000,
            ..photonbox::spec::PhotonMapping::PHOTON
        })
    };
    let out = photonbox::render::render(&scene, &params, &Control::none()).unwrap();
    assert_eq!(out.stats.photons.caustic_emitted, 0);
    assert_eq!(out.stats.photons.caustic_stored, 0);
    assert!(!out.stats.effects["caustics"].simulated);
    assert!(out.stats.photons.global_emitted > 0);
}

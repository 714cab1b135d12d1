//! The same scene, parameters and seed give bit-identical images whatever the thread count
//! (issue 2, acceptance 3), across integrators, photon-store modes, final gathering, glossy
//! rays, area lights and the BVH path. tests/cli.rs checks the EXR bytes end to end.

use std::path::Path;

use photonbox::render::photon::PhotonStore;
use photonbox::render::{Control, RenderOutput, Scene, render};
use photonbox::spec::{PhotonMapping, RenderSpec};

/// A scene of scenes/.
fn load(scene_file: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(scene_file);
    Scene::load(&path).unwrap()
}

/// `params`' render of `scene` on a pool of `threads` threads.
fn render_with_threads(scene: &Scene, params: &RenderSpec, threads: usize) -> RenderOutput {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| render(scene, params, &Control::none()).unwrap())
}

/// An image's bits.
fn bits(v: &[[f32; 3]]) -> Vec<u32> {
    v.iter().flatten().map(|c| c.to_bits()).collect()
}

fn check(scene_file: &str, params: RenderSpec) {
    let scene = load(scene_file);
    let bits_with = |threads| bits(&render_with_threads(&scene, &params, threads).image.pixels);
    let one = bits_with(1);
    assert!(
        one == bits_with(2),
        "{scene_file} {params:?}: 1 vs 2 threads differ"
    );
    assert!(
        one == bits_with(3),
        "{scene_file} {params:?}: 1 vs 3 threads differ"
    );
    assert!(one.iter().any(|&b| f32::from_bits(b) > 0.0));
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

/// `auto`'s pilot renders its pairs side by side (`run/pilot.rs`): its variances, and so
/// its choice and the image, are the same bits whatever the thread count, through both
/// stages (cornell_spheres: `pt` does poorly there, so gathering is piloted too).
#[test]
fn auto_s_pilot_and_choice() {
    use photonbox::spec::{Integrator, Passes, Stop};
    let scene = load("cornell_spheres.json");
    let spec = RenderSpec {
        width: Some(32),
        height: Some(32),
        ..RenderSpec::new(Integrator::Auto(Passes {
            spp: 1,
            stop: Stop::after(1),
        }))
    };
    let with_threads = |threads| {
        let out = render_with_threads(&scene, &spec, threads);
        let reason = out.stats.effects["integrator"].reason.clone();
        (reason, bits(&out.image.pixels))
    };
    let (reason, image) = with_threads(1);
    assert!(reason.contains("gathering"), "both stages: {reason}");
    for threads in [2, 3] {
        let (r, b) = with_threads(threads);
        assert_eq!(r, reason, "{threads} threads: another pilot");
        assert!(b == image, "{threads} threads: other bits");
    }
}

/// A one-shot render split into bands of rows (the farm's tiles, `Inputs::rows`), each
/// band rendered apart, half of them over photon maps traced again as on another worker,
/// merges to the bits of the whole render; rows outside the image, a band measured against
/// a reference and a band of a progressive render are refused.
#[test]
fn bands_of_rows_rendered_apart_merge_to_the_bits_of_the_whole_image() {
    use photonbox::farm::Unit;
    use photonbox::farm::outcome::merge;
    use photonbox::farm::task::{Kept, render_unit, split};
    use photonbox::render::{Inputs, Rows, run};
    use std::sync::atomic::AtomicBool;

    let scene = load("cornell_mirror_glass.json");
    let raytrace = RenderSpec {
        width: Some(48),
        height: Some(40),
        ..RenderSpec::raytrace(2)
    };
    let cancel = AtomicBool::new(false);
    for spec in [small(SMALL), raytrace.clone()] {
        let whole = render(&scene, &spec, &Control::none()).unwrap().image;
        let tasks = split(&spec, 1e9, 40, 0);
        assert!(tasks.len() > 1, "{:?}", tasks[0].unit);
        let shared = Kept::default();
        let units: Vec<(Unit, Vec<u8>)> = tasks
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let own = Kept::default();
                let kept = if i % 2 == 0 { &shared } else { &own };
                let key: &[u8] = b"";
                let result = render_unit(&scene, &spec, (key, None), t.unit, kept, &cancel);
                (t.unit, result.unwrap().bytes)
            })
            .collect();
        let merged = merge((48, 40), &units, None).unwrap().image;
        assert!(
            bits(&merged.pixels) == bits(&whole.pixels),
            "{spec:?}: the bands differ from the whole image"
        );
        let mut missing = units.clone();
        missing.remove(1);
        assert!(merge((48, 40), &missing, None).is_err());
    }

    let band = |spec: &RenderSpec, first, count, reference| {
        let inputs = Inputs {
            rows: Some(Rows { first, count }),
            reference,
            ..Inputs::fresh()
        };
        run(&scene, spec, inputs, &Control::none(), &mut |_| {
            std::ops::ControlFlow::Continue(())
        })
        .map(|out| (out.image.width, out.image.height))
        .map_err(|e| e.to_string())
    };
    assert_eq!(band(&raytrace, 39, 1, None), Ok((48, 1)));
    assert!(
        band(&raytrace, 39, 2, None)
            .unwrap_err()
            .contains("rows 39..41")
    );
    assert!(band(&raytrace, 0, 0, None).is_err());
    let reference = photonbox::render::Image::new(48, 40);
    assert!(
        band(&raytrace, 0, 8, Some(&reference))
            .unwrap_err()
            .contains("reference")
    );
    let ppm = RenderSpec {
        width: Some(48),
        height: Some(40),
        ..RenderSpec::ppm(photonbox::spec::Progressive {
            stop: photonbox::spec::Stop::after(2),
            ..photonbox::spec::Progressive::DEFAULT
        })
    };
    assert!(band(&ppm, 0, 8, None).unwrap_err().contains("one-shot"));
}

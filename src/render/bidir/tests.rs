//! The techniques' weights add up to one for every path: rendered with one kind of weight
//! scaled, a furnace (a closed diffuse sphere lit from inside, radiance known in closed
//! form) comes out wrong by the share that kind carries; unbroken, right.

use std::ops::ControlFlow;

use super::vertex::{Mis, Roulette, Walk};
use super::weights::Technique;
use super::{BidirPasses, Modes};
use crate::render::control::Control;
use crate::render::effects::analyse;
use crate::render::geometry::Ray;
use crate::render::material::Material;
use crate::render::math::Rgb;
use crate::render::progressive::{ProgressiveRun, run_passes};
use crate::render::scene::Scene;
use crate::spec::{Integrator, Merging, Passes, RenderSpec, Stop};

/// A kind of technique whose weight a test scales.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Broken {
    Merge,
    Connect,
    Nee,
}

impl Broken {
    pub fn is(self, t: &Technique) -> bool {
        matches!(
            (self, t),
            (Broken::Merge, Technique::Merge { .. })
                | (Broken::Connect, Technique::Connect { .. })
                | (Broken::Nee, Technique::Nee { .. })
        )
    }
}

const FURNACE: &str = r#"{
    "camera": {"position": [0, 0.4, 0.6], "look_at": [0, -1, -2], "up": [0, 1, 0], "fov": 70,
               "width": 24, "height": 24},
    "materials": {"wall": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "objects": [{"type": "sphere", "material": "wall", "center": [0, 0, 0], "radius": 2}],
    "lights": [{"type": "point", "position": [0, 0, 0], "power": [10, 10, 10]}]
}"#;

/// The furnace's mean radiance over its exact value, minus one, rendered by `modes` with
/// `broken`'s weights scaled.
fn furnace_error(modes: Modes, broken: Option<(Broken, f32)>) -> f64 {
    let scene = Scene::parse(FURNACE, None).unwrap();
    let passes = Passes {
        spp: 1,
        stop: Stop::after(256),
    };
    let spec = RenderSpec::new(match modes {
        Modes::Vcm => Integrator::Vcm(Merging {
            passes: passes.clone(),
            ..Merging::DEFAULT
        }),
        _ => Integrator::Bdpt(passes.clone()),
    });
    let analysis = analyse(&scene, &spec);
    let mut bidir = BidirPasses::new(&scene, &spec, &analysis, scene.camera.clone(), modes);
    bidir.broken = broken;
    let run = ProgressiveRun {
        reference: None,
        resume: None,
        fingerprint: String::new(),
        stop: &passes.stop,
        seed: 1,
        radius: spec.merge_radius().map(|(a, r)| (a, r.is_some())),
        size: (24, 24),
        piece: None,
        choice: None,
    };
    let out = run_passes(&mut bidir, run, &Control::none(), &mut |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    let want = (0.5 / std::f64::consts::PI) * 10.0 / (4.0 * std::f64::consts::PI * 4.0) / 0.5;
    out.image.mean_rgb(0, 0, 24, 24)[0] / want - 1.0
}

#[test]
fn the_weights_add_up_to_one_and_a_broken_one_shows() {
    for (modes, kinds) in [
        (
            Modes::Vcm,
            &[Broken::Merge, Broken::Connect, Broken::Nee][..],
        ),
        (Modes::Bdpt, &[Broken::Connect, Broken::Nee][..]),
    ] {
        let right = furnace_error(modes, None);
        assert!(right.abs() < 0.01, "{modes:?}: {right:+.4}");
        for &kind in kinds {
            let wrong = furnace_error(modes, Some((kind, 2.0)));
            eprintln!("{modes:?}: right {right:+.4}, {kind:?} weights doubled {wrong:+.4}");
            assert!(
                wrong > 0.03,
                "{modes:?} with {kind:?} weights doubled: {wrong:+.4}"
            );
        }
    }
}

/// `pt`'s roulette spares the first vertices, then follows the throughput; every other
/// walk's is the material's own probability, whatever the path.
#[test]
fn pt_s_roulette_spares_the_first_bounces_then_follows_the_throughput() {
    let ray = Ray::new(glam::Vec3A::ZERO, glam::Vec3A::Z);
    let mis = Mis {
        d_vcm: 0.0,
        d_vc: 0.0,
        d_vm: 0.0,
    };
    let grey = Material::Diffuse {
        albedo: Rgb::new(0.5, 0.4, 0.3),
    };
    let black = Material::Diffuse { albedo: Rgb::ZERO };
    let mut walk = Walk::start(ray, Rgb::new(0.2, 0.1, 0.1), mis);
    walk.len = 1;
    assert_eq!(walk.survival(&grey), 0.5);
    walk.roulette = Roulette::Throughput;
    assert_eq!(walk.survival(&grey), 1.0);
    assert_eq!(walk.survival(&black), 0.0);
    walk.len = Roulette::FREE - 1;
    assert_eq!(walk.survival(&grey), 1.0);
    walk.len = Roulette::FREE;
    assert_eq!(walk.survival(&grey), 0.2 * 0.5);
    walk.throughput = Rgb::new(3.0, 1.0, 1.0);
    assert_eq!(walk.survival(&grey), 1.0);
}

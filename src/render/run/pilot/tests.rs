//! The pilot's first look against eight passes, and its continued renders.

use super::*;
use crate::spec::{Progressive, Stop};

/// The pilot's looks with no early decision: eight passes each stage.
const EIGHT: Looks = Looks {
    first: PILOT_PASSES,
    last: PILOT_PASSES,
};

/// Passes stopped after `n`.
fn after(n: u32) -> Passes {
    Passes {
        spp: 1,
        stop: Stop::after(n),
    }
}

/// A time limit of `t` seconds alone.
fn limit(t: f64) -> Passes {
    Passes {
        spp: 1,
        stop: Stop {
            iterations: None,
            time_limit: Some(t),
            target_error: None,
        },
    }
}

/// A white box 2 wide lit by `light` (JSON).
fn box_lit_by(light: &str) -> Scene {
    let wall = |c: &str, u: &str, v: &str| {
        let quad = r#""type": "quad", "material": "white""#;
        format!(r#"{{{quad}, "corner": {c}, "edge_u": {u}, "edge_v": {v}}}"#)
    };
    let walls = [
        wall("[-1, 0, -1]", "[0, 0, 2]", "[2, 0, 0]"),
        wall("[-1, 2, -1]", "[2, 0, 0]", "[0, 0, 2]"),
        wall("[-1, 0, -1]", "[2, 0, 0]", "[0, 2, 0]"),
        wall("[-1, 0, -1]", "[0, 2, 0]", "[0, 0, 2]"),
        wall("[1, 0, -1]", "[0, 0, 2]", "[0, 2, 0]"),
    ]
    .join(", ");
    let json = format!(
        r#"{{"camera": {{"position": [0, 1, 3.9], "look_at": [0, 1, 0], "up": [0, 1, 0],
             "fov": 37, "width": 256, "height": 256}},
           "materials": {{"white": {{"type": "diffuse", "albedo": [0.75, 0.75, 0.75]}}}},
           "objects": [{walls}], "lights": [{light}]}}"#
    );
    Scene::parse(&json, None).expect("the test scene parses")
}

/// The first look decides as eight passes do, and early in rooms that are clear: an open
/// box under a ceiling light (gathering by stage 1), a light washing the wall it faces from
/// 2 cm (`bdpt` by stage 2), a point light's hot spot in the bare box (gathering by stage 2).
/// So does a short time limit's, stage 1 after 2 passes and stage 2 after 4.
#[test]
fn the_first_look_chooses_as_eight_passes_do() {
    let spec = RenderSpec::ppm(Progressive::DEFAULT);
    let rooms = [
        (
            r#"{"type": "quad", "corner": [-0.3, 1.998, -0.3], "edge_u": [0.6, 0, 0],
                "edge_v": [0, 0, 0.6], "radiance": [12, 12, 12]}"#,
            false,
        ),
        (
            r#"{"type": "quad", "corner": [-0.5, 0.6, -0.98], "edge_u": [0, 0.8, 0],
                "edge_v": [1, 0, 0], "radiance": [20, 20, 20]}"#,
            true,
        ),
        (POINT_LIGHT, false),
    ];
    for (light, bdpt) in rooms {
        let scene = box_lit_by(light);
        let control = Control::none();
        let first = run_pilot(&scene, &spec, &after(64), &control).unwrap();
        let eight = pilot_looking(&scene, &spec, &control, EIGHT).unwrap();
        assert_eq!(eight.passes, [PILOT_PASSES; 2]);
        assert_eq!(first.passes, [FIRST_LOOK; 2], "{light}: {first:?}");
        assert_eq!(first.prefers_bdpt(), bdpt, "{light}: {first:?}");
        assert_eq!(eight.prefers_bdpt(), bdpt, "{light}: {eight:?}");
        assert_eq!(first.gather_shape(), eight.gather_shape(), "{light}");
        let short = run_pilot(&scene, &spec, &limit(1.0), &control).unwrap();
        let stage_two = if first.gathering.is_some() {
            FIRST_LOOK
        } else {
            SHORT_FIRST_LOOK
        };
        assert_eq!(short.passes, [SHORT_FIRST_LOOK, stage_two], "{light}");
        assert_eq!(short.prefers_bdpt(), bdpt, "{light}: {short:?}");
        assert_eq!(short.gather_shape(), first.gather_shape(), "{light}");
    }
}

/// Under a short time limit alone the pilot decides at its first look where otherwise it
/// would continue: a room lit by two sphere lights (docs/validation/rooms), whose stage 1
/// ratio after 4 passes lies near its threshold, continues to 8 passes under a pass count and
/// a long limit, and under a 1-s limit looks once: stage 1 after 2 passes, stage 2 after 4.
#[test]
fn a_short_time_limit_decides_at_the_first_look() {
    let scene = Scene::load(std::path::Path::new(
        "docs/validation/rooms/sphere_room.json",
    ))
    .expect("the room loads");
    let spec = RenderSpec::ppm(Progressive::DEFAULT);
    let control = Control::none();
    for passes in [after(64), limit(64.0)] {
        let pilot = run_pilot(&scene, &spec, &passes, &control).unwrap();
        assert_eq!(pilot.passes[0], PILOT_PASSES, "{passes:?}: {pilot:?}");
    }
    let short = run_pilot(&scene, &spec, &limit(1.0), &control).unwrap();
    assert_eq!(short.passes, [SHORT_FIRST_LOOK, FIRST_LOOK], "{short:?}");
}

const POINT_LIGHT: &str = r#"{"type": "point", "position": [0, 1.75, 0], "power": [30, 30, 30]}"#;

/// Where a stage does not decide at its first look, its renders continue from their states:
/// `bdpt`'s and the pilot's gathering's images after 4 passes continued to 8 are, to the
/// bit, the images of renders of 8 never stopped (so an undecided pilot chooses as before).
#[test]
fn a_continued_pilot_render_is_one_never_stopped() {
    let scene = box_lit_by(POINT_LIGHT);
    let spec = RenderSpec::ppm(Progressive::DEFAULT);
    let control = Control::none();
    let renders = Renders::new(&scene, &spec, &control);
    let gathering = |p: Passes| renders.gathering(p);
    let made: [&renders::IntegratorFor; 2] = [&Integrator::Bdpt, &gathering];
    for integrator in made {
        let first = renders.look(integrator, 1, FIRST_LOOK, None).unwrap();
        let continued = renders
            .look(integrator, 1, PILOT_PASSES, Some(first.state))
            .unwrap();
        let whole = renders.look(integrator, 1, PILOT_PASSES, None).unwrap();
        assert_eq!(continued.state.passes, PILOT_PASSES);
        assert!(
            continued.image == whole.image,
            "continued and whole renders differ"
        );
        assert!(
            whole.image != first.image,
            "the continuation rendered nothing"
        );
    }
}

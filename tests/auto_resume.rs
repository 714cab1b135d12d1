//! `auto`'s choice across a pause (issue 20). A progressive render of `auto`'s keeps what its
//! pilot chose in its state, so that resuming it renders on without a second pilot (a
//! server job resumes after every turn it gives way to another user), to the bytes of a
//! render never paused. A state without the choice (written before it was kept) resumes
//! with a pilot, to the same bytes. The pilot's seconds are reported as `times.choose`, by
//! the resumed render too (the kept ones).

mod common;

use std::ops::ControlFlow;

use common::{WALL_PATCH, assert_all_finite, scene};
use photonbox::render::ppm::PpmState;
use photonbox::render::{Control, Inputs, RenderOutput, Scene, run};
use photonbox::spec::{Integrator, Passes, RenderSpec, Stop};

/// `auto` for `passes` passes of one sample a pixel.
fn auto(passes: u32) -> RenderSpec {
    RenderSpec::new(Integrator::Auto(Passes {
        spp: 1,
        stop: Stop::after(passes),
    }))
}

/// `spec` on `s` from `resume`, paused (its state saved) after pass `pause_at` if given.
fn render(
    s: &Scene,
    spec: &RenderSpec,
    resume: Option<PpmState>,
    pause_at: Option<u32>,
) -> (RenderOutput, Option<PpmState>) {
    let mut saved = None;
    let inputs = Inputs {
        resume,
        scene_key: b"auto",
        ..Inputs::fresh()
    };
    let out = run(s, spec, inputs, &Control::none(), &mut |st| {
        if Some(st.passes) == pause_at {
            let mut bytes = Vec::new();
            st.save(&mut bytes).unwrap();
            saved = Some(PpmState::load(&bytes[..]).unwrap());
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_all_finite(&out.image);
    (out, saved)
}

#[test]
fn a_resumed_auto_render_keeps_its_choice_and_runs_no_second_pilot() {
    let s = scene(WALL_PATCH);
    let spec = auto(4);
    let (whole, _) = render(&s, &spec, None, None);
    let why = whole.stats.effects["integrator"].clone();
    assert!(why.how.starts_with("auto chose "), "{why:?}");
    let t = &whole.stats.times;
    assert!(t.choose > 0.0, "the pilot's seconds: {t:?}");
    assert!(t.total >= t.choose + t.render, "{t:?}");

    let (paused, state) = render(&s, &spec, None, Some(2));
    assert!(paused.paused());
    let state = state.expect("saved after pass 2");
    let kept = state.choice.clone().expect("the state keeps auto's choice");
    assert_eq!(kept.effect, why);

    let chose = paused.stats.times.choose;
    assert!(chose > 0.0 && kept.seconds == chose, "{kept:?}");
    let (resumed, _) = render(&s, &spec, Some(state.clone()), None);
    // The kept seconds, not a second pilot's (whose clock would not give the same bits).
    assert_eq!(resumed.stats.times.choose, chose, "a second pilot ran");
    assert_eq!(resumed.stats.effects["integrator"], why);
    assert!(resumed.image == whole.image, "the resumed image differs");

    // A state written before the choice was kept: a pilot again, the same choice and bytes.
    let mut old = state;
    old.choice = None;
    let (again, _) = render(&s, &spec, Some(old), None);
    assert!(again.stats.times.choose > 0.0);
    assert_eq!(again.stats.effects["integrator"], why);
    assert!(
        again.image == whole.image,
        "the image resumed with a pilot differs"
    );
}

/// A kept choice whose form no longer parses (another version's) is not trusted: the pilot
/// runs again and the render goes on to the same bytes.
#[test]
fn a_kept_choice_that_does_not_parse_is_chosen_again() {
    let s = scene(WALL_PATCH);
    let spec = auto(3);
    let (whole, _) = render(&s, &spec, None, None);
    let (_, state) = render(&s, &spec, None, Some(1));
    let mut state = state.expect("saved after pass 1");
    let kept = state.choice.as_mut().expect("a choice");
    kept.params = serde_json::json!({"integrator": "ppm", "no_such_field": 1});
    let (resumed, _) = render(&s, &spec, Some(state), None);
    assert!(resumed.stats.times.choose > 0.0);
    assert!(resumed.image == whole.image);
}

/// A farm worker keeps the choice of a job's first piece for its next ones (`farm::task`'s
/// `Kept`): one pilot a job and worker, not one a piece; the pieces merge to the bits of the
/// whole render.
#[test]
fn a_farm_worker_runs_one_pilot_a_job() {
    use photonbox::farm::Unit;
    use photonbox::farm::outcome::merge;
    use photonbox::farm::task::{Kept, render_unit};
    use std::sync::atomic::AtomicBool;

    let s = scene(WALL_PATCH);
    let spec = auto(4);
    let (whole, _) = render(&s, &spec, None, None);
    let (kept, cancel) = (Kept::default(), AtomicBool::new(false));
    let mut units = Vec::new();
    let mut chose = Vec::new();
    for (first, count) in [(1, 2), (3, 2)] {
        let unit = Unit::Passes { first, count };
        let r = render_unit(&s, &spec, (b"auto", None), unit, &kept, &cancel).unwrap();
        let stats: serde_json::Value = serde_json::from_str(&r.stats_json).unwrap();
        chose.push(stats["times"]["choose"].as_f64().expect("times.choose"));
        units.push((unit, r.bytes));
    }
    // The pilot is the first piece's work (the farm sums its pieces' times).
    assert!(
        chose[0] > 0.0 && chose[1] == 0.0,
        "pilot seconds a piece: {chose:?}"
    );
    let merged = merge((24, 24), &units, None).unwrap().image;
    assert!(
        merged == whole.image,
        "the pieces differ from the whole render"
    );
}

//! Progress and cancellation reach every phase of a render (issue 2: "a progress callback
//! and a cancel flag reach into every long loop").

use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use photonbox::render::{Cancelled, Control, Phase, Progress, Scene, SceneDesc, render};
use photonbox::spec::{PhotonMapping, RenderSpec};

fn scene1() -> Scene {
    Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json"))
        .unwrap()
}

fn params() -> RenderSpec {
    RenderSpec {
        width: Some(64),
        height: Some(64),
        ..RenderSpec::photon(PhotonMapping {
            photons: 100_000,
            caustic_photons: 100_000,
            gather_rays: 2,
            spp: 1,
            ..PhotonMapping::PHOTON
        })
    }
}

#[test]
fn progress_is_reported_for_every_phase_monotonically_to_completion() {
    let scene = scene1();
    let log = Mutex::new(Vec::<Progress>::new());
    let cb = |p: Progress| log.lock().unwrap().push(p);
    let control = Control {
        cancel: None,
        progress: Some(&cb),
    };
    render(&scene, &params(), &control).unwrap();
    let log = log.into_inner().unwrap();
    for phase in [
        Phase::PhotonTrace,
        Phase::BuildMaps,
        Phase::Precompute,
        Phase::Render,
    ] {
        let reports: Vec<&Progress> = log.iter().filter(|p| p.phase == phase).collect();
        assert!(reports.len() >= 2, "{phase:?}: {} reports", reports.len());
        assert!(
            reports.windows(2).all(|w| w[0].done <= w[1].done),
            "{phase:?} went backwards"
        );
        let last = reports.last().unwrap();
        assert_eq!(last.done, last.total, "{phase:?} ends complete");
        assert!(last.total > 0);
    }
    // Phases come in order.
    let first = |ph: Phase| log.iter().position(|p| p.phase == ph).unwrap();
    assert!(first(Phase::PhotonTrace) < first(Phase::BuildMaps));
    assert!(first(Phase::BuildMaps) < first(Phase::Precompute));
    assert!(first(Phase::Precompute) < first(Phase::Render));
}

/// Cancelling from inside each phase stops the render with `Err(Cancelled)` before that
/// phase completes.
#[test]
fn cancel_stops_every_phase() {
    let scene = scene1();
    for phase in [Phase::PhotonTrace, Phase::Precompute, Phase::Render] {
        let cancel = AtomicBool::new(false);
        let finished = AtomicBool::new(false);
        let cb = |p: Progress| {
            if p.phase == phase && p.done > 0 {
                cancel.store(true, Ordering::Relaxed);
                if p.done == p.total {
                    finished.store(true, Ordering::Relaxed);
                }
            }
        };
        let control = Control {
            cancel: Some(&cancel),
            progress: Some(&cb),
        };
        let mut p = params();
        p.width = Some(256);
        p.height = Some(256);
        let result = render(&scene, &p, &control);
        assert_eq!(
            result.err(),
            Some(Cancelled.into()),
            "cancel during {phase:?}"
        );
        assert!(
            !finished.load(Ordering::Relaxed),
            "{phase:?} ran to its end"
        );
    }
    // A flag set before the start cancels at once.
    let cancel = AtomicBool::new(true);
    let control = Control {
        cancel: Some(&cancel),
        progress: None,
    };
    assert_eq!(
        render(&scene, &params(), &control).err(),
        Some(Cancelled.into())
    );
}

/// Scene building reports its own phase to completion, and a cancel from inside it (after
/// its first object) stops it with `Err(Cancelled)`.
#[test]
fn scene_building_reports_progress_and_honours_cancel() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json");
    let desc = SceneDesc::load(&path).unwrap();
    let log = Mutex::new(Vec::<Progress>::new());
    let cb = |p: Progress| log.lock().unwrap().push(p);
    let control = Control {
        cancel: None,
        progress: Some(&cb),
    };
    assert!(Scene::build_with(&desc, &control).is_ok());
    let log = log.into_inner().unwrap();
    assert!(log.iter().all(|p| p.phase == Phase::BuildScene));
    assert!(log.len() >= 3, "{} reports", log.len());
    assert!(log.windows(2).all(|w| w[0].done <= w[1].done));
    let last = log.last().unwrap();
    assert_eq!(last.done, last.total);

    let cancel = AtomicBool::new(false);
    let reports = Mutex::new(0u64);
    let cb = |p: Progress| {
        if p.done > 0 {
            cancel.store(true, Ordering::Relaxed);
        }
        *reports.lock().unwrap() = p.done;
    };
    let control = Control {
        cancel: Some(&cancel),
        progress: Some(&cb),
    };
    assert_eq!(Scene::build_with(&desc, &control).err(), Some(Cancelled));
    assert_eq!(
        *reports.lock().unwrap(),
        1,
        "stopped after its first object"
    );
}

//! Cancel stops a render promptly whatever its parameters: the camera pass reads the flag
//! at a grain of samples, not of tiles. Latency is compared with work measured in the same
//! run (a tile row's time), never with an absolute time.

use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use photonbox::render::{Cancelled, Control, Phase, Progress, RenderError, Scene, render};
use photonbox::spec::{PhotonMapping, RenderSpec};

/// Times of one cancelled render: a tile row's work, and from the flag to the return.
struct Cancel {
    result: Result<(), RenderError>,
    row: Duration,
    latency: Duration,
}

/// Render `params` and set the cancel flag at the camera pass's first report after work
/// (the end of its first tile row), when the rest of that tile is still to do.
fn cancel_after_first_row(scene: &Scene, params: &RenderSpec) -> Cancel {
    let cancel = AtomicBool::new(false);
    let marks = Mutex::new((None::<Instant>, None::<(Instant, Duration)>));
    let cb = |p: Progress| {
        if p.phase != Phase::Render {
            return;
        }
        let mut m = marks.lock().unwrap();
        let now = Instant::now();
        let start = *m.0.get_or_insert(now);
        if p.done > 0 && m.1.is_none() {
            cancel.store(true, Ordering::Relaxed);
            m.1 = Some((now, now - start));
        }
    };
    let control = Control {
        cancel: Some(&cancel),
        progress: Some(&cb),
    };
    let result = render(scene, params, &control).map(|_| ());
    let end = Instant::now();
    let (_, set) = marks.into_inner().unwrap();
    let (at, row) = set.expect("the camera pass reported a finished row");
    Cancel {
        result,
        row,
        latency: end - at,
    }
}

/// One 16 x 16 tile of 256 samples a pixel, each with 256 final-gather rays: a tile is
/// seconds of work, its first row (16 pixels) a sixteenth of it. Cancelled at the end of
/// that row, the render must stop within a fraction of a row (a few samples' work), not
/// finish the tile as a check per tile did.
#[test]
fn cancel_stops_the_camera_pass_within_a_few_samples() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_mirror_glass.json");
    let scene = Scene::load(&path).unwrap();
    let params = RenderSpec {
        width: Some(16),
        height: Some(16),
        ..RenderSpec::photon(PhotonMapping {
            photons: 20_000,
            caustic_photons: 20_000,
            gather_rays: 256,
            spp: 256,
            ..PhotonMapping::PHOTON
        })
    };
    let c = cancel_after_first_row(&scene, &params);
    eprintln!("row {:?}, latency {:?}", c.row, c.latency);
    assert_eq!(c.result, Err(Cancelled.into()));
    assert!(
        c.latency * 8 < c.row,
        "latency {:?} against {:?} for a row of 4096 samples",
        c.latency,
        c.row
    );
}

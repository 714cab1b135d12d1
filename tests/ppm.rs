//! Progressive photon mapping (issue 4): the radius schedule, convergence toward analytic
//! answers, determinism across thread counts, and resuming from a saved state.

mod common;

use std::f64::consts::PI;
use std::ops::ControlFlow;

use common::{WALL_PATCH, assert_all_finite, scene};
use photonbox::render::accuracy::compare;
use photonbox::render::photon::PhotonStore;
use photonbox::render::ppm::{PpmState, StopReason};
use photonbox::render::{Control, Image, Inputs, Piece, RenderError, RenderOutput, Scene, run};
use photonbox::spec::{Integrator, Passes, PhotonMapping, Progressive, RenderSpec, Stop};

/// A point light over a large diffuse floor, seen from above (as in tests/analytic.rs).
const FLOOR: &str = r#"{
    "camera": {"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov": 60,
               "width": 48, "height": 48},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "objects": [{"type": "quad", "material": "floor", "corner": [-50, 0, -50],
                 "edge_u": [0, 0, 100], "edge_v": [100, 0, 0]}],
    "lights": [{"type": "point", "position": [0, 1, 0], "power": [100, 100, 100]}]
}"#;

/// A glass sphere over a floor, and a mirror: caustics, both maps.
const CAUSTIC: &str = r#"{
    "camera": {"position": [0, 2, 4], "look_at": [0, 0.5, 0], "up": [0, 1, 0], "fov": 45,
               "width": 40, "height": 32},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "glass": {"type": "dielectric", "ior": 1.5},
                  "mirror": {"type": "mirror", "reflectance": [0.9, 0.9, 0.9]}},
    "objects": [{"type": "quad", "material": "floor", "corner": [-5, 0, 5],
                 "edge_u": [10, 0, 0], "edge_v": [0, 0, -10]},
                {"type": "sphere", "material": "glass", "center": [0, 0.6, 0], "radius": 0.5},
                {"type": "sphere", "material": "mirror", "center": [1.2, 0.4, -0.5], "radius": 0.4}],
    "lights": [{"type": "point", "position": [0, 3, 0], "power": [200, 200, 200]}]
}"#;

fn ppm_params(photons: u64, iterations: u32) -> Progressive {
    Progressive {
        pass: PhotonMapping {
            photons,
            caustic_photons: photons,
            ..PhotonMapping::PPM_PASS
        },
        stop: Stop::after(iterations),
        ..Progressive::DEFAULT
    }
}

/// A ppm render from `resume` (or pass 0), with the image after every pass; `on_pass` may
/// stop it.
fn run_with(
    scene: &Scene,
    spec: &RenderSpec,
    resume: Option<PpmState>,
    scene_key: &[u8],
    on_pass: &mut dyn FnMut(&PpmState) -> ControlFlow<()>,
) -> Result<RenderOutput, RenderError> {
    let inputs = Inputs {
        resume,
        scene_key,
        ..Inputs::fresh()
    };
    run(scene, spec, inputs, &Control::none(), on_pass)
}

/// A ppm render, with the image after every pass.
fn render_ppm(
    scene: &Scene,
    p: Progressive,
    resume: Option<PpmState>,
) -> (RenderOutput, Vec<Image>) {
    let mut images = Vec::new();
    let spec = RenderSpec::ppm(p);
    let out = run_with(scene, &spec, resume, b"test", &mut |s| {
        images.push(s.image());
        ControlFlow::Continue(())
    })
    .unwrap();
    assert_all_finite(&out.image);
    (out, images)
}

/// The passes a render reports.
fn history(out: &RenderOutput) -> &[photonbox::render::ppm::PassStats] {
    &out.stats.ppm.as_ref().expect("a ppm render").history
}

#[test]
fn radius_follows_the_knaus_zwicker_schedule() {
    let s = scene(CAUSTIC);
    for (radius, alpha) in [(Some(0.3f32), 0.7), (None, 0.5)] {
        let params = Progressive {
            radius,
            alpha,
            ..ppm_params(5_000, 12)
        };
        let (out, _) = render_ppm(&s, params, None);
        let h = history(&out);
        assert_eq!(h.len(), 12);
        let r0 = [h[0].radius_global, h[0].radius_caustic];
        match radius {
            Some(r) => assert_eq!(r0, [r as f64; 2]),
            None => {
                // Automatic: a k-NN radius, positive and within a tenth of the scene.
                let extent = s.extent() as f64;
                for r in r0 {
                    assert!(
                        r > 0.0 && r <= 0.1 * extent + 1e-6,
                        "{r} vs extent {extent}"
                    );
                }
            }
        }
        // r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1), so r_i^2 = r_1^2 prod_{j<i} (j + a)/(j + 1).
        let mut factor = 1.0f64;
        for (i, p) in h.iter().enumerate() {
            assert_eq!(p.pass, i as u32 + 1);
            for (got, first) in [(p.radius_global, r0[0]), (p.radius_caustic, r0[1])] {
                let want = first * factor.sqrt();
                assert!(
                    (got / want - 1.0).abs() < 1e-6,
                    "pass {}: {got} vs {want}",
                    p.pass
                );
            }
            factor *= (i as f64 + 1.0 + alpha) / (i as f64 + 2.0);
        }
        assert!(h[11].radius_global < 0.75 * h[0].radius_global);
        let report = out.stats.ppm.as_ref().unwrap();
        assert_eq!((report.passes, report.alpha), (12, alpha));
        assert_eq!(report.stopped_by, StopReason::Iterations);
    }
}

/// Fixed-radius estimates blur the irradiance peak under a point light (bias ~ r^2); the
/// shrinking radius removes it, where one pass keeps it.
#[test]
fn ppm_converges_under_a_point_light() {
    let s = scene(FLOOR);
    let mut params = Progressive {
        radius: Some(0.6),
        ..ppm_params(40_000, 64)
    };
    params.pass.photon_store = PhotonStore::DirectOnly;
    let (_, images) = render_ppm(&s, params, None);
    // The centre 4x4 pixels look straight down at the peak: E = P/(4 pi h^2) (cos = 1).
    let want = 0.5 / PI * 100.0 / (4.0 * PI);
    let peak = |img: &Image| img.mean_rgb(22, 22, 26, 26)[0] / want - 1.0;
    let e: Vec<f64> = [1, 4, 16, 64]
        .iter()
        .map(|&i| peak(&images[i - 1]))
        .collect();
    eprintln!("peak error at passes 1, 4, 16, 64: {e:+.4?}");
    assert!(
        e[0] < -0.1,
        "one pass at r = 0.6 should blur the peak: {:+.4}",
        e[0]
    );
    // The mean of the passes' biases (each ~ r_i^2) falls steadily.
    for w in e.windows(2) {
        assert!(w[1].abs() < w[0].abs(), "{e:+.4?}");
    }
    assert!(e[3].abs() < 0.65 * e[0].abs(), "{e:+.4?}");
    // Noise falls too: the whole image against the analytic field.
    let exact = |x: u32, y: u32| {
        // Pixel centre to floor point (the camera looks straight down from 3 units).
        let t = (60f64.to_radians() / 2.0).tan();
        let u = ((x as f64 + 0.5) / 48.0 * 2.0 - 1.0) * t * 3.0;
        let v = ((y as f64 + 0.5) / 48.0 * 2.0 - 1.0) * t * 3.0;
        let d2 = u * u + v * v + 1.0;
        0.5 / PI * 100.0 / (4.0 * PI) / d2 / d2.sqrt()
    };
    let rms = |img: &Image| {
        let mut sum = 0.0;
        for y in 8..40 {
            for x in 8..40 {
                sum += (img.get(x, y)[0] as f64 / exact(x, y) - 1.0).powi(2);
            }
        }
        (sum / (32.0 * 32.0)).sqrt()
    };
    let (r1, r64) = (rms(&images[0]), rms(&images[63]));
    eprintln!("relative rms: pass 1 {r1:.4}, pass 64 {r64:.4}");
    assert!(r64 < 0.5 * r1, "{r64} vs {r1}");
}

/// A pixel's camera samples continue one Sobol sequence from pass to pass (`Samples` in
/// integrator/shade.rs): with final gathering, the gather directions of four passes are one
/// stratified set, not four independent ones. Measured between seeds 1 and 2 (3 and 4):
/// relmse 0.047 (0.054) with each pass's samples drawn on their own, 0.018 (0.020) now.
#[test]
fn passes_continue_each_pixel_s_stratified_samples() {
    let s = scene(WALL_PATCH);
    let render = |seed| {
        let mut params = ppm_params(50_000, 4);
        params.pass.gather_rays = 16;
        let spec = RenderSpec {
            seed,
            ..RenderSpec::ppm(params)
        };
        let out = run_with(&s, &spec, None, b"test", &mut |_| ControlFlow::Continue(()));
        out.unwrap().image
    };
    let relmse = compare(&render(1), &render(2)).unwrap().relmse;
    eprintln!("ppm's gather noise between seeds over four passes: relmse {relmse:.4}");
    assert!(
        relmse < 0.03,
        "relmse {relmse:.4}: the passes' gathers do not stratify each other"
    );
}

#[test]
fn ppm_is_bit_identical_across_thread_counts() {
    let s = scene(CAUSTIC);
    let params = ppm_params(8_000, 3);
    let bits = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let (out, _) = pool.install(|| render_ppm(&s, params.clone(), None));
        out.image
            .pixels
            .iter()
            .flatten()
            .map(|c| c.to_bits())
            .collect::<Vec<_>>()
    };
    let one = bits(1);
    assert_eq!(one, bits(2));
    assert_eq!(one, bits(3));
    assert!(one.iter().any(|&b| b != 0));
}

/// A farm's split (issue 21): passes 1-3, 4-5 and 6-7 rendered as separate pieces, each
/// resumed from the state before it with the sum taken out, merged out of order, give the
/// bits of one uninterrupted run.
#[test]
fn passes_rendered_in_pieces_merge_to_the_bits_of_one_run() {
    let s = scene(CAUSTIC);
    let params = ppm_params(4_000, 7);
    let spec = RenderSpec::ppm(params);
    let mut whole = None;
    let full = run_with(&s, &spec, None, b"test", &mut |st| {
        whole = Some(st.sum().clone());
        ControlFlow::Continue(())
    })
    .unwrap();
    let mut pieces = Vec::new();
    let mut start: Option<PpmState> = None;
    for end in [3, 5, 7] {
        let mut at_end = None;
        run_with(&s, &spec, start.take(), b"test", &mut |st| {
            if st.passes == end {
                at_end = Some(st.clone());
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        let mut state = at_end.expect("the piece ran to its last pass");
        pieces.push(state.take_sum());
        start = Some(state);
    }
    let mut merged = pieces[2].clone();
    merged.merge(&pieces[0]);
    merged.merge(&pieces[1]);
    // The sums themselves, not only the f32 images (which would hide a last-bit slip).
    assert!(
        Some(&merged) == whole.as_ref(),
        "merged pieces differ from one run"
    );
    assert!(merged.mean(7) == full.image);
    assert!(
        pieces[0].mean(3) != full.image,
        "the pieces are not the whole"
    );
}

/// The exact sum of passes `first ..= last` rendered as a piece (a farm's task), from the
/// initial radii if given; and the initial radii it rendered with.
fn piece_sum(
    s: &Scene,
    spec: &RenderSpec,
    first: u32,
    last: u32,
    radii: Option<[f64; 2]>,
) -> (photonbox::render::ppm::PassSum, [f64; 2]) {
    let mut out = None;
    let inputs = Inputs {
        scene_key: b"test",
        piece: Some(Piece {
            first,
            count: last - first + 1,
            radii,
        }),
        ..Inputs::fresh()
    };
    run(s, spec, inputs, &Control::none(), &mut |st| {
        assert!(
            st.passes >= first && st.passes <= last,
            "pass {} outside the piece",
            st.passes
        );
        if st.passes == last {
            out = Some((st.sum().clone(), st.radius_initial));
        }
        ControlFlow::Continue(())
    })
    .unwrap();
    out.expect("the piece ran to its last pass")
}

#[test]
fn pieces_rendered_apart_merge_to_the_bits_of_one_run() {
    use photonbox::spec::{Integrator, Merging, Passes};
    let s = scene(CAUSTIC);
    let vcm = Merging {
        passes: Passes {
            spp: 1,
            stop: Stop::after(7),
        },
        ..Merging::DEFAULT
    };
    // Both integrators with a radius that pass 1 computes (ppm from its photons, vcm from a
    // pilot): a later piece must find the same one.
    for spec in [
        RenderSpec::ppm(ppm_params(4_000, 7)),
        RenderSpec::new(Integrator::Vcm(vcm)),
    ] {
        let mut whole = None;
        let full = run_with(&s, &spec, None, b"test", &mut |st| {
            whole = Some(st.sum().clone());
            ControlFlow::Continue(())
        })
        .unwrap();
        // Rendered last piece first, as a farm might.
        // The first piece computes the initial radii, the second is given them, the third
        // (pass 1) sets them as any render does.
        let (mut merged, radii) = piece_sum(&s, &spec, 6, 7, None);
        merged.merge(&piece_sum(&s, &spec, 3, 5, Some(radii)).0);
        merged.merge(&piece_sum(&s, &spec, 1, 2, None).0);
        assert!(
            Some(&merged) == whole.as_ref(),
            "{spec:?}: merged pieces differ from one run"
        );
        assert!(merged.mean(7) == full.image);
    }
}

#[test]
fn a_piece_outside_its_render_is_refused() {
    let s = scene(CAUSTIC);
    let spec = RenderSpec::ppm(ppm_params(1_000, 4));
    for (first, count) in [(0, 2), (4, 2), (2, 0)] {
        let inputs = Inputs {
            piece: Some(Piece {
                first,
                count,
                radii: None,
            }),
            ..Inputs::fresh()
        };
        let got = run(&s, &spec, inputs, &Control::none(), &mut |_| {
            ControlFlow::Continue(())
        });
        assert!(
            matches!(got, Err(RenderError::Input(_))),
            "piece {first}+{count} of 4 passes accepted"
        );
    }
}

#[test]
fn resumed_render_equals_an_uninterrupted_one() {
    let s = scene(CAUSTIC);
    let params = ppm_params(8_000, 6);
    let (full, _) = render_ppm(&s, params.clone(), None);

    // Stop after pass 2 (the callback asks to), save, load, continue to 6.
    let mut saved = Vec::new();
    let spec = RenderSpec::ppm(params.clone());
    let first = run_with(&s, &spec, None, b"test", &mut |st| {
        if st.passes == 2 {
            st.save(&mut saved).unwrap();
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
    .unwrap();
    let report = first.stats.ppm.as_ref().unwrap();
    assert_eq!(report.passes, 2);
    assert_eq!(report.stopped_by, StopReason::Paused);
    assert!(first.paused());
    let state = PpmState::load(&saved[..]).unwrap();
    let (resumed, passes_seen) = render_ppm(&s, params, Some(state));
    assert_eq!(passes_seen.len(), 4, "passes 3..=6 run after resuming");
    assert_eq!(resumed.stats.ppm.as_ref().unwrap().passes, 6);
    assert!(resumed.image == full.image, "resumed image differs");
    assert_eq!(history(&resumed).len(), 6);

    // A state of another scene is refused, not silently restarted.
    let state = PpmState::load(&saved[..]).unwrap();
    let other = run_with(&s, &spec, Some(state), b"another", &mut |_| {
        ControlFlow::Continue(())
    });
    assert!(
        matches!(other, Err(RenderError::Input(_))),
        "{:?}",
        other.err()
    );
}

#[test]
fn target_error_and_time_limit_stop_early() {
    let s = scene(CAUSTIC);
    let reference = render_ppm(&s, ppm_params(4_000, 4), None).0.image;
    let stop = |stop: Stop| {
        RenderSpec::ppm(Progressive {
            stop,
            ..ppm_params(4_000, 1_000)
        })
    };
    let spec = stop(Stop {
        target_error: Some(1e9),
        ..Stop::after(1_000)
    });
    let inputs = Inputs {
        reference: Some(&reference),
        ..Inputs::fresh()
    };
    let out = run(&s, &spec, inputs, &Control::none(), &mut |_| {
        ControlFlow::Continue(())
    })
    .unwrap();
    // Any error meets a target of 1e9: one pass, and its error recorded.
    let report = out.stats.ppm.as_ref().unwrap();
    assert_eq!(report.passes, 1);
    assert_eq!(report.stopped_by, StopReason::TargetError);
    assert!(report.history[0].error.is_some() && out.stats.error.is_some());

    let spec = stop(Stop {
        time_limit: Some(1e-9),
        ..Stop::after(1_000)
    });
    let out = photonbox::render::render(&s, &spec, &Control::none()).unwrap();
    let report = out.stats.ppm.as_ref().unwrap();
    assert_eq!(report.passes, 1, "at least one pass, then the limit");
    assert_eq!(report.stopped_by, StopReason::TimeLimit);
}

/// The inside of a closed diffuse cube lit from its centre, seen into a corner: three
/// walls, three concave edges.
const CUBE_CORNER: &str = r#"{
    "camera": {"position": [0.6, 0.6, 0.9], "look_at": [-1, -1, -1], "up": [0, 1, 0],
               "fov": 60, "width": 48, "height": 48},
    "materials": {"wall": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
    "objects": [
        {"type": "quad", "material": "wall", "corner": [-1, -1, -1], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0]},
        {"type": "quad", "material": "wall", "corner": [-1, -1, 1], "edge_u": [2, 0, 0], "edge_v": [0, 2, 0]},
        {"type": "quad", "material": "wall", "corner": [-1, -1, -1], "edge_u": [0, 2, 0], "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "wall", "corner": [1, -1, -1], "edge_u": [0, 2, 0], "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "wall", "corner": [-1, -1, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]},
        {"type": "quad", "material": "wall", "corner": [-1, 1, -1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 2]}
    ],
    "lights": [{"type": "point", "position": [0, 0, 0], "power": [10, 10, 10]}]
}"#;

/// Near an edge a density estimate's disc reaches past its wall and counts too few photons.
/// A gather ray from beside the edge lands there, a few radii away, and shows that loss
/// undiluted; gather rays from across the room land there too. ppm with final gathering and
/// a large radius (0.15, on walls 2 wide) against `pt`, in 6x6-pixel blocks: every block
/// within 0.6% of `pt`'s, the edges' as bright as the rest. Measured (three seeds): with the
/// map read at every gather hit, blocks about 0.975 to 0.997 of `pt`'s; with the hits within
/// 4 radii bouncing once more, 0.989 to 0.997 (the far walls' edges still dark); with the
/// hits within a radius of their quad's edges bouncing too, 0.998 to 1.002.
#[test]
fn gathering_keeps_a_corners_edges_as_bright_as_a_path_tracer() {
    corner_blocks_against_pt(0.0, 16, 0.006);
}

/// The same with the gathers smoothed between pixels (`auto`'s 5 global radii over
/// pass^0.35, `integrator/smooth.rs`): the blur it adds in the corner's edges, where the
/// light falls off faster than a line, fades as the passes go on. Measured 0.9953-1.0004
/// after 64 passes; with no fade (`SMOOTHING_FADE` 0) 0.9875, which fails.
#[test]
fn smoothed_gathers_fade_to_a_path_tracer_s_corner() {
    corner_blocks_against_pt(5.0, 64, 0.006);
}

/// ppm with final gathering (smoothed within `smoothing` radii) after `passes`, against
/// `pt` in the cube's corner by 6x6-pixel blocks: every block within `tolerance`.
fn corner_blocks_against_pt(smoothing: f32, passes: u32, tolerance: f64) {
    let s = scene(CUBE_CORNER);
    let pt = Passes {
        spp: 1,
        stop: Stop::after(2048),
    };
    let pt = common::render_checked(&s, &RenderSpec::new(Integrator::Pt(pt))).image;
    let gathering = Progressive {
        pass: PhotonMapping {
            photons: 20_000,
            gather_rays: 8,
            ..PhotonMapping::PPM_PASS
        },
        radius: Some(0.15),
        gather_smoothing: smoothing,
        stop: Stop::after(passes),
        ..Progressive::DEFAULT
    };
    let gathered = common::render_checked(&s, &RenderSpec::ppm(gathering)).image;
    let mut ratios = Vec::new();
    for by in 0..8 {
        for bx in 0..8 {
            let block = |img: &Image| img.mean_rgb(bx * 6, by * 6, bx * 6 + 6, by * 6 + 6)[0];
            ratios.push(block(&gathered) / block(&pt));
        }
    }
    let (lo, hi) = ratios
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    eprintln!(
        "cube corner, gathering (smoothing {smoothing}) over pt by 6x6 blocks: {lo:.4} to {hi:.4}"
    );
    assert!(
        lo > 1.0 - tolerance && hi < 1.0 + tolerance,
        "blocks from {lo:.4} to {hi:.4} of pt's"
    );
}

//! Numerical stability, accumulation (issue 5): the power of 1e8 photons sums exactly, and
//! a progressive render stays finite and right after 100k passes, its radius shrunk by
//! five orders of magnitude in area.

mod common;

use std::ops::ControlFlow;

use photonbox::render::math::Rgb;
use photonbox::render::photon::sum_power;
use photonbox::render::{Control, Inputs, run};
use photonbox::spec::{PhotonMapping, Progressive, RenderSpec, Stop};

/// 1e8 photon powers of seven distinct values: the exact total is seven products.
#[test]
fn the_power_of_1e8_photons_sums_exactly() {
    const N: u64 = 100_000_000;
    let value = |i: u64| 0.1f32 + (i % 7) as f32 * 0.013;
    let got = sum_power((0..N).map(|i| Rgb::splat(value(i))))[0];
    let exact: f64 = (0..7u64)
        .map(|j| {
            let count = N / 7 + u64::from(j < N % 7);
            count as f64 * value(j) as f64
        })
        .sum();
    // An f32 running sum, for contrast: it stalls once the total dwarfs each term.
    let naive = (0..N).fold(0.0f32, |s, i| s + value(i)) as f64;
    eprintln!(
        "1e8 photons: compensated {got:.6} (error {:.2e}), exact {exact:.6}, f32 sum {naive:.1}",
        (got - exact).abs() / exact
    );
    assert!((got - exact).abs() <= 1e-12 * exact, "{got} vs {exact}");
    assert!(
        (naive - exact).abs() > 0.1 * exact,
        "the f32 sum would lose it too"
    );
}

/// A point light over a floor, 2x2 pixels: 100k passes of 100 photons each. The radius
/// shrinks to (i + alpha)/(i + 1) of its area each pass; the estimate must stay finite and
/// converge to the analytic radiance at the pixels' centre.
#[test]
fn ppm_after_100k_passes_stays_finite_and_right() {
    let s = common::scene(
        r#"{
        "camera": {"position": [0, 3, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov": 2,
                   "width": 2, "height": 2},
        "materials": {"floor": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
        "objects": [{"type": "quad", "material": "floor", "corner": [-5, 0, -5],
                     "edge_u": [0, 0, 10], "edge_v": [10, 0, 0]}],
        "lights": [{"type": "point", "position": [0, 1, 0], "power": [100, 100, 100]}]
    }"#,
    );
    let passes = 100_000;
    let params = RenderSpec::ppm(Progressive {
        pass: PhotonMapping {
            photons: 100,
            caustic_photons: 0,
            photon_store: photonbox::render::PhotonStore::All,
            ..PhotonMapping::PPM_PASS
        },
        alpha: 0.5,
        radius: Some(0.3),
        stop: Stop::after(passes),
        ..Progressive::DEFAULT
    });
    let t0 = std::time::Instant::now();
    // The state after the last pass (the radius of the next pass, the passes done).
    let mut last = (0.0, 0);
    let out = run(&s, &params, Inputs::fresh(), &Control::none(), &mut |st| {
        last = (st.r2_global, st.passes);
        ControlFlow::Continue(())
    })
    .unwrap();
    let report = out.stats.ppm.clone().unwrap();
    let img = &out.image;
    common::assert_all_finite(img);
    let want = 0.5 / std::f64::consts::PI * 100.0 / (4.0 * std::f64::consts::PI);
    let mean = img.mean_rgb(0, 0, 2, 2)[0];
    let r0 = report.radius_initial_global;
    let (r2, done) = last;
    // The state holds the radius of the next pass: r_{N+1}^2 / r_1^2 = prod_{i<=N} (i +
    // alpha) / (i + 1).
    let shrink: f64 = (1..=passes)
        .map(|i| (i as f64 + 0.5) / (i as f64 + 1.0))
        .product();
    eprintln!(
        "{} passes in {:.1} s: mean {mean:.5} against {want:.5}; radius {r0} -> {}",
        done,
        t0.elapsed().as_secs_f64(),
        r2.sqrt()
    );
    assert_eq!((done, report.passes), (passes, passes));
    assert!(r2 > 0.0 && r2.is_finite());
    assert!(
        (r2 / (r0 * r0) / shrink - 1.0).abs() < 1e-9,
        "{r2} vs {}",
        r0 * r0 * shrink
    );
    // About 2500 photons fall within the shrinking radius over all passes: 2% noise.
    assert!((mean / want - 1.0).abs() < 0.03, "{mean} vs {want}");
}

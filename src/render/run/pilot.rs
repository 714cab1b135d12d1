//! `auto`'s pilot between camera paths and connections on a room without mirror or glass.
//! In an open box lit from its ceiling a camera path's bounce finds the indirect light
//! (`pt` reaches an error 15-20% sooner than `bdpt` there, and `ppm` with final gathering,
//! whose gather ray is that bounce, 1.5-5x sooner than `pt`), but where the camera sees
//! mostly light that came off a small bright patch (a light facing a wall at a few
//! centimetres, a light around a corner) `bdpt` wins, by up to 4x over `pt` and far more
//! over gathering (docs/performance-history.md, "auto's pilot", "auto's gathering"). The
//! scene's facts do not tell the two apart (the share of seen surfaces lit directly was
//! tried: 0.70 in cornell, 0.74 and 0.89 in two rooms where `bdpt` won), the variance of a
//! small render does.
//!
//! The pilot renders the image at about 48x48 pixels, twice per integrator under two seeds
//! of its own, and compares the per-pass variance of the two integrators (the squared
//! difference between a pair, relative as `relmse` weighs it). `bdpt` is chosen when
//! `pt`'s variance is more than [`BDPT_PASS_COST`] x [`GATHERING_GAIN`] times `bdpt`'s:
//! what a `bdpt` pass costs against a `pt` pass, times how much sooner gathering reaches
//! `pt`'s error where a bounce finds the light. A function of the scene and the spec alone
//! (the pilot's bytes do not depend on the thread count or the clock), so the choice is the
//! same on every run.

use std::ops::ControlFlow;

use super::Inputs;
use crate::render::control::Control;
use crate::render::film::Image;
use crate::render::outcome::RenderError;
use crate::render::sampling::splitmix64;
use crate::render::scene::Scene;
use crate::spec::{Integrator, Passes, RenderSpec, Stop};

/// About how many times a `pt` pass's time a `bdpt` pass takes (1.5-1.8 in the rooms of
/// docs/performance-history.md, "auto's pilot").
const BDPT_PASS_COST: f64 = 1.8;

/// At least about how many times sooner `ppm` with final gathering reached Mitsuba's error
/// than `pt` did on cornell, knot and cornell_spheres at 1, 4 and 16 s (1.5-5 for relmse,
/// 1.4-2.2 for block_err but where both met the reference's noise; docs/performance.md,
/// "2026-12-04, late night").
const GATHERING_GAIN: f64 = 1.7;

/// Pixels of a pilot image (its aspect the camera's).
const PILOT_PIXELS: f64 = 2304.0;

/// Passes of each pilot render.
const PILOT_PASSES: u32 = 16;

/// What the pilot found: each integrator's per-pass variance (relative, summed over the
/// pilot image's pixels and channels).
#[derive(Clone, Copy, Debug)]
pub(super) struct Pilot {
    pub pt: f64,
    pub bdpt: f64,
}

impl Pilot {
    /// Whether `bdpt` reaches a given error sooner than camera paths' bounces (`ppm`'s
    /// final gathering), by the pilot.
    pub fn prefers_bdpt(&self) -> bool {
        self.pt > BDPT_PASS_COST * GATHERING_GAIN * self.bdpt
    }
}

/// The pilot of `spec` (its seed, depth and effect switches) on `scene`, cancelled with
/// `control`.
pub(super) fn pt_against_bdpt(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
) -> Result<Pilot, RenderError> {
    let (w, h) = spec.resolution((scene.camera.width, scene.camera.height));
    let aspect = (w as f64 / h as f64).sqrt();
    let width = ((PILOT_PIXELS.sqrt() * aspect).round() as u32).clamp(4, 256);
    let height = ((PILOT_PIXELS.sqrt() / aspect).round() as u32).clamp(4, 256);
    let quiet = Control {
        cancel: control.cancel,
        progress: None,
    };
    let passes = Passes {
        spp: 1,
        stop: Stop::after(PILOT_PASSES),
    };
    let render = |integrator: &Integrator, k: u64| {
        let pilot = RenderSpec {
            width: Some(width),
            height: Some(height),
            seed: splitmix64(splitmix64(spec.seed ^ 0x7069_6c6f_7400_0000).wrapping_add(k)),
            integrator: integrator.clone(),
            ..spec.clone()
        };
        let mut go_on = |_: &_| ControlFlow::Continue(());
        super::run(scene, &pilot, Inputs::fresh(), &quiet, &mut go_on).map(|o| o.image)
    };
    let pt = Integrator::Pt(passes.clone());
    let bdpt = Integrator::Bdpt(passes);
    let images = [
        render(&pt, 1)?,
        render(&pt, 2)?,
        render(&bdpt, 1)?,
        render(&bdpt, 2)?,
    ];
    Ok(pass_variances(&images))
}

/// Each integrator's per-pass variance from its pair of pilot images (`images`: pt, pt,
/// bdpt, bdpt; each the mean of [`PILOT_PASSES`] passes): a pair's squared difference is
/// twice the variance of a mean, weighed by 1 / (m^2 + 0.01) with m the mean of all four
/// images (as `relmse` weighs an error, but the same weight for both integrators, where
/// `accuracy::compare` would weigh each by its own noisy second image).
fn pass_variances(images: &[Image; 4]) -> Pilot {
    let (mut pt, mut bdpt) = (0.0, 0.0);
    for i in 0..images[0].pixels.len() {
        for c in 0..3 {
            let [a, b, x, y] = images.each_ref().map(|im| im.pixels[i][c] as f64);
            let weight = 1.0 / (((a + b + x + y) / 4.0).powi(2) + 0.01);
            pt += (a - b).powi(2) * weight;
            bdpt += (x - y).powi(2) * weight;
        }
    }
    let per_pass = PILOT_PASSES as f64 / 2.0;
    Pilot {
        pt: pt * per_pass,
        bdpt: bdpt * per_pass,
    }
}

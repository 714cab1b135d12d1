//! `auto`'s pilot between final gathering and connections on a room without mirror or
//! glass. In an open box lit from its ceiling `ppm` with final gathering reached Mitsuba's
//! error 1.5-5x sooner than `pt`, and `pt` 15-20% sooner than `bdpt` (docs/performance.md,
//! "2026-12-04, late night"; docs/performance-history.md, "auto's pilot"); where the camera
//! sees mostly light that came off a small bright patch (a skewed quad light facing a wall
//! at a few centimetres, which shadow rays sample by area) a gather ray finds the patch as
//! rarely as a camera path's bounce does, and `bdpt`'s connections may win. The scene's
//! facts do not tell the two apart (the share of seen surfaces lit directly was tried: 0.70
//! in cornell, 0.74 and 0.89 in two rooms where `bdpt` won against `pt`), the variance of
//! a small render does.
//!
//! The pilot renders the image at about 48x48 pixels, twice per integrator under two seeds
//! of its own, [`PILOT_PASSES`] passes each, and compares per-pass variances (the squared
//! difference between a pair, relative as `relmse` weighs it), in two stages:
//!
//! 1. `pt` against `bdpt`: where `pt`'s variance is within [`BOUNCE_FINDS_THE_LIGHT`]
//!    times `bdpt`'s, a camera path's bounce finds the light,
//!    and so do gather rays: gathering, without more pilot (cornell, knot);
//! 2. otherwise `auto`'s gathering itself (its photons scaled to the pilot's pixels, so
//!    that a density estimate spans as many pixels as in the render; about as long again)
//!    against `bdpt`: `bdpt` when gathering's variance times [`GATHERING_PASS_COST`] is
//!    the larger. A point light's hot spot (cornell_spheres) makes `pt` poor but not
//!    gathering, whose shadow rays reach the light from where its gather rays land; a
//!    light that shadow rays sample poorly from there (a parallelogram a few centimetres
//!    from the wall it faces) makes both poor.
//!
//! Before 2026-12-05 the first stage decided alone, and chose `bdpt` on cornell_spheres,
//! where gathering is 1.3-3x sooner. A function of the scene and the spec alone (the
//! pilot's bytes do not depend on the thread count or the clock), so the choice is the
//! same on every run.

use std::ops::ControlFlow;

use super::Inputs;
use super::auto::GatherShape;
use crate::render::control::Control;
use crate::render::film::Image;
use crate::render::outcome::RenderError;
use crate::render::sampling::splitmix64;
use crate::render::scene::Scene;
use crate::spec::{Integrator, Passes, RenderSpec, Stop};

/// Below how many times `bdpt`'s per-pass variance `pt`'s lies where a camera path's bounce
/// finds the light, so that gathering needs no pilot of its own: a `bdpt` pass's cost in
/// `pt` passes (1.5-1.8), times the least of how much sooner gathering reached Mitsuba's
/// error than `pt` (1.7). pt/bdpt read 1.5-2.0 on cornell and knot, 4.4-6.4 where a bright
/// patch lights the room, with 16 passes and the old weight (docs/performance-history.md,
/// "auto's pilot"); 1.7-2.4 and 6.2-37 with 8 passes weighed by `bdpt`'s mean.
const BOUNCE_FINDS_THE_LIGHT: f64 = 1.8 * 1.7;

/// About how many times a `bdpt` pass's time a pass of `auto`'s gathering takes (one
/// sample and its gather rays a pixel, and the pass's photons): 1.64 on cornell_spheres,
/// 2.15 on cornell, 2.08 on tests/bidir.rs's `WALL_WASH` at 256x256, since its density
/// estimates search a hashed grid (docs/performance-history.md, "ppm's range search in a
/// hashed grid").
const GATHERING_PASS_COST: f64 = 2.0;

/// Pixels of a pilot image (its aspect the camera's).
const PILOT_PIXELS: f64 = 2304.0;

/// Passes of each pilot render. With the pixels weighed by `bdpt`'s mean
/// ([`pass_variance`]) 8 tell the rooms apart as 16 did, seeds 1-5: the first stage's pt/bdpt
/// 1.7-2.4 on cornell and knot against 6.2-6.6 on cornell_spheres and 23-37 where a light
/// washes a wall; the second stage's bdpt/gathering over the pass cost 1.9-2.1 on
/// cornell_spheres, 0.5-0.6 and under 0.03 on a washed wall lit by a rectangle and by a
/// parallelogram (docs/performance-history.md, "the pilot weighed by bdpt's mean").
const PILOT_PASSES: u32 = 8;

/// How the second stage's gathering spends its rays, and so the render's where it ran:
/// where `pt`'s bounce finds the light poorly, more rays a camera sample.
const SECOND_STAGE_SHAPE: GatherShape = GatherShape::OnOneSample;

/// The fewest photons a pilot pass of gathering traces, however small the image.
const MIN_PILOT_PHOTONS: u64 = 1_000;

/// What the pilot found: each integrator's per-pass variance (relative, summed over the
/// pilot image's pixels and channels); gathering's only where `pt`'s bounce found the
/// light poorly.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pilot {
    pub pt: f64,
    pub bdpt: f64,
    pub gathering: Option<f64>,
}

impl Pilot {
    /// Whether `bdpt` reaches a given error sooner than `ppm` with final gathering, by the
    /// pilot: variance times the cost of a pass.
    pub fn prefers_bdpt(&self) -> bool {
        self.gathering
            .is_some_and(|g| g * GATHERING_PASS_COST > self.bdpt)
    }

    /// How gathering should spend its rays: over more camera samples where a camera path's
    /// bounce found the light (the first stage decided alone), else as the second stage
    /// rendered it ([`SECOND_STAGE_SHAPE`]), the shape its variance vouches for.
    pub fn gather_shape(&self) -> GatherShape {
        match self.gathering {
            None => GatherShape::OverSamples,
            Some(_) => SECOND_STAGE_SHAPE,
        }
    }
}

/// The pilot of `spec` (its seed, depth and effect switches) on `scene`, cancelled with
/// `control`: `pt` against `bdpt`, then, where `pt` did poorly, gathering against `bdpt`.
pub(super) fn run_pilot(
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
    // A pair's two renders run side by side: a pilot image's passes are too small to keep
    // every thread busy alone (each render's bytes are the same either way).
    let pair = |integrator: &Integrator| {
        let (a, b) = rayon::join(|| render(integrator, 1), || render(integrator, 2));
        Ok::<_, RenderError>([a?, b?])
    };
    let (bdpt_pair, pt_pair) = rayon::join(
        || pair(&Integrator::Bdpt(passes.clone())),
        || pair(&Integrator::Pt(passes.clone())),
    );
    let bdpt_pair = bdpt_pair?;
    let bdpt = pass_variance(&bdpt_pair, &bdpt_pair);
    let pt = pass_variance(&pt_pair?, &bdpt_pair);
    if pt <= BOUNCE_FINDS_THE_LIGHT * bdpt {
        return Ok(Pilot {
            pt,
            bdpt,
            gathering: None,
        });
    }
    // As many photons a pilot pixel as the render will have a pixel.
    let mut gathering = super::auto::gathering(&passes, SECOND_STAGE_SHAPE);
    let scale = (width * height) as f64 / (w as f64 * h as f64);
    let scaled = |n: u64| {
        ((n as f64 * scale).round() as u64)
            .max(MIN_PILOT_PHOTONS)
            .min(n)
    };
    gathering.pass.photons = scaled(gathering.pass.photons);
    gathering.pass.caustic_photons = scaled(gathering.pass.caustic_photons);
    // Unsmoothed, as the thresholds were measured: smoothing lowers a pass's variance by a
    // blur, which a variance does not charge, so it would tip the choice toward gathering
    // where its gather rays find the light poorly (a washed wall).
    gathering.gather_smoothing = 0.0;
    // One shadow ray a light, as the thresholds were measured (more lowers gathering's
    // variance under an area light: the choice stays the one made before they were added).
    gathering.pass.shadow_rays = 1;
    let gathering = pass_variance(&pair(&Integrator::Ppm(gathering))?, &bdpt_pair);
    Ok(Pilot {
        pt,
        bdpt,
        gathering: Some(gathering),
    })
}

/// An integrator's per-pass variance from a pair of its pilot images (each the mean of
/// [`PILOT_PASSES`] passes): a pair's squared difference is twice the variance of a mean,
/// weighed by 1 / (m^2 + 0.01) with m the mean of `bdpt`'s pair `weigh_by` (as `relmse`
/// weighs an error by the reference), the same weight for every integrator compared.
/// `bdpt`'s images are the steadier ones wherever the choice is close; a mean that also
/// held the measured integrator's images would rise with its own fireflies and discount
/// them: with it, a washed wall's pt/bdpt read 4.4-5.9 after 16 passes and 1.9-2.5 after 8,
/// below [`BOUNCE_FINDS_THE_LIGHT`].
fn pass_variance([a, b]: &[Image; 2], weigh_by: &[Image; 2]) -> f64 {
    let [x, y] = weigh_by;
    let mut sum = 0.0;
    for i in 0..a.pixels.len() {
        for c in 0..3 {
            let [a, b, x, y] = [a, b, x, y].map(|im| im.pixels[i][c] as f64);
            let weight = 1.0 / (((x + y) / 2.0).powi(2) + 0.01);
            sum += (a - b).powi(2) * weight;
        }
    }
    sum * PILOT_PASSES as f64 / 2.0
}

//! The pilot's small renders: a pair of one integrator under the pilot's two seeds, each to
//! a pass count and continued from its state, and the per-pass variance a pair shows.

use std::ops::ControlFlow;

use super::{MIN_PILOT_PHOTONS, PILOT_PIXELS, SECOND_STAGE_SHAPE};
use crate::render::control::Control;
use crate::render::film::Image;
use crate::render::outcome::RenderError;
use crate::render::ppm::PpmState;
use crate::render::run::Inputs;
use crate::render::sampling::splitmix64;
use crate::render::scene::Scene;
use crate::spec::{Integrator, Passes, RenderSpec, Stop};

/// A pilot render's image, and its state to continue from.
pub(super) struct Look {
    pub(super) image: Image,
    pub(super) state: PpmState,
}

/// A pair of pilot renders of one integrator under the pilot's two seeds.
pub(super) type Pair = [Look; 2];

/// The pilot's small renders of one job: their image size, the job's spec and cancellation.
pub(super) struct Renders<'a> {
    scene: &'a Scene,
    spec: &'a RenderSpec,
    quiet: Control<'a>,
    /// The pilot image's size, and the render's.
    size: (u32, u32),
    render_size: (u32, u32),
}

impl<'a> Renders<'a> {
    pub(super) fn new(
        scene: &'a Scene,
        spec: &'a RenderSpec,
        control: &Control<'a>,
    ) -> Renders<'a> {
        let (w, h) = spec.resolution((scene.camera.width, scene.camera.height));
        let aspect = (w as f64 / h as f64).sqrt();
        let width = ((PILOT_PIXELS.sqrt() * aspect).round() as u32).clamp(4, 256);
        let height = ((PILOT_PIXELS.sqrt() / aspect).round() as u32).clamp(4, 256);
        Renders {
            scene,
            spec,
            quiet: Control {
                cancel: control.cancel,
                progress: None,
            },
            size: (width, height),
            render_size: (w, h),
        }
    }

    /// A render of `integrator` (made for a pass count) under the pilot's seed `k`, to pass
    /// `upto`, continued from `resume` if given: the same bytes as one render of `upto`
    /// passes.
    pub(super) fn look(
        &self,
        integrator: &IntegratorFor<'_>,
        k: u64,
        upto: u32,
        resume: Option<PpmState>,
    ) -> Result<Look, RenderError> {
        let spec = self.spec;
        let pilot = RenderSpec {
            width: Some(self.size.0),
            height: Some(self.size.1),
            seed: splitmix64(splitmix64(spec.seed ^ 0x7069_6c6f_7400_0000).wrapping_add(k)),
            integrator: integrator(Passes {
                spp: 1,
                stop: Stop::after(upto),
            }),
            ..spec.clone()
        };
        let mut state = None;
        let mut keep = |s: &PpmState| {
            if s.passes == upto {
                state = Some(s.clone());
            }
            ControlFlow::Continue(())
        };
        let inputs = Inputs {
            resume,
            ..Inputs::fresh()
        };
        let image =
            crate::render::run::run(self.scene, &pilot, inputs, &self.quiet, &mut keep)?.image;
        let state = state.ok_or_else(|| RenderError::Input("a pilot render ran no pass".into()))?;
        Ok(Look { image, state })
    }

    /// A pair's two renders, side by side: a pilot image's passes are too small to keep
    /// every thread busy alone (each render's bytes are the same either way). A `resume`
    /// pair that ran `upto` passes already is the answer itself.
    pub(super) fn pair(
        &self,
        integrator: &IntegratorFor<'_>,
        upto: u32,
        resume: Option<Pair>,
    ) -> Result<Pair, RenderError> {
        let resume = match resume {
            Some(done) if done.iter().all(|l| l.state.passes >= upto) => return Ok(done),
            resume => resume,
        };
        let [ra, rb] = resume.map_or([None, None], |[a, b]| [Some(a.state), Some(b.state)]);
        let (a, b) = rayon::join(
            || self.look(integrator, 1, upto, ra),
            || self.look(integrator, 2, upto, rb),
        );
        Ok([a?, b?])
    }

    /// `auto`'s gathering as the pilot renders it, for `passes`.
    pub(super) fn gathering(&self, passes: Passes) -> Integrator {
        let mut g = crate::render::run::auto::gathering(&passes, SECOND_STAGE_SHAPE);
        // As many photons a pilot pixel as the render will have a pixel.
        let (width, height) = self.size;
        let (w, h) = self.render_size;
        let scale = (width * height) as f64 / (w as f64 * h as f64);
        let scaled = |n: u64| {
            ((n as f64 * scale).round() as u64)
                .max(MIN_PILOT_PHOTONS)
                .min(n)
        };
        g.pass.photons = scaled(g.pass.photons);
        g.pass.caustic_photons = scaled(g.pass.caustic_photons);
        // Unsmoothed, as the thresholds were measured: smoothing lowers a pass's variance
        // by a blur, which a variance does not charge, so it would tip the choice toward
        // gathering where its gather rays find the light poorly (a washed wall).
        g.gather_smoothing = 0.0;
        // One shadow ray a light, as the thresholds were measured (more lowers gathering's
        // variance under an area light: the choice stays the one made before they were
        // added).
        g.pass.shadow_rays = 1;
        Integrator::Ppm(g)
    }
}

/// An integrator made for a pass count.
pub(super) type IntegratorFor<'m> = dyn Fn(Passes) -> Integrator + Sync + 'm;

/// The per-pass variances of `measured`'s pair and of `bdpt`'s, both weighed by `bdpt`'s
/// mean ([`pass_variance`]), each pair the mean of `passes` passes.
pub(super) fn variances(measured: &Pair, bdpt: &Pair, passes: u32) -> (f64, f64) {
    (
        pass_variance(measured, bdpt, passes),
        pass_variance(bdpt, bdpt, passes),
    )
}

/// An integrator's per-pass variance from a pair of its pilot images (each the mean of
/// `passes` passes): a pair's squared difference is twice the variance of a mean,
/// weighed by 1 / (m^2 + 0.01) with m the mean of `bdpt`'s pair `weigh_by` (as `relmse`
/// weighs an error by the reference), the same weight for every integrator compared.
/// `bdpt`'s images are the steadier ones wherever the choice is close; a mean that also
/// held the measured integrator's images would rise with its own fireflies and discount
/// them: with it, a washed wall's pt/bdpt read 4.4-5.9 after 16 passes and 1.9-2.5 after 8,
/// below [`BOUNCE_FINDS_THE_LIGHT`].
fn pass_variance([a, b]: &Pair, weigh_by: &Pair, passes: u32) -> f64 {
    let [a, b, x, y] = [a, b, &weigh_by[0], &weigh_by[1]].map(|l| &l.image);
    let mut sum = 0.0;
    for i in 0..a.pixels.len() {
        for c in 0..3 {
            let [a, b, x, y] = [a, b, x, y].map(|im| im.pixels[i][c] as f64);
            let weight = 1.0 / (((x + y) / 2.0).powi(2) + 0.01);
            sum += (a - b).powi(2) * weight;
        }
    }
    sum * passes as f64 / 2.0
}

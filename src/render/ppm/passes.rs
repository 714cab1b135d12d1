//! A ppm pass: trace fresh photon maps (from the pass's seed alone), read them with
//! fixed-radius estimates at the state's radii, and render the camera pass. The pass loop
//! itself is shared by every progressive integrator (`render/progressive.rs`).

use std::time::Instant;

use super::{MAX_RADIUS_FRACTION, PpmState, initial_radius};
use crate::render::camera::Camera;
use crate::render::control::Control;
use crate::render::effects::Analysis;
use crate::render::film::render_film;
use crate::render::integrator::{Samples, SeenLights, Shader, smooth_gathers};
use crate::render::outcome::RenderError;
use crate::render::photon::{Density, PhotonMap, PhotonMaps, RadiusLookup, build_photon_maps};
use crate::render::progressive::{PassAt, PassOutput, PassResult, Progression};
use crate::render::scene::Scene;
use crate::render::stats::{RenderStats, StatsInput, collect};
use crate::spec::{Progressive, RenderSpec};

/// How fast the smoothing's blur fades over the passes, beyond the global map's own
/// shrinking (n^((alpha - 1) / 2)): its radius falls as pass^-SMOOTHING_FADE. After a few
/// passes the error left is the gathers' noise, not the blur (on knot the mean of two
/// seeds' renders has 1/sqrt(2) of either's block_err), so a fade slower than the first
/// choice, 0.5, pays: with 0.35 block_err after 4 and 16 passes 2-4% lower on cornell and
/// knot, relmse after 16 and 64 passes 10-40% lower, block_err the same after 256 passes on
/// cornell, 2.6% higher on cornell_spheres after 64; 0.25 raised that by 7% over 0.5
/// (docs/performance-history.md, "smoothing on planes, fading slower"), and no extra fade
/// at all raised its block_err after 16 passes by 40% ("smoothed final gathers").
pub(crate) const SMOOTHING_FADE: f32 = 0.35;

/// Progressive photon mapping's passes over one scene and spec.
pub(crate) struct PpmPasses<'a> {
    pub scene: &'a Scene,
    pub spec: &'a RenderSpec,
    pub ppm: &'a Progressive,
    pub analysis: &'a Analysis,
    pub camera: Camera,
    /// The pixels that read the lights they see first by rays of their own, found once.
    seen: SeenLights,
    /// The last pass's maps and radii (global, caustic), for the final statistics; only
    /// one pass's maps exist at a time.
    last: Option<(PhotonMaps, (f32, f32))>,
}

impl<'a> PpmPasses<'a> {
    pub fn new(
        scene: &'a Scene,
        spec: &'a RenderSpec,
        ppm: &'a Progressive,
        analysis: &'a Analysis,
        camera: Camera,
    ) -> PpmPasses<'a> {
        PpmPasses {
            scene,
            spec,
            ppm,
            analysis,
            seen: SeenLights::of(scene, &camera),
            camera,
            last: None,
        }
    }

    /// The radius within which pass `pass` smooths its final gathers (`integrator/smooth.rs`),
    /// if it does: `gather_smoothing` times the global map's radius `r_global` over
    /// pass^[`SMOOTHING_FADE`]. None where the camera's points gather nothing
    /// (`--no-indirect`).
    fn smoothing_radius(&self, pass: u32, r_global: f32) -> Option<f32> {
        let radius = self.ppm.gather_smoothing * r_global / (pass as f32).powf(SMOOTHING_FADE);
        let smooths = self.ppm.smooths_gathers() && self.analysis.plan.primary.gather;
        (smooths && radius > 0.0 && radius.is_finite()).then_some(radius)
    }

    /// The initial radii, given or from the first pass's photons.
    fn set_initial_radii(&self, state: &mut PpmState, maps: &PhotonMaps) {
        let r_max = MAX_RADIUS_FRACTION * self.scene.extent().max(f32::MIN_POSITIVE);
        let k = self.ppm.pass.k;
        let r0 = |m: &Option<PhotonMap>| match (self.ppm.radius, m) {
            (Some(r), _) => r as f64,
            (None, Some(m)) => initial_radius(m, k, r_max) as f64,
            (None, None) => 0.0,
        };
        state.radius_initial = [r0(&maps.global), r0(&maps.caustic)];
        state.r2_global = state.radius_initial[0].powi(2);
        state.r2_caustic = state.radius_initial[1].powi(2);
    }
}

impl Progression for PpmPasses<'_> {
    fn pass(&mut self, state: &mut PpmState, at: PassAt, control: &Control) -> PassResult {
        let PassAt { pass, seed } = at;
        let photon_params = crate::render::photon::PhotonParams {
            seed,
            ..self.analysis.photon_params.clone()
        };
        // One pass's maps at a time: the last pass's go before this pass's are traced.
        drop(self.last.take());
        let maps = build_photon_maps(self.scene, &photon_params, control)?;
        if pass == 1 {
            self.set_initial_radii(state, &maps);
        }
        let radii = (
            state.r2_global.sqrt() as f32,
            state.r2_caustic.sqrt() as f32,
        );
        fn lookup(m: &Option<PhotonMap>, r: f32) -> Option<Density<'_>> {
            m.as_ref().map(|m| Density::Radius(RadiusLookup::new(m, r)))
        }
        let spp = self.ppm.pass.spp;
        let smoothing = self.smoothing_radius(pass, radii.0);
        let shader = Shader {
            scene: self.scene,
            plan: self.analysis.plan,
            caustic: lookup(&maps.caustic, radii.1),
            global: lookup(&maps.global, radii.0),
            gather_rays: self.ppm.pass.gather_rays,
            max_depth: self.spec.max_depth,
            control: *control,
            // The job's sequences, continued pass after pass: a pixel's samples (and their
            // gathers) over every pass are one stratified set, as in the bidirectional
            // family's passes.
            samples: Samples {
                seed: self.spec.seed,
                first: (pass as u64 - 1) * spp as u64,
            },
            record_gathers: smoothing.is_some(),
            seen: &self.seen,
        };
        let t_render = Instant::now();
        let mut film = render_film(&shader, &self.camera, spp, control)?;
        if let Some(radius) = smoothing {
            smooth_gathers(&mut film.image, &film.extra, radius, &self.camera);
        }
        let render = t_render.elapsed().as_secs_f64();
        drop(shader);
        let stored = |m: &Option<PhotonMap>| m.as_ref().map_or(0, |m| m.len() as u64);
        let radius = |m: &Option<PhotonMap>, r: f32| if m.is_some() { r as f64 } else { 0.0 };
        let out = PassOutput {
            image: film.image,
            nonfinite_samples: film.nonfinite_samples,
            radii: (
                radius(&maps.global, radii.0),
                radius(&maps.caustic, radii.1),
            ),
            photon_trace: maps.trace_seconds,
            build_maps: maps.build_seconds,
            render,
            stored: (stored(&maps.global), stored(&maps.caustic)),
        };
        self.last = Some((maps, radii));
        Ok(out)
    }

    /// Pass 1's maps, traced for their photons' spacing and dropped (unless the radius is
    /// given, when nothing is traced).
    fn initial_radii(
        &mut self,
        state: &mut PpmState,
        at: PassAt,
        control: &Control,
    ) -> Result<(), RenderError> {
        let maps = match self.ppm.radius {
            Some(_) => PhotonMaps::none(self.analysis.photon_params.clone()),
            None => {
                let params = crate::render::photon::PhotonParams {
                    seed: at.seed,
                    ..self.analysis.photon_params.clone()
                };
                build_photon_maps(self.scene, &params, control)?
            }
        };
        self.set_initial_radii(state, &maps);
        Ok(())
    }

    /// Stats of the last pass's maps (none if a resumed render had no pass left to run).
    fn stats(&self, state: &PpmState) -> RenderStats {
        let no_maps;
        let (maps, (rg, rc)) = match &self.last {
            Some((maps, radii)) => (maps, *radii),
            None => {
                no_maps = PhotonMaps::none(self.analysis.photon_params.clone());
                (&no_maps, (0.0, 0.0))
            }
        };
        collect(&StatsInput {
            scene: self.scene,
            maps,
            spec: self.spec,
            camera: &self.camera,
            cache: None,
            radii: (rc, rg),
            times: (0.0, 0.0),
            nonfinite_samples: state.nonfinite_samples,
            effects: self.analysis.effects.clone(),
        })
    }
}

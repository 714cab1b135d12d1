//! The bidirectional family, one implementation restricted by which techniques it counts:
//! vertex connection and merging (`vcm`: Georgiev, Krivanek, Davidovic and Slusallek,
//! "Light Transport Simulation with Vertex Connection and Merging", SIGGRAPH Asia 2012;
//! Hachisuka, Pantaleoni and Jensen, "A Path Space Extension for Robust Light Transport
//! Simulation", 2012), bidirectional path tracing (`bdpt`, Veach 1997), path tracing with
//! next-event estimation (`pt`) and light tracing (`lt`). SmallVCM (Davidovic and Georgiev)
//! was read for the structure and the MIS bookkeeping; the code is ours.
//!
//! A pass is `spp` iterations; an iteration traces one light subpath per pixel
//! (`light_paths.rs`), keeps their non-specular vertices in a kd-tree when it merges, and
//! then one camera subpath per pixel (`camera_paths.rs`), which joins them by every technique
//! the integrator counts. The iteration's image is the camera pass plus the light-tracing
//! splats; a pass is the mean of its iterations, the render the mean of its passes
//! (`render/progressive.rs`), the merge radius shrinking as ppm's.

mod camera_paths;
mod effects;
mod light_paths;
mod lights;
mod radius;
#[cfg(test)]
mod tests;
mod vertex;
mod weights;

use std::time::Instant;

use crate::render::camera::Camera;
use crate::render::control::Control;
use crate::render::effects::Analysis;
use crate::render::film::{Image, render_film};
use crate::render::light::LightPicker;
use crate::render::outcome::RenderError;
use crate::render::photon::{PhotonMaps, RangeGrid};
use crate::render::ppm::PpmState;
use crate::render::progressive::{PassAt, PassOutput, PassResult, Progression};
use crate::render::sampling::{Sampler, Stream};
use crate::render::scene::Scene;
use crate::render::stats::{RenderStats, StatsInput, collect};
use crate::spec::{EffectSwitches, RenderSpec};

use camera_paths::CameraPass;
use light_paths::{LightPaths, trace_light_paths};
use vertex::Factors;
use weights::{Technique, weight};

/// Which techniques an integrator of the family counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Modes {
    Pt,
    Lt,
    Bdpt,
    Vcm,
}

impl Modes {
    fn traces_light_paths(self) -> bool {
        self != Modes::Pt
    }

    fn keep_light_vertices(self) -> bool {
        matches!(self, Modes::Bdpt | Modes::Vcm)
    }

    fn light_tracing(self) -> bool {
        self != Modes::Pt
    }

    fn nee(self) -> bool {
        self != Modes::Lt
    }

    fn connects(self) -> bool {
        matches!(self, Modes::Bdpt | Modes::Vcm)
    }

    fn merges(self) -> bool {
        self == Modes::Vcm
    }
}

/// What one iteration's subpaths share.
pub(super) struct Iteration<'a> {
    scene: &'a Scene,
    camera: Camera,
    picker: &'a LightPicker,
    modes: Modes,
    factors: Factors,
    max_depth: u32,
    effects: EffectSwitches,
    /// The seed of the subpaths' Sobol sequences (`render/qmc`): the render's (the pilot's
    /// own for the pilot iteration).
    seed: u64,
    /// This iteration's index among all passes' iterations (0-based): the point of every
    /// sequence it draws.
    n: u64,
    /// Light subpaths (one per pixel).
    paths: u64,
}

impl Iteration<'_> {
    /// The random numbers of subpath `index` of `stream` in this iteration.
    fn sampler(&self, stream: Stream, index: u64) -> Sampler {
        Sampler::sobol(self.seed, stream, index, self.n)
    }

    fn weight(&self, t: Technique) -> f32 {
        weight(self.modes, &self.factors, t)
    }
}

/// The passes of one bidirectional render.
pub(crate) struct BidirPasses<'a> {
    pub scene: &'a Scene,
    pub spec: &'a RenderSpec,
    pub analysis: &'a Analysis,
    pub camera: Camera,
    pub modes: Modes,
    /// Iterations per pass.
    pub spp: u32,
    /// The given initial merge radius (`vcm`).
    pub radius: Option<f32>,
    picker: LightPicker,
    /// Light vertices the last pass kept.
    stored: u64,
    #[cfg(test)]
    broken: Option<(tests::Broken, f32)>,
}

impl<'a> BidirPasses<'a> {
    pub fn new(
        scene: &'a Scene,
        spec: &'a RenderSpec,
        analysis: &'a Analysis,
        camera: Camera,
        modes: Modes,
    ) -> BidirPasses<'a> {
        let passes = spec.passes().expect("a bidirectional integrator");
        BidirPasses {
            scene,
            spec,
            analysis,
            camera,
            modes,
            spp: passes.spp,
            radius: spec.merge_radius().and_then(|(_, r)| r),
            picker: LightPicker::new(&scene.lights, &analysis.photon_params.dark_lights),
            stored: 0,
            #[cfg(test)]
            broken: None,
        }
    }

    fn iteration(&self, seed: u64, n: u64, r2: f32) -> Iteration<'_> {
        let (w, h) = (self.camera.width as u64, self.camera.height as u64);
        let modes = self.modes;
        #[allow(unused_mut)]
        let mut factors = Factors::new(w * h, r2, modes.connects(), modes.merges());
        #[cfg(test)]
        {
            factors.broken = self.broken;
        }
        Iteration {
            scene: self.scene,
            camera: self.camera.clone(),
            picker: &self.picker,
            modes,
            factors,
            max_depth: self.spec.max_depth,
            effects: self.spec.effects,
            seed,
            n,
            paths: w * h,
        }
    }

    /// One iteration: light subpaths, then camera subpaths; its image and the non-finite
    /// samples it dropped.
    fn run_iteration(
        &self,
        n: u64,
        r2: f32,
        control: &Control,
    ) -> Result<(Image, u64, u64), RenderError> {
        let it = self.iteration(self.spec.seed, n, r2);
        let lights = if self.modes.traces_light_paths() {
            trace_light_paths(&it, control)?
        } else {
            LightPaths::empty(&it.camera)
        };
        // No grid without a light vertex: then nothing is merged.
        let grid = if self.modes.merges() {
            RangeGrid::build(&lights.vertices, r2)
        } else {
            None
        };
        let pass = CameraPass {
            it: &it,
            lights: &lights,
            grid: grid.as_ref(),
        };
        let film = render_film(&pass, &it.camera, 1, control)?;
        let mut image = film.image;
        for (px, s) in image.pixels.iter_mut().zip(&lights.splats.pixels) {
            for c in 0..3 {
                px[c] += s[c];
            }
        }
        let dropped = film.nonfinite_samples + lights.nonfinite;
        Ok((image, dropped, lights.vertices.len() as u64))
    }
}

impl Progression for BidirPasses<'_> {
    /// The merge radius, given or from a pilot iteration of pass 1's seed; none without
    /// merging.
    fn initial_radii(
        &mut self,
        state: &mut PpmState,
        at: PassAt,
        control: &Control,
    ) -> Result<(), RenderError> {
        if self.modes.merges() {
            let r = match self.radius {
                Some(r) => r,
                None => self.pilot_radius(at.seed, control)?,
            };
            state.radius_initial = [r as f64, 0.0];
            state.r2_global = (r as f64).powi(2);
        }
        Ok(())
    }

    fn pass(&mut self, state: &mut PpmState, at: PassAt, control: &Control) -> PassResult {
        let pass = at.pass;
        if pass == 1 {
            self.initial_radii(state, at, control)?;
        }
        let r2 = state.r2_global as f32;
        let t0 = Instant::now();
        let mut sum = vec![[0.0f64; 3]; self.camera.width as usize * self.camera.height as usize];
        let (mut dropped, mut stored) = (0, 0);
        for j in 0..self.spp {
            let n = (pass as u64 - 1) * self.spp as u64 + j as u64;
            let (image, d, s) = self.run_iteration(n, r2, control)?;
            for (acc, px) in sum.iter_mut().zip(&image.pixels) {
                for c in 0..3 {
                    acc[c] += px[c] as f64;
                }
            }
            (dropped, stored) = (dropped + d, stored + s);
        }
        let mut image = Image::new(self.camera.width, self.camera.height);
        for (px, acc) in image.pixels.iter_mut().zip(&sum) {
            *px = acc.map(|v| (v / self.spp as f64) as f32);
        }
        self.stored = stored;
        Ok(PassOutput {
            image,
            nonfinite_samples: dropped,
            radii: (
                if self.modes.merges() {
                    r2.sqrt() as f64
                } else {
                    0.0
                },
                0.0,
            ),
            photon_trace: 0.0,
            build_maps: 0.0,
            render: t0.elapsed().as_secs_f64(),
            stored: (stored, 0),
        })
    }

    fn stats(&self, state: &PpmState) -> RenderStats {
        let maps = PhotonMaps::none(self.analysis.photon_params.clone());
        let mut effects = self.analysis.effects.clone();
        effects::describe(&mut effects, self.modes, self.spec.effects);
        let mut stats = collect(&StatsInput {
            scene: self.scene,
            maps: &maps,
            spec: self.spec,
            camera: &self.camera,
            cache: None,
            radii: (0.0, 0.0),
            times: (0.0, 0.0),
            nonfinite_samples: state.nonfinite_samples,
            effects,
        });
        stats.photons.global_stored = self.stored;
        stats
    }
}

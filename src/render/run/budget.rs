//! What a render will cost before it runs, by integrator: its peak memory, its work and the
//! size of its result files (a server admits jobs by them), and the relative cost of its
//! phases (one progress fraction over a whole render).

use super::auto::{self, GatherShape};
use crate::render::control::{Phase, Progress};
use crate::render::scene::Scene;
use crate::spec::{Integrator, PhotonMapping, RenderSpec, Stop};

/// What a render needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Needs {
    /// An upper estimate of the render's peak memory.
    pub memory_bytes: u64,
    /// Work in ray-sized units: every camera sample and final-gather ray, every emitted
    /// photon, and (for `photon`) each k-NN neighbour of the irradiance precompute, times
    /// the passes of a progressive render (one pass of a render that runs until its time
    /// limit: the time, not the work, bounds it). An upper guide, not a prediction of
    /// seconds: it bounds what one render may take from a machine, whatever its parameters.
    pub work: f64,
    /// An upper estimate of the result files: the EXR (f32 RGBA), the PNG, and a
    /// progressive render's saved state (the exact sum image, 48 bytes a pixel).
    pub result_bytes: u64,
}

/// Bytes a pixel for ppm's smoothed gathers (`render/integrator/smooth.rs`), where they
/// run: the film's record of each pixel's gathers (60, held twice while the tiles are
/// joined), their surfaces (56) and the fits along the rows (16).
fn smoothing_bytes(spec: &RenderSpec) -> u64 {
    match &spec.integrator {
        Integrator::Ppm(p) if p.smooths_gathers() => 192,
        _ => 0,
    }
}

impl Needs {
    /// The needs of `spec` at `pixels` pixels over a scene of `triangles` triangles.
    ///
    /// Memory: photons while traced and in their kd-trees (a global photon path stores at
    /// most a few photons: 3 per emitted photon bounds the built-in scenes' 1.35 with
    /// room), twice while traced (per-chunk buffers, then the map) and while a ppm pass
    /// searches them (the map, and its range grid's copy and table); the irradiance cache;
    /// the film and its encodings, 48 bytes a pixel, and (progressive) the exact sum (48),
    /// a pass's image and the saved state's buffer (48), 48 + 96 bytes a pixel; the scene's description, primitives and BVH build,
    /// 1,200 bytes a triangle. The per-pixel and per-triangle figures are measured on the
    /// largest jobs the server's test limits accept (tests/server/memory.rs).
    pub fn of(spec: &RenderSpec, pixels: u64, triangles: usize) -> Needs {
        const PHOTON_BYTES: u64 = 32;
        let (global, caustic) = spec
            .photon_mapping()
            .map_or((0, 0), |p| (p.photons * 3, p.caustic_photons));
        let maps = (global + caustic) * PHOTON_BYTES * 2;
        let irradiance = global / 4 * 64;
        let progressive = spec.is_progressive() as u64;
        let film = pixels * 48 * (1 + 2 * progressive) + pixels * smoothing_bytes(spec);
        let geometry = triangles as u64 * 1200;
        // Auto may choose vcm (counted below), ppm with final gathering in either shape
        // or, under a short time limit, a photon render: the largest needs of them.
        let alternatives = match &spec.integrator {
            Integrator::Auto(passes) => {
                let gathering = |shape| Some(Integrator::Ppm(auto::gathering(passes, shape)));
                [
                    auto::budget_photon(passes, pixels).map(Integrator::Photon),
                    gathering(GatherShape::OverSamples),
                    gathering(GatherShape::OnOneSample),
                ]
            }
            _ => [None, None, None],
        };
        let own = Needs {
            memory_bytes: maps
                + irradiance
                + film
                + light_vertices(spec, pixels)
                + geometry
                + (16 << 20),
            work: work(spec, pixels),
            result_bytes: pixels * 20 + progressive * pixels * 48 + (64 << 10),
        };
        alternatives
            .into_iter()
            .flatten()
            .fold(own, |needs, integrator| {
                let alternative = RenderSpec {
                    integrator,
                    ..spec.clone()
                };
                needs.or(Needs::of(&alternative, pixels, triangles))
            })
    }

    /// Needs that cover both `self` and `other` (either may run).
    fn or(self, other: Needs) -> Needs {
        Needs {
            memory_bytes: self.memory_bytes.max(other.memory_bytes),
            work: self.work.max(other.work),
            result_bytes: self.result_bytes.max(other.result_bytes),
        }
    }
}

/// The light vertices a bidirectional iteration keeps (one subpath per pixel, a few vertices
/// each, about 100 bytes a vertex, twice with the merging's kd-tree) and its splat image.
fn light_vertices(spec: &RenderSpec, pixels: u64) -> u64 {
    match &spec.integrator {
        Integrator::Raytrace(_)
        | Integrator::Photon(_)
        | Integrator::Ppm(_)
        | Integrator::Pt(_) => 0,
        Integrator::Lt(_) => pixels * 12,
        Integrator::Bdpt(_) => pixels * (12 + 4 * 100),
        // Auto may choose vcm: its needs bound the others'.
        Integrator::Vcm(_) | Integrator::Auto(_) => pixels * (12 + 2 * 4 * 100),
    }
}

/// The passes a progressive render's work counts: its pass count, or one pass when it runs
/// until its time limit.
fn work_passes(stop: &Stop) -> f64 {
    stop.iterations.map_or(1.0, f64::from)
}

fn work(spec: &RenderSpec, pixels: u64) -> f64 {
    // A camera ray, its gather rays and its shadow rays beyond the first (each area light's
    // extra rays: counted as one light's).
    let camera = |spp: u32, more_rays: u32| pixels as f64 * spp as f64 * (1.0 + more_rays as f64);
    let mapping_rays = |p: &PhotonMapping| {
        p.gather_rays
            .saturating_add(p.shadow_rays.saturating_sub(1))
    };
    match &spec.integrator {
        Integrator::Raytrace(r) => camera(r.spp, 0),
        Integrator::Photon(p) => {
            let photons = (p.photons + p.caustic_photons) as f64;
            camera(p.spp, mapping_rays(p)) + photons + p.photons as f64 / 4.0 * p.k as f64
        }
        Integrator::Ppm(p) => {
            let photons = (p.pass.photons + p.pass.caustic_photons) as f64;
            (camera(p.pass.spp, mapping_rays(&p.pass)) + photons) * work_passes(&p.stop)
        }
        // A light and a camera subpath per sample, each a few rays (the connections and
        // shadow rays of its vertices): counted as 8 rays a sample.
        Integrator::Pt(p) | Integrator::Lt(p) | Integrator::Bdpt(p) | Integrator::Auto(p) => {
            camera(p.spp, 7) * work_passes(&p.stop)
        }
        Integrator::Vcm(m) => camera(m.passes.spp, 7) * work_passes(&m.passes.stop),
    }
}

/// One monotone-ready fraction of a whole render from the engine's per-phase progress: the
/// phases weighted by their expected cost (photon tracing, tree building, the irradiance
/// precompute, the camera pass), and a progressive render's passes in sequence. A render
/// with a time limit is as far along as the larger of its passes and its time, since it
/// stops at whichever runs out first (and one that runs until its time is spent has
/// nothing else to count).
pub struct ProgressModel {
    /// Relative cost of each phase of one pass: tracing (with scene building), building,
    /// precompute, camera pass.
    weights: [f64; 4],
    /// Passes the render may run.
    passes: f64,
    /// Seconds the render may run, if it stops by time.
    time_limit: Option<f64>,
}

impl ProgressModel {
    pub fn new(spec: &RenderSpec, pixels: u64) -> ProgressModel {
        let samples =
            |spp: u32, gather: u32| (pixels * spp as u64) as f64 * (1.0 + 1.5 * gather as f64);
        let (weights, passes) = match &spec.integrator {
            Integrator::Raytrace(r) => ([0.0, 0.0, 0.0, samples(r.spp, 0) / 3e6], 1.0),
            Integrator::Photon(p) => {
                let photons = (p.photons + p.caustic_photons) as f64;
                let precompute = p.photons as f64 * 0.35 * p.k as f64 / 2e7;
                let camera = samples(p.spp, p.gather_rays) / 3e6;
                ([photons / 3e6, photons / 1e7, precompute, camera], 1.0)
            }
            // A fixed-radius estimate: no irradiance precompute.
            Integrator::Ppm(p) => {
                let photons = (p.pass.photons + p.pass.caustic_photons) as f64;
                let camera = samples(p.pass.spp, p.pass.gather_rays) / 3e6;
                let passes = p.stop.pass_limit() as f64;
                ([photons / 3e6, photons / 1e7, 0.0, camera], passes)
            }
            // The camera pass carries a pass's progress (light subpaths are part of it).
            Integrator::Pt(p) | Integrator::Lt(p) | Integrator::Bdpt(p) | Integrator::Auto(p) => {
                ([0.0, 0.0, 0.0, 1.0], p.stop.pass_limit() as f64)
            }
            Integrator::Vcm(m) => ([0.0, 0.0, 0.0, 1.0], m.passes.stop.pass_limit() as f64),
        };
        let time_limit = spec.stop().and_then(|s| s.time_limit);
        ProgressModel {
            weights,
            passes,
            time_limit,
        }
    }

    /// [`ProgressModel::new`] for what will render `spec` on `scene`: an `auto` job that
    /// the scene and spec resolve to one photon render (no pilot) counts that render's
    /// phases; counted as `auto`, it would wait for passes it never reports.
    pub fn for_scene(scene: &Scene, spec: &RenderSpec, pixels: u64) -> ProgressModel {
        ProgressModel::new(&auto::known_choice(scene, spec), pixels)
    }

    /// The fraction of the render done when a phase reports `p`, given `passes_done` (the
    /// last `Phase::Passes` report's count) and `pass_seconds`, the render's seconds of
    /// passes and of `auto`'s pilot by now (what its time limit counts:
    /// `PpmState::elapsed` and `PpmState::choosing`).
    pub fn fraction(&self, p: Progress, passes_done: u64, pass_seconds: f64) -> f64 {
        let by_time = self
            .time_limit
            .filter(|&t| t > 0.0)
            .map_or(0.0, |t| pass_seconds / t);
        self.fraction_of_passes(p, passes_done).max(by_time)
    }

    fn fraction_of_passes(&self, p: Progress, passes_done: u64) -> f64 {
        let within = if p.total > 0 {
            p.done as f64 / p.total as f64
        } else {
            1.0
        };
        let i = match p.phase {
            Phase::Passes => return within,
            Phase::BuildScene | Phase::PhotonTrace => 0,
            Phase::BuildMaps => 1,
            Phase::Precompute => 2,
            Phase::Render => 3,
        };
        let total: f64 = self.weights.iter().sum::<f64>().max(1e-12);
        let before: f64 = self.weights[..i].iter().sum();
        let in_pass = (before + self.weights[i] * within) / total;
        (passes_done as f64 + in_pass) / self.passes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::Progressive;

    fn ppm(stop: Stop) -> ProgressModel {
        let spec = RenderSpec::ppm(Progressive {
            stop,
            ..Progressive::DEFAULT
        });
        ProgressModel::new(&spec, 64 * 64)
    }

    fn passes(done: u64, total: u64) -> Progress {
        Progress {
            phase: Phase::Passes,
            done,
            total,
        }
    }

    /// A render that runs until its time limit is as far along as its time, not as its
    /// passes over the engine's cap of a million.
    #[test]
    fn a_render_until_its_time_limit_counts_its_time() {
        let until = Stop {
            iterations: None,
            time_limit: Some(10.0),
            target_error: None,
        };
        let cap = until.pass_limit() as u64;
        let m = ppm(until);
        assert_eq!(m.fraction(passes(3, cap), 3, 2.5), 0.25);
        assert_eq!(m.fraction(passes(3, cap), 3, 0.0), 3.0 / cap as f64);
    }

    /// `auto`'s needs cover every integrator it may choose: at a small image, ppm with final
    /// gathering's photon maps outweigh vcm's light vertices.
    #[test]
    fn auto_needs_what_ppm_with_gathering_needs() {
        let passes = crate::spec::Passes::DEFAULT;
        let auto = Needs::of(
            &RenderSpec::new(Integrator::Auto(passes.clone())),
            32 * 32,
            0,
        );
        for shape in [GatherShape::OverSamples, GatherShape::OnOneSample] {
            let ppm = RenderSpec::ppm(super::auto::gathering(&passes, shape));
            let gathering = Needs::of(&ppm, 32 * 32, 0);
            assert!(gathering.memory_bytes > 10 << 20, "{gathering:?}");
            assert!(auto.memory_bytes >= gathering.memory_bytes, "{auto:?}");
            assert!(auto.work >= gathering.work, "{shape:?}: {auto:?}");
        }
    }

    /// An `auto` job that mirror or glass and a short time limit make one photon render is
    /// as far along as that render's phases (half its camera pass: more than half done);
    /// counted as `auto`'s passes, it read next to nothing until it ended. A room without
    /// mirror or glass goes to the pilot's choice, which reports passes: counted as given.
    #[test]
    fn auto_as_one_photon_render_counts_its_phases() {
        let until = Stop {
            iterations: None,
            time_limit: Some(2.0),
            target_error: None,
        };
        let spec = RenderSpec::new(Integrator::Auto(crate::spec::Passes {
            spp: 1,
            stop: until,
        }));
        let half_camera = Progress {
            phase: Phase::Render,
            done: 1,
            total: 2,
        };
        let glass = include_str!("../../../scenes/cornell_mirror_glass.json");
        let glass = Scene::parse(glass, None).expect("the built-in scene");
        let model = ProgressModel::for_scene(&glass, &spec, 64 * 64);
        let f = model.fraction(half_camera, 0, 0.0);
        assert!(f > 0.5 && f < 1.0, "{f}");
        let as_given = ProgressModel::new(&spec, 64 * 64).fraction(half_camera, 0, 0.0);
        assert!(as_given < 1e-3, "{as_given}");
        let diffuse = Scene::parse(include_str!("../../../scenes/cornell.json"), None).unwrap();
        let room = ProgressModel::for_scene(&diffuse, &spec, 64 * 64);
        assert_eq!(room.fraction(half_camera, 0, 0.0), as_given);
    }

    /// Passes and a time limit: whichever runs out first leads.
    #[test]
    fn passes_and_a_time_limit_report_the_larger_share() {
        let both = Stop {
            time_limit: Some(10.0),
            ..Stop::after(100)
        };
        let m = ppm(both);
        assert_eq!(m.fraction(passes(50, 100), 50, 1.0), 0.5);
        assert_eq!(m.fraction(passes(10, 100), 10, 8.0), 0.8);
        assert_eq!(
            ppm(Stop::after(100)).fraction(passes(10, 100), 10, 8.0),
            0.1
        );
    }
}

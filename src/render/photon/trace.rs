//! Photon tracing (Jensen 2001, chapter 5): emission from the lights in proportion to their
//! power, scattering by the BSDFs with Russian roulette, storage at non-specular surfaces.

use std::time::Instant;

use rayon::prelude::*;

use super::{IRRADIANCE_STRIDE, PathClass, Photon, PhotonMap, PhotonMaps};
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::geometry::{Surface, spawn_ray};
use crate::render::light::Light;
use crate::render::material::Transport;
use crate::render::math::{luminance, luminance_f64, max_component};
use crate::render::sampling::{Sampler, Stream, splitmix64};
use crate::render::scene::Scene;

/// Which first-hit photons the global map keeps (the seed's tri-state).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PhotonStore {
    /// No first-hit photons: direct light comes from shadow rays.
    Indirect,
    /// Every non-specular hit: direct light from the maps too.
    All,
    /// Only first-hit photons: the photon-map view of direct light.
    DirectOnly,
}

impl PhotonStore {
    pub fn name(self) -> &'static str {
        match self {
            PhotonStore::Indirect => "indirect",
            PhotonStore::All => "all",
            PhotonStore::DirectOnly => "direct_only",
        }
    }

    fn keeps(self, class: PathClass) -> bool {
        match self {
            PhotonStore::Indirect => class != PathClass::Direct,
            PhotonStore::All => true,
            PhotonStore::DirectOnly => class == PathClass::Direct,
        }
    }
}

/// Everything that shapes the photon maps (and so keys a cache of them).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct PhotonParams {
    /// Photons emitted for the global map; 0 builds none.
    pub global_photons: u64,
    /// Photons emitted for the caustic map; 0 builds none.
    pub caustic_photons: u64,
    pub store: PhotonStore,
    /// Surface interactions followed per photon path.
    pub max_depth: u32,
    pub seed: u64,
    /// Emit caustic photons only toward the specular objects' bounds (photon/targets.rs);
    /// false: in every direction, as blindly as global photons.
    pub aim_caustics: bool,
    /// Lights that emit no photons (indices, ascending): shut inside a closed object the
    /// camera is outside of (see `render::effects`).
    pub dark_lights: Vec<u32>,
}

/// Which map a tracing run fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Target {
    Global(PhotonStore),
    /// Only light -> specular+ -> non-specular paths; tracing stops at the first
    /// non-specular hit.
    Caustic,
}

impl Target {
    /// Whether a path stores at most one photon in this map (at its first non-specular
    /// hit): nothing later on the path can be stored, so tracing stops there.
    fn one_per_path(self) -> bool {
        matches!(
            self,
            Target::Caustic | Target::Global(PhotonStore::DirectOnly)
        )
    }
}

/// Photons of one tracing run, in photon-index order, with their flux unit (W).
pub struct TraceOutput {
    pub photons: Vec<Photon>,
    pub emitted: u64,
    pub unit: f32,
}

/// Photons per parallel work item: large enough to amortise scheduling, small enough for
/// prompt cancellation and smooth progress.
const CHUNK: u64 = 4096;

/// Light-selection table: cumulative luminance of the lights' power, dark lights left out.
struct LightPicker {
    cdf: Vec<f32>,
    total: f32,
}

impl LightPicker {
    fn new(lights: &[Light], dark: &[u32]) -> LightPicker {
        let mut cdf = Vec::with_capacity(lights.len());
        let mut acc = 0.0;
        for (i, l) in lights.iter().enumerate() {
            if !dark.contains(&(i as u32)) {
                acc += luminance(l.power()).max(0.0);
            }
            cdf.push(acc);
        }
        LightPicker { cdf, total: acc }
    }

    /// The light for `u` in [0, 1) and its selection probability.
    fn pick(&self, u: f32) -> (usize, f32) {
        let x = u * self.total;
        // x can round up to the total: then the last light with any power (never one with
        // none, whose probability 0 would divide a photon's flux).
        let i = self.cdf.partition_point(|&c| c <= x);
        let i = if i < self.cdf.len() {
            i
        } else {
            self.cdf.partition_point(|&c| c < self.total)
        };
        let prev = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (i, (self.cdf[i] - prev) / self.total)
    }
}

/// Trace `emitted` photons for one map. Photon i uses random stream (seed, map, i) only, so
/// the result is the same whatever the thread count.
fn trace(
    scene: &Scene,
    emitted: u64,
    target: Target,
    params: &PhotonParams,
    control: &Control,
    tracker: &crate::render::control::Tracker,
) -> Result<TraceOutput, Cancelled> {
    let (max_depth, seed) = (params.max_depth, params.seed);
    let aim = params.aim_caustics && target == Target::Caustic;
    let picker = LightPicker::new(&scene.lights, &params.dark_lights);
    let nothing_to_aim_at = aim && scene.caustic_targets.is_empty();
    if emitted == 0 || !(picker.total > 0.0) || nothing_to_aim_at {
        tracker.advance(emitted);
        return Ok(TraceOutput {
            photons: Vec::new(),
            emitted,
            unit: 1.0,
        });
    }
    // Every photon leaves its light with luminance total / emitted: the map's flux unit.
    let unit = picker.total / emitted as f32;
    let stream = match target {
        Target::Global(_) => Stream::GlobalPhotons,
        Target::Caustic => Stream::CausticPhotons,
    };
    let chunks = emitted.div_ceil(CHUNK);
    let parts: Vec<Vec<Photon>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            control.check()?;
            // Room for two stored photons per path, so that a chunk of the global map seldom
            // regrows; maps of at most one a path (blind caustic paths mostly store none)
            // grow on demand.
            let mut out = if target.one_per_path() {
                Vec::new()
            } else {
                Vec::with_capacity(2 * CHUNK as usize)
            };
            let end = ((c + 1) * CHUNK).min(emitted);
            for i in c * CHUNK..end {
                let mut s = Sampler::new(seed, stream, i);
                // Global-map paths are picked to carry irradiance points by a hash of their
                // index: a thinning independent of where their photons land.
                let irradiance_point = matches!(target, Target::Global(_))
                    && splitmix64(i ^ splitmix64(seed)).is_multiple_of(IRRADIANCE_STRIDE);
                let path = PathSetup {
                    picker: &picker,
                    target,
                    max_depth,
                    irradiance_point,
                    aim,
                };
                trace_one(scene, &path, &mut s, &mut out);
            }
            tracker.advance(end - c * CHUNK);
            Ok(out)
        })
        .collect::<Result<_, Cancelled>>()?;
    let mut photons = Vec::with_capacity(parts.iter().map(Vec::len).sum());
    for p in parts {
        photons.extend(p);
    }
    let unit = if aim {
        renormalise(&mut photons, unit)
    } else {
        unit
    };
    Ok(TraceOutput {
        photons,
        emitted,
        unit,
    })
}

/// Aimed caustic photons carry a fraction of a blind photon's flux (the solid angle of their
/// targets): rescale the stored powers to a mean luminance of 1 and the unit to match, so
/// that they stay O(1), as the estimators' fixed-point sums expect. The product is unchanged.
fn renormalise(photons: &mut [Photon], unit: f32) -> f32 {
    if photons.is_empty() {
        return unit;
    }
    let mean = luminance_f64(super::sum_power(photons.iter().map(Photon::relative_power)))
        / photons.len() as f64;
    if !(mean > 0.0 && mean.is_finite()) {
        return unit;
    }
    let f = (1.0 / mean) as f32;
    for p in photons.iter_mut() {
        p.power = p.power.map(|c| c * f);
    }
    unit * mean as f32
}

/// What every photon path of one tracing run shares, and this path's irradiance-point mark.
struct PathSetup<'a> {
    picker: &'a LightPicker,
    target: Target,
    max_depth: u32,
    irradiance_point: bool,
    /// Aim the photon at the caustic targets.
    aim: bool,
}

fn trace_one(scene: &Scene, path: &PathSetup, s: &mut Sampler, out: &mut Vec<Photon>) {
    let PathSetup {
        picker,
        target,
        max_depth,
        irradiance_point,
        aim,
    } = *path;
    let (li, p_light) = picker.pick(s.next_f32());
    let (u_pos, u_dir) = (s.next_2d(), s.next_2d());
    let light = &scene.lights[li];
    let em = if aim {
        // Aimed at the specular objects (photon/targets.rs), weighted by the light's own
        // direction pdf over the aiming pdf.
        let origin = light.emission_origin(u_pos);
        let td = scene
            .caustic_targets
            .sample(origin.sp.p, s.next_f32(), u_dir);
        let weight = origin.direction_pdf(td.dir) / td.pdf;
        if !(weight > 0.0) || !weight.is_finite() {
            return;
        }
        crate::render::light::Emission {
            ray: origin.ray(td.dir),
            flux: light.power() * weight,
        }
    } else {
        let em = light.sample_emission(u_pos, u_dir);
        if target == Target::Caustic && !scene.caustic_targets.may_reach(em.ray.o, em.ray.d) {
            return; // it would end unstored at its first hit (see `may_reach`)
        }
        em
    };
    // Flux relative to the map's unit, total / emitted: luminance 1 when it leaves the light
    // (on average, for aimed caustic photons).
    let mut power = em.flux / (p_light * picker.total);
    let mut ray = em.ray;
    let mut non_specular_before = false;
    for depth in 0..max_depth {
        let Some(hit) = scene.intersect(&ray) else {
            return;
        };
        let Surface::Material(mi) = scene.surface(hit.point.prim) else {
            return; // lights absorb
        };
        let m = &scene.materials[mi as usize];
        let wo = -ray.d;
        if !m.is_specular() {
            let class = if depth == 0 {
                PathClass::Direct
            } else if non_specular_before {
                PathClass::Indirect
            } else {
                PathClass::Caustic
            };
            let n = hit.point.n;
            let n_side = if n.dot(wo) < 0.0 { -n } else { n };
            let keep = match target {
                Target::Global(store) => store.keeps(class),
                Target::Caustic => class == PathClass::Caustic,
            };
            if keep {
                out.push(Photon::new(
                    hit.point.p,
                    power,
                    n_side,
                    class,
                    irradiance_point,
                ));
            }
            if target.one_per_path() {
                return;
            }
        }
        let Some(bs) = m.sample(
            wo,
            hit.point.n,
            s.next_f32(),
            s.next_2d(),
            Transport::Importance,
        ) else {
            return;
        };
        // Russian roulette by the sampled albedo keeps photon power about constant.
        let survive = max_component(bs.weight).min(1.0);
        if !(survive > 0.0) || s.next_f32() >= survive {
            return;
        }
        power *= bs.weight / survive;
        non_specular_before |= !bs.specular;
        ray = spawn_ray(&hit.point, bs.wi);
    }
}

/// Trace and build the photon maps for `params` (a map with 0 photons is not built).
///
/// The caustic photons are traced while the global map's tree is balanced: the top of a
/// balance runs on one thread, and the other one has the caustic paths to trace meanwhile.
/// `trace_seconds` runs until the last photon is traced, `build_seconds` from then on.
pub fn build_photon_maps(
    scene: &Scene,
    params: &PhotonParams,
    control: &Control,
) -> Result<PhotonMaps, Cancelled> {
    let t0 = Instant::now();
    let tracker = control.tracker(
        Phase::PhotonTrace,
        params.global_photons + params.caustic_photons,
    );
    let make = |t: TraceOutput| {
        (t.emitted > 0)
            .then(|| PhotonMap::build(t.photons, t.emitted, t.unit, control))
            .transpose()
    };
    let store = Target::Global(params.store);
    let global = trace(
        scene,
        params.global_photons,
        store,
        params,
        control,
        &tracker,
    )?;
    let (global, caustic) = rayon::join(
        || make(global),
        || {
            let caustic = trace(
                scene,
                params.caustic_photons,
                Target::Caustic,
                params,
                control,
                &tracker,
            )?;
            tracker.finish();
            let traced = t0.elapsed().as_secs_f64();
            // From here on only tree building remains.
            let building = control.tracker(Phase::BuildMaps, 2);
            let map = make(caustic)?;
            building.advance(1);
            Ok::<_, Cancelled>((map, traced, building))
        },
    );
    let (global, (caustic, trace_seconds, building)) = (global?, caustic?);
    building.finish();
    Ok(PhotonMaps {
        global,
        caustic,
        params: params.clone(),
        trace_seconds,
        build_seconds: t0.elapsed().as_secs_f64() - trace_seconds,
    })
}

//! Photon tracing runs (Jensen 2001, chapter 5): the photons of a map traced in parallel
//! chunks of paths, four paths in flight per chunk, and the maps built from them. A single
//! path (emission, storage, scattering) is `path.rs`.

use std::time::Instant;

use rayon::prelude::*;

use super::path::{PathSetup, PhotonPath, Target};
use super::{PathClass, Photon, PhotonMap, PhotonMaps};
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::light::LightPicker;
use crate::render::math::luminance_f64;
use crate::render::sampling::Stream;
use crate::render::scene::Scene;

pub use crate::spec::PhotonStore;

impl PhotonStore {
    /// Whether the global map keeps a photon of this path class.
    pub(super) fn keeps(self, class: PathClass) -> bool {
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

/// Photons of one tracing run, in photon-index order, with their flux unit (W).
pub struct TraceOutput {
    pub photons: Vec<Photon>,
    pub emitted: u64,
    pub unit: f32,
}

/// Photons per parallel work item at paths of at most [`CHUNK_DEPTH`] bounces: large enough
/// to amortise scheduling, small enough for prompt cancellation and smooth progress.
const CHUNK: u64 = 4096;

/// Longer paths (`max_depth` goes to 1024; a closed box of mirrors keeps them all) take
/// proportionally fewer photons a chunk, so that a chunk's work, and with it the delay of a
/// cancel, stays bounded (up to this depth, the default, chunks are of [`CHUNK`]). The maps
/// do not depend on the chunking: a chunk's photons come back in path order.
const CHUNK_DEPTH: u64 = 32;

/// Photons per work item for paths of up to `max_depth` bounces.
fn chunk_len(max_depth: u32) -> u64 {
    (CHUNK * CHUNK_DEPTH / (max_depth as u64).max(CHUNK_DEPTH)).max(1)
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
    let setup = PathSetup {
        scene,
        picker: &picker,
        target,
        max_depth,
        aim,
        seed,
        stream,
    };
    let chunk = chunk_len(max_depth);
    let chunks = emitted.div_ceil(chunk);
    let parts: Vec<Vec<Photon>> = (0..chunks)
        .into_par_iter()
        .map(|c| {
            control.check()?;
            let (start, end) = (c * chunk, ((c + 1) * chunk).min(emitted));
            let out = trace_chunk(&setup, start..end);
            tracker.advance(end - start);
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

/// The photons of paths `range`, in path order, each path's in the order stored. Four
/// paths are in flight at a time and their next hits found together
/// ([`Scene::closest4`]); a lane whose path ends takes up the next one. Against one path
/// at a time: see docs/performance-history.md ("Fifth session").
fn trace_chunk(setup: &PathSetup, range: std::ops::Range<u64>) -> Vec<Photon> {
    let paths = (range.end - range.start) as usize;
    // Room for two stored photons per path, so that a chunk of the global map seldom
    // regrows; maps of at most one a path (blind caustic paths mostly store none) grow on
    // demand.
    let room = if setup.target.one_per_path() {
        0
    } else {
        2 * paths
    };
    let mut out = Vec::with_capacity(room);
    let mut slots: Vec<u32> = Vec::with_capacity(room);
    let mut lanes: [PhotonPath; 4] = std::array::from_fn(|_| PhotonPath::idle());
    let mut live = [false; 4];
    let mut next = range.start;
    loop {
        for (lane, live) in lanes.iter_mut().zip(&mut live) {
            while !*live && next < range.end {
                let slot = (next - range.start) as u32;
                *live = PhotonPath::emit(setup, next, slot, lane);
                next += 1;
            }
        }
        if live == [false; 4] {
            break;
        }
        let rays = std::array::from_fn(|l| live[l].then_some(&lanes[l].ray));
        let hits = setup.scene.closest4(rays);
        for l in 0..4 {
            if !live[l] {
                continue;
            }
            let p = &mut lanes[l];
            let stored = out.len();
            live[l] = p.interact(setup, hits[l], &mut out);
            if out.len() > stored {
                slots.push(p.slot);
            }
        }
    }
    in_path_order(out, &slots, paths)
}

/// `photons`, stored by interleaved paths, stably reordered by their paths' `slots` (a
/// counting sort): the order one path at a time would have stored them in.
fn in_path_order(photons: Vec<Photon>, slots: &[u32], paths: usize) -> Vec<Photon> {
    if slots.is_sorted() {
        return photons;
    }
    let mut at = vec![0u32; paths + 1];
    for &s in slots {
        at[s as usize + 1] += 1;
    }
    for i in 1..=paths {
        at[i] += at[i - 1];
    }
    let mut sorted = photons.clone();
    for (p, &s) in photons.iter().zip(slots) {
        sorted[at[s as usize] as usize] = *p;
        at[s as usize] += 1;
    }
    sorted
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

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;
    use crate::render::math::Rgb;

    #[test]
    fn chunks_shrink_with_the_path_length() {
        assert_eq!(chunk_len(1), CHUNK);
        assert_eq!(chunk_len(32), CHUNK);
        assert_eq!(chunk_len(64), CHUNK / 2);
        assert_eq!(chunk_len(1024), 128);
        assert_eq!(chunk_len(u32::MAX), 1);
    }

    /// Photons stored by interleaved paths come back grouped by path, in path order, each
    /// path's own in the order it stored them.
    #[test]
    fn photons_return_to_path_order() {
        let photon = |x: f32| {
            Photon::new(
                Vec3A::new(x, 0.0, 0.0),
                Rgb::ONE,
                Vec3A::Z,
                PathClass::Indirect,
                false,
            )
        };
        let xs = [10.0, 0.0, 11.0, 20.0, 1.0, 12.0];
        let slots = [1, 0, 1, 2, 0, 1];
        let photons: Vec<Photon> = xs.iter().map(|&x| photon(x)).collect();
        let sorted = in_path_order(photons, &slots, 4);
        let got: Vec<f32> = sorted.iter().map(|p| p.pos[0]).collect();
        assert_eq!(got, [0.0, 1.0, 10.0, 11.0, 12.0, 20.0]);
    }
}

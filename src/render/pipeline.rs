//! A render, phase by phase: analyse the job, trace and build photon maps, precompute
//! irradiance, run the camera pass. The maps are a separate value so that a caller (the
//! server's cache) can reuse them for another camera, resolution, k or spp.

use std::ops::ControlFlow;
use std::time::Instant;

use crate::render::accuracy::{SizeMismatch, compare};
use crate::render::camera::Camera;
use crate::render::control::{Cancelled, Control};
use crate::render::effects::analyse;
use crate::render::film::{Image, render_film};
use crate::render::integrator::{IntegratorKind, RenderParams, Shader};
use crate::render::photon::{
    CausticLookup, Density, IrradianceCache, Photon, PhotonMap, PhotonMaps, build_photon_maps,
};
use crate::render::ppm::{PpmError, PpmOptions, Stop, render_ppm};
use crate::render::scene::Scene;
use crate::render::stats::{ParamsEcho, PhotonCounts, Radius, RenderStats, Times};

/// k-NN searches in the global map reach at most this fraction of the scene's extent.
const GLOBAL_SEARCH_FRACTION: f32 = 0.1;

/// k-NN searches in the caustic map reach at most this fraction of the scene's extent:
/// caustics are sharp, and a tight bound keeps queries where no caustic falls cheap.
const CAUSTIC_SEARCH_FRACTION: f32 = 0.01;

/// An image and the statistics of the render that made it.
pub struct RenderOutput {
    pub image: Image,
    pub stats: RenderStats,
}

impl RenderOutput {
    /// Record the image's errors against `reference`, if any, in `stats.error` (a ppm render
    /// records them itself, after every pass).
    pub fn measure(&mut self, reference: Option<&Image>) -> Result<(), SizeMismatch> {
        if let Some(r) = reference {
            self.stats.error = Some(compare(&self.image, r)?);
        }
        Ok(())
    }
}

/// Trace the photon maps a job needs (none for `raytrace`).
pub fn trace_maps(
    scene: &Scene,
    params: &RenderParams,
    control: &Control,
) -> Result<PhotonMaps, Cancelled> {
    let analysis = analyse(scene, params);
    build_photon_maps(scene, &analysis.photon_params, control)
}

/// A full render: photon maps, then the camera pass; for `ppm`, `params.iterations`
/// progressive passes (see `render::ppm` for checkpoints, references and other stops).
pub fn render(
    scene: &Scene,
    params: &RenderParams,
    control: &Control,
) -> Result<RenderOutput, Cancelled> {
    if params.integrator == IntegratorKind::Ppm {
        let opts = PpmOptions::new(Stop::after(params.iterations), String::new());
        return match render_ppm(scene, params, opts, control, &mut |_| {
            ControlFlow::Continue(())
        }) {
            Ok(out) => Ok(out.output),
            Err(PpmError::Cancelled(c)) => Err(c),
            Err(PpmError::Input(m)) => unreachable!("no state or reference to refuse: {m}"),
        };
    }
    let maps = trace_maps(scene, params, control)?;
    render_with_maps(scene, &maps, params, control)
}

/// The camera pass over existing photon maps (traced for the same scene and for photon
/// parameters equal to those `params` implies).
pub fn render_with_maps(
    scene: &Scene,
    maps: &PhotonMaps,
    params: &RenderParams,
    control: &Control,
) -> Result<RenderOutput, Cancelled> {
    let analysis = analyse(scene, params);
    assert_eq!(
        maps.params, analysis.photon_params,
        "photon maps traced for other photon parameters than these render parameters imply"
    );
    let plan = analysis.plan;
    let extent = scene.extent().max(f32::MIN_POSITIVE);
    let global_max = GLOBAL_SEARCH_FRACTION * extent;
    let caustic_max = CAUSTIC_SEARCH_FRACTION * extent;

    let t_pre = Instant::now();
    let classes = plan.global_classes();
    // The two maps' lookup structures are independent: built side by side.
    let (cache, caustic) = rayon::join(
        || match &maps.global {
            Some(g) if !classes.is_empty() => {
                IrradianceCache::build(g, params.k, global_max * global_max, classes, control)
                    .map(Some)
            }
            _ => Ok(None),
        },
        || {
            maps.caustic
                .as_ref()
                .map(|m| Density::Knn(CausticLookup::new(m, params.k, caustic_max)))
        },
    );
    let cache = cache?;
    let precompute = t_pre.elapsed().as_secs_f64();

    let camera = scene.camera.clone().with_resolution(
        params.width.unwrap_or(scene.camera.width),
        params.height.unwrap_or(scene.camera.height),
    );
    let shader = Shader {
        scene,
        plan,
        caustic,
        global: cache.as_ref().map(Density::Cached),
        gather_rays: params.gather_rays,
        max_depth: params.max_depth,
        control: *control,
    };
    let t_render = Instant::now();
    let film = render_film(&shader, &camera, params.spp, params.seed, control)?;
    let render = t_render.elapsed().as_secs_f64();

    let stats = collect_stats(&StatsInput {
        scene,
        maps,
        params,
        camera: &camera,
        cache: cache.as_ref(),
        radii: (caustic_max, global_max),
        times: (precompute, render),
        nonfinite_samples: film.nonfinite_samples,
        effects: analysis.effects,
    });
    Ok(RenderOutput {
        image: film.image,
        stats,
    })
}

/// What `collect_stats` reports on.
pub(crate) struct StatsInput<'a> {
    pub scene: &'a Scene,
    pub maps: &'a PhotonMaps,
    pub params: &'a RenderParams,
    pub camera: &'a Camera,
    pub cache: Option<&'a IrradianceCache>,
    /// Caustic and global search bounds.
    pub radii: (f32, f32),
    /// Precompute and camera-pass seconds.
    pub times: (f64, f64),
    pub nonfinite_samples: u64,
    pub effects: std::collections::BTreeMap<String, crate::render::stats::Effect>,
}

/// STATS.json for one render.
pub(crate) fn collect_stats(s: &StatsInput) -> RenderStats {
    let (maps, params) = (s.maps, s.params);
    let count = |m: &Option<PhotonMap>| m.as_ref().map_or((0, 0), |m| (m.emitted, m.len() as u64));
    let (global_emitted, global_stored) = count(&maps.global);
    let (caustic_emitted, caustic_stored) = count(&maps.caustic);
    let stored = global_stored + caustic_stored;
    let (precompute, render) = s.times;
    let (caustic_max, global_max) = s.radii;
    RenderStats {
        scene: s.scene.name.clone(),
        params: ParamsEcho {
            integrator: params.integrator.name().into(),
            photons: params.photons,
            caustic_photons: params.caustic_photons,
            k: params.k,
            photon_store: params.photon_store.name().into(),
            gather_rays: params.gather_rays,
            spp: params.spp,
            max_depth: params.max_depth,
            seed: params.seed,
            width: s.camera.width,
            height: s.camera.height,
        },
        times: Times {
            photon_trace: maps.trace_seconds,
            build_maps: maps.build_seconds,
            precompute,
            render,
            total: maps.trace_seconds + maps.build_seconds + precompute + render,
        },
        photons: PhotonCounts {
            global_emitted,
            global_stored,
            caustic_emitted,
            caustic_stored,
            map_bytes: maps.bytes() as u64,
            bytes_per_photon: if stored > 0 {
                maps.bytes() as f64 / stored as f64
            } else {
                std::mem::size_of::<Photon>() as f64
            },
            irradiance_points: s.cache.map_or(0, |c| c.len() as u64),
        },
        effects: s.effects.clone(),
        radius: Radius {
            caustic_max: if maps.caustic.is_some() {
                caustic_max as f64
            } else {
                0.0
            },
            global_rms: s.cache.map_or(0.0, |c| c.mean_r2.sqrt()),
            global_max: if s.cache.is_some() {
                global_max as f64
            } else {
                0.0
            },
        },
        nonfinite_samples: s.nonfinite_samples,
        threads: rayon::current_num_threads(),
        ppm: None,
        error: None,
    }
}

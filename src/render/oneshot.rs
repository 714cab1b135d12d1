//! A one-shot render over photon maps (`photon`, and `raytrace` over none): precompute
//! irradiance, then the camera pass (Jensen 2001, chapter 9; Christensen 1999). The maps
//! are an input, so that a caller (the server's cache) can reuse them for another camera,
//! resolution, k or spp.

use std::time::Instant;

use crate::render::control::{Cancelled, Control};
use crate::render::effects::{Analysis, analyse};
use crate::render::film::render_film_rows;
use crate::render::integrator::{Samples, SeenLights, Shader};
use crate::render::outcome::RenderOutput;
use crate::render::photon::{
    CausticLookup, Density, IrradianceCache, PhotonMaps, build_photon_maps,
};
use crate::render::scene::Scene;
use crate::render::stats::{StatsInput, collect};
use crate::spec::RenderSpec;

/// k-NN searches in the global map reach at most this fraction of the scene's extent.
const GLOBAL_SEARCH_FRACTION: f32 = 0.1;

/// k-NN searches in the caustic map reach at most this fraction of the scene's extent:
/// caustics are sharp, and a tight bound keeps queries where no caustic falls cheap.
const CAUSTIC_SEARCH_FRACTION: f32 = 0.01;

/// Trace the photon maps a job needs (none for `raytrace`).
pub fn trace_maps(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
) -> Result<PhotonMaps, Cancelled> {
    build_photon_maps(scene, &analyse(scene, spec).photon_params, control)
}

/// The camera pass over photon maps traced for this scene and `analysis.photon_params`,
/// over image rows `rows` (all of them, but for a farm's tile).
pub(crate) fn render_with_maps(
    scene: &Scene,
    maps: &PhotonMaps,
    spec: &RenderSpec,
    analysis: &Analysis,
    rows: std::ops::Range<u32>,
    control: &Control,
) -> Result<RenderOutput, Cancelled> {
    assert_eq!(
        maps.params, analysis.photon_params,
        "photon maps traced for other photon parameters than the spec implies"
    );
    let plan = analysis.plan;
    // k and the final gather of photon mapping; an integrator without photons reads no map.
    let (k, gather_rays) = spec
        .photon_mapping()
        .map_or((1, 0), |p| (p.k, p.gather_rays));
    let extent = scene.extent().max(f32::MIN_POSITIVE);
    let global_max = GLOBAL_SEARCH_FRACTION * extent;
    let caustic_max = CAUSTIC_SEARCH_FRACTION * extent;

    let t_pre = Instant::now();
    let classes = plan.global_classes();
    // The two maps' lookup structures are independent: built side by side.
    let (cache, caustic) = rayon::join(
        || match &maps.global {
            Some(g) if !classes.is_empty() => {
                IrradianceCache::build(g, k, global_max * global_max, classes, control).map(Some)
            }
            _ => Ok(None),
        },
        || {
            maps.caustic
                .as_ref()
                .map(|m| Density::Knn(CausticLookup::new(m, k, caustic_max)))
        },
    );
    let cache = cache?;
    let precompute = t_pre.elapsed().as_secs_f64();

    let (width, height) = spec.resolution((scene.camera.width, scene.camera.height));
    let camera = scene.camera.clone().with_resolution(width, height);
    let seen = SeenLights::of(scene, &camera);
    let shader = Shader {
        scene,
        plan,
        caustic,
        global: cache.as_ref().map(Density::Cached),
        gather_rays,
        max_depth: spec.max_depth,
        control: *control,
        samples: Samples {
            seed: spec.seed,
            first: 0,
        },
        record_gathers: false,
        seen: &seen,
    };
    let t_render = Instant::now();
    let film = render_film_rows(&shader, &camera, rows, spec.spp(), control)?;
    let render = t_render.elapsed().as_secs_f64();

    let stats = collect(&StatsInput {
        scene,
        maps,
        spec,
        camera: &camera,
        cache: cache.as_ref(),
        radii: (caustic_max, global_max),
        times: (precompute, render),
        nonfinite_samples: film.nonfinite_samples,
        effects: analysis.effects.clone(),
    });
    Ok(RenderOutput {
        image: film.image,
        stats,
    })
}

//! What a render reports about itself (STATS.json, and the server's job stats).
//! A boundary type: it is serialized, the engine's own types are not.

use serde::{Deserialize, Serialize};

use crate::render::accuracy::ImageError;

use crate::render::camera::Camera;
use crate::render::photon::{IrradianceCache, Photon, PhotonMap, PhotonMaps};
use crate::render::scene::Scene;
use crate::spec::{RenderSpec, SpecForm};

#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct Times {
    pub photon_trace: f64,
    pub build_maps: f64,
    /// Irradiance precomputation at photons (Christensen 1999), and the grids the camera
    /// pass's lookups read; part of the camera pass's cost.
    pub precompute: f64,
    pub render: f64,
    /// `auto`'s choice of integrator (its pilot renders, `render::run`): counted in `total`
    /// and in a time limit; 0 for an explicit integrator. A render resumed from a state that
    /// kept the choice reports the seconds it took when it was made.
    pub choose: f64,
    pub total: f64,
}

#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct PhotonCounts {
    pub global_emitted: u64,
    pub global_stored: u64,
    pub caustic_emitted: u64,
    pub caustic_stored: u64,
    /// Bytes held by the photon maps (photons and kd-tree).
    pub map_bytes: u64,
    /// map_bytes per stored photon.
    pub bytes_per_photon: f64,
    /// Points with precomputed irradiance used by this render.
    pub irradiance_points: u64,
    /// Photons this render emitted itself: 0 when its maps were traced before (a cache).
    pub traced_by_this_job: u64,
}

/// One effect of light transport, whether this job simulates it, and why.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct Effect {
    pub simulated: bool,
    pub how: String,
    pub reason: String,
}

/// What `auto` chose for a progressive render, kept in its state (`PpmState::choice`) so
/// that the render resumes with it instead of running the pilot again: a server job resumes
/// after every turn it gives way to another user, and a pilot costs a few passes.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct AutoChoice {
    /// The chosen spec's form (`SpecForm`), as JSON: a state written by another version
    /// whose form does not parse still loads, and resumes with a pilot. A resumed render
    /// takes the integrator's parameters from it, its stop conditions from its own spec.
    pub params: serde_json::Value,
    /// `effects.integrator`: which, and why.
    pub effect: Effect,
    /// The seconds the choice took (`times.choose`): a resumed render reports them again,
    /// and its time limit counts them once, with the passes before and after the pause.
    #[serde(default)]
    pub seconds: f64,
}

#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct Radius {
    /// Bound of the caustic map's k-NN search (scene units).
    pub caustic_max: f64,
    /// Root-mean-square k-NN radius of the global map's irradiance estimates.
    pub global_rms: f64,
    /// Bound of the global map's k-NN search.
    pub global_max: f64,
}

#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct RenderStats {
    pub scene: Option<String>,
    /// The spec rendered, every field its integrator reads given, at the output's size.
    pub params: SpecForm,
    pub times: Times,
    pub photons: PhotonCounts,
    pub effects: std::collections::BTreeMap<String, Effect>,
    pub radius: Radius,
    pub nonfinite_samples: u64,
    pub threads: usize,
    /// Progressive photon mapping: parameters, radii and errors per pass.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ppm: Option<PpmReport>,
    /// The final image against the reference, when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ImageError>,
}

/// Why a progressive render stopped.
#[derive(Serialize, Clone, Copy, Debug, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    Iterations,
    TimeLimit,
    TargetError,
    /// The caller's per-pass callback asked to stop (to yield, or to save and exit).
    Paused,
}

/// The `ppm` section of STATS.json.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct PpmReport {
    pub alpha: f64,
    pub passes: u32,
    /// Initial radius of the global and caustic maps' estimates (scene units).
    pub radius_initial_global: f64,
    pub radius_initial_caustic: f64,
    /// "radius": given; "auto": ppm's median k-NN distance (k = `params.k`) in the first
    /// pass, or vcm's pilot radius (`render/bidir/radius.rs`).
    pub radius_source: &'static str,
    pub stopped_by: StopReason,
    /// Every pass up to 256, then thinned to about 256 per doubling of the pass count.
    pub history: Vec<PassStats>,
}

/// What one pass did.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct PassStats {
    /// 1-based.
    pub pass: u32,
    /// Radii of this pass's estimates (scene units; 0 where the map was not built).
    pub radius_global: f64,
    pub radius_caustic: f64,
    pub photon_trace: f64,
    pub build_maps: f64,
    pub render: f64,
    /// Seconds spent in all passes up to and including this one.
    pub elapsed: f64,
    pub global_stored: u64,
    pub caustic_stored: u64,
    /// The pass average so far against the reference, when there is one.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<ImageError>,
}

/// Seconds summed over all passes, by phase.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTotals {
    pub photon_trace: f64,
    pub build_maps: f64,
    pub render: f64,
}

/// What [`collect`] reports on.
pub(crate) struct StatsInput<'a> {
    pub scene: &'a Scene,
    pub maps: &'a PhotonMaps,
    pub spec: &'a RenderSpec,
    pub camera: &'a Camera,
    pub cache: Option<&'a IrradianceCache>,
    /// Caustic and global search bounds.
    pub radii: (f32, f32),
    /// Precompute and camera-pass seconds.
    pub times: (f64, f64),
    pub nonfinite_samples: u64,
    pub effects: std::collections::BTreeMap<String, Effect>,
}

/// STATS.json for one render (a progressive render adds its `ppm` section and sums).
pub(crate) fn collect(s: &StatsInput) -> RenderStats {
    let maps = s.maps;
    let count = |m: &Option<PhotonMap>| m.as_ref().map_or((0, 0), |m| (m.emitted, m.len() as u64));
    let (global_emitted, global_stored) = count(&maps.global);
    let (caustic_emitted, caustic_stored) = count(&maps.caustic);
    let stored = global_stored + caustic_stored;
    let (precompute, render) = s.times;
    let (caustic_max, global_max) = s.radii;
    let mut params = SpecForm::of(s.spec);
    (params.width, params.height) = (Some(s.camera.width), Some(s.camera.height));
    RenderStats {
        scene: s.scene.name.clone(),
        params,
        times: Times {
            photon_trace: maps.trace_seconds,
            build_maps: maps.build_seconds,
            precompute,
            render,
            choose: 0.0,
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
            traced_by_this_job: global_emitted + caustic_emitted,
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

impl RenderStats {
    /// The render read maps traced before (a cache): it traced nothing itself.
    pub(crate) fn maps_were_reused(&mut self) {
        let t = &mut self.times;
        (t.photon_trace, t.build_maps) = (0.0, 0.0);
        t.total = t.precompute + t.render;
        self.photons.traced_by_this_job = 0;
    }
}

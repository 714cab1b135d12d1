//! What a render reports about itself (STATS.json, and the server's job stats).
//! A boundary type: it is serialized, the engine's own types are not.

use serde::Serialize;

#[derive(Serialize, Clone, Debug, Default, PartialEq)]
pub struct Times {
    pub photon_trace: f64,
    pub build_maps: f64,
    /// Irradiance precomputation at photons (Christensen 1999), and the grids the camera
    /// pass's lookups read; part of the camera pass's cost.
    pub precompute: f64,
    pub render: f64,
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
}

/// One effect of light transport, whether this job simulates it, and why.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct Effect {
    pub simulated: bool,
    pub how: String,
    pub reason: String,
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
pub struct ParamsEcho {
    pub integrator: String,
    pub photons: u64,
    pub caustic_photons: u64,
    pub k: usize,
    pub photon_store: String,
    pub gather_rays: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub seed: u64,
    pub width: u32,
    pub height: u32,
}

#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct RenderStats {
    pub scene: Option<String>,
    pub params: ParamsEcho,
    pub times: Times,
    pub photons: PhotonCounts,
    pub effects: std::collections::BTreeMap<String, Effect>,
    pub radius: Radius,
    pub nonfinite_samples: u64,
    pub threads: usize,
    /// Progressive photon mapping: parameters, radii and errors per pass.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ppm: Option<crate::render::ppm::PpmReport>,
    /// The final image against the reference, when one was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<crate::render::accuracy::ImageError>,
}

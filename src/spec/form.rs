//! The spec as flat, optional fields: one struct for the REST API's `params` (serde, and its
//! OpenAPI schema through utoipa), the CLI's flags (clap) and the stored form of a job's
//! spec. The doc comments below are the CLI's help and the schema's descriptions; the
//! defaults are added to both from `RenderSpec`'s (describe.rs).

use serde::{Deserialize, Serialize};

use super::PhotonStore;

/// An integrator's name.
#[derive(
    Serialize, Deserialize, clap::ValueEnum, utoipa::ToSchema, Clone, Copy, Debug, PartialEq, Eq,
)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorName {
    Raytrace,
    Photon,
    Ppm,
    Pt,
    Lt,
    Bdpt,
    Vcm,
    Auto,
}

impl IntegratorName {
    /// The integrator of a spec that names none (issue 20: the scene's choice).
    pub const DEFAULT: IntegratorName = IntegratorName::Auto;

    pub fn as_str(self) -> &'static str {
        match self {
            IntegratorName::Raytrace => "raytrace",
            IntegratorName::Photon => "photon",
            IntegratorName::Ppm => "ppm",
            IntegratorName::Pt => "pt",
            IntegratorName::Lt => "lt",
            IntegratorName::Bdpt => "bdpt",
            IntegratorName::Vcm => "vcm",
            IntegratorName::Auto => "auto",
        }
    }
}

/// Which photons the global map keeps.
#[derive(
    Serialize, Deserialize, clap::ValueEnum, utoipa::ToSchema, Clone, Copy, Debug, PartialEq, Eq,
)]
#[serde(rename_all = "snake_case")]
pub enum StoreName {
    /// No first-hit photons: direct light by shadow rays.
    Indirect,
    /// Every non-specular hit: direct light from the maps too.
    All,
    /// Only first-hit photons: the photon-map view of direct light.
    #[value(name = "direct_only")]
    DirectOnly,
}

impl From<StoreName> for PhotonStore {
    fn from(s: StoreName) -> PhotonStore {
        match s {
            StoreName::Indirect => PhotonStore::Indirect,
            StoreName::All => PhotonStore::All,
            StoreName::DirectOnly => PhotonStore::DirectOnly,
        }
    }
}

impl From<PhotonStore> for StoreName {
    fn from(s: PhotonStore) -> StoreName {
        match s {
            PhotonStore::Indirect => StoreName::Indirect,
            PhotonStore::All => StoreName::All,
            PhotonStore::DirectOnly => StoreName::DirectOnly,
        }
    }
}

impl PhotonStore {
    pub fn name(self) -> &'static str {
        match StoreName::from(self) {
            StoreName::Indirect => "indirect",
            StoreName::All => "all",
            StoreName::DirectOnly => "direct_only",
        }
    }
}

/// `params.effects`: each effect on (true, the default) or off.
#[derive(Serialize, Deserialize, utoipa::ToSchema, Debug, Default, Clone, Copy, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EffectsForm {
    /// Direct light at what the camera sees.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub direct_light: Option<bool>,
    /// Caustics (light -> specular+ -> diffuse); off, no caustic photon is traced.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub caustics: Option<bool>,
    /// Light from other diffuse surfaces (global map, final gathering).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffuse_interreflection: Option<bool>,
}

/// A render's parameters: every field optional, defaults by integrator (the REST API's
/// `params`, the CLI's flags).
#[derive(
    Serialize, Deserialize, clap::Args, utoipa::ToSchema, Debug, Default, Clone, PartialEq,
)]
#[serde(deny_unknown_fields)]
#[schema(as = Params)]
pub struct SpecForm {
    /// Version of this form (1); a stored spec says which it is.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub version: Option<u32>,
    /// The integrator.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long, value_enum)]
    pub integrator: Option<IntegratorName>,
    /// Image width (default: the scene camera's).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene camera's).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub height: Option<u32>,
    /// Photons emitted for the global map (ppm: per pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub photons: Option<u64>,
    /// Photons emitted for the caustic map (ppm: per pass), aimed at the mirror and glass
    /// objects.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub caustic_photons: Option<u64>,
    /// Photons per radiance estimate (ppm: sets the automatic initial radius).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub k: Option<usize>,
    /// Which photons the global map keeps.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long, value_enum)]
    pub photon_store: Option<StoreName>,
    /// Final-gather rays per camera sample; 0 reads the global map.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub gather_rays: Option<u32>,
    /// Shadow rays to each area light per camera sample where the camera sees a
    /// non-specular surface (a point light takes one).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub shadow_rays: Option<u32>,
    /// Jittered samples per pixel (progressive integrators: per pass).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub spp: Option<u32>,
    /// Longest path, in surface interactions.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// The random seed: the same seed gives the same image bytes, whatever the thread count.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub seed: Option<u64>,
    /// Emit caustic photons toward the mirror and glass objects (true) or in every direction
    /// (false, the seed's way).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub aim_caustics: Option<bool>,
    /// Progressive integrators: passes (with --time-limit alone: as many as fit).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub iterations: Option<u32>,
    /// ppm, vcm: radius reduction per pass, r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub alpha: Option<f64>,
    /// ppm, vcm: initial radius in scene units (default: ppm, the median k-NN distance among
    /// the first pass's photons; vcm, the median 4-NN distance to a pilot iteration's light
    /// vertices around them and around the points the camera sees, the smaller).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub radius: Option<f32>,
    /// ppm with final gathering: share each pass's gathers at the points the camera sees
    /// between neighbouring pixels on one surface, within this many global-map radii over
    /// pass^0.35 (0: none; auto's gathering: 5).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub gather_smoothing: Option<f32>,
    /// Progressive integrators: no pass starts that would end after this many seconds of
    /// passes.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Progressive integrators: stop once relmse against the reference is at most this.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub target_error: Option<f64>,
    /// Effects to switch off, e.g. `{"caustics": false}`; unnamed ones stay on.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub effects: Option<EffectsForm>,
    /// PNG exposure in stops.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub exposure: Option<f32>,
    /// A finished job (same width and height) whose EXR this job is measured against.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(skip)]
    pub reference_job: Option<i64>,
    /// Emit caustic photons in every direction (as the seed did) instead of aiming them at
    /// the mirror and glass objects.
    #[serde(skip)]
    #[arg(long)]
    pub blind_caustics: bool,
    /// Leave out direct light at what the camera sees (to see the other effects alone).
    #[serde(skip)]
    #[arg(long)]
    pub no_direct_light: bool,
    /// Leave out caustics: no caustic photons are traced.
    #[serde(skip)]
    #[arg(long)]
    pub no_caustics: bool,
    /// Leave out light from other diffuse surfaces (no global-map reads, no gathering).
    #[serde(skip)]
    #[arg(long, alias = "no-indirect")]
    pub no_diffuse_interreflection: bool,
}

//! The render spec: everything a render job asks for besides its scene, as one typed value
//! that every front end converts into and the engine takes as given (`render::run`).
//!
//! - [`RenderSpec`]: what is common to every render (resolution, seed, depth, effects) and
//!   the [`Integrator`] with its own settings. A closed set: the variants are named here, and
//!   the engine's entry point (`render/run/`) is the one place that dispatches on them.
//! - [`SpecForm`] (`form.rs`): the same spec as flat, optional fields: the REST API's
//!   `params` object (serde, with its OpenAPI schema), the CLI's flags (clap), and the form
//!   a job's spec is stored in. One conversion each way ([`SpecForm::to_spec`],
//!   [`SpecForm::of`]); defaults, names, ranges and validation exist once, in this module
//!   (`rules.rs`), and every error names its field, which each front end spells its own way
//!   (`params.k`, `--k`).
//! - `describe.rs`: the defaults as text for the CLI's help and the API's schema, derived
//!   from the defaults here, never written twice.
//!
//! **Architecture invariant:** this module depends on nothing else in the crate: the engine,
//! the server and the CLI depend on it.

mod convert;
mod defaults;
mod describe;
mod form;
mod rules;

pub use describe::{default_text, defaults_by_integrator};
pub use form::{EffectsForm, IntegratorName, SpecForm, StoreName};
pub use rules::{MAX_IMAGE_SIDE, MAX_ITERATIONS, MAX_PHOTONS, RULES, Range, Rule, Scope};

/// The integrator references are rendered with when none is given (`sweep`): progressive
/// photon mapping converges to the scene's true image however hard its caustics are.
pub const REFERENCE_INTEGRATOR: IntegratorName = IntegratorName::Ppm;

/// The version of the spec's stored and REST form; a form with another version is refused.
pub const SPEC_VERSION: u32 = 1;

/// Everything a render asks for besides its scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSpec {
    /// Resolution override (else the scene camera's).
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub seed: u64,
    /// Longest path (surface interactions) for photons and camera rays.
    pub max_depth: u32,
    /// Effects the job switched off (to see their contribution, or to save time).
    pub effects: EffectSwitches,
    pub integrator: Integrator,
}

/// The closed set of integrators, each with the settings only it reads.
#[derive(Clone, Debug, PartialEq)]
pub enum Integrator {
    /// Direct light by shadow rays and perfect specular chains; no photon maps.
    Raytrace(Raytrace),
    /// Jensen-style photon mapping with global and caustic maps (Jensen 1996, 2001).
    Photon(PhotonMapping),
    /// Progressive photon mapping (Knaus and Zwicker 2011): independent passes of photon
    /// mapping with fixed-radius estimates whose radius shrinks, averaged.
    Ppm(Progressive),
    /// Unidirectional path tracing with next-event estimation, the two combined by multiple
    /// importance sampling (Veach 1997): the camera-side techniques of `vcm` alone.
    Pt(Passes),
    /// Light tracing: light subpaths connected to the camera (and the camera's specular
    /// chains to the lights they see): the camera-connection technique of `vcm` alone.
    Lt(Passes),
    /// Bidirectional path tracing (Veach 1997): every vertex connection of `vcm`, without
    /// merging.
    Bdpt(Passes),
    /// Vertex connection and merging (Georgiev, Krivanek, Davidovic and Slusallek 2012):
    /// bidirectional path tracing and photon density estimation between the two subpaths,
    /// combined by multiple importance sampling, with a merge radius that shrinks as ppm's.
    Vcm(Merging),
    /// The integrator the scene calls for, chosen when the render starts (`render/run`):
    /// these passes of `pt`, `bdpt` or `vcm`.
    Auto(Passes),
}

/// The passes of a bidirectional integrator: each pass traces one light subpath per camera
/// sample (Georgiev et al. 2012), so a pass is a sample per pixel and the image converges
/// as passes add up.
#[derive(Clone, Debug, PartialEq)]
pub struct Passes {
    /// Camera samples per pixel in a pass (each with a light subpath of its own).
    pub spp: u32,
    pub stop: Stop,
}

/// `vcm`'s passes and its merge radius: r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1), as ppm's.
#[derive(Clone, Debug, PartialEq)]
pub struct Merging {
    pub passes: Passes,
    pub alpha: f64,
    /// Initial merge radius (scene units); `None`: from the 4-NN distances to a pilot
    /// iteration's light vertices, around them and around the points the camera sees
    /// (`render/bidir/radius.rs`).
    pub radius: Option<f32>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Raytrace {
    /// Jittered samples per pixel (box filter).
    pub spp: u32,
}

/// The settings of one photon-mapping render (of one pass, for `ppm`).
#[derive(Clone, Debug, PartialEq)]
pub struct PhotonMapping {
    /// Photons emitted for the global map.
    pub photons: u64,
    /// Photons emitted for the caustic map.
    pub caustic_photons: u64,
    /// Photons per radiance estimate (`ppm`: sets the automatic initial radius).
    pub k: usize,
    pub photon_store: PhotonStore,
    /// Final-gather rays per camera sample at the first diffuse point; 0 reads the global map.
    pub gather_rays: u32,
    /// Shadow rays to each area light per camera sample at the first non-specular point (a
    /// point light takes one; read where direct light is by shadow rays, `photon_store`
    /// indirect): soft shadows and a large light's extent are most of what is
    /// left of a pixel's noise once gathers are shared (`auto`'s gathering takes 2).
    pub shadow_rays: u32,
    /// Jittered samples per pixel (box filter).
    pub spp: u32,
    /// Aim caustic photons at the specular objects; false emits them in every direction, as
    /// the seed did (its timing tables are measured that way).
    pub aim_caustics: bool,
}

/// Progressive photon mapping: per-pass settings, the radius schedule and when to stop.
#[derive(Clone, Debug, PartialEq)]
pub struct Progressive {
    pub pass: PhotonMapping,
    /// Radius reduction, r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1), in (0, 1).
    pub alpha: f64,
    /// Initial radius of both maps' estimates (scene units); `None`: from the k-NN radius of
    /// the first pass's photons.
    pub radius: Option<f32>,
    /// With final gathering: each pass shares the gathers at the points the camera sees
    /// between neighbouring pixels on one surface, within this many global-map radii over
    /// pass^0.35 (`render/integrator/smooth.rs`); 0 shares none.
    pub gather_smoothing: f32,
    pub stop: Stop,
}

impl Progressive {
    /// Whether its passes smooth their final gathers (`render/integrator/smooth.rs`): with
    /// final gathering and a positive `gather_smoothing`.
    pub fn smooths_gathers(&self) -> bool {
        self.gather_smoothing > 0.0 && self.pass.gather_rays > 0
    }
}

/// When a progressive render stops: the first condition met wins; at least one pass runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Stop {
    /// Passes in all (counting those of a resumed state); `None`: as many as the time limit
    /// allows (a time limit is then set), at most [`MAX_ITERATIONS`].
    pub iterations: Option<u32>,
    /// Seconds of passes in all: no pass starts that would, at the mean pass time so far,
    /// end after this.
    pub time_limit: Option<f64>,
    /// Stop once `relmse` against the reference is at most this.
    pub target_error: Option<f64>,
}

impl Stop {
    /// Stop after `iterations` passes, and on nothing else.
    pub fn after(iterations: u32) -> Stop {
        Stop {
            iterations: Some(iterations),
            time_limit: None,
            target_error: None,
        }
    }

    /// Whether passes run until the time limit is spent: a time limit given without a pass
    /// count.
    pub fn until_time(&self) -> bool {
        self.iterations.is_none() && self.time_limit.is_some()
    }

    /// The time limit when it is the only stop condition (no pass count, no target error):
    /// a budget to spend, which `auto` sizes its render to.
    pub fn time_limit_alone(&self) -> Option<f64> {
        match (self.iterations, self.target_error) {
            (None, None) => self.time_limit,
            _ => None,
        }
    }

    /// The most passes the render may run: its pass count, else the engine's most.
    pub fn pass_limit(&self) -> u32 {
        self.iterations.unwrap_or(MAX_ITERATIONS)
    }
}

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

/// Effects a job may switch off, each for what the camera sees: at the first non-specular
/// point of a camera path and at points seen through a glossy reflection. Light that
/// reaches those points by other paths (direct light at a final-gather hit is indirect
/// light at the point gathering) stays with the effect it belongs to there.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct EffectSwitches {
    pub direct_light: bool,
    /// Caustics from the caustic map; off, no caustic photon is traced.
    pub caustics: bool,
    /// Light from other diffuse surfaces (global map, final gathering).
    pub diffuse_interreflection: bool,
}

impl EffectSwitches {
    pub const ALL_ON: EffectSwitches = EffectSwitches {
        direct_light: true,
        caustics: true,
        diffuse_interreflection: true,
    };
}

/// A spec's field out of range or not for its integrator: the field as the REST form names
/// it (snake_case; the CLI's flag is `--` and the name with dashes) and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {message}")]
pub struct SpecError {
    pub field: &'static str,
    pub message: String,
}

impl SpecError {
    pub fn new(field: &'static str, message: impl Into<String>) -> SpecError {
        SpecError {
            field,
            message: message.into(),
        }
    }

    /// The error in the REST API's words: the JSON path under `prefix` (e.g. `params`).
    pub fn json_path(&self, prefix: &str) -> String {
        format!("{prefix}.{}", self.field)
    }

    /// The error in the CLI's words: `--flag-name message`.
    pub fn as_flag(&self) -> String {
        format!("--{} {}", self.field.replace('_', "-"), self.message)
    }
}

impl RenderSpec {
    /// The spec of an integrator with every other setting at its default.
    pub fn new(integrator: Integrator) -> RenderSpec {
        RenderSpec {
            width: None,
            height: None,
            seed: 1,
            max_depth: 32,
            effects: EffectSwitches::ALL_ON,
            integrator,
        }
    }

    /// `photon` with its defaults: what a job that names nothing renders.
    pub fn photon(p: PhotonMapping) -> RenderSpec {
        RenderSpec::new(Integrator::Photon(p))
    }

    /// `ppm` with its defaults but for these.
    pub fn ppm(p: Progressive) -> RenderSpec {
        RenderSpec::new(Integrator::Ppm(p))
    }

    pub fn raytrace(spp: u32) -> RenderSpec {
        RenderSpec::new(Integrator::Raytrace(Raytrace { spp }))
    }

    /// The photon-mapping settings a render (or each of its passes) uses; None for
    /// integrators that trace no photons.
    pub fn photon_mapping(&self) -> Option<&PhotonMapping> {
        match &self.integrator {
            Integrator::Raytrace(_)
            | Integrator::Pt(_)
            | Integrator::Lt(_)
            | Integrator::Bdpt(_)
            | Integrator::Vcm(_)
            | Integrator::Auto(_) => None,
            Integrator::Photon(p) => Some(p),
            Integrator::Ppm(p) => Some(&p.pass),
        }
    }

    /// The passes of a bidirectional integrator.
    pub fn passes(&self) -> Option<&Passes> {
        match &self.integrator {
            Integrator::Raytrace(_) | Integrator::Photon(_) | Integrator::Ppm(_) => None,
            Integrator::Pt(p) | Integrator::Lt(p) | Integrator::Bdpt(p) | Integrator::Auto(p) => {
                Some(p)
            }
            Integrator::Vcm(m) => Some(&m.passes),
        }
    }

    /// The radius schedule of an integrator that merges (density estimation with a radius
    /// that shrinks over passes): alpha and the initial radius.
    pub fn merge_radius(&self) -> Option<(f64, Option<f32>)> {
        match &self.integrator {
            Integrator::Ppm(p) => Some((p.alpha, p.radius)),
            Integrator::Vcm(m) => Some((m.alpha, m.radius)),
            _ => None,
        }
    }

    /// Samples per pixel (per pass, for a progressive integrator).
    pub fn spp(&self) -> u32 {
        match (&self.integrator, self.passes()) {
            (_, Some(p)) => p.spp,
            (Integrator::Raytrace(r), _) => r.spp,
            (Integrator::Photon(p), _) => p.spp,
            (Integrator::Ppm(p), _) => p.pass.spp,
            _ => unreachable!("the bidirectional integrators have passes"),
        }
    }

    /// The stop conditions of a progressive integrator (None: one pass, one image).
    pub fn stop(&self) -> Option<&Stop> {
        match &self.integrator {
            Integrator::Raytrace(_) | Integrator::Photon(_) => None,
            Integrator::Ppm(p) => Some(&p.stop),
            _ => self.passes().map(|p| &p.stop),
        }
    }

    pub fn is_progressive(&self) -> bool {
        self.stop().is_some()
    }

    /// A one-shot render (photon maps, if any, and one camera pass): its image can be
    /// split into bands of rows (`render::Rows`, a farm's tiles).
    pub fn is_one_shot(&self) -> bool {
        matches!(
            self.integrator,
            Integrator::Raytrace(_) | Integrator::Photon(_)
        )
    }

    /// The number of passes, when it is known before the render starts: a progressive
    /// integrator (not `auto`, which may choose a one-shot render) that stops by its pass
    /// count alone. Such a render can be split into pieces of passes ahead of time (a
    /// farm's tasks).
    pub fn passes_known_ahead(&self) -> Option<u32> {
        if matches!(self.integrator, Integrator::Auto(_)) {
            return None;
        }
        let stop = self.stop()?;
        stop.iterations
            .filter(|_| stop.time_limit.is_none() && stop.target_error.is_none())
    }

    /// The output size: the override, else the scene camera's (`camera`).
    pub fn resolution(&self, camera: (u32, u32)) -> (u32, u32) {
        (
            self.width.unwrap_or(camera.0),
            self.height.unwrap_or(camera.1),
        )
    }

    /// Check every field's range (a spec made in code rather than from a form).
    pub fn validate(&self) -> Result<(), SpecError> {
        let has_reference = true; // the reference is the caller's: checked where it is given
        SpecForm::of(self).to_spec(has_reference).map(|_| ())
    }
}

/// The names of the integrators whose default spec has `what`, for messages about what
/// only they take.
pub fn names_where(what: impl Fn(&RenderSpec) -> bool) -> String {
    let names: Vec<&str> = Integrator::ALL
        .iter()
        .filter(|i| what(&RenderSpec::new((*i).clone())))
        .map(|i| i.name().as_str())
        .collect();
    names.join(", ")
}

/// The names of the progressive integrators.
pub fn progressive_names() -> String {
    names_where(RenderSpec::is_progressive)
}

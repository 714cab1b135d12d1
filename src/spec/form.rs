//! The spec as flat, optional fields: one struct for the REST API's `params` (serde, and its
//! OpenAPI schema through utoipa), the CLI's flags (clap) and the stored form of a job's
//! spec. The doc comments below are the CLI's help and the schema's descriptions; the
//! defaults are added to both from `RenderSpec`'s (describe.rs).

use serde::{Deserialize, Serialize};

use super::rules::{RULES, Scope, check_numbers, rule_of};
use super::{
    EffectSwitches, Integrator, PhotonMapping, PhotonStore, Progressive, Raytrace, RenderSpec,
    SPEC_VERSION, SpecError, Stop,
};

/// An integrator's name.
#[derive(
    Serialize, Deserialize, clap::ValueEnum, utoipa::ToSchema, Clone, Copy, Debug, PartialEq, Eq,
)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorName {
    Raytrace,
    Photon,
    Ppm,
}

impl IntegratorName {
    pub fn as_str(self) -> &'static str {
        match self {
            IntegratorName::Raytrace => "raytrace",
            IntegratorName::Photon => "photon",
            IntegratorName::Ppm => "ppm",
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
    /// Jittered samples per pixel (ppm: per pass).
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
    /// ppm: passes.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub iterations: Option<u32>,
    /// ppm: radius reduction per pass, r_{i+1}^2 = r_i^2 (i + alpha) / (i + 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub alpha: Option<f64>,
    /// ppm: initial radius in scene units (default: the median k-NN distance among the
    /// first pass's photons).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub radius: Option<f32>,
    /// ppm: no pass starts that would end after this many seconds of passes.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// ppm: stop once relmse against the reference is at most this.
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

impl SpecForm {
    /// The CLI's switches folded into the fields the REST form has (`aim_caustics`,
    /// `effects`), so that what follows reads one set of fields.
    fn normalized(&self) -> SpecForm {
        let mut f = self.clone();
        if f.blind_caustics {
            f.aim_caustics = Some(false);
        }
        let mut e = f.effects.unwrap_or_default();
        for (off, on) in [
            (f.no_direct_light, &mut e.direct_light),
            (f.no_caustics, &mut e.caustics),
            (f.no_diffuse_interreflection, &mut e.diffuse_interreflection),
        ] {
            if off {
                *on = Some(false);
            }
        }
        if e != EffectsForm::default() {
            f.effects = Some(e);
        }
        (f.blind_caustics, f.no_direct_light, f.no_caustics) = (false, false, false);
        f.no_diffuse_interreflection = false;
        f
    }

    /// The names of the fields this form gives (as the REST form spells them).
    fn given(&self) -> Vec<String> {
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(m)) => m.keys().cloned().collect(),
            _ => Vec::new(),
        }
    }

    /// The typed spec: defaults of the named integrator for what is not given, every range
    /// checked, and no setting of another integrator's (the default integrator's settings
    /// are accepted by every integrator, so a client can switch integrators without clearing
    /// them; those an integrator does not read are ignored). `has_reference`: whether a
    /// reference image comes with the render (`target_error` needs one).
    pub fn to_spec(&self, has_reference: bool) -> Result<RenderSpec, SpecError> {
        let f = self.normalized();
        if let Some(v) = f.version
            && v != SPEC_VERSION
        {
            return Err(SpecError::new(
                "version",
                format!("this server reads version {SPEC_VERSION}, got {v}"),
            ));
        }
        check_numbers(&f)?;
        let name = f.integrator.unwrap_or(IntegratorName::Photon);
        let mut spec = RenderSpec::new(Integrator::default_of(name));
        for field in f.given() {
            if let Some(rule) = rule_of(&field)
                && rule.scope == Scope::Progressive
                && !spec.is_progressive()
            {
                return Err(SpecError::new(
                    rule.field,
                    format!("is only for integrator {}", super::progressive_names()),
                ));
            }
        }
        if f.target_error.is_some() && !has_reference {
            return Err(SpecError::new(
                "target_error",
                "needs a reference to measure the error against",
            ));
        }
        spec.width = f.width;
        spec.height = f.height;
        spec.seed = f.seed.unwrap_or(spec.seed);
        spec.max_depth = f.max_depth.unwrap_or(spec.max_depth);
        spec.effects = f.effects.unwrap_or_default().switches();
        match &mut spec.integrator {
            Integrator::Raytrace(r) => r.spp = f.spp.unwrap_or(r.spp),
            Integrator::Photon(p) => f.fill_photon_mapping(p),
            Integrator::Ppm(p) => {
                f.fill_photon_mapping(&mut p.pass);
                p.alpha = f.alpha.unwrap_or(p.alpha);
                p.radius = f.radius;
                p.stop.iterations = f.iterations.unwrap_or(p.stop.iterations);
                p.stop.time_limit = f.time_limit;
                p.stop.target_error = f.target_error;
            }
        }
        Ok(spec)
    }

    fn fill_photon_mapping(&self, p: &mut PhotonMapping) {
        p.photons = self.photons.unwrap_or(p.photons);
        p.caustic_photons = self.caustic_photons.unwrap_or(p.caustic_photons);
        p.k = self.k.unwrap_or(p.k);
        p.photon_store = self.photon_store.map_or(p.photon_store, PhotonStore::from);
        p.gather_rays = self.gather_rays.unwrap_or(p.gather_rays);
        p.spp = self.spp.unwrap_or(p.spp);
        p.aim_caustics = self.aim_caustics.unwrap_or(p.aim_caustics);
    }

    /// The form of a spec with every field its integrator reads given: the stored form of a
    /// job's spec, and what STATS.json echoes.
    pub fn of(spec: &RenderSpec) -> SpecForm {
        let e = spec.effects;
        let mut f = SpecForm {
            version: Some(SPEC_VERSION),
            integrator: Some(spec.integrator.name()),
            width: spec.width,
            height: spec.height,
            seed: Some(spec.seed),
            max_depth: Some(spec.max_depth),
            effects: Some(EffectsForm {
                direct_light: Some(e.direct_light),
                caustics: Some(e.caustics),
                diffuse_interreflection: Some(e.diffuse_interreflection),
            }),
            ..SpecForm::default()
        };
        match &spec.integrator {
            Integrator::Raytrace(Raytrace { spp }) => f.spp = Some(*spp),
            Integrator::Photon(p) => f.set_photon_mapping(p),
            Integrator::Ppm(Progressive {
                pass,
                alpha,
                radius,
                stop,
            }) => {
                f.set_photon_mapping(pass);
                let Stop {
                    iterations,
                    time_limit,
                    target_error,
                } = stop;
                (f.alpha, f.radius, f.iterations) = (Some(*alpha), *radius, Some(*iterations));
                (f.time_limit, f.target_error) = (*time_limit, *target_error);
            }
        }
        f
    }

    fn set_photon_mapping(&mut self, p: &PhotonMapping) {
        self.photons = Some(p.photons);
        self.caustic_photons = Some(p.caustic_photons);
        self.k = Some(p.k);
        self.photon_store = Some(p.photon_store.into());
        self.gather_rays = Some(p.gather_rays);
        self.spp = Some(p.spp);
        self.aim_caustics = Some(p.aim_caustics);
    }

    /// This form without the fields its integrator does not read (a sweep's shared flags
    /// over a grid that mixes integrators).
    pub fn only_fields_of_its_integrator(&self) -> SpecForm {
        let name = self.integrator.unwrap_or(IntegratorName::Photon);
        if RenderSpec::new(Integrator::default_of(name)).is_progressive() {
            return self.clone();
        }
        let mut value = serde_json::to_value(self).expect("a form serializes");
        if let Some(map) = value.as_object_mut() {
            for r in RULES.iter().filter(|r| r.scope == Scope::Progressive) {
                map.remove(r.field);
            }
        }
        let mut f: SpecForm = serde_json::from_value(value).expect("a form reads back");
        // The CLI's switches are not in the serialized form: keep them.
        (f.blind_caustics, f.no_direct_light) = (self.blind_caustics, self.no_direct_light);
        (f.no_caustics, f.no_diffuse_interreflection) =
            (self.no_caustics, self.no_diffuse_interreflection);
        f
    }
}

impl EffectsForm {
    fn switches(&self) -> EffectSwitches {
        EffectSwitches {
            direct_light: self.direct_light.unwrap_or(true),
            caustics: self.caustics.unwrap_or(true),
            diffuse_interreflection: self.diffuse_interreflection.unwrap_or(true),
        }
    }
}

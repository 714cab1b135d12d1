//! The one conversion each way between the spec and its form: [`SpecForm::to_spec`] (the
//! integrator's defaults for what is not given, every range checked, no setting of another
//! integrator's) and [`SpecForm::of`] (every field the spec's integrator reads).

use super::form::{EffectsForm, IntegratorName, SpecForm};
use super::rules::{Scope, check_numbers, scope_of, scopes};
use super::{
    EffectSwitches, Integrator, MAX_ITERATIONS, Passes, PhotonMapping, PhotonStore, Progressive,
    Raytrace, RenderSpec, SPEC_VERSION, SpecError, Stop,
};

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
    /// checked, and no setting of another integrator's (settings of every integrator's
    /// scope, `Scope::Any`, are accepted by each and ignored by those that do not read
    /// them). `has_reference`: whether a
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
        let name = f.integrator.unwrap_or(IntegratorName::DEFAULT);
        let mut spec = RenderSpec::new(Integrator::default_of(name));
        for field in f.given() {
            if let Some((field, scope)) = scope_of(&field)
                && !scope.read_by(&spec)
            {
                let names = super::names_where(|s| scope.read_by(s));
                let default = match f.integrator {
                    None => format!(" (the default integrator is {})", name.as_str()),
                    Some(_) => String::new(),
                };
                return Err(SpecError::new(
                    field,
                    format!("is only for integrator {names}{default}"),
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
                f.fill_radius(&mut p.alpha, &mut p.radius);
                f.fill_stop(&mut p.stop);
                p.gather_smoothing = f.gather_smoothing.unwrap_or(p.gather_smoothing);
            }
            Integrator::Pt(p) | Integrator::Lt(p) | Integrator::Bdpt(p) | Integrator::Auto(p) => {
                f.fill_passes(p)
            }
            Integrator::Vcm(m) => {
                f.fill_passes(&mut m.passes);
                f.fill_radius(&mut m.alpha, &mut m.radius);
            }
        }
        Ok(spec)
    }

    /// A progressive render's stop: a time limit alone runs passes until it is spent.
    fn fill_stop(&self, stop: &mut Stop) {
        stop.iterations = match (self.iterations, self.time_limit) {
            // The engine's most passes with a time limit: until the time is spent (as
            // jobs stored before 2026-12-04 recorded it).
            (Some(MAX_ITERATIONS), Some(_)) => None,
            (Some(n), _) => Some(n),
            (None, Some(_)) => None,
            (None, None) => stop.iterations,
        };
        stop.time_limit = self.time_limit;
        stop.target_error = self.target_error;
    }

    fn fill_radius(&self, alpha: &mut f64, radius: &mut Option<f32>) {
        *alpha = self.alpha.unwrap_or(*alpha);
        *radius = self.radius;
    }

    fn fill_passes(&self, p: &mut Passes) {
        p.spp = self.spp.unwrap_or(p.spp);
        self.fill_stop(&mut p.stop);
    }

    fn fill_photon_mapping(&self, p: &mut PhotonMapping) {
        p.photons = self.photons.unwrap_or(p.photons);
        p.caustic_photons = self.caustic_photons.unwrap_or(p.caustic_photons);
        p.k = self.k.unwrap_or(p.k);
        p.photon_store = self.photon_store.map_or(p.photon_store, PhotonStore::from);
        p.gather_rays = self.gather_rays.unwrap_or(p.gather_rays);
        p.shadow_rays = self.shadow_rays.unwrap_or(p.shadow_rays);
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
                gather_smoothing,
                stop,
            }) => {
                f.set_photon_mapping(pass);
                f.set_stop(stop);
                (f.alpha, f.radius) = (Some(*alpha), *radius);
                f.gather_smoothing = Some(*gather_smoothing);
            }
            Integrator::Pt(p) | Integrator::Lt(p) | Integrator::Bdpt(p) | Integrator::Auto(p) => {
                f.set_passes(p)
            }
            Integrator::Vcm(m) => {
                f.set_passes(&m.passes);
                (f.alpha, f.radius) = (Some(m.alpha), m.radius);
            }
        }
        f
    }

    fn set_stop(&mut self, stop: &Stop) {
        self.iterations = stop.iterations;
        (self.time_limit, self.target_error) = (stop.time_limit, stop.target_error);
    }

    fn set_passes(&mut self, p: &Passes) {
        self.spp = Some(p.spp);
        self.set_stop(&p.stop);
    }

    fn set_photon_mapping(&mut self, p: &PhotonMapping) {
        self.photons = Some(p.photons);
        self.caustic_photons = Some(p.caustic_photons);
        self.k = Some(p.k);
        self.photon_store = Some(p.photon_store.into());
        self.gather_rays = Some(p.gather_rays);
        self.shadow_rays = Some(p.shadow_rays);
        self.spp = Some(p.spp);
        self.aim_caustics = Some(p.aim_caustics);
    }

    /// This form without the fields its integrator does not read (a sweep's shared flags
    /// over a grid that mixes integrators).
    pub fn only_fields_of_its_integrator(&self) -> SpecForm {
        let name = self.integrator.unwrap_or(IntegratorName::DEFAULT);
        let spec = RenderSpec::new(Integrator::default_of(name));
        let mut value = serde_json::to_value(self).expect("a form serializes");
        if let Some(map) = value.as_object_mut() {
            for (field, _) in scopes().filter(|(_, scope)| !scope.read_by(&spec)) {
                map.remove(field);
            }
        }
        let mut f: SpecForm = serde_json::from_value(value).expect("a form reads back");
        // The CLI's switches are not in the serialized form: keep those it reads.
        let aims = Scope::PhotonMaps.read_by(&spec);
        f.blind_caustics = self.blind_caustics && aims;
        f.no_direct_light = self.no_direct_light;
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

//! Each integrator's defaults: the one place they are written (the CLI's help, the API's
//! schema, the gallery and the README read them from here).

use super::{
    Integrator, IntegratorName, Merging, Passes, PhotonMapping, PhotonStore, Progressive, Raytrace,
    Stop,
};

impl PhotonMapping {
    /// `photon`'s defaults.
    pub const PHOTON: PhotonMapping = PhotonMapping {
        photons: 200_000,
        caustic_photons: 200_000,
        k: 50,
        photon_store: PhotonStore::Indirect,
        gather_rays: 8,
        shadow_rays: 1,
        spp: 4,
        aim_caustics: true,
    };

    /// A `ppm` pass's defaults: one sample per pixel and no final gathering (the passes
    /// average both out), fewer photons a pass, and a small k, which only sets the initial
    /// radius: a small k starts with little blur and the passes average its noise away
    /// (k = 10 against 50: block_err 0.014 against 0.020 after 64 passes on the caustic
    /// scene; docs/accuracy.md).
    pub const PPM_PASS: PhotonMapping = PhotonMapping {
        photons: 100_000,
        caustic_photons: 100_000,
        k: 10,
        gather_rays: 0,
        spp: 1,
        ..PhotonMapping::PHOTON
    };
}

impl Raytrace {
    pub const DEFAULT: Raytrace = Raytrace { spp: 4 };
}

impl Progressive {
    pub const DEFAULT: Progressive = Progressive {
        pass: PhotonMapping::PPM_PASS,
        alpha: 0.7,
        radius: None,
        gather_smoothing: 0.0,
        stop: Stop {
            iterations: Some(16),
            time_limit: None,
            target_error: None,
        },
    };
}

impl Passes {
    /// A bidirectional integrator's defaults: one sample per pixel a pass, 16 passes.
    pub const DEFAULT: Passes = Passes {
        spp: 1,
        stop: Stop {
            iterations: Some(16),
            time_limit: None,
            target_error: None,
        },
    };
}

impl Merging {
    /// `vcm`'s defaults: alpha 0.75 as in Georgiev et al.'s SmallVCM, the radius from the
    /// first pass.
    pub const DEFAULT: Merging = Merging {
        passes: Passes::DEFAULT,
        alpha: 0.75,
        radius: None,
    };
}

impl Integrator {
    /// Every integrator with its defaults, the default one (`auto`, [`IntegratorName::DEFAULT`])
    /// first.
    pub const ALL: [Integrator; 8] = [
        Integrator::Auto(Passes::DEFAULT),
        Integrator::Photon(PhotonMapping::PHOTON),
        Integrator::Raytrace(Raytrace::DEFAULT),
        Integrator::Ppm(Progressive::DEFAULT),
        Integrator::Pt(Passes::DEFAULT),
        Integrator::Lt(Passes::DEFAULT),
        Integrator::Bdpt(Passes::DEFAULT),
        Integrator::Vcm(Merging::DEFAULT),
    ];

    /// The name the REST form and the CLI use.
    pub fn name(&self) -> IntegratorName {
        match self {
            Integrator::Raytrace(_) => IntegratorName::Raytrace,
            Integrator::Photon(_) => IntegratorName::Photon,
            Integrator::Ppm(_) => IntegratorName::Ppm,
            Integrator::Pt(_) => IntegratorName::Pt,
            Integrator::Lt(_) => IntegratorName::Lt,
            Integrator::Bdpt(_) => IntegratorName::Bdpt,
            Integrator::Vcm(_) => IntegratorName::Vcm,
            Integrator::Auto(_) => IntegratorName::Auto,
        }
    }

    /// The integrator of this name, with its defaults.
    pub fn default_of(name: IntegratorName) -> Integrator {
        Integrator::ALL
            .into_iter()
            .find(|i| i.name() == name)
            .expect("every name has an integrator")
    }
}

//! Deciding, before any photon is traced, which light-transport effects a job simulates,
//! and so which photon maps it needs: no map the integrator does not read, no caustic map
//! in a scene without specular surfaces, no photons from lights that emit nothing or are
//! shut inside a closed object the camera is outside of, nothing the job switched off.

use std::collections::BTreeMap;

use crate::render::integrator::Plan;
use crate::render::light::Light;
use crate::render::material::Material;
use crate::render::math::max_component;
use crate::render::photon::PhotonParams;
use crate::render::scene::Scene;
use crate::render::stats::Effect;
use crate::spec::{EffectSwitches, PhotonMapping, PhotonStore, RenderSpec};

/// What a job will simulate and the photon maps that takes.
pub struct Analysis {
    pub plan: Plan,
    pub photon_params: PhotonParams,
    pub effects: BTreeMap<String, Effect>,
}

fn effect(simulated: bool, how: &str, reason: &str) -> Effect {
    Effect {
        simulated,
        how: how.to_string(),
        reason: reason.to_string(),
    }
}

fn switched_off(name: &str) -> Effect {
    effect(
        false,
        "none",
        &format!("switched off by the job (effects.{name}: false)"),
    )
}

/// Whether a light contributes, and why not when it does not.
fn light_effect(scene: &Scene, i: usize, light: &Light, how: &str) -> Effect {
    if !(max_component(light.power()) > 0.0) {
        return effect(false, "none", "the light emits no power");
    }
    if let Some(o) = scene.shut_in[i] {
        return effect(
            false,
            "none",
            &format!(
                "shut inside objects[{o}], a closed opaque object the camera is outside of: \
                 it emits no photons"
            ),
        );
    }
    effect(
        true,
        how,
        "it emits power and its light can reach the camera's view",
    )
}

pub fn analyse(scene: &Scene, spec: &RenderSpec) -> Analysis {
    let plan = Plan::new(spec);
    let dark_lights: Vec<u32> = (0..scene.lights.len() as u32)
        .filter(|&i| scene.shut_in[i as usize].is_some())
        .collect();
    let f = Facts::gather(scene, spec, &plan, &dark_lights);

    let mut e = BTreeMap::new();
    e.insert("direct_light".into(), direct_light(&f));
    e.insert("shadows".into(), shadows(&f));
    e.insert("specular_reflection".into(), specular_reflection(&f));
    e.insert("refraction".into(), refraction(&f));
    e.insert("caustics".into(), caustics(&f));
    e.insert(
        "diffuse_interreflection".into(),
        diffuse_interreflection(&f),
    );
    e.insert("glossy".into(), glossy(&f));
    insert_lights(scene, &f, &mut e);

    let photon_params = photon_params(&f, spec, dark_lights);
    Analysis {
        plan,
        photon_params,
        effects: e,
    }
}

/// What the scene holds and what the job asks for: all each effect's verdict reads.
struct Facts<'a> {
    glass: bool,
    phong: bool,
    /// Mirror or glass surfaces.
    specular: bool,
    /// Some light emits power and is not shut in.
    lit: bool,
    switches: EffectSwitches,
    mapping: Option<&'a PhotonMapping>,
    /// The integrator traces photons.
    photon: bool,
    direct_only: bool,
    shadow_rays: bool,
    glossy_rays: bool,
    /// The integrator reads a caustic map and the scene gives it something to hold.
    caustic_map: bool,
    /// The integrator reads a global map and the scene gives it something to hold.
    global_map: bool,
}

impl<'a> Facts<'a> {
    fn gather(scene: &Scene, spec: &'a RenderSpec, plan: &Plan, dark_lights: &[u32]) -> Facts<'a> {
        let has = |f: fn(&Material) -> bool| scene.materials.iter().any(f);
        let mirror = has(|m| matches!(m, Material::Mirror { .. }));
        let glass = has(|m| matches!(m, Material::Dielectric { .. }));
        let phong = has(|m| matches!(m, Material::Phong { .. }));
        let diffuse = has(|m| m.diffuse_reflectance() != crate::render::math::Rgb::ZERO);
        let specular = mirror || glass;
        let lit = scene
            .lights
            .iter()
            .enumerate()
            .any(|(i, l)| max_component(l.power()) > 0.0 && !dark_lights.contains(&(i as u32)));
        let mapping = spec.photon_mapping();
        Facts {
            glass,
            phong,
            specular,
            lit,
            switches: spec.effects,
            mapping,
            photon: mapping.is_some(),
            direct_only: mapping.is_some_and(|p| p.photon_store == PhotonStore::DirectOnly),
            shadow_rays: plan.primary.shadow_rays,
            glossy_rays: plan.primary.glossy_rays,
            caustic_map: plan.needs_caustic_map() && specular && lit && diffuse,
            global_map: !plan.global_classes().is_empty() && lit && diffuse,
        }
    }
}

fn direct_light(f: &Facts) -> Effect {
    if !f.switches.direct_light {
        switched_off("direct_light")
    } else if !f.lit {
        effect(false, "none", "no light emits any power")
    } else if f.shadow_rays {
        effect(
            true,
            "shadow rays",
            "exact for point lights, low noise for area lights",
        )
    } else {
        effect(
            true,
            "global photon map",
            "--photon-store all/direct_only reads direct light from photons",
        )
    }
}

fn shadows(f: &Facts) -> Effect {
    effect(
        f.lit && f.switches.direct_light,
        if f.shadow_rays {
            "shadow rays"
        } else {
            "photon density"
        },
        "follows direct light",
    )
}

fn specular_reflection(f: &Facts) -> Effect {
    if f.specular {
        effect(true, "ray traced", "the scene has mirror or glass surfaces")
    } else {
        effect(false, "none", "no mirror or glass in the scene")
    }
}

fn refraction(f: &Facts) -> Effect {
    if f.glass {
        effect(true, "ray traced, exact Fresnel", "the scene has glass")
    } else {
        effect(false, "none", "no glass in the scene")
    }
}

/// Why an effect read from a photon map is not simulated, when the job decides it: an
/// integrator that traces no photons, the effect `name` switched off (`on` false), or only
/// first-hit photons stored. None: the job asks for the effect.
fn left_out_by_the_job(f: &Facts, on: bool, name: &str) -> Option<Effect> {
    if !f.photon {
        Some(effect(
            false,
            "none",
            "the raytrace integrator traces no photons",
        ))
    } else if !on {
        Some(switched_off(name))
    } else if f.direct_only {
        Some(effect(
            false,
            "none",
            "--photon-store direct_only shows first-hit photons only",
        ))
    } else {
        None
    }
}

fn caustics(f: &Facts) -> Effect {
    if f.caustic_map {
        effect(
            true,
            "caustic photon map, photons aimed at the specular objects' bounds",
            "specular surfaces can focus light onto diffuse ones",
        )
    } else if let Some(off) = left_out_by_the_job(f, f.switches.caustics, "caustics") {
        off
    } else if !f.specular {
        effect(
            false,
            "none",
            "no specular surface: no caustic photons traced",
        )
    } else {
        effect(false, "none", "no lit diffuse surface to receive caustics")
    }
}

fn diffuse_interreflection(f: &Facts) -> Effect {
    if f.global_map && !f.direct_only {
        let how = if f.mapping.is_some_and(|p| p.gather_rays > 0) {
            "final gathering over the global photon map"
        } else {
            "global photon map"
        };
        effect(
            true,
            how,
            "light bounces between diffuse surfaces (colour bleeding)",
        )
    } else if let Some(off) = left_out_by_the_job(
        f,
        f.switches.diffuse_interreflection,
        "diffuse_interreflection",
    ) {
        off
    } else {
        effect(false, "none", "no lit diffuse surface")
    }
}

fn glossy(f: &Facts) -> Effect {
    if f.phong {
        let how = if f.glossy_rays {
            "shadow rays and a ray traced Phong lobe"
        } else {
            "shadow rays only"
        };
        effect(true, how, "the scene has Phong surfaces")
    } else {
        effect(false, "none", "no Phong surface in the scene")
    }
}

/// One entry a light, `lights[i]`: whether it contributes and by what.
fn insert_lights(scene: &Scene, f: &Facts, e: &mut BTreeMap<String, Effect>) {
    let how = match (f.photon && (f.global_map || f.caustic_map), f.shadow_rays) {
        (true, true) => "photons and shadow rays",
        (true, false) => "photons",
        (false, _) => "shadow rays",
    };
    for (i, light) in scene.lights.iter().enumerate() {
        e.insert(format!("lights[{i}]"), light_effect(scene, i, light, how));
    }
}

/// The photons to trace: none for a map the integrator does not read or the scene cannot fill.
fn photon_params(f: &Facts, spec: &RenderSpec, dark_lights: Vec<u32>) -> PhotonParams {
    let mapping = f.mapping;
    let (global_map, caustic_map) = (f.global_map && f.photon, f.caustic_map && f.photon);
    PhotonParams {
        global_photons: mapping.filter(|_| global_map).map_or(0, |p| p.photons),
        caustic_photons: mapping
            .filter(|_| caustic_map)
            .map_or(0, |p| p.caustic_photons),
        store: mapping.map_or(PhotonStore::Indirect, |p| p.photon_store),
        max_depth: spec.max_depth,
        seed: spec.seed,
        aim_caustics: mapping.is_none_or(|p| p.aim_caustics),
        dark_lights,
    }
}

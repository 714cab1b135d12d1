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
use crate::spec::{PhotonStore, RenderSpec};

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
    let has = |f: fn(&Material) -> bool| scene.materials.iter().any(f);
    let mirror = has(|m| matches!(m, Material::Mirror { .. }));
    let glass = has(|m| matches!(m, Material::Dielectric { .. }));
    let phong = has(|m| matches!(m, Material::Phong { .. }));
    let diffuse = has(|m| m.diffuse_reflectance() != crate::render::math::Rgb::ZERO);
    let specular = mirror || glass;
    let dark_lights: Vec<u32> = (0..scene.lights.len() as u32)
        .filter(|&i| scene.shut_in[i as usize].is_some())
        .collect();
    let lit = scene
        .lights
        .iter()
        .enumerate()
        .any(|(i, l)| max_component(l.power()) > 0.0 && !dark_lights.contains(&(i as u32)));
    let switches = spec.effects;
    let mapping = spec.photon_mapping();
    let photon = mapping.is_some();
    let direct_only = mapping.is_some_and(|p| p.photon_store == PhotonStore::DirectOnly);

    let caustic_map = plan.needs_caustic_map() && specular && lit && diffuse;
    let global_map = !plan.global_classes().is_empty() && lit && diffuse;

    let mut e = BTreeMap::new();
    let shadow_rays = plan.primary.shadow_rays;
    e.insert(
        "direct_light".into(),
        if !switches.direct_light {
            switched_off("direct_light")
        } else if !lit {
            effect(false, "none", "no light emits any power")
        } else if shadow_rays {
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
        },
    );
    e.insert(
        "shadows".into(),
        effect(
            lit && switches.direct_light,
            if shadow_rays {
                "shadow rays"
            } else {
                "photon density"
            },
            "follows direct light",
        ),
    );
    e.insert(
        "specular_reflection".into(),
        if specular {
            effect(true, "ray traced", "the scene has mirror or glass surfaces")
        } else {
            effect(false, "none", "no mirror or glass in the scene")
        },
    );
    e.insert(
        "refraction".into(),
        if glass {
            effect(true, "ray traced, exact Fresnel", "the scene has glass")
        } else {
            effect(false, "none", "no glass in the scene")
        },
    );
    e.insert(
        "caustics".into(),
        if caustic_map {
            effect(
                true,
                "caustic photon map, photons aimed at the specular objects' bounds",
                "specular surfaces can focus light onto diffuse ones",
            )
        } else if !photon {
            effect(false, "none", "the raytrace integrator traces no photons")
        } else if !switches.caustics {
            switched_off("caustics")
        } else if direct_only {
            effect(
                false,
                "none",
                "--photon-store direct_only shows first-hit photons only",
            )
        } else if !specular {
            effect(
                false,
                "none",
                "no specular surface: no caustic photons traced",
            )
        } else {
            effect(false, "none", "no lit diffuse surface to receive caustics")
        },
    );
    e.insert(
        "diffuse_interreflection".into(),
        if global_map && !direct_only {
            let how = if mapping.is_some_and(|p| p.gather_rays > 0) {
                "final gathering over the global photon map"
            } else {
                "global photon map"
            };
            effect(
                true,
                how,
                "light bounces between diffuse surfaces (colour bleeding)",
            )
        } else if !photon {
            effect(false, "none", "the raytrace integrator traces no photons")
        } else if !switches.diffuse_interreflection {
            switched_off("diffuse_interreflection")
        } else if direct_only {
            effect(
                false,
                "none",
                "--photon-store direct_only shows first-hit photons only",
            )
        } else {
            effect(false, "none", "no lit diffuse surface")
        },
    );
    e.insert(
        "glossy".into(),
        if phong {
            let how = if plan.primary.glossy_rays {
                "shadow rays and a ray traced Phong lobe"
            } else {
                "shadow rays only"
            };
            effect(true, how, "the scene has Phong surfaces")
        } else {
            effect(false, "none", "no Phong surface in the scene")
        },
    );

    let how = match (photon && (global_map || caustic_map), shadow_rays) {
        (true, true) => "photons and shadow rays",
        (true, false) => "photons",
        (false, _) => "shadow rays",
    };
    for (i, light) in scene.lights.iter().enumerate() {
        e.insert(format!("lights[{i}]"), light_effect(scene, i, light, how));
    }

    let (global_map, caustic_map) = (global_map && photon, caustic_map && photon);
    let photon_params = PhotonParams {
        global_photons: mapping.filter(|_| global_map).map_or(0, |p| p.photons),
        caustic_photons: mapping
            .filter(|_| caustic_map)
            .map_or(0, |p| p.caustic_photons),
        store: mapping.map_or(PhotonStore::Indirect, |p| p.photon_store),
        max_depth: spec.max_depth,
        seed: spec.seed,
        aim_caustics: mapping.is_none_or(|p| p.aim_caustics),
        dark_lights,
    };
    Analysis {
        plan,
        photon_params,
        effects: e,
    }
}

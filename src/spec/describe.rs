//! The spec's defaults as the front ends show them: every integrator's full form (the API's
//! schema carries it, and the gallery fills its fields from it) and one line of text a
//! field (the CLI's help, the README's tables, which a test compares with it). Derived from
//! the defaults in mod.rs, never written a second time.

use serde_json::{Map, Value};

use super::{Integrator, RenderSpec, SpecForm};

/// Every integrator's form at its defaults (no resolution: the scene's), by name, the
/// default integrator first.
pub fn defaults_by_integrator() -> Vec<(&'static str, Map<String, Value>)> {
    Integrator::ALL
        .into_iter()
        .map(|i| {
            let name = i.name().as_str();
            let mut form = match serde_json::to_value(SpecForm::of(&RenderSpec::new(i))) {
                Ok(Value::Object(m)) => m,
                _ => Map::new(),
            };
            form.remove("version");
            (name, form)
        })
        .collect()
}

/// A field's default as text: `200000 (ppm: 100000)` where integrators differ, `32` where
/// they agree (or only one reads it); None where no integrator has one (the resolution: the
/// scene camera's) or the field is not a single value.
pub fn default_text(field: &str) -> Option<String> {
    let defaults = defaults_by_integrator();
    if field == "integrator" {
        return defaults.first().map(|(name, _)| name.to_string());
    }
    let values: Vec<(&str, String)> = defaults
        .iter()
        .filter_map(|(name, form)| Some((*name, scalar(form.get(field)?)?)))
        .collect();
    let (_, first) = values.first()?;
    // The other values, each with the integrators that have it, in the integrators' order.
    let mut others: Vec<(String, Vec<&str>)> = Vec::new();
    for (name, v) in values.iter().filter(|(_, v)| v != first) {
        match others.iter_mut().find(|(o, _)| o == v) {
            Some((_, names)) => names.push(name),
            None => others.push((v.clone(), vec![name])),
        }
    }
    let others: Vec<String> = others
        .iter()
        .map(|(v, names)| format!("{}: {v}", names.join(", ")))
        .collect();
    Some(if others.is_empty() {
        first.clone()
    } else {
        format!("{first} ({})", others.join("; "))
    })
}

fn scalar(v: &Value) -> Option<String> {
    match v {
        Value::Number(n) => Some(n.to_string()),
        Value::String(s) => Some(s.clone()),
        Value::Bool(b) => Some(b.to_string()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_read_as_the_integrators_have_them() {
        assert_eq!(
            default_text("photons").as_deref(),
            Some("200000 (ppm: 100000)")
        );
        assert_eq!(
            default_text("spp").as_deref(),
            Some("1 (photon, raytrace: 4)")
        );
        assert_eq!(default_text("alpha").as_deref(), Some("0.7 (vcm: 0.75)"));
        assert_eq!(default_text("iterations").as_deref(), Some("16"));
        assert_eq!(default_text("max_depth").as_deref(), Some("32"));
        assert_eq!(default_text("integrator").as_deref(), Some("auto"));
        assert_eq!(default_text("width"), None);
    }
}

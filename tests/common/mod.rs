//! Helpers shared by the integration tests.
#![allow(dead_code)]

use photonbox::render::{Control, Image, RenderParams, Scene, render};

/// Parse a scene from JSON text (no folder: no OBJ files).
pub fn scene(json: &str) -> Scene {
    Scene::parse(json, None).unwrap_or_else(|e| panic!("test scene does not parse: {e}"))
}

/// Render on the current thread pool, with no progress or cancel hooks.
pub fn render_image(scene: &Scene, params: &RenderParams) -> Image {
    let out = render(scene, params, &Control::none()).expect("not cancelled");
    assert_all_finite(&out.image);
    assert_eq!(
        out.stats.nonfinite_samples, 0,
        "non-finite samples were dropped"
    );
    out.image
}

pub fn assert_all_finite(img: &Image) {
    let bad = img
        .pixels
        .iter()
        .flatten()
        .filter(|c| !c.is_finite())
        .count();
    assert_eq!(bad, 0, "{bad} non-finite pixel channels");
}

/// Relative difference a/b - 1.
pub fn rel(a: f64, b: f64) -> f64 {
    a / b - 1.0
}

/// The same scene scaled by `s` about the origin and then moved by `t`: points are
/// transformed, edge vectors and radii scaled, point-light power multiplied by s^2 (so that
/// every radiance stays the same), area-light radiance kept.
pub fn transform_scene(json: &str, s: f64, t: [f64; 3]) -> String {
    use serde_json::{Value, json};
    let mut v: Value = serde_json::from_str(json).unwrap();
    let coords = |x: &Value| -> Vec<f64> {
        x.as_array()
            .unwrap()
            .iter()
            .map(|c| c.as_f64().unwrap())
            .collect()
    };
    let point = |x: &Value| -> Value {
        let a = coords(x);
        json!([a[0] * s + t[0], a[1] * s + t[1], a[2] * s + t[2]])
    };
    let vector = |x: &Value| -> Value {
        let a = coords(x);
        json!([a[0] * s, a[1] * s, a[2] * s])
    };
    for key in ["position", "look_at"] {
        v["camera"][key] = point(&v["camera"][key]);
    }
    for list in ["objects", "lights"] {
        for o in v[list].as_array_mut().unwrap() {
            for key in ["center", "corner", "position"] {
                if o.get(key).is_some() {
                    o[key] = point(&o[key]);
                }
            }
            for key in ["edge_u", "edge_v"] {
                if o.get(key).is_some() {
                    o[key] = vector(&o[key]);
                }
            }
            if let Some(r) = o.get("radius").and_then(Value::as_f64) {
                o["radius"] = json!(r * s);
            }
            if let Some(p) = o.get_mut("positions").and_then(Value::as_array_mut) {
                for q in p.iter_mut() {
                    *q = point(q);
                }
            }
            if let Some(p) = o.get("power") {
                // vector() scales once; twice is s^2.
                o["power"] = vector(&vector(p));
            }
        }
    }
    v.to_string()
}

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

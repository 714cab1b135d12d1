//! The semantic checks of a scene's values once they have their types: colours not
//! negative, reflectances at most 1, positive radii and indices of refraction,
//! non-degenerate quads and triangles, a camera with a usable fov, size and view and up
//! directions, energy-conserving Phong.
//! Apart from `load.rs`, which turns JSON into those typed values, so that what makes a
//! scene valid reads in one place. Every error names its JSON path.

use glam::DVec3;

use super::format::{CameraDef, Num, V3};
use super::load::{dvec, err};
use super::{MeshData, SceneError};
use crate::render::camera::MAX_IMAGE_SIDE;
use crate::render::math::Rgb;

pub(super) fn color(v: V3, path: String) -> Result<Rgb, SceneError> {
    if v.0.iter().any(|c| *c < 0.0) {
        return Err(err(path, "colour components must be >= 0"));
    }
    Ok(Rgb::new(v.0[0] as f32, v.0[1] as f32, v.0[2] as f32))
}

/// A reflectance (albedo): a fraction of light reflected, so at most 1 per channel.
pub(super) fn reflectance(v: V3, path: String) -> Result<Rgb, SceneError> {
    if v.0.iter().any(|c| *c > 1.0) {
        return Err(err(
            path,
            "components must be at most 1: a surface cannot reflect more light than it receives \
             (colours written 0-255 need dividing by 255)",
        ));
    }
    color(v, path)
}

pub(super) fn positive(n: Num, path: String) -> Result<f64, SceneError> {
    if n.0 > 0.0 {
        Ok(n.0)
    } else {
        Err(err(path, format!("must be > 0, got {}", n.0)))
    }
}

/// Rejects parallel or zero edges: sin(angle) * |u||v| below 1e-10 |u||v|.
pub(super) fn non_degenerate_pair(
    u: DVec3,
    v: DVec3,
    path: &str,
    what: &str,
) -> Result<(), SceneError> {
    let area = u.cross(v).length();
    if !(area > 1e-10 * u.length() * v.length()) || area == 0.0 {
        return Err(err(path, format!("degenerate {what} (zero area)")));
    }
    Ok(())
}

pub(super) fn check_camera(c: CameraDef) -> Result<CameraDef, SceneError> {
    let fov = c.fov.0;
    if !(fov > 0.0 && fov < 180.0) {
        return Err(err(
            "camera.fov",
            format!("must be in (0, 180) degrees, got {fov}"),
        ));
    }
    for (field, v) in [("width", c.width), ("height", c.height)] {
        if !(1..=MAX_IMAGE_SIDE).contains(&v) {
            return Err(err(
                format!("camera.{field}"),
                format!("must be in 1..={MAX_IMAGE_SIDE}, got {v}"),
            ));
        }
    }
    let (position, look_at) = (dvec(c.position), dvec(c.look_at));
    let forward = look_at - position;
    // The direction is taken in f64 (Scene::build), so only f64's own precision limits it.
    if !(forward.length() > 1e-12 * position.length().max(look_at.length())) {
        return Err(err("camera.look_at", "must differ from camera.position"));
    }
    let up = dvec(c.up);
    if !(forward.normalize().cross(up).length() > 1e-6 * up.length()) {
        return Err(err(
            "camera.up",
            "must not be zero or parallel to the view direction",
        ));
    }
    Ok(c)
}

/// A modified Phong material's exponent in range and kd + ks <= 1 in every channel, the
/// condition under which it conserves energy (Lafortune and Willems 1994).
pub(super) fn check_phong(
    diffuse: Rgb,
    specular: Rgb,
    exponent: f64,
    path: &str,
) -> Result<(), SceneError> {
    if !(0.0..=1e6).contains(&exponent) {
        return Err(err(format!("{path}.exponent"), "must be in [0, 1e6]"));
    }
    if (diffuse + specular).max_element() > 1.0 + 1e-6 {
        return Err(err(
            path,
            "diffuse + specular exceeds 1 in some channel: the material would create energy",
        ));
    }
    Ok(())
}

pub(super) fn check_mesh(mesh: &MeshData, path: &str) -> Result<(), SceneError> {
    if mesh.triangles.is_empty() {
        return Err(err(
            format!("{path}.triangles"),
            "a mesh needs at least one triangle",
        ));
    }
    let n = mesh.positions.len();
    for (j, tri) in mesh.triangles.iter().enumerate() {
        let tpath = || format!("{path}.triangles[{j}]");
        if let Some(bad) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(err(
                tpath(),
                format!("vertex index {bad} out of range ({n} positions)"),
            ));
        }
        let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
        let (u, v) = (b - a, c - a);
        let area = u.cross(v).length();
        if !(area > 1e-10 * u.length() * v.length()) || area == 0.0 {
            return Err(err(tpath(), "degenerate triangle (zero area)"));
        }
    }
    Ok(())
}

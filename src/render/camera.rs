//! The pinhole camera of the scene format: vertical field of view, image right
//! = normalize(cross(look_at - position, up)), pixel (0, 0) at the top left.

use glam::Vec3A;

use crate::render::geometry::Ray;

/// The largest image side, from a scene or a render's parameters.
pub use crate::spec::MAX_IMAGE_SIDE;

#[derive(Clone, Debug)]
pub struct Camera {
    pub position: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    tan_half_fov: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// `forward` and `up` need not be unit or orthogonal, only not parallel (checked by the
    /// scene loader).
    pub fn new(
        position: Vec3A,
        look_at: Vec3A,
        up: Vec3A,
        fov_degrees: f32,
        width: u32,
        height: u32,
    ) -> Camera {
        let forward = (look_at - position).normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Camera {
            position,
            forward,
            right,
            up,
            tan_half_fov: (fov_degrees.to_radians() * 0.5).tan(),
            width,
            height,
        }
    }

    /// The same view at another resolution (the vertical field of view is kept).
    pub fn with_resolution(mut self, width: u32, height: u32) -> Camera {
        self.width = width;
        self.height = height;
        self
    }

    /// The viewing direction (unit).
    pub fn forward(&self) -> Vec3A {
        self.forward
    }

    /// The distance from the pinhole of the image plane on which a pixel is a unit square:
    /// there, sampling one point per pixel is a density of 1 per unit area, and a camera
    /// ray's solid-angle density is distance^2 / cos^3 (Georgiev et al. 2012, technical
    /// report; SmallVCM's camera).
    pub fn image_plane_distance(&self) -> f32 {
        0.5 * self.height as f32 / self.tan_half_fov
    }

    /// The film position (pixels, as [`Camera::ray`] takes it) that world point `p`
    /// projects to: None behind the camera or off the film.
    pub fn raster(&self, p: Vec3A) -> Option<glam::Vec2> {
        let q = self.film_position(p)?;
        let on_film =
            q.x >= 0.0 && q.y >= 0.0 && q.x < self.width as f32 && q.y < self.height as f32;
        on_film.then_some(q)
    }

    /// Where on the film's plane world point `p` projects to, on the film or off it: None
    /// for a point not in front of the camera.
    pub fn film_position(&self, p: Vec3A) -> Option<glam::Vec2> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if !(z > 0.0) {
            return None;
        }
        let aspect = self.width as f32 / self.height as f32;
        let sx = d.dot(self.right) / z;
        let sy = d.dot(self.up) / z;
        let x = (sx / (self.tan_half_fov * aspect) + 1.0) * 0.5 * self.width as f32;
        let y = (1.0 - sy / self.tan_half_fov) * 0.5 * self.height as f32;
        Some(glam::Vec2::new(x, y))
    }

    /// The ray through film position (x, y) in pixels, (0, 0) the top-left corner of the image.
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let sx = (2.0 * x / self.width as f32 - 1.0) * self.tan_half_fov * aspect;
        let sy = (1.0 - 2.0 * y / self.height as f32) * self.tan_half_fov;
        let d = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.position, d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_right_and_top_follow_the_contract() {
        let cam = Camera::new(
            Vec3A::new(0.0, 0.0, 5.0),
            Vec3A::ZERO,
            Vec3A::Y,
            40.0,
            64,
            48,
        );
        let left = cam.ray(0.0, 24.0);
        let top = cam.ray(32.0, 0.0);
        let centre = cam.ray(32.0, 24.0);
        assert!(
            left.d.x < 0.0,
            "pixel column 0 looks to -x (image right is +x)"
        );
        assert!(top.d.y > 0.0, "pixel row 0 looks up");
        assert!((centre.d - Vec3A::new(0.0, 0.0, -1.0)).length() < 1e-6);
        let half = (cam.ray(32.0, 0.0).d.y / -cam.ray(32.0, 0.0).d.z)
            .atan()
            .to_degrees();
        assert!((half - 20.0).abs() < 1e-3, "vertical half-angle {half}");
    }

    #[test]
    fn raster_inverts_ray() {
        let cam = Camera::new(
            Vec3A::new(1.0, 2.0, 5.0),
            Vec3A::new(0.0, 0.5, 0.0),
            Vec3A::Y,
            50.0,
            64,
            48,
        );
        for (x, y) in [(0.25, 0.5), (32.0, 24.0), (63.5, 47.75), (10.0, 40.0)] {
            let r = cam.ray(x, y);
            let at = cam.raster(r.at(3.7)).expect("in front and on the film");
            assert!(
                (at.x - x).abs() < 1e-3 && (at.y - y).abs() < 1e-3,
                "{x},{y} -> {at}"
            );
        }
        assert!(cam.raster(Vec3A::new(1.0, 2.0, 9.0)).is_none(), "behind");
        // A pixel is a unit square on the image plane.
        let d = cam.image_plane_distance();
        let (a, b) = (cam.ray(10.0, 10.0), cam.ray(11.0, 10.0));
        let on_plane = |r: &Ray| r.d * (d / r.d.dot(cam.forward()));
        assert!(((on_plane(&a) - on_plane(&b)).length() - 1.0).abs() < 1e-3);
    }
}

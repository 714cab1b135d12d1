//! Area lights the camera sees directly, sampled over more of each pixel than the camera
//! samples alone cover.
//!
//! A pixel's radiance (the box filter's mean over its area) is the sum of two integrals over
//! that area: the emission of the light surfaces its camera rays reach first, and everything
//! else. Where a light's edge crosses a pixel the first is the contrast between a light and
//! a dim wall, and a few camera samples land on either side of the edge or not: on a room
//! under a ceiling quad light (docs/validation/rooms/spheres_quad.json) after one pass of 2
//! samples a pixel, the 100 pixels along the light's two visible edges carried 85% of the
//! image's relmse. Each integral may be estimated with samples of its own (splitting the
//! integrand: Veach 1997, section 2.5): the camera samples still carry everything else, and
//! [`SEEN_LIGHT_RAYS`] more rays a sample, spread over the pixel by their own stratified
//! sequence (a [`Branch::SeenLight`] of the sample's), carry the first. A ray that is only
//! a first hit costs one intersection; only pixels a visible light's screen box covers
//! ([`SeenLights`]) pay it. Both estimates are unbiased, so the image's expectation is
//! unchanged; lights seen through a mirror or glass stay with the camera samples.

use super::Shader;
use super::shade::{Emission, Scratch};
use crate::render::camera::Camera;
use crate::render::geometry::{Ray, Surface};
use crate::render::light::Light;
use crate::render::math::Rgb;
use crate::render::qmc::Branch;
use crate::render::sampling::Sampler;
use crate::render::scene::Scene;

/// Rays a camera sample spends on the light surfaces seen first, where a light covers its
/// pixel: with 2 samples a pixel a pass, 16 a pixel a pass.
pub const SEEN_LIGHT_RAYS: u32 = 8;

/// Where on the film the camera may see an area light directly: each light's bounding box
/// (a quad's corners, a sphere's bounding cube) projected to the film, the box of the
/// projections. A light behind the camera's plane in part may cover any pixel.
#[derive(Clone, Debug)]
pub struct SeenLights {
    camera: Camera,
    /// [x0, y0, x1, y1] in film pixels, as [`Camera::ray`] takes them.
    boxes: Vec<[f32; 4]>,
    everywhere: bool,
}

impl SeenLights {
    /// The film boxes of `scene`'s area lights seen by `camera`.
    pub fn of(scene: &Scene, camera: &Camera) -> SeenLights {
        let mut seen = SeenLights::none(camera);
        for light in &scene.lights {
            let corners: Vec<_> = match *light {
                Light::Point { .. } => continue,
                Light::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    ..
                } => vec![
                    corner,
                    corner + edge_u,
                    corner + edge_v,
                    corner + edge_u + edge_v,
                ],
                Light::Sphere { center, radius, .. } => (0..8)
                    .map(|i| {
                        let sign = |bit: u32| if i & bit == 0 { -radius } else { radius };
                        center + glam::Vec3A::new(sign(1), sign(2), sign(4))
                    })
                    .collect(),
            };
            let projected: Option<Vec<_>> =
                corners.iter().map(|&p| camera.film_position(p)).collect();
            let Some(points) = projected else {
                seen.everywhere = true;
                continue;
            };
            let lo = points.iter().fold(glam::Vec2::MAX, |a, &p| a.min(p));
            let hi = points.iter().fold(glam::Vec2::MIN, |a, &p| a.max(p));
            seen.boxes.push([lo.x, lo.y, hi.x, hi.y]);
        }
        seen
    }

    /// No pixel splits: every light seen is left to the camera samples.
    pub fn none(camera: &Camera) -> SeenLights {
        SeenLights {
            camera: camera.clone(),
            boxes: Vec::new(),
            everywhere: false,
        }
    }

    /// Whether the pixel at column and row `xy` may see a light directly.
    #[inline]
    pub fn covers(&self, [x, y]: [u32; 2]) -> bool {
        let (x, y) = (x as f32, y as f32);
        self.everywhere
            || self
                .boxes
                .iter()
                .any(|&[x0, y0, x1, y1]| x + 1.0 > x0 && x < x1 && y + 1.0 > y0 && y < y1)
    }
}

impl Shader<'_> {
    /// Radiance arriving at the camera along `ray` at the pixel at `xy`: where a light may be
    /// seen there, the light surfaces the camera sees first by rays of their own
    /// ([`Shader::seen_light`]) and the rest along `ray` (lights only through a mirror or
    /// glass).
    pub fn camera_sample(
        &self,
        ray: &Ray,
        xy: [u32; 2],
        s: &mut Sampler,
        scratch: &mut Scratch,
    ) -> Rgb {
        if !self.seen.covers(xy) {
            return self.camera_ray(ray, s, scratch);
        }
        let rest = self.camera_segment(ray, Emission::AfterSpecular, s, scratch);
        rest + self.seen_light(xy, s)
    }

    /// The emission of the light surfaces first seen over the pixel at `xy`, by
    /// [`SEEN_LIGHT_RAYS`] rays from the sample `s`'s branches.
    fn seen_light(&self, xy: [u32; 2], s: &mut Sampler) -> Rgb {
        let camera = &self.seen.camera;
        let mut sum = Rgb::ZERO;
        for k in 0..SEEN_LIGHT_RAYS {
            let jitter = s.branch(Branch::SeenLight, k, SEEN_LIGHT_RAYS).next_2d();
            let ray = camera.ray(xy[0] as f32 + jitter.x, xy[1] as f32 + jitter.y);
            sum += self.first_emission(&ray);
        }
        sum / SEEN_LIGHT_RAYS as f32
    }

    /// The emission of the surface `ray` reaches first, if it is a light's.
    fn first_emission(&self, ray: &Ray) -> Rgb {
        let Some(hit) = self.scene.intersect(ray) else {
            return Rgb::ZERO;
        };
        match self.scene.surface(hit.point.prim) {
            Surface::Light(li) => self.scene.lights[li as usize].emitted(hit.point.n, -ray.d),
            Surface::Material(_) => Rgb::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::control::Control;
    use crate::spec::RenderSpec;

    /// A quad light of radiance 1 facing the camera squarely, nothing else: its film image
    /// is a rectangle whose edges fall inside pixels.
    const FACING_LIGHT: &str = r#"{
      "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 40,
                 "width": 48, "height": 48},
      "materials": {},
      "objects": [],
      "lights": [{"type": "quad", "corner": [-0.613, -0.377, 0], "edge_u": [1.071, 0, 0],
                  "edge_v": [0, 0.853, 0], "radiance": [1, 1, 1]}]
    }"#;

    /// The share of the pixel at (x, y) that the film rectangle [x0, x1) x [y0, y1) covers.
    fn covered(x: u32, y: u32, [x0, y0, x1, y1]: [f32; 4]) -> f32 {
        let span = |p: u32, lo: f32, hi: f32| (hi.min(p as f32 + 1.0) - lo.max(p as f32)).max(0.0);
        span(x, x0, x1) * span(y, y0, y1)
    }

    /// After a single camera sample, a pixel the light's edge crosses holds the light's
    /// radiance times the share of the pixel it covers, to within the stratification of the
    /// seen-light rays (an edge's share to 1/8, a corner's, two edges, to 2/8; the camera
    /// sample alone gives 0 or 1), and the image holds the light's projected area.
    #[test]
    fn a_seen_light_covers_its_pixels_by_its_share_of_them() {
        let scene = Scene::parse(FACING_LIGHT, None).unwrap();
        let Light::Quad {
            corner,
            edge_u,
            edge_v,
            ..
        } = scene.lights[0]
        else {
            panic!("a quad light");
        };
        let film = |p| scene.camera.raster(p).expect("the corners are on the film");
        let (a, b) = (film(corner + edge_v), film(corner + edge_u));
        let rect = [a.x, a.y, b.x, b.y];
        let spec = RenderSpec::raytrace(1);
        let image = crate::render::render(&scene, &spec, &Control::none())
            .unwrap()
            .image;
        let (mut worst, mut sum, mut area, mut edges) = (0.0f32, 0.0f64, 0.0f64, 0);
        for y in 0..image.height {
            for x in 0..image.width {
                let share = covered(x, y, rect);
                let v = image.get(x, y)[1];
                worst = worst.max((v - share).abs());
                sum += v as f64;
                area += share as f64;
                edges += (share > 0.05 && share < 0.95) as u32;
            }
        }
        assert!(edges > 40, "the edges cross {edges} pixels");
        assert!(worst <= 0.26, "a pixel is {worst} from its share");
        let ratio = sum / area;
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "the image holds {ratio} of the area"
        );
    }
}

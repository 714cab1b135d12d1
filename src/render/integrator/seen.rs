//! Area lights the camera sees directly, sampled over more of each pixel than the camera
//! samples alone cover.
//!
//! A pixel's radiance (the box filter's mean over its area) is the sum of two integrals over
//! that area: the emission of the light surfaces its camera rays reach first, and everything
//! else. Where a light's edge crosses a pixel the first is the contrast between a light and
//! a dim wall, and a few camera samples land on either side of the edge or not: on a room
//! under a ceiling quad light (docs/validation/rooms/spheres_quad.json) after one pass of 2
//! samples a pixel, the 100 pixels along the light's two visible edges carried 85% of the
//! image's relmse. Each integral may be estimated with samples of its own (the integral of
//! a sum is the sum of the integrals): the camera samples still carry everything else, and
//! [`SEEN_LIGHT_RAYS`] more rays a sample, spread over the pixel by their own stratified
//! sequence (a [`Branch::SeenLight`] of the sample's), carry the first. A ray that is only
//! a first hit costs one intersection; only pixels a light's edge may cross
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
use rayon::prelude::*;

/// Rays a camera sample spends on the light surfaces seen first, where a light's edge may
/// cross its pixel: with 2 samples a pixel a pass, 16 a pixel a pass.
pub const SEEN_LIGHT_RAYS: u32 = 8;

/// Which film pixels split their light seen first from the rest: those where a light's edge
/// may cross the pixel. Each visible area light's bounding box (a quad's corners, a sphere's
/// bounding cube) is projected to the film (all of it where the light lies partly behind
/// the camera's plane); over that box, rays through the pixels' corners, edge midpoints and
/// centres (a grid at half-pixel steps) find which light each sees first, if any. A pixel
/// whose nine points do not all agree is split. The choice is a function of the scene and
/// the camera alone, never of a sample, so each pixel's estimate stays unbiased; a pixel
/// wholly inside a light, or wholly off it, pays no extra rays (a light that fills the view
/// made `raytrace` 4.5 times slower when every pixel of its box was split).
#[derive(Clone, Debug)]
pub struct SeenLights {
    camera: Camera,
    /// One bit a film pixel, row-major: whether the pixel is split.
    split: Vec<u64>,
}

impl SeenLights {
    /// The pixels of `scene`'s film through `camera` that a light's edge may cross.
    pub fn of(scene: &Scene, camera: &Camera) -> SeenLights {
        let mut seen = SeenLights::none(camera);
        for light in &scene.lights {
            if let Some(film_box) = film_box(light, camera) {
                seen.mark_edges(scene, film_box);
            }
        }
        seen
    }

    /// No pixel splits: every light seen is left to the camera samples.
    fn none(camera: &Camera) -> SeenLights {
        let pixels = camera.width as usize * camera.height as usize;
        SeenLights {
            camera: camera.clone(),
            split: vec![0; pixels.div_ceil(64)],
        }
    }

    /// Whether the pixel at column and row `xy` is split.
    #[inline]
    pub fn covers(&self, [x, y]: [u32; 2]) -> bool {
        let i = y as usize * self.camera.width as usize + x as usize;
        self.split
            .get(i / 64)
            .is_some_and(|w| w >> (i % 64) & 1 == 1)
    }

    /// Mark the pixels of `[x0, y0, x1, y1)` whose nine points see different lights first.
    fn mark_edges(&mut self, scene: &Scene, [x0, y0, x1, y1]: [u32; 4]) {
        let camera = &self.camera;
        let (gw, gh) = (2 * (x1 - x0) + 1, 2 * (y1 - y0) + 1);
        let grid: Vec<Vec<u32>> = (0..gh)
            .into_par_iter()
            .map(|j| {
                let fy = y0 as f32 + j as f32 * 0.5;
                (0..gw)
                    .map(|i| first_light(scene, &camera.ray(x0 as f32 + i as f32 * 0.5, fy)).0)
                    .collect()
            })
            .collect();
        for y in y0..y1 {
            for x in x0..x1 {
                let (i, j) = ((2 * (x - x0)) as usize, (2 * (y - y0)) as usize);
                let seen = grid[j][i];
                let same = grid[j..j + 3]
                    .iter()
                    .all(|row| row[i..i + 3].iter().all(|&l| l == seen));
                if !same {
                    let p = y as usize * camera.width as usize + x as usize;
                    self.split[p / 64] |= 1 << (p % 64);
                }
            }
        }
    }
}

/// The film pixels `[x0, y0, x1, y1)` where `camera` may see `light` (none for a point
/// light), a pixel wider than its projected bounding box on each side; the whole film where
/// the light lies partly behind the camera's plane.
fn film_box(light: &Light, camera: &Camera) -> Option<[u32; 4]> {
    let corners: Vec<_> = match *light {
        Light::Point { .. } => return None,
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
    let (w, h) = (camera.width, camera.height);
    let projected: Option<Vec<_>> = corners.iter().map(|&p| camera.film_position(p)).collect();
    let Some(points) = projected else {
        return Some([0, 0, w, h]);
    };
    let lo = points.iter().fold(glam::Vec2::MAX, |a, &p| a.min(p));
    let hi = points.iter().fold(glam::Vec2::MIN, |a, &p| a.max(p));
    let clamp = |v: f32, max: u32| v.clamp(0.0, max as f32) as u32;
    let b = [
        clamp(lo.x.floor() - 1.0, w),
        clamp(lo.y.floor() - 1.0, h),
        clamp(hi.x.ceil() + 1.0, w),
        clamp(hi.y.ceil() + 1.0, h),
    ];
    (b[0] < b[2] && b[1] < b[3]).then_some(b)
}

/// Which light `ray` reaches first (its index plus one; 0 for none, or a light seen from
/// behind), and the radiance it emits toward the ray.
fn first_light(scene: &Scene, ray: &Ray) -> (u32, Rgb) {
    let Some(hit) = scene.intersect(ray) else {
        return (0, Rgb::ZERO);
    };
    match scene.surface(hit.point.prim) {
        Surface::Light(li) => {
            let le = scene.lights[li as usize].emitted(hit.point.n, -ray.d);
            if le == Rgb::ZERO {
                (0, le)
            } else {
                (li + 1, le)
            }
        }
        Surface::Material(_) => (0, Rgb::ZERO),
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
            sum += first_light(self.scene, &ray).1;
        }
        sum / SEEN_LIGHT_RAYS as f32
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
        // Only pixels an edge crosses split: none inside the light or off it.
        let seen = SeenLights::of(&scene, &scene.camera);
        let split = (0..image.height)
            .flat_map(|y| (0..image.width).map(move |x| [x, y]))
            .filter(|&xy| seen.covers(xy))
            .inspect(|&[x, y]| {
                let share = covered(x, y, rect);
                assert!(share > 0.0 && share < 1.0, "{x} {y} split at share {share}");
            })
            .count();
        assert!(
            split >= edges as usize,
            "{split} pixels split, {edges} crossed"
        );
        assert!(worst <= 0.26, "a pixel is {worst} from its share");
        let ratio = sum / area;
        assert!(
            (ratio - 1.0).abs() < 0.01,
            "the image holds {ratio} of the area"
        );
    }
}

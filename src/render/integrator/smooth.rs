//! Smoothed final gathers: a ppm pass's indirect light at the points the camera sees,
//! shared between neighbouring pixels on the same surface.
//!
//! Light from other surfaces varies slowly over a diffuse surface (Ward, Rubinstein and
//! Clear 1988, "A Ray Tracing Solution for Diffuse Interreflection", interpolate it between
//! sparse gathers for that reason). So a pass replaces each pixel's gathered radiance by
//! the value at its point of a weighted linear fit (local linear regression) to the gathers
//! of the pixels about it whose points lie on its surface: its plane, its normal and its
//! reflectance, within a radius that is a multiple of the pass's global-map radius over
//! pass^0.35 (`ppm/passes.rs`, `SMOOTHING_FADE`). That radius shrinks faster than the map's
//! (Knaus and Zwicker 2011), so each pass's blur vanishes as the passes go on and the mean
//! of the passes converges, while the first passes show the noise of many pixels' gathers
//! instead of one's. A fit rather than a mean: where the kernel is cut (the image's border,
//! a corner's other wall) a mean would lean toward the side that remains by the light's
//! gradient there; a fit follows it. Measured in docs/performance-history.md, "smoothed
//! final gathers" and "smoothing on planes, fading slower".

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::render::camera::Camera;
use crate::render::film::Image;
use crate::render::math::Rgb;

/// A camera sample's final gather at the first point the camera sees (straight, not through
/// a mirror or glass), as `shade.rs` leaves it for the film: what is shared.
#[derive(Clone, Copy, Debug)]
pub struct GatherSample {
    pub p: Vec3A,
    /// The normal on the side the camera sees.
    pub n: Vec3A,
    /// The mean radiance the gather rays brought (times rho: the indirect light it adds).
    pub g: Rgb,
    pub rho: Rgb,
}

/// Two points lie on one surface when the cosine between their normals is at least this
/// (8 degrees): a plane, or a surface that curves little within the kernel. Across a
/// tighter curve the light is not near linear in the pixel's position (a tube's light turns
/// with its normal, and falls into the creases where it faces other surfaces), and a fit
/// there brightened the surface: with 0.9 (26 degrees) knot's tube read 2.2% above the
/// reference after one pass and 0.6% after 16, when its blocks held twice the block_err
/// they hold unsmoothed (docs/performance-history.md, "smoothing on planes, fading
/// slower"). The same bound marks a pixel whose samples' normals differ by more as mixed
/// (`GatherPixel::add`): on such a curve, with two samples a pixel, many pixels are.
const SAME_NORMAL: f32 = 0.99;

/// Two points with such normals lie on one surface when the one lies at most this fraction
/// of the kernel's radius off the other's plane.
const PLANE_FRACTION: f32 = 0.1;

/// The most pixels a fit reads along each axis: a bound on its cost (with 8, a pass of
/// `auto`'s gathering took 4-5% more CPU than unsmoothed on cornell and knot:
/// docs/performance-history.md, "smoothed final gathers").
const MAX_WINDOW: usize = 8;

/// A pixel's samples gathered on two surfaces when the line between their points leaves
/// the first's plane by more than this sine (30 degrees): a silhouette, not a slope.
const MIXED_SINE: f32 = 0.5;

/// A pixel's samples' gathers at the points the camera saw (film side, `film.rs`).
#[derive(Clone, Debug, Default)]
pub struct GatherPixel {
    /// Finite samples (the pixel's mean is over these).
    good: u32,
    /// Of them, those that gathered.
    gathered: u32,
    /// The samples gathered on different surfaces: left as they are, and lent to none.
    mixed: bool,
    /// The sums of the gathers' points and normals, and of their gathered radiances
    /// (each the mean over its rays); the reflectance, the same for all.
    p: Vec3,
    n: Vec3,
    g: Vec3,
    rho: Vec3,
}

impl GatherPixel {
    /// Fold in a sample, finite or not, with its gather if it made one.
    pub fn add(&mut self, finite: bool, gather: Option<GatherSample>) {
        if !finite {
            return;
        }
        self.good += 1;
        let Some(s) = gather else {
            return;
        };
        if self.gathered > 0 {
            let n = Vec3A::from(self.n).normalize_or_zero();
            let d = s.p - Vec3A::from(self.p) / self.gathered as f32;
            let off_plane = n.dot(d).abs() > MIXED_SINE * d.length();
            if Vec3A::from(self.rho) != s.rho || s.n.dot(n) < SAME_NORMAL || off_plane {
                self.mixed = true;
            }
        }
        self.gathered += 1;
        self.p += Vec3::from(s.p);
        self.n += Vec3::from(s.n);
        self.g += Vec3::from(s.g);
        self.rho = s.rho.into();
    }

    /// The pixel as the smoothing reads it, where its gathers can be shared.
    fn surface(&self) -> Option<Surface> {
        if self.gathered == 0 || self.mixed {
            return None;
        }
        let k = self.gathered as f32;
        Some(Surface {
            p: self.p / k,
            n: self.n.normalize_or_zero(),
            g: self.g / k,
            rho: self.rho,
            count: k,
        })
    }
}

/// A pixel whose samples gathered on one surface: their mean point, normal and gather, the
/// surface's reflectance and how many samples (unaligned vectors: one a pixel of the image).
#[derive(Clone, Copy, Debug)]
struct Surface {
    p: Vec3,
    n: Vec3,
    g: Vec3,
    rho: Vec3,
    count: f32,
}

/// Replace each pixel's gathered light in `image` (seen through `camera`) by the value at
/// its point of a weighted linear fit to its neighbours' on its surface within `radius`
/// (scene units) and [`MAX_WINDOW`] pixels, separably: a fit
/// along each row ([`Line::fit`] over x), then a fit of those along each column (over y).
/// On a plane a linear field passes both unchanged, and the two 1D windows of 2w + 1 pixels
/// average about as many gathers as one square window of (2w + 1)^2 at about a ninth of its
/// cost for w = 8. A pure function of the pass's pixels: the same bytes whatever the threads.
pub fn smooth_gathers(image: &mut Image, pixels: &[GatherPixel], radius: f32, camera: &Camera) {
    let line = Line {
        surfaces: &pixels.iter().map(GatherPixel::surface).collect::<Vec<_>>(),
        width: image.width as usize,
        radius,
        camera,
    };
    let rows: Vec<(Vec3, f32)> = (0..pixels.len())
        .into_par_iter()
        .map(|i| {
            line.fit(i, 1, |q| {
                line.surfaces[q].map_or((Vec3::ZERO, 0.0), |q| (q.g, q.count))
            })
        })
        .collect();
    image
        .pixels
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, out)| {
            let (a, weight) = line.fit(i, line.width, |q| rows[q]);
            if weight > 0.0 {
                let px = &pixels[i];
                let me = line.surfaces[i].expect("a fit has a surface");
                let shared = Rgb::from(me.rho * (a * me.count - px.g) / px.good as f32);
                *out = (Rgb::from(*out) + shared).to_array();
            }
        });
}

/// What a separable pass's fits along rows and columns read.
struct Line<'a> {
    surfaces: &'a [Option<Surface>],
    width: usize,
    radius: f32,
    camera: &'a Camera,
}

impl Line<'_> {
    /// How many pixels the kernel about `me` spans on the film along each axis, at most
    /// [`MAX_WINDOW`].
    fn window(&self, me: &Surface) -> usize {
        let camera = self.camera;
        let depth = (Vec3A::from(me.p) - camera.position).dot(camera.forward());
        let reach = self.radius * camera.image_plane_distance() / depth.max(f32::MIN_POSITIVE);
        reach.ceil().min(MAX_WINDOW as f32) as usize
    }

    /// The weighted linear fit, along the line through pixel `i` in steps of `step` pixels
    /// (1: its row, the image's width: its column), to the values (and their weights) that
    /// `value` gives of the pixels in its window whose points lie on `i`'s surface within
    /// the radius, each weighted by the Epanechnikov kernel 1 - d^2 / r^2: the fit's value
    /// at `i` and its total weight (0: no fit).
    fn fit(&self, i: usize, step: usize, value: impl Fn(usize) -> (Vec3, f32)) -> (Vec3, f32) {
        let Some(me) = self.surfaces[i] else {
            return (Vec3::ZERO, 0.0);
        };
        let win = self.window(&me);
        let (w, len) = (self.width, self.surfaces.len());
        // Steps to the line's ends: the row's, or the image's top and bottom.
        let (before, after) = if step == 1 {
            (i % w, w - 1 - i % w)
        } else {
            (i / w, (len - 1 - i) / w)
        };
        let r = self.radius;
        let (r2, plane) = (r * r, PLANE_FRACTION * r);
        let (p, n) = (Vec3A::from(me.p), Vec3A::from(me.n));
        let [mut s0, mut s1, mut s2] = [0.0f32; 3];
        let (mut r0, mut r1) = (Vec3::ZERO, Vec3::ZERO);
        for o in -(win.min(before) as isize)..=win.min(after) as isize {
            let q = (i as isize + o * step as isize) as usize;
            let Some(sq) = self.surfaces[q] else {
                continue;
            };
            let d = Vec3A::from(sq.p) - p;
            let d2 = d.length_squared();
            let same = Vec3A::from(sq.n).dot(n) >= SAME_NORMAL && sq.rho == me.rho;
            if d2 >= r2 || !same || n.dot(d).abs() > plane {
                continue;
            }
            let (g, weight) = value(q);
            let k = (1.0 - d2 / r2) * weight;
            let t = o as f32 / (win as f32 + 1.0);
            s0 += k;
            s1 += k * t;
            s2 += k * t * t;
            r0 += k * g;
            r1 += (k * t) * g;
        }
        if !(s0 > 0.0) {
            return (Vec3::ZERO, 0.0);
        }
        // The intercept of the fit g = a + b t; the weighted mean where all the weight lies
        // at one offset (no slope to fit).
        let det = s0 * s2 - s1 * s1;
        let a = if det > 1e-3 * s0 * s2 {
            (s2 * r0 - s1 * r1) / det
        } else {
            r0 / s0
        };
        (a, s0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampling::{Sampler, Stream};

    const W: u32 = 48;

    /// A camera square on to the plane z = 0 from (0, 0, -5), so that a point's position
    /// on the plane is linear in its pixel's.
    fn camera() -> Camera {
        let eye = Vec3A::new(0.0, 0.0, -5.0);
        Camera::new(eye, Vec3A::ZERO, Vec3A::Y, 30.0, W, W)
    }

    /// Pixel (x, y)'s point on the plane z = 0.
    fn point(c: &Camera, x: u32, y: u32) -> Vec3A {
        let ray = c.ray(x as f32 + 0.5, y as f32 + 0.5);
        ray.o + ray.d * (-ray.o.z / ray.d.z)
    }

    /// One gathering sample a pixel, of `g(x, y, point)` on reflectance `rho(x)`, facing the
    /// camera, the image what the film holds (rho g), smoothed within `radius`.
    fn smoothed(
        g: impl Fn(u32, u32, Vec3A) -> Rgb,
        rho: impl Fn(u32) -> Rgb,
        radius: f32,
    ) -> (Image, Image) {
        let sample = |x, y, p| GatherSample {
            p,
            n: -Vec3A::Z,
            g: g(x, y, p),
            rho: rho(x),
        };
        smoothed_samples(sample, radius)
    }

    /// The same for any sample `sample(x, y, point)` at each pixel's point.
    fn smoothed_samples(
        sample: impl Fn(u32, u32, Vec3A) -> GatherSample,
        radius: f32,
    ) -> (Image, Image) {
        let c = camera();
        let mut image = Image::new(W, W);
        let mut pixels = vec![GatherPixel::default(); (W * W) as usize];
        for y in 0..W {
            for x in 0..W {
                let (i, p) = ((y * W + x) as usize, point(&c, x, y));
                let sample = sample(x, y, p);
                pixels[i].add(true, Some(sample));
                image.pixels[i] = (sample.rho * sample.g).to_array();
            }
        }
        let before = image.clone();

        smooth_gathers(&mut image, &pixels, radius, &c);
        (before, image)
    }

    fn max_difference(a: &Image, b: &Image) -> f32 {
        let d = a.pixels.iter().zip(&b.pixels);
        d.map(|(a, b)| (Rgb::from(*a) - Rgb::from(*b)).abs().max_element())
            .fold(0.0, f32::max)
    }

    /// A fit, not a mean: light that changes linearly over a plane comes out as it went in,
    /// at the image's borders and corners too, where the kernel is cut.
    #[test]
    fn a_linear_gradient_on_a_plane_passes_unchanged() {
        let g =
            |_, _, p: Vec3A| Rgb::new(1.0 + 0.5 * p.x, 2.0 - 0.3 * p.y, 1.0 + 0.2 * (p.x + p.y));
        let (before, after) = smoothed(g, |_| Rgb::splat(0.5), 1.0);
        let d = max_difference(&before, &after);
        assert!(d < 1e-4, "changed by {d}");
    }

    /// Independent noise on one surface is averaged over the kernel: its variance falls
    /// by far more than five, and its mean stays.
    #[test]
    fn noise_on_a_surface_is_averaged() {
        let noise = |x: u32, y: u32, _| {
            let mut s = Sampler::new(3, Stream::Camera, (y * W + x) as u64);
            Rgb::splat(1.0 + (s.next_f32() - 0.5))
        };
        let (before, after) = smoothed(noise, |_| Rgb::ONE, 1.0);
        let stats = |im: &Image| {
            let v: Vec<f64> = im.pixels.iter().map(|p| p[0] as f64).collect();
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
            (mean, var)
        };
        let ((m0, v0), (m1, v1)) = (stats(&before), stats(&after));
        assert!(v1 < v0 / 20.0, "variance {v0} -> {v1}");
        assert!((m1 - m0).abs() < 0.01, "mean {m0} -> {m1}");
    }

    /// Pixels on another surface (here another reflectance: another material) lend nothing:
    /// a step in the light where two materials meet stays a step.
    #[test]
    fn other_surfaces_lend_nothing() {
        let left = |x: u32| x < W / 2;
        let g = move |x, _, _| Rgb::splat(if left(x) { 1.0 } else { 3.0 });
        let rho = move |x| Rgb::splat(if left(x) { 0.5 } else { 0.6 });
        let (before, after) = smoothed(g, rho, 1.0);
        let d = max_difference(&before, &after);
        assert!(d < 1e-5, "mixed across the step by {d}");
    }

    /// A surface that curves (its normal turning 10 degrees from pixel to pixel along each
    /// row, as across a thin tube, between -40 and 40 degrees and back, never the same
    /// within a window) lends nothing along it, though its points lie within the radius (each
    /// row another reflectance, so that columns lend nothing either).
    #[test]
    fn a_curved_surface_lends_nothing() {
        let sample = |x: u32, y: u32, p| {
            let turn = ((x % 9) as f32 * 10.0 - 40.0).to_radians();
            GatherSample {
                p,
                n: Vec3A::new(turn.sin(), 0.0, -turn.cos()),
                g: Rgb::splat(((x * 7 + y * 13) % 5) as f32),
                rho: Rgb::splat(0.5 + y as f32 / 256.0),
            }
        };
        let (before, after) = smoothed_samples(sample, 1.0);
        let d = max_difference(&before, &after);
        assert!(before == after, "shared across the curve by {d}");
    }

    /// Nothing is shared beyond the radius: with a radius just under the pixels' spacing
    /// on the plane (0.056) each pixel keeps its own gather.
    #[test]
    fn a_radius_under_a_pixel_shares_nothing() {
        let g = |x: u32, y: u32, _| Rgb::splat(((x * 7 + y * 13) % 5) as f32);
        let (before, after) = smoothed(g, |_| Rgb::ONE, 0.05);
        assert_eq!(before, after);
    }

    /// The memory estimate (`run/budget.rs`, `smoothing_bytes`) counts a pixel's record at
    /// 60 bytes and its surface at 56.
    #[test]
    fn records_are_no_larger_than_the_memory_estimate_counts() {
        assert!(std::mem::size_of::<GatherPixel>() <= 60);
        assert!(std::mem::size_of::<Option<Surface>>() <= 56);
        assert!(std::mem::size_of::<(Vec3, f32)>() <= 16);
    }
}

//! The film: a linear RGB image filled tile by tile in parallel, with the box pixel filter.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::render::camera::Camera;
use crate::render::control::{Cancelled, Control, Phase};
use crate::render::geometry::Ray;
use crate::render::integrator::{GatherPixel, Samples, Scratch, Shader};
use crate::render::math::Rgb;
use crate::render::sampling::{Sampler, Stream};

/// A linear-radiance image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Mean of each channel over a rectangle [x0, x1) x [y0, y1), in f64.
    pub fn mean_rgb(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> [f64; 3] {
        let mut sum = [0.0f64; 3];
        for y in y0..y1 {
            for x in x0..x1 {
                let p = self.get(x, y);
                for c in 0..3 {
                    sum[c] += p[c] as f64;
                }
            }
        }
        let n = ((x1 - x0) * (y1 - y0)).max(1) as f64;
        sum.map(|s| s / n)
    }
}

const TILE: u32 = 16;

/// What the camera pass asks of an integrator: the radiance a camera ray brings to pixel
/// `pixel` (its index, row-major), with a per-thread scratch.
pub(crate) trait CameraPaths: Sync {
    type Scratch: Default + Send;
    /// What a pixel keeps of its samples besides their mean radiance (`()` for most).
    type Extra: Default + Send;

    /// The radiance camera `ray` brings to the pixel at index `pixel`, column and row `xy`.
    fn radiance(
        &self,
        ray: &Ray,
        pixel: u64,
        xy: [u32; 2],
        s: &mut Sampler,
        scratch: &mut Self::Scratch,
    ) -> Rgb;

    /// Sample `j`'s random numbers at `pixel`, which is at column and row `xy`.
    fn sampler(&self, pixel: u64, xy: [u32; 2], j: u32) -> Sampler;

    /// Whether the film keeps each pixel's [`CameraPaths::Extra`]: if not, none is made.
    fn keeps_extra(&self) -> bool {
        false
    }

    /// Fold into `extra` what a sample of radiance `l` left in `scratch` (called only where
    /// [`CameraPaths::keeps_extra`], after every sample, finite or not).
    fn add_extra(&self, _extra: &mut Self::Extra, _l: Rgb, _scratch: &mut Self::Scratch) {}
}

impl CameraPaths for Shader<'_> {
    type Scratch = Scratch;
    type Extra = GatherPixel;

    /// Point `first + j` of the pixel's own scrambled Sobol sequence (`render/qmc`,
    /// [`crate::render::integrator::Samples`]): a pixel's samples, over all the passes of a
    /// progressive render, are stratified in their jitter, their light samples and, through
    /// [`Sampler::branch`], in their final gathers' directions together (measured:
    /// docs/performance-history.md, "quasi-random samples for the camera pass"); the
    /// gathers' directions are also interleaved between the pixels of a tile
    /// ([`crate::render::qmc::SobolStream::interleaved`]).
    #[inline]
    fn sampler(&self, pixel: u64, xy: [u32; 2], j: u32) -> Sampler {
        let Samples { seed, first } = self.samples;
        let n = first + j as u64;
        // Only gathers draw interleaved branches (shadow rays' branches are the pixel's
        // own): without them the tile's seed would go unused.
        match self.gather_rays {
            0 => Sampler::sobol(seed, Stream::Camera, pixel, n),
            _ => Sampler::sobol_interleaved(seed, Stream::Camera, pixel, xy, n),
        }
    }

    #[inline]
    fn radiance(&self, ray: &Ray, _: u64, xy: [u32; 2], s: &mut Sampler, sc: &mut Scratch) -> Rgb {
        self.camera_sample(ray, xy, s, sc)
    }

    fn keeps_extra(&self) -> bool {
        self.record_gathers
    }

    #[inline]
    fn add_extra(&self, extra: &mut GatherPixel, l: Rgb, scratch: &mut Scratch) {
        extra.add(l.is_finite(), scratch.gather.take());
    }
}

/// The result of the camera pass.
pub struct FilmOutput<E = ()> {
    pub image: Image,
    /// Samples dropped because they were NaN or infinite.
    pub nonfinite_samples: u64,
    /// Each pixel's [`CameraPaths::Extra`], row-major; empty unless the paths keep them.
    pub extra: Vec<E>,
}

/// A pixel's samples so far: the sum of the finite ones and how many were not finite. Those
/// are dropped (and reported as `nonfinite_samples`) rather than poisoning the pixel. No
/// finite sample leaves the pixel black.
#[derive(Default)]
struct PixelSum {
    sum: Rgb,
    good: u32,
    bad: u32,
}

impl PixelSum {
    #[inline]
    fn add(&mut self, l: Rgb) {
        if l.is_finite() {
            self.sum += l;
            self.good += 1;
        } else {
            self.bad += 1;
        }
    }

    fn mean(&self) -> Rgb {
        if self.good > 0 {
            self.sum / self.good as f32
        } else {
            Rgb::ZERO
        }
    }
}

/// Render every pixel with `spp` jittered samples. Sample j of pixel i draws its random
/// numbers from `paths.sampler(i, [x, y], j)` alone, so the image is bit-identical whatever the
/// number of threads.
///
/// The cancel flag is read after every sample: a tile of 4096 samples a pixel with 512
/// gather rays each takes minutes, and cancel must stop a render within a second whatever
/// its parameters. (The shader also reads it within a sample's final gather; a sample cut
/// short there is caught by the check after it, so no cut sample reaches an image.) The
/// check is one relaxed atomic load; a sample is at least a camera ray. Progress is counted
/// in pixels, a report a tile row.
pub(crate) fn render_film<P: CameraPaths>(
    paths: &P,
    camera: &Camera,
    spp: u32,
    control: &Control,
) -> Result<FilmOutput<P::Extra>, Cancelled> {
    render_film_rows(paths, camera, 0..camera.height, spp, control)
}

/// [`render_film`] of image rows `rows` alone: the output is that band (`rows.len()` rows),
/// each pixel the bits it has in the whole image.
pub(crate) fn render_film_rows<P: CameraPaths>(
    paths: &P,
    camera: &Camera,
    rows: std::ops::Range<u32>,
    spp: u32,
    control: &Control,
) -> Result<FilmOutput<P::Extra>, Cancelled> {
    let (w, y_start) = (camera.width, rows.start);
    let h = rows.end.min(camera.height).saturating_sub(y_start);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let n_tiles = tiles_x * tiles_y;
    let tracker = control.tracker(Phase::Render, w as u64 * h as u64);
    let dropped = AtomicU64::new(0);
    let keep = paths.keeps_extra();
    let tiles: Vec<Tile<P::Extra>> = (0..n_tiles)
        .into_par_iter()
        .map_init(P::Scratch::default, |scratch, t| {
            control.check()?;
            let (tx, ty) = (t % tiles_x, t / tiles_x);
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let tw = (x1 - x0) as usize;
            let mut out = vec![[0.0f32; 3]; tw * (y1 - y0) as usize];
            let mut extras = Vec::new();
            if keep {
                extras.resize_with(out.len(), P::Extra::default);
            }
            let mut bad = 0;
            for y in y0..y1 {
                // Rows alternate direction (a serpentine), so that each pixel follows a
                // neighbour: the density lookups start from the last answer.
                let forward = (y - y0) % 2 == 0;
                for i in 0..x1 - x0 {
                    let x = if forward { x0 + i } else { x1 - 1 - i };
                    let pixel = (y_start + y) as u64 * w as u64 + x as u64;
                    let mut px = PixelSum::default();
                    let at = (y - y0) as usize * tw + (x - x0) as usize;
                    for j in 0..spp {
                        let mut s = paths.sampler(pixel, [x, y_start + y], j);
                        let jitter = s.next_2d();
                        let y_image = (y_start + y) as f32;
                        let ray = camera.ray(x as f32 + jitter.x, y_image + jitter.y);
                        let xy = [x, y_start + y];
                        let l = paths.radiance(&ray, pixel, xy, &mut s, scratch);
                        control.check()?;
                        px.add(l);
                        if keep {
                            paths.add_extra(&mut extras[at], l, scratch);
                        }
                    }
                    bad += px.bad as u64;
                    out[at] = px.mean().to_array();
                }
                tracker.advance(tw as u64);
            }
            if bad > 0 {
                dropped.fetch_add(bad, Ordering::Relaxed);
            }
            Ok((out, extras))
        })
        .collect::<Result<_, Cancelled>>()?;
    let (image, extra) = join_tiles(tiles, w, h, keep);
    Ok(FilmOutput {
        image,
        nonfinite_samples: dropped.into_inner(),
        extra,
    })
}

/// A tile's pixels, row-major, and their extras (none unless kept).
type Tile<E> = (Vec<[f32; 3]>, Vec<E>);

/// The tiles of a `w` x `h` film (in tile order, [`TILE`] pixels square) as one image, and
/// their pixels' extras as one row-major list where `keep` (else none).
fn join_tiles<E: Default>(tiles: Vec<Tile<E>>, w: u32, h: u32, keep: bool) -> (Image, Vec<E>) {
    let tiles_x = w.div_ceil(TILE);
    let mut image = Image::new(w, h);
    let mut extra = Vec::new();
    if keep {
        extra.resize_with(image.pixels.len(), E::default);
    }
    for (t, (tile, extras)) in tiles.into_iter().enumerate() {
        let t = t as u32;
        let (x0, y0) = ((t % tiles_x) * TILE, (t / tiles_x) * TILE);
        let x1 = (x0 + TILE).min(w);
        let tw = (x1 - x0) as usize;
        let at = |i: usize| {
            let (dx, dy) = ((i % tw) as u32, (i / tw) as u32);
            (y0 + dy) as usize * w as usize + (x0 + dx) as usize
        };
        for (i, px) in tile.into_iter().enumerate() {
            image.pixels[at(i)] = px;
        }
        for (i, e) in extras.into_iter().enumerate() {
            extra[at(i)] = e;
        }
    }
    (image, extra)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mean_of(samples: &[Rgb]) -> (Rgb, u32) {
        let mut px = PixelSum::default();
        samples.iter().for_each(|&l| px.add(l));
        (px.mean(), px.bad)
    }

    #[test]
    fn non_finite_samples_are_dropped_and_counted() {
        let nan = Rgb::new(f32::NAN, 0.0, 0.0);
        let inf = Rgb::new(0.0, f32::INFINITY, 0.0);
        let (m, bad) = mean_of(&[Rgb::ONE, nan, Rgb::splat(3.0), inf]);
        assert_eq!((m, bad), (Rgb::splat(2.0), 2));
        let (m, bad) = mean_of(&[nan, nan]);
        assert_eq!((m, bad), (Rgb::ZERO, 2));
    }
}

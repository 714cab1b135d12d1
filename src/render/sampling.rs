//! Random numbers and the warps from the unit square to directions.
//!
//! Determinism: every random stream is a pure function of (seed, purpose, index), e.g.
//! (seed, camera, pixel * spp + sample) or (seed, global photons, photon index), so an image
//! never depends on how work was split between threads (pbrt-v4 section 8.3).

use std::f32::consts::{FRAC_1_PI, TAU};

use glam::{Vec2, Vec3A};

use crate::render::math::sin_cos_turns;
use crate::render::qmc::{Branch, SobolStream};
use rand::Rng;
use rand_pcg::Pcg64Mcg;

/// What a random stream is used for; part of its seed so that streams never overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    Camera = 1,
    GlobalPhotons = 2,
    CausticPhotons = 3,
    /// Light subpaths of the bidirectional integrators.
    LightPaths = 4,
}

/// A path's random numbers: independent ones from a small, fast generator (PCG 128-bit
/// MCG, O'Neill 2014) seeded from a hash of (seed, stream, index), or, for the progressive
/// path integrators, the next point of the path's own scrambled Sobol sequence
/// ([`crate::render::qmc`]).
pub struct Sampler {
    source: Source,
}

enum Source {
    Independent(Pcg64Mcg),
    Sobol(SobolStream),
}

impl Sampler {
    pub fn new(seed: u64, stream: Stream, index: u64) -> Sampler {
        let a = splitmix64(seed ^ splitmix64(stream as u64));
        let b = splitmix64(a ^ splitmix64(index.wrapping_add(0x9e37_79b9)));
        let state = ((a as u128) << 64) | b as u128;
        Sampler {
            source: Source::Independent(Pcg64Mcg::new(state)),
        }
    }

    /// Path `index` of `stream` at iteration `n` (0-based) of a progressive render: the
    /// n-th point of the path's own scrambled Sobol sequence.
    pub fn sobol(seed: u64, stream: Stream, index: u64, n: u64) -> Sampler {
        Sampler {
            source: Source::Sobol(SobolStream::new(seed, stream, index, n)),
        }
    }

    /// [`Sampler::sobol`] for the pixel at `xy`, interleaved between the pixels of its
    /// tile ([`SobolStream::interleaved`]).
    pub fn sobol_interleaved(
        seed: u64,
        stream: Stream,
        pixel: u64,
        xy: [u32; 2],
        n: u64,
    ) -> Sampler {
        Sampler {
            source: Source::Sobol(SobolStream::interleaved(seed, stream, pixel, xy, n)),
        }
    }

    /// Branch `k` of `count` of `kind` from this sample (the rays of a final gather, the
    /// shadow rays to an area light): for a Sobol stream, a stream such that the branches
    /// of all of a pixel's samples are one stratified sequence ([`SobolStream::branch`]);
    /// for independent numbers, a stream seeded from this one's next number.
    pub fn branch(&mut self, kind: Branch, k: u32, count: u32) -> Sampler {
        let source = match &mut self.source {
            Source::Independent(rng) => {
                let state = ((rng.random::<u64>() as u128) << 64) | splitmix64(k as u64) as u128;
                Source::Independent(Pcg64Mcg::new(state))
            }
            Source::Sobol(q) => Source::Sobol(q.branch(kind, k, count)),
        };
        Sampler { source }
    }

    /// A placeholder for a lane without work, never drawn from.
    pub fn idle() -> Sampler {
        Sampler {
            source: Source::Independent(Pcg64Mcg::new(1)),
        }
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        match &mut self.source {
            Source::Independent(rng) => rng.random::<f32>(),
            Source::Sobol(q) => q.next_f32(),
        }
    }

    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        match &mut self.source {
            Source::Independent(rng) => Vec2::new(rng.random::<f32>(), rng.random::<f32>()),
            Source::Sobol(q) => Vec2::from_array(q.next_2d()),
        }
    }
}

/// SplitMix64 finaliser (Steele et al. 2014): a bijective 64-bit mixer.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The vector at distance `r` from the z axis, azimuth 2 pi `u_phi`, height `z`: where every
/// warp below puts its sample once it has drawn the distance and height.
#[inline]
fn around_z(r: f32, u_phi: f32, z: f32) -> Vec3A {
    let (sin_phi, cos_phi) = sin_cos_turns(u_phi);
    Vec3A::new(r * cos_phi, r * sin_phi, z)
}

/// Uniform direction on the unit sphere; pdf 1/(4 pi).
#[inline]
pub fn uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    around_z(r, u.y, z)
}

/// Cosine-weighted direction in the local hemisphere around +z (Malley's method);
/// pdf cos(theta)/pi. The disk point comes from the polar map (r = sqrt(u.x), phi = 2 pi
/// u.y), not Shirley and Chiu's concentric one: it has no branch and no division, and for
/// independent samples the two are equivalent (measured: docs/performance-history.md,
/// "polar map for cosine sampling"). Both preserve area, so the stratified points of the
/// bidirectional family (`render/qmc`) stay stratified on the disk, in strata of poorer shape
/// near its centre (Shirley and Chiu 1997); untested against the concentric map there.
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3A {
    let r = u.x.sqrt();
    around_z(r, u.y, (1.0 - u.x).max(0.0).sqrt())
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction in the cone around +z with half-angle acos(cos_max);
/// pdf 1 / (2 pi (1 - cos_max)). `one_minus_cos_max` is passed separately to keep its
/// precision for very small cones (a distant small sphere light).
#[inline]
pub fn uniform_cone(u: Vec2, one_minus_cos_max: f32) -> Vec3A {
    let one_minus_cos = u.x * one_minus_cos_max;
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    around_z(sin_theta, u.y, cos_theta)
}

/// Direction around +z distributed as cos^exponent (the modified-Phong lobe, Lafortune and
/// Willems 1994); pdf (exponent + 1)/(2 pi) cos^exponent.
#[inline]
pub fn power_cosine(u: Vec2, exponent: f32) -> Vec3A {
    let cos_theta = u.x.powf(1.0 / (exponent + 1.0));
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    around_z(sin_theta, u.y, cos_theta)
}

#[inline]
pub fn power_cosine_pdf(cos_theta: f32, exponent: f32) -> f32 {
    if cos_theta <= 0.0 {
        0.0
    } else {
        (exponent + 1.0) / TAU * cos_theta.powf(exponent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let mut a = Sampler::new(7, Stream::Camera, 42);
        let mut b = Sampler::new(7, Stream::Camera, 42);
        let mut c = Sampler::new(7, Stream::Camera, 43);
        let mut d = Sampler::new(7, Stream::GlobalPhotons, 42);
        let xa: Vec<f32> = (0..8).map(|_| a.next_f32()).collect();
        let xb: Vec<f32> = (0..8).map(|_| b.next_f32()).collect();
        let xc: Vec<f32> = (0..8).map(|_| c.next_f32()).collect();
        let xd: Vec<f32> = (0..8).map(|_| d.next_f32()).collect();
        assert_eq!(xa, xb);
        assert_ne!(xa, xc);
        assert_ne!(xa, xd);
        assert!(xa.iter().all(|x| (0.0..1.0).contains(x)));
    }

    #[test]
    fn warps_land_where_they_should() {
        let mut s = Sampler::new(1, Stream::Camera, 0);
        for _ in 0..10_000 {
            let u = s.next_2d();
            assert!((uniform_sphere(u).length() - 1.0).abs() < 1e-5);
            let c = cosine_hemisphere(u);
            assert!(c.z >= 0.0 && (c.length() - 1.0).abs() < 1e-5);
            let k = uniform_cone(u, 0.01);
            assert!(k.z >= 0.99 - 1e-6);
            let p = power_cosine(u, 20.0);
            assert!(p.z >= 0.0 && (p.length() - 1.0).abs() < 1e-4);
        }
    }
}

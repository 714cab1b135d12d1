//! What a job may ask for and what it needs: the server's limits, and the estimates of a
//! job's memory, work and result files that are checked against them at submit.

use super::error::ApiError;
use crate::render::scene::{SceneDesc, ShapeDesc};
use crate::render::{IntegratorKind, RenderParams};

/// Server limits on what one job may ask for (flags of `photonbox serve`).
#[derive(Clone, Debug)]
pub struct Limits {
    pub body_bytes: usize,
    pub max_pixels: u64,
    pub max_photons: u64,
    pub max_k: usize,
    pub max_iterations: u32,
    pub max_triangles: usize,
    pub max_queued_per_user: usize,
    /// Memory all running renders together may use.
    pub memory_bytes: u64,
    /// Most work units ([`JobNeeds::work`]) one job may ask for.
    pub max_work: f64,
    /// Disk one user's uploaded scenes and result files may take.
    pub storage_bytes_per_user: u64,
}

impl Limits {
    pub const DEFAULT: Limits = Limits {
        body_bytes: 16 << 20,
        max_pixels: 4096 * 4096,
        max_photons: 50_000_000,
        max_k: 1000,
        max_iterations: 100_000,
        max_triangles: 2_000_000,
        max_queued_per_user: 32,
        memory_bytes: 8 << 30,
        // About 10^12 rays: days of this 2-core machine; a typical final render is 10^9.
        max_work: 1e12,
        storage_bytes_per_user: 2 << 30,
    };
}

impl Default for Limits {
    fn default() -> Limits {
        Limits::DEFAULT
    }
}

/// What a job needs, checked against the limits before it is accepted.
pub struct JobNeeds {
    pub pixels: u64,
    pub triangles: usize,
    pub memory_bytes: u64,
    /// The job's work in ray-sized units: every camera sample and final-gather ray, every
    /// emitted photon, and (for `photon`) each k-NN neighbour of the irradiance precompute,
    /// times the passes of a progressive job. An upper guide, not a prediction of seconds:
    /// it bounds what one job may take from the box, whatever its parameters.
    pub work: f64,
    /// An upper estimate of the job's result files: the EXR (f32 RGBA), the PNG, and a
    /// progressive job's state (the f64 sum image).
    pub result_bytes: u64,
}

impl JobNeeds {
    /// An upper estimate of a render's peak memory: photons while traced and in their
    /// kd-trees (a global photon path stores at most a few photons: 3 per emitted photon
    /// bounds the built-in scenes' 1.35 with room), the irradiance cache, the film, the BVH.
    pub fn estimate(desc: &SceneDesc, p: &RenderParams) -> JobNeeds {
        let width = p.width.unwrap_or(desc.camera.width) as u64;
        let height = p.height.unwrap_or(desc.camera.height) as u64;
        let pixels = width * height;
        let triangles: usize = desc
            .objects
            .iter()
            .map(|o| match &o.shape {
                ShapeDesc::Mesh(m) => m.triangles.len(),
                _ => 1,
            })
            .sum();
        let photon_bytes = 32u64;
        let (global, caustic) = match p.integrator {
            IntegratorKind::Raytrace => (0, 0),
            // ppm: one pass's maps at a time, whatever the number of passes.
            IntegratorKind::Photon | IntegratorKind::Ppm => (p.photons * 3, p.caustic_photons),
        };
        // Traced photons are gathered in per-chunk buffers, then copied into the map.
        let maps = (global + caustic) * photon_bytes * 2;
        let irradiance = global / 4 * 64;
        // The camera pass's tiles and image, the images' encodings (PNG, EXR); a progressive
        // job adds its f64 sum, a pass's image and the saved state. Measured on the largest
        // images the test limits accept (tests/server/memory.rs): 36 and 75 bytes a pixel.
        let film = pixels * 48
            + if p.integrator == IntegratorKind::Ppm {
                pixels * 48
            } else {
                0
            };
        // Measured on the largest mesh the test limits accept (tests/server/memory.rs): the
        // scene's parsed JSON and description, primitives, the BVH's build, all alive at
        // once in the submit handler and the job's start, about 900 bytes a triangle.
        let geometry = triangles as u64 * 1200;
        JobNeeds {
            pixels,
            triangles,
            memory_bytes: maps + irradiance + film + geometry + (16 << 20),
            work: Self::work(pixels, p),
            result_bytes: pixels * 20
                + if p.integrator == IntegratorKind::Ppm {
                    pixels * 24
                } else {
                    0
                }
                + (64 << 10),
        }
    }

    fn work(pixels: u64, p: &RenderParams) -> f64 {
        let camera = pixels as f64 * p.spp as f64 * (1.0 + p.gather_rays as f64);
        let photons = match p.integrator {
            IntegratorKind::Raytrace => 0.0,
            IntegratorKind::Photon | IntegratorKind::Ppm => (p.photons + p.caustic_photons) as f64,
        };
        match p.integrator {
            IntegratorKind::Ppm => (camera + photons) * p.iterations as f64,
            IntegratorKind::Photon => camera + photons + p.photons as f64 / 4.0 * p.k as f64,
            IntegratorKind::Raytrace => camera,
        }
    }

    pub fn check(&self, p: &RenderParams, limits: &Limits) -> Result<(), ApiError> {
        // (field, what the job asks, the limit, what is counted)
        let counts: [(&str, u64, u64, &str); 6] = [
            (
                "params.width",
                self.pixels,
                limits.max_pixels,
                "pixels (width*height)",
            ),
            ("params.photons", p.photons, limits.max_photons, "photons"),
            (
                "params.caustic_photons",
                p.caustic_photons,
                limits.max_photons,
                "photons",
            ),
            (
                "params.k",
                p.k as u64,
                limits.max_k as u64,
                "neighbours (k)",
            ),
            (
                "params.iterations",
                p.iterations as u64,
                limits.max_iterations as u64,
                "passes",
            ),
            (
                "scene.objects",
                self.triangles as u64,
                limits.max_triangles as u64,
                "triangles",
            ),
        ];
        for (field, n, limit, what) in counts {
            if n > limit {
                return Err(ApiError::invalid(
                    field,
                    format!("{n} {what} exceed the limit of {limit}"),
                ));
            }
        }
        if self.work > limits.max_work {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "this job is an estimated {:.3e} ray samples of work (pixels x spp x (1 + \
                     gather_rays), photons, passes), more than the server's limit of {:.3e} \
                     (fewer samples, gather rays, pixels, photons or passes would fit)",
                    self.work, limits.max_work
                ),
            ));
        }
        if self.memory_bytes > limits.memory_bytes {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "this job needs an estimated {} MiB, more than the server's memory budget of {} MiB \
                     (fewer photons or pixels would fit)",
                    self.memory_bytes >> 20,
                    limits.memory_bytes >> 20
                ),
            ));
        }
        Ok(())
    }
}

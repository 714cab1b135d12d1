//! What a job may ask for and what it needs: the server's limits, and the estimates of a
//! job's memory, work and result files that are checked against them at submit.

use super::error::ApiError;
use crate::render::Needs;
use crate::render::scene::{SceneDesc, ShapeDesc};
use crate::spec::{RenderSpec, SpecForm};

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
    /// Memory, work and result files (the engine's estimates, `render::Needs`).
    pub render: Needs,
}

impl JobNeeds {
    pub fn estimate(desc: &SceneDesc, spec: &RenderSpec) -> JobNeeds {
        let (width, height) = spec.resolution((desc.camera.width, desc.camera.height));
        let pixels = width as u64 * height as u64;
        let triangles: usize = desc
            .objects
            .iter()
            .map(|o| match &o.shape {
                ShapeDesc::Mesh(m) => m.triangles.len(),
                _ => 1,
            })
            .sum();
        JobNeeds {
            pixels,
            triangles,
            render: Needs::of(spec, pixels, triangles),
        }
    }

    pub fn check(&self, spec: &RenderSpec, limits: &Limits) -> Result<(), ApiError> {
        // The spec's fields as the API names them: no integrator is special here.
        let f = SpecForm::of(spec);
        // (field, what the job asks, the limit, what is counted)
        let counts: [(&str, Option<u64>, u64, &str); 6] = [
            (
                "params.width",
                Some(self.pixels),
                limits.max_pixels,
                "pixels (width*height)",
            ),
            ("params.photons", f.photons, limits.max_photons, "photons"),
            (
                "params.caustic_photons",
                f.caustic_photons,
                limits.max_photons,
                "photons",
            ),
            (
                "params.k",
                f.k.map(|k| k as u64),
                limits.max_k as u64,
                "neighbours (k)",
            ),
            (
                "params.iterations",
                f.iterations.map(u64::from),
                limits.max_iterations as u64,
                "passes",
            ),
            (
                "scene.objects",
                Some(self.triangles as u64),
                limits.max_triangles as u64,
                "triangles",
            ),
        ];
        for (field, n, limit, what) in counts {
            if let Some(n) = n
                && n > limit
            {
                return Err(ApiError::invalid(
                    field,
                    format!("{n} {what} exceed the limit of {limit}"),
                ));
            }
        }
        self.check_estimates(spec, limits)
    }

    /// The estimated work and memory against the server's limits.
    fn check_estimates(&self, spec: &RenderSpec, limits: &Limits) -> Result<(), ApiError> {
        let needs = &self.render;
        // Passes until a time limit is spent: the time bounds their number, and the work
        // counted is one pass's (`Needs::work`).
        let (what, fewer) = if spec.stop().is_some_and(|s| s.until_time()) {
            (
                "one pass of this job",
                "samples, gather or shadow rays, pixels or photons",
            )
        } else {
            (
                "this job",
                "samples, gather or shadow rays, pixels, photons or passes",
            )
        };
        if needs.work > limits.max_work {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "{what} is an estimated {:.3e} ray samples of work (pixels x spp x \
                     (gather_rays + shadow_rays), photons, passes), more than the server's \
                     limit of {:.3e} (fewer {fewer} would fit)",
                    needs.work, limits.max_work
                ),
            ));
        }
        if needs.memory_bytes > limits.memory_bytes {
            return Err(ApiError::invalid(
                "params",
                format!(
                    "this job needs an estimated {} MiB, more than the server's memory budget of {} MiB \
                     (fewer photons or pixels would fit)",
                    needs.memory_bytes >> 20,
                    limits.memory_bytes >> 20
                ),
            ));
        }
        Ok(())
    }
}

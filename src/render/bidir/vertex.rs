//! Subpaths and their multiple-importance-sampling quantities.
//!
//! A path of k vertices can be made by many techniques: a camera subpath of t vertices and a
//! light subpath of s, joined by a connection (or a camera path reaching a light, or a light
//! vertex seen by the camera), or merged at a vertex both share. The balance heuristic
//! weights each by its density over the sum of all of theirs. Evaluating that sum afresh is
//! quadratic in k; Georgiev et al. ("Implementing Vertex Connection and Merging", technical
//! report 2012, eqs. 31-36) carry three running quantities along each subpath instead,
//! dVCM, dVC and dVM, updated at every hit and every scattering, from which the weight of
//! any technique is a few products (`weights.rs`). The equations cited are that report's.

use glam::Vec3A;

use crate::render::geometry::{Ray, SurfacePoint, spawn_ray};
use crate::render::material::{Material, Transport};
use crate::render::math::{Rgb, max_component};
use crate::render::photon::KdItem;
use crate::render::sampling::Sampler;

/// The running MIS quantities of a subpath (all 0 where a technique is not used).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Mis {
    pub d_vcm: f32,
    pub d_vc: f32,
    pub d_vm: f32,
}

/// What one iteration's weights share: how many light subpaths there are and how merging
/// compares with connecting at this radius (eq. 20 with n_VC = 1, n_VM = the light paths).
#[derive(Clone, Copy, Debug)]
pub(super) struct Factors {
    /// Light subpaths (and camera samples) in the iteration.
    pub light_paths: f32,
    /// eta_VCM = pi r^2 n_VM when merging (its technique's weight relative to a
    /// connection's), else 0.
    pub vm: f32,
    /// 1 / eta_VCM when connecting, else 0.
    pub vc: f32,
    /// 1 / (pi r^2 n_VM): the merge estimate's normalisation.
    pub vm_normalization: f32,
    /// Tests only: a factor on every weight of one kind of technique, to see the checks of
    /// the weights fail when one is wrong (`tests.rs`).
    #[cfg(test)]
    pub broken: Option<(super::tests::Broken, f32)>,
}

impl Factors {
    pub fn new(light_paths: u64, radius2: f32, connect: bool, merge: bool) -> Factors {
        let n = light_paths as f32;
        let eta = std::f32::consts::PI * radius2 * n;
        Factors {
            light_paths: n,
            vm: if merge { eta } else { 0.0 },
            vc: if connect && eta > 0.0 { 1.0 / eta } else { 0.0 },
            vm_normalization: if merge { 1.0 / eta } else { 0.0 },
            #[cfg(test)]
            broken: None,
        }
    }
}

/// A subpath being traced.
pub(super) struct Walk {
    pub ray: Ray,
    pub throughput: Rgb,
    /// Surface vertices so far, the one the ray is about to reach included once it hits.
    pub len: u32,
    pub mis: Mis,
    /// Every scattering so far was specular (a camera path: what it sees of a light,
    /// light tracing cannot).
    pub specular: bool,
    /// Non-specular scatterings so far.
    pub non_specular: u32,
    /// The first non-specular vertex's `len` (0: none yet): where a camera path's effect is
    /// decided (`effects.rs`).
    pub first_non_specular: u32,
    pub roulette: Roulette,
}

/// How a subpath plays Russian roulette.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Roulette {
    /// By the material's largest reflectance alone ([`Material::continuation`], as SmallVCM
    /// does): a constant of the vertex, so the density of the reverse direction is known,
    /// which connections and merging weigh.
    Local,
    /// `pt` only, whose two techniques weigh only the density at the vertex itself (so the
    /// probability may depend on the path): none at the first [`Roulette::FREE`] vertices,
    /// then by the path's throughput times the material's reflectance, so that bright paths
    /// go on and dim ones end (Mitsuba 3 and pbrt-v4 play it on the throughput after a few
    /// bounces too). At equal time, 10-20% less relmse than `Local` on the built-in diffuse
    /// scenes (docs/performance-history.md, "Russian roulette for pt").
    Throughput,
}

impl Roulette {
    /// Vertices with no roulette under [`Roulette::Throughput`] (4 bounces).
    pub const FREE: u32 = 5;
}

impl Walk {
    /// A subpath leaving its origin along `ray`.
    pub fn start(ray: Ray, throughput: Rgb, mis: Mis) -> Walk {
        Walk {
            ray,
            throughput,
            len: 0,
            mis,
            specular: true,
            non_specular: 0,
            first_non_specular: 0,
            roulette: Roulette::Local,
        }
    }

    /// The probability that the walk goes on after scattering at a vertex of material `m`
    /// (this vertex's `len` and throughput so far).
    pub fn survival(&self, m: &Material) -> f32 {
        let local = m.continuation();
        match self.roulette {
            Roulette::Local => local,
            Roulette::Throughput if self.len < Roulette::FREE => {
                if local > 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Roulette::Throughput => (max_component(self.throughput) * local).min(1.0),
        }
    }

    /// At the surface the ray reached, `dist` away with cosine `cos` to its normal: the
    /// quantities gain the segment's geometry (eqs. 31-33 completed, or 34-36).
    pub fn arrive(&mut self, dist: f32, cos: f32) {
        let cos = cos.abs();
        self.mis.d_vcm *= dist * dist;
        self.mis.d_vcm /= cos;
        self.mis.d_vc /= cos;
        self.mis.d_vm /= cos;
        self.len += 1;
    }

    /// Scattered into a direction sampled with (solid-angle) density `pdf` (its reverse
    /// `rev_pdf`), cosine `cos_out`, throughput factor `weight` (f cos / pdf) and survival
    /// probability `survive`: eqs. 34-36 (non-specular) or 53-55 (specular), partially; the
    /// hit completes them ([`Walk::arrive`]).
    pub fn scatter(&mut self, sample: Scattered, f: &Factors) {
        let Scattered {
            weight,
            pdf,
            rev_pdf,
            cos_out,
            specular,
            survive,
        } = sample;
        let m = &mut self.mis;
        if specular {
            m.d_vcm = 0.0;
            m.d_vc *= cos_out;
            m.d_vm *= cos_out;
        } else {
            let (pdf, rev_pdf) = (pdf * survive, rev_pdf * survive);
            m.d_vc = cos_out / pdf * (m.d_vc * rev_pdf + m.d_vcm + f.vm);
            m.d_vm = cos_out / pdf * (m.d_vm * rev_pdf + m.d_vcm * f.vc + 1.0);
            m.d_vcm = 1.0 / pdf;
        }
        self.specular &= specular;
        self.non_specular += !specular as u32;
        self.throughput *= weight / survive;
    }
}

impl Walk {
    /// Sample a scattering at `hit` (where the path arrived from direction `wo`), survive
    /// Russian roulette with probability `survive` (the caller's [`Walk::survival`], the
    /// one its techniques at this vertex weighed), and go on: false when the path ends.
    pub fn scatter_at(
        &mut self,
        (m, survive): (&Material, f32),
        hit: &SurfacePoint,
        wo: Vec3A,
        (s, mode): (&mut Sampler, Transport),
        f: &Factors,
    ) -> bool {
        let n = hit.n;
        let Some(b) = m.sample(wo, n, s.next_f32(), s.next_2d(), mode) else {
            return false;
        };
        if !(survive > 0.0) || s.next_f32() >= survive {
            return false;
        }
        let (pdf, rev_pdf) = if b.specular {
            (1.0, 1.0)
        } else {
            (b.pdf, m.pdf(b.wi, wo, n))
        };
        let scattered = Scattered {
            weight: b.weight,
            pdf,
            rev_pdf,
            cos_out: b.wi.dot(n).abs(),
            specular: b.specular,
            survive,
        };
        self.scatter(scattered, f);
        self.ray = spawn_ray(hit, b.wi);
        true
    }
}

/// A scattering sampled at a vertex.
pub(super) struct Scattered {
    pub weight: Rgb,
    pub pdf: f32,
    pub rev_pdf: f32,
    pub cos_out: f32,
    pub specular: bool,
    pub survive: f32,
}

/// A non-specular vertex of a light subpath, kept for connections and merging.
#[derive(Clone, Copy, Debug)]
pub(super) struct LightVertex {
    pub sp: SurfacePoint,
    /// Toward the previous vertex: where the light arrived from.
    pub wo: Vec3A,
    pub throughput: Rgb,
    pub material: u32,
    /// Surface vertices from the light to this one (1: the first hit).
    pub len: u32,
    /// A vertex before this one scattered non-specularly (else the light reached it
    /// through specular surfaces only, or directly).
    pub non_specular_before: bool,
    pub mis: Mis,
}

impl KdItem for LightVertex {
    #[inline]
    fn position(&self) -> Vec3A {
        self.sp.p
    }
}

impl Material {
    /// The probability that a subpath goes on after scattering here (Russian roulette by
    /// the material's largest reflectance, as SmallVCM does): a constant of the material,
    /// so that the density of the reverse direction is known too.
    pub(super) fn continuation(&self) -> f32 {
        let r = match *self {
            Material::Diffuse { albedo } => max_component(albedo),
            Material::Mirror { reflectance } => max_component(reflectance),
            Material::Dielectric { .. } => 1.0,
            Material::Phong {
                diffuse, specular, ..
            } => max_component(diffuse + specular),
        };
        r.clamp(0.0, 1.0)
    }
}

//! The balance-heuristic weight of each technique, from the running quantities of the two
//! subpaths it joins (Georgiev et al. 2012, technical report, eqs. 37-47). Each integrator
//! of the family counts only its own techniques in the sum:
//!
//! - `pt`: a camera path reaching a light, and next-event estimation (the two-technique
//!   balance heuristic of Veach 1997, section 9.2);
//! - `lt`: light vertices seen by the camera, and the camera's specular chains seeing a light
//!   (disjoint sets of paths: weight 1 each);
//! - `bdpt`: every connection; `vcm`: every connection and merging.

use super::Modes;
use super::vertex::{Factors, LightVertex, Mis};

/// A technique about to contribute, with the densities its weight needs. Densities include
/// the light-selection probability and the survival probability where they apply.
pub(super) enum Technique<'a> {
    /// A camera path reaching a light by scattering (eqs. 42-43). `direct_pdf_area`: how
    /// next-event estimation from the previous vertex would have picked the point;
    /// `emission_pdf`: how a light subpath would have left it toward that vertex.
    Hit {
        camera: &'a Mis,
        len: u32,
        specular: bool,
        direct_pdf_area: f32,
        emission_pdf: f32,
    },
    /// Next-event estimation (eqs. 44-45): `bsdf_pdf` the density of scattering toward the
    /// light (0 for a point light), `direct_pdf` of sampling that direction (solid angle),
    /// `emission_pdf` of the light emitting back, the cosines at both ends.
    Nee {
        camera: &'a Mis,
        bsdf_pdf: f32,
        bsdf_rev_pdf: f32,
        direct_pdf: f32,
        emission_pdf: f32,
        cos_camera: f32,
        cos_light: f32,
    },
    /// A camera vertex joined to a light vertex (eqs. 40-41), densities in area measure at
    /// the far end.
    Connect {
        camera: &'a Mis,
        light: &'a LightVertex,
        camera_pdf_area: f32,
        camera_rev_pdf: f32,
        light_pdf_area: f32,
        light_rev_pdf: f32,
    },
    /// A light vertex seen by the camera (eq. 46): `camera_pdf_area` of a camera sample
    /// landing there.
    LightTrace {
        vertex: &'a LightVertex,
        camera_pdf_area: f32,
        rev_pdf: f32,
    },
    /// A light vertex merged at a camera vertex (eqs. 38-39).
    Merge {
        camera: &'a Mis,
        light: &'a LightVertex,
        camera_pdf: f32,
        camera_rev_pdf: f32,
    },
}

/// The weight of technique `t` under `modes`' techniques.
pub(super) fn weight(modes: Modes, f: &Factors, t: Technique) -> f32 {
    #[cfg(test)]
    if let Some((kind, scale)) = f.broken
        && kind.is(&t)
    {
        return scale * unbroken(modes, f, t);
    }
    unbroken(modes, f, t)
}

fn unbroken(modes: Modes, f: &Factors, t: Technique) -> f32 {
    let bidir = matches!(modes, Modes::Bdpt | Modes::Vcm);
    let w = match t {
        Technique::Hit { len: 1, .. } => return 1.0,
        Technique::Hit { specular, .. } if modes == Modes::Lt => return specular as u8 as f32,
        Technique::Hit {
            camera,
            direct_pdf_area,
            emission_pdf,
            ..
        } => {
            let later = if bidir {
                emission_pdf * camera.d_vc
            } else {
                0.0
            };
            direct_pdf_area * camera.d_vcm + later
        }
        Technique::Nee {
            camera,
            bsdf_pdf,
            bsdf_rev_pdf,
            direct_pdf,
            emission_pdf,
            cos_camera,
            cos_light,
        } => {
            let by_hit = bsdf_pdf / direct_pdf;
            let by_light_paths = if bidir {
                emission_pdf * cos_camera / (direct_pdf * cos_light)
                    * (f.vm + camera.d_vcm + camera.d_vc * bsdf_rev_pdf)
            } else {
                0.0
            };
            by_hit + by_light_paths
        }
        Technique::Connect {
            camera,
            light,
            camera_pdf_area,
            camera_rev_pdf,
            light_pdf_area,
            light_rev_pdf,
        } => {
            let l = &light.mis;
            camera_pdf_area * (f.vm + l.d_vcm + l.d_vc * light_rev_pdf)
                + light_pdf_area * (f.vm + camera.d_vcm + camera.d_vc * camera_rev_pdf)
        }
        Technique::LightTrace { .. } if modes == Modes::Lt => return 1.0,
        Technique::LightTrace {
            vertex,
            camera_pdf_area,
            rev_pdf,
        } => {
            let l = &vertex.mis;
            camera_pdf_area / f.light_paths * (f.vm + l.d_vcm + l.d_vc * rev_pdf)
        }
        Technique::Merge {
            camera,
            light,
            camera_pdf,
            camera_rev_pdf,
        } => {
            let l = &light.mis;
            l.d_vcm * f.vc
                + l.d_vm * camera_pdf
                + camera.d_vcm * f.vc
                + camera.d_vm * camera_rev_pdf
        }
    };
    1.0 / (1.0 + w)
}

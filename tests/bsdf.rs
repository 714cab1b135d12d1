//! BSDFs: white-furnace energy checks and sampling against the pdf (issue 2, acceptance 1d).

use std::f64::consts::PI;

use glam::{Vec2, Vec3A};
use photonbox::render::material::{Material, Transport, fresnel_dielectric};
use photonbox::render::math::{Frame, Rgb, reflect};
use photonbox::render::sampling::{Sampler, Stream};

const N: Vec3A = Vec3A::Z;

fn wo_at(theta_deg: f32) -> Vec3A {
    let t = theta_deg.to_radians();
    Vec3A::new(t.sin(), 0.0, t.cos())
}

/// Integrate g(wi) over the sphere by the midpoint rule in a frame around `axis`, dense near
/// the axis (where a glossy lobe is).
fn integrate_sphere(axis: Vec3A, g: impl Fn(Vec3A) -> f64) -> f64 {
    let frame = Frame::from_normal(axis);
    let (nt, np) = (3000, 360);
    let mut sum = 0.0;
    for i in 0..nt {
        // theta = pi * u^2 concentrates samples near the axis; dtheta = 2 pi u du.
        let u = (i as f64 + 0.5) / nt as f64;
        let theta = PI * u * u;
        let dtheta = 2.0 * PI * u / nt as f64;
        for j in 0..np {
            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let local = Vec3A::new(
                (theta.sin() * phi.cos()) as f32,
                (theta.sin() * phi.sin()) as f32,
                theta.cos() as f32,
            );
            sum += g(frame.to_world(local)) * theta.sin() * dtheta * (2.0 * PI / np as f64);
        }
    }
    sum
}

/// Directional albedo by quadrature: integral of f(wo, wi) cos(theta_i).
fn albedo_quadrature(m: &Material, wo: Vec3A) -> f64 {
    let axis = reflect(wo, N);
    integrate_sphere(axis, |wi| (m.eval(wo, wi, N).x * wi.dot(N).max(0.0)) as f64)
}

/// Directional albedo by importance sampling: the mean sample weight (no sample = 0).
fn albedo_sampled(m: &Material, wo: Vec3A, n: usize) -> f64 {
    let mut s = Sampler::new(11, Stream::Camera, 0);
    let mut sum = 0.0;
    for _ in 0..n {
        if let Some(bs) = m.sample(wo, N, s.next_f32(), s.next_2d(), Transport::Radiance) {
            sum += bs.weight.x as f64;
        }
    }
    sum / n as f64
}

#[test]
fn lambertian_white_furnace() {
    let m = Material::Diffuse {
        albedo: Rgb::splat(0.8),
    };
    for theta in [0.0, 30.0, 60.0, 85.0] {
        let q = albedo_quadrature(&m, wo_at(theta));
        let s = albedo_sampled(&m, wo_at(theta), 10_000);
        assert!(
            (q - 0.8).abs() < 0.002,
            "quadrature albedo {q} at {theta} deg"
        );
        assert!((s - 0.8).abs() < 1e-5, "sampled albedo {s} at {theta} deg");
    }
}

#[test]
fn phong_never_exceeds_one_and_sampling_matches_quadrature() {
    for (kd, ks) in [(0.0, 1.0), (0.5, 0.5), (0.8, 0.2)] {
        for e in [0.0f32, 1.0, 10.0, 100.0, 1000.0] {
            let m = Material::Phong {
                diffuse: Rgb::splat(kd),
                specular: Rgb::splat(ks),
                exponent: e,
            };
            for theta in [0.0, 45.0, 80.0] {
                let wo = wo_at(theta);
                let q = albedo_quadrature(&m, wo);
                let s = albedo_sampled(&m, wo, 200_000);
                assert!(
                    q <= 1.0 + 1e-3,
                    "kd {kd} ks {ks} e {e} theta {theta}: albedo {q} > 1"
                );
                assert!(
                    (s - q).abs() < 0.01,
                    "kd {kd} ks {ks} e {e} theta {theta}: sampled {s} vs quadrature {q}"
                );
            }
        }
    }
}

#[test]
fn mirror_reflects_its_reflectance() {
    let m = Material::Mirror {
        reflectance: Rgb::new(0.9, 0.5, 0.1),
    };
    for theta in [0.0, 40.0, 89.0] {
        let wo = wo_at(theta);
        let bs = m
            .sample(wo, N, 0.3, Vec2::new(0.2, 0.7), Transport::Radiance)
            .unwrap();
        assert!(bs.specular);
        assert!((bs.wi - reflect(wo, N)).length() < 1e-6);
        assert_eq!(bs.weight, Rgb::new(0.9, 0.5, 0.1));
        // Two-sided: from below it reflects about -n.
        let bs = m
            .sample(-wo, N, 0.3, Vec2::ZERO, Transport::Radiance)
            .unwrap();
        assert!(bs.wi.z < 0.0);
    }
}

#[test]
fn glass_conserves_energy_from_both_sides() {
    let m = Material::Dielectric { ior: 1.5 };
    for theta in [0.0f32, 20.0, 41.0, 42.0, 60.0, 89.0] {
        for (wo, eta) in [(wo_at(theta), 1.5f32), (-wo_at(theta), 1.0 / 1.5)] {
            let b = m.specular_branches(wo, N, Transport::Importance);
            let r = b.reflection.map_or(0.0, |x| x.weight.x);
            let t = b.transmission.map_or(0.0, |x| x.weight.x);
            assert!(
                (r + t - 1.0).abs() < 1e-5,
                "theta {theta} eta {eta}: R {r} + T {t}"
            );
            assert!((r - fresnel_dielectric(theta.to_radians().cos(), eta)).abs() < 1e-5);
            // Radiance is scaled by 1/eta^2 on refraction (Veach 1997, 5.2).
            let br = m.specular_branches(wo, N, Transport::Radiance);
            let tr = br.transmission.map_or(0.0, |x| x.weight.x);
            assert!((tr - t / (eta * eta)).abs() < 1e-5);
            if let Some(tb) = b.transmission {
                // Snell: n_i sin_i = n_t sin_t.
                let sin_t = (1.0 - tb.wi.z * tb.wi.z).sqrt();
                assert!((sin_t * eta - theta.to_radians().sin()).abs() < 1e-4);
            }
        }
    }
    // Beyond the critical angle from inside: total internal reflection.
    let b = m.specular_branches(-wo_at(60.0), N, Transport::Importance);
    assert!(b.transmission.is_none());
    assert_eq!(b.reflection.unwrap().weight.x, 1.0);
    // Index 1: the interface vanishes.
    let b =
        Material::Dielectric { ior: 1.0 }.specular_branches(wo_at(70.0), N, Transport::Radiance);
    assert!(b.reflection.is_none());
    let t = b.transmission.unwrap();
    assert!((t.wi + wo_at(70.0)).length() < 1e-5 && (t.weight.x - 1.0).abs() < 1e-6);
}

/// Sampled directions follow the pdf: their histogram over bins of (cos theta, phi) matches
/// the pdf integrated over each bin, and the pdf integrates to the fraction of valid samples.
fn check_sampling_matches_pdf(m: &Material, wo: Vec3A) {
    const NB: usize = 12;
    let n = 400_000;
    let mut hist = vec![0usize; NB * NB];
    let mut valid = 0usize;
    let mut s = Sampler::new(5, Stream::Camera, 1);
    let bin = |wi: Vec3A| -> Option<usize> {
        if wi.z <= 0.0 {
            return None;
        }
        let c = ((wi.z as f64) * NB as f64).min(NB as f64 - 1.0) as usize;
        let phi = (wi.y as f64).atan2(wi.x as f64) + PI;
        let p = ((phi / (2.0 * PI)) * NB as f64).min(NB as f64 - 1.0) as usize;
        Some(c * NB + p)
    };
    for _ in 0..n {
        if let Some(bs) = m.sample(wo, N, s.next_f32(), s.next_2d(), Transport::Radiance) {
            valid += 1;
            let b = bin(bs.wi).expect("a sample of a reflective BSDF lies above the surface");
            hist[b] += 1;
            let p = m.pdf(wo, bs.wi, N);
            assert!(
                ((bs.pdf - p) / p).abs() < 1e-4,
                "returned pdf {} vs pdf() {p}",
                bs.pdf
            );
        }
    }
    // Expected counts: the pdf integrated over each bin (cos theta and phi are uniform in
    // solid angle on the hemisphere, so each bin has solid angle 2 pi / NB^2).
    let mut expect = vec![0.0f64; NB * NB];
    let sub = 24;
    let mut total = 0.0;
    for c in 0..NB {
        for p in 0..NB {
            let mut acc = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let z = (c as f64 + (i as f64 + 0.5) / sub as f64) / NB as f64;
                    let phi =
                        (p as f64 + (j as f64 + 0.5) / sub as f64) / NB as f64 * 2.0 * PI - PI;
                    let r = (1.0 - z * z).sqrt();
                    let wi = Vec3A::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                    acc += m.pdf(wo, wi, N) as f64;
                }
            }
            let omega = 2.0 * PI / (NB * NB) as f64;
            let mass = acc / (sub * sub) as f64 * omega;
            expect[c * NB + p] = mass * n as f64;
            total += mass;
        }
    }
    let frac_valid = valid as f64 / n as f64;
    assert!(
        (total - frac_valid).abs() < 0.01,
        "{m:?}: pdf integrates to {total}, valid samples {frac_valid}"
    );
    for (b, (&h, &e)) in hist.iter().zip(&expect).enumerate() {
        if e > 200.0 {
            let z = (h as f64 - e) / e.sqrt();
            assert!(
                z.abs() < 5.0,
                "{m:?} bin {b}: {h} samples, expected {e:.0} (z = {z:.1})"
            );
        }
    }
}

#[test]
fn sampling_matches_pdf() {
    check_sampling_matches_pdf(
        &Material::Diffuse {
            albedo: Rgb::splat(0.5),
        },
        wo_at(30.0),
    );
    for e in [1.0, 8.0, 30.0] {
        for theta in [0.0, 50.0] {
            check_sampling_matches_pdf(
                &Material::Phong {
                    diffuse: Rgb::splat(0.3),
                    specular: Rgb::splat(0.6),
                    exponent: e,
                },
                wo_at(theta),
            );
        }
    }
}

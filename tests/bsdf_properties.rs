//! Property tests of the BSDFs and the sampling warps (issue 5): reciprocity, energy, pdfs
//! that integrate to 1 and agree with the samplers, and Fresnel's range. tests/bsdf.rs holds
//! the deterministic checks at fixed angles; here proptest draws the directions, normals,
//! materials and random streams. Each test has a modest default case count so that the
//! file runs in a few seconds; `PROPTEST_CASES=N` sets every test's count to N.

mod common;

use std::f32::consts::TAU;
use std::f64::consts::PI;

use glam::{Vec2, Vec3A};
use photonbox::render::material::{
    BsdfSample, Material, SpecularBranch, Transport, fresnel_dielectric, refract,
};
use photonbox::render::math::{Frame, Rgb, reflect};
use photonbox::render::sampling::{
    Sampler, Stream, cosine_hemisphere, cosine_hemisphere_pdf, power_cosine, power_cosine_pdf,
    uniform_cone, uniform_sphere,
};
use proptest::prelude::*;

// ----- strategies -----

/// A unit vector, uniform on the sphere.
fn unit() -> impl Strategy<Value = Vec3A> {
    (-1.0f32..=1.0, 0.0f32..TAU).prop_map(|(z, phi)| {
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3A::new(r * phi.cos(), r * phi.sin(), z).normalize()
    })
}

/// A reflectance channel in [0, 1], with the ends drawn often.
fn channel() -> impl Strategy<Value = f32> {
    prop_oneof![4 => 0.0f32..=1.0, 1 => Just(0.0f32), 1 => Just(1.0f32)]
}

fn reflectance() -> impl Strategy<Value = Rgb> {
    prop::array::uniform3(channel()).prop_map(Rgb::from_array)
}

/// Phong exponents: 0 and 1 exactly, else log-uniform in [1, 1000].
fn exponent() -> impl Strategy<Value = f32> {
    prop_oneof![
        1 => Just(0.0f32),
        1 => Just(1.0f32),
        6 => (0.0f32..=3.0).prop_map(|x| 10f32.powf(x)),
    ]
}

/// Relative index (n_t / n_i) in (0.2, 5): exactly 1, a few ulps either side of 1, glass,
/// and uniform draws.
fn eta() -> impl Strategy<Value = f32> {
    prop_oneof![
        1 => Just(1.0f32),
        1 => Just(1.5f32),
        1 => Just(1.0f32 / 1.5),
        1 => (-4i32..=4).prop_map(|k| f32::from_bits((1.0f32.to_bits() as i32 + k) as u32)),
        6 => 0.2001f32..4.999,
    ]
}

fn diffuse() -> impl Strategy<Value = Material> {
    reflectance().prop_map(|albedo| Material::Diffuse { albedo })
}

/// Phong with kd + ks <= 1 per channel (what the scene loader enforces).
fn phong() -> impl Strategy<Value = Material> {
    (reflectance(), reflectance(), exponent()).prop_map(|(diffuse, t, exponent)| Material::Phong {
        diffuse,
        specular: t * (Rgb::ONE - diffuse),
        exponent,
    })
}

fn mirror() -> impl Strategy<Value = Material> {
    reflectance().prop_map(|reflectance| Material::Mirror { reflectance })
}

fn glass() -> impl Strategy<Value = Material> {
    eta().prop_map(|ior| Material::Dielectric { ior })
}

fn transport() -> impl Strategy<Value = Transport> {
    prop_oneof![Just(Transport::Radiance), Just(Transport::Importance)]
}

// ----- helpers -----

/// The normal on `wo`'s side (every material but glass is two-sided).
fn facing(wo: Vec3A, n: Vec3A) -> Vec3A {
    if wo.dot(n) < 0.0 { -n } else { n }
}

fn close(a: f32, b: f32, rel: f32, abs: f32) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + abs
}

/// Checks every sample must pass, whatever the material: a unit direction, a finite
/// non-negative weight and pdf, delta samples exactly for mirror and glass, and for the
/// others a sample above the surface with the pdf of `pdf()` and the weight f |cos| / pdf.
fn check_sample(m: &Material, wo: Vec3A, n: Vec3A, bs: &BsdfSample) -> Result<(), TestCaseError> {
    prop_assert!(
        (bs.wi.length() - 1.0).abs() < 1e-4,
        "wi {:?} not unit",
        bs.wi
    );
    prop_assert!(
        bs.weight.is_finite() && bs.weight.min_element() >= 0.0,
        "weight {:?}",
        bs.weight
    );
    prop_assert!(bs.pdf.is_finite() && bs.pdf >= 0.0, "pdf {}", bs.pdf);
    prop_assert_eq!(bs.specular, m.is_specular());
    if !bs.specular {
        let cos = bs.wi.dot(facing(wo, n));
        prop_assert!(cos > 0.0, "non-delta sample below the surface: cos {}", cos);
        let pdf = m.pdf(wo, bs.wi, n);
        prop_assert!(
            bs.pdf > 0.0 && close(bs.pdf, pdf, 1e-5, 0.0),
            "sample pdf {} vs pdf() {}",
            bs.pdf,
            pdf
        );
        let want = m.eval(wo, bs.wi, n) * (cos / pdf);
        for c in 0..3 {
            prop_assert!(
                close(bs.weight[c], want[c], 1e-4, 1e-6),
                "weight {:?} vs f cos / pdf {:?}",
                bs.weight,
                want
            );
        }
    }
    Ok(())
}

/// Midpoint rule over the sphere in a frame around `axis`, with theta = pi u^2 so that the
/// cells are small near the axis (where a glossy lobe is).
fn integrate_sphere(axis: Vec3A, nt: usize, np: usize, g: impl Fn(Vec3A) -> f64) -> f64 {
    let frame = Frame::from_normal(axis);
    let mut sum = 0.0;
    for i in 0..nt {
        let u = (i as f64 + 0.5) / nt as f64;
        let theta = PI * u * u;
        let dtheta = 2.0 * PI * u / nt as f64;
        let (st, ct) = theta.sin_cos();
        let mut ring = 0.0;
        for j in 0..np {
            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
            let local = Vec3A::new((st * phi.cos()) as f32, (st * phi.sin()) as f32, ct as f32);
            ring += g(frame.to_world(local));
        }
        sum += ring * st * dtheta * (2.0 * PI / np as f64);
    }
    sum
}

/// Polar angle of a local direction about +z, exact for small angles (atan2 of sin and cos
/// rather than acos of a cosine that rounds to 1).
fn polar(d: Vec3A) -> f64 {
    let (x, y, z) = (d.x as f64, d.y as f64, d.z as f64);
    x.hypot(y).atan2(z)
}

/// The cumulative distribution of the polar angle under a pdf p(cos theta) on the sphere
/// that depends on theta only: (theta_k, integral of 2 pi p sin over [0, theta_k]) on the
/// grid theta_k = pi (k / nt)^2; the last entry is the pdf's integral.
fn radial_cdf(pdf: impl Fn(f32) -> f32, nt: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(nt + 1);
    out.push((0.0, 0.0));
    let mut acc = 0.0;
    for i in 0..nt {
        let u = (i as f64 + 0.5) / nt as f64;
        let theta = PI * u * u;
        let dtheta = 2.0 * PI * u / nt as f64;
        acc += 2.0 * PI * pdf(theta.cos() as f32) as f64 * theta.sin() * dtheta;
        let u1 = (i + 1) as f64 / nt as f64;
        out.push((PI * u1 * u1, acc));
    }
    out
}

/// Linear interpolation in a table from [`radial_cdf`].
fn cdf_at(table: &[(f64, f64)], theta: f64) -> f64 {
    let k = table.partition_point(|&(t, _)| t < theta);
    if k == 0 {
        return 0.0;
    }
    if k == table.len() {
        return table[k - 1].1;
    }
    let ((t0, c0), (t1, c1)) = (table[k - 1], table[k]);
    c0 + (c1 - c0) * (theta - t0) / (t1 - t0)
}

/// Kolmogorov-Smirnov distance between samples and a distribution function.
fn ks_distance(mut xs: Vec<f64>, cdf: impl Fn(f64) -> f64) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len() as f64;
    xs.iter().enumerate().fold(0.0, |d, (i, &x)| {
        let f = cdf(x);
        d.max((f - i as f64 / n).abs())
            .max((f - (i + 1) as f64 / n).abs())
    })
}

/// KS threshold for `n` samples: 3/sqrt(n) has a false-alarm probability about 2 exp(-18),
/// so a correct sampler never fails whatever seed proptest draws.
fn ks_bound(n: usize) -> f64 {
    3.0 / (n as f64).sqrt()
}

// ----- properties -----

proptest! {
    #![proptest_config(common::proptest_config(256))]

    /// f(wo, wi) = f(wi, wo) for the non-delta materials (Helmholtz reciprocity), for
    /// directions on either side and any normal. Directions within 1e-3 of the surface
    /// plane are skipped: eval takes the side from wo (cos >= 0 counts as the front), so
    /// exactly in the plane the two orders may disagree, on a set of measure zero.
    #[test]
    fn diffuse_and_phong_are_reciprocal(
        m in prop_oneof![diffuse(), phong()],
        wo in unit(),
        wi in unit(),
        n in unit(),
    ) {
        prop_assume!(wo.dot(n).abs() > 1e-3 && wi.dot(n).abs() > 1e-3);
        let (a, b) = (m.eval(wo, wi, n), m.eval(wi, wo, n));
        prop_assert!(a.is_finite() && a.min_element() >= 0.0, "f = {:?}", a);
        for c in 0..3 {
            // cos^e amplifies the rounding of cos(alpha) by e (up to 1000): 1e-3 relative.
            prop_assert!(close(a[c], b[c], 1e-3, 1e-6), "f(wo, wi) {:?} != f(wi, wo) {:?}", a, b);
        }
        // Opposite sides of the surface: no transmission through these materials.
        if wo.dot(n) * wi.dot(n) < 0.0 {
            prop_assert_eq!(a, Rgb::ZERO);
        }
    }

    /// A specular interaction never creates energy: the branch weights sum to at most 1.
    /// Glass carrying importance (flux) is lossless, R + T = 1; with radiance its transmitted
    /// weight is the importance one over eta^2 (eta = n_t / n_i), which may exceed 1 and is
    /// not energy. Branch directions are unit, reflection on wo's side, transmission across.
    #[test]
    fn specular_branches_conserve_energy(
        m in prop_oneof![mirror(), glass()],
        wo in unit(),
        n in unit(),
    ) {
        let imp = m.specular_branches(wo, n, Transport::Importance);
        let rad = m.specular_branches(wo, n, Transport::Radiance);
        let weight = |b: Option<SpecularBranch>| b.map_or(Rgb::ZERO, |x| x.weight);
        let sum = weight(imp.reflection) + weight(imp.transmission);
        prop_assert!(sum.is_finite() && sum.max_element() <= 1.0 + 1e-6, "R + T = {:?}", sum);
        prop_assert!(weight(imp.reflection).min_element() >= 0.0);
        prop_assert!(weight(imp.transmission).min_element() >= 0.0);
        let nf = facing(wo, n);
        if let Some(r) = imp.reflection {
            prop_assert!((r.wi - reflect(wo, nf)).length() < 1e-5);
            prop_assert!((r.wi.length() - 1.0).abs() < 1e-5);
            prop_assert!(r.wi.dot(nf) >= -1e-6, "reflection {:?} below the surface", r.wi);
        }
        match m {
            Material::Mirror { reflectance } => {
                prop_assert!(imp.transmission.is_none());
                prop_assert_eq!(weight(imp.reflection), reflectance);
                prop_assert_eq!(weight(rad.reflection), reflectance);
            }
            Material::Dielectric { ior } => {
                prop_assert!(
                    sum.min_element() >= 1.0 - 1e-5,
                    "glass loses energy: R + T = {:?}", sum
                );
                let eta = if wo.dot(n) > 0.0 { ior } else { 1.0 / ior };
                if let Some(t) = imp.transmission {
                    prop_assert!((t.wi.length() - 1.0).abs() < 1e-5);
                    prop_assert!(t.wi.dot(nf) <= 1e-6, "transmission {:?} on wo's side", t.wi);
                    let tr = rad.transmission.expect("both modes refract alike");
                    prop_assert!(close(tr.weight.x, t.weight.x / (eta * eta), 1e-5, 1e-7));
                }
            }
            _ => unreachable!(),
        }
    }

    /// Fresnel reflectance is finite and in [0, 1] for any cosine in [-1, 1] and relative
    /// index in (0.2, 5), including exactly 1 and total internal reflection (where it is 1).
    #[test]
    fn fresnel_is_in_unit_interval(
        cos_i in prop_oneof![
            4 => -1.0f32..=1.0,
            1 => prop::sample::select(vec![-1.0f32, 0.0, 1.0]),
        ],
        eta in eta(),
    ) {
        let f = fresnel_dielectric(cos_i, eta);
        prop_assert!(f.is_finite() && (0.0..=1.0).contains(&f), "F({}, {}) = {}", cos_i, eta, f);
        if eta == 1.0 {
            prop_assert_eq!(f, 0.0);
        }
        // Total internal reflection, with a margin for rounding at the critical angle.
        let c = cos_i.max(0.0) as f64;
        if 1.0 - c * c > (eta as f64).powi(2) * (1.0 + 1e-5) {
            prop_assert_eq!(f, 1.0);
        }
        // Away from grazing, the reflectance is the same from either side of the interface:
        // F(cos_i, eta) = F(cos_t, 1 / eta).
        if c > 0.05 && eta != 1.0 {
            let sin2_t = (1.0 - c * c) / (eta as f64).powi(2);
            if sin2_t < 1.0 - 1e-3 {
                let cos_t = (1.0 - sin2_t).sqrt() as f32;
                let g = fresnel_dielectric(cos_t, 1.0 / eta);
                prop_assert!(
                    (f - g).abs() < 2e-4,
                    "F({}, {}) = {} but F({}, 1/eta) = {}", cos_i, eta, f, cos_t, g
                );
            }
        }
    }

    /// Refraction gives a unit direction across the surface that obeys Snell's law; it is
    /// None exactly under total internal reflection, where Fresnel reflects everything.
    #[test]
    fn refraction_is_unit_and_obeys_snell(wo in unit(), n in unit(), eta in eta()) {
        let nf = facing(wo, n);
        let cos_i = wo.dot(nf);
        match refract(wo, nf, eta) {
            Some(wt) => {
                prop_assert!((wt.length() - 1.0).abs() < 1e-5, "|wt| = {}", wt.length());
                prop_assert!(wt.dot(nf) <= 1e-6, "wt {:?} on the incident side", wt);
                let sin_i = wo.cross(nf).length();
                let sin_t = wt.cross(nf).length();
                prop_assert!(
                    (eta * sin_t - sin_i).abs() < 3e-5 * eta.max(1.0),
                    "Snell: eta {} sin_t {} sin_i {}", eta, sin_t, sin_i
                );
            }
            None => {
                prop_assert!(eta < 1.0, "no refraction into a denser medium (eta {})", eta);
                prop_assert_eq!(fresnel_dielectric(cos_i, eta), 1.0);
            }
        }
    }
}

proptest! {
    #![proptest_config(common::proptest_config(64))]

    /// No material creates energy: the directional albedo, the mean sample weight over 2^15
    /// samples from a stream seeded by proptest, is at most 1 per channel up to six standard
    /// errors of the mean (Phong's bound is tight at normal incidence with kd + ks = 1, so
    /// the estimate may exceed 1 by its noise). Every sample passes [`check_sample`]. Glass
    /// carries importance here: radiance is scaled by 1/eta^2 on refraction, which is not
    /// energy.
    #[test]
    fn albedo_is_at_most_one(
        m in prop_oneof![diffuse(), phong(), mirror(), glass()],
        wo in unit(),
        n in unit(),
        mode in transport(),
        seed in any::<u64>(),
    ) {
        let mode = match m {
            Material::Dielectric { .. } => Transport::Importance,
            _ => mode,
        };
        const COUNT: usize = 1 << 15;
        let mut s = Sampler::new(seed, Stream::Camera, 0);
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        for _ in 0..COUNT {
            if let Some(bs) = m.sample(wo, n, s.next_f32(), s.next_2d(), mode) {
                check_sample(&m, wo, n, &bs)?;
                for c in 0..3 {
                    let w = bs.weight[c] as f64;
                    sum[c] += w;
                    sum2[c] += w * w;
                }
            }
        }
        for c in 0..3 {
            let mean = sum[c] / COUNT as f64;
            let var = (sum2[c] / COUNT as f64 - mean * mean).max(0.0);
            let se = (var / COUNT as f64).sqrt();
            prop_assert!(
                mean <= 1.0 + 6.0 * se + 1e-5,
                "{:?}: albedo {} (standard error {}) in channel {}", m, mean, se, c
            );
        }
    }

    /// The pdf of the non-delta materials integrates to the probability that `sample`
    /// returns a direction. Diffuse: exactly 1 (a black one returns None by design, so
    /// there only the integral is checked). Phong: `pdf` is the mixture
    /// (1 - ps) cos/pi + ps (e + 1)/(2 pi) cos^e(alpha) restricted to the upper hemisphere,
    /// and the sampler drops the glossy samples that fall below the horizon (returns None)
    /// rather than renormalising, so the integral is 1 minus the clipped lobe mass: at most
    /// 1, and equal to the fraction of samples that are Some (2^17 samples; tolerance five
    /// binomial standard errors plus the quadrature's error).
    #[test]
    fn pdf_integrates_to_the_sampled_fraction(
        m in prop_oneof![diffuse(), phong()],
        wo in unit(),
        n in unit(),
        seed in any::<u64>(),
    ) {
        let nf = facing(wo, n);
        let axis = match m {
            Material::Phong { .. } => reflect(wo, nf),
            _ => nf,
        };
        let total = integrate_sphere(axis, 1200, 360, |wi| m.pdf(wo, wi, n) as f64);
        const COUNT: usize = 1 << 17;
        let mut s = Sampler::new(seed, Stream::Camera, 1);
        let mut valid = 0usize;
        for _ in 0..COUNT {
            if let Some(bs) = m.sample(wo, n, s.next_f32(), s.next_2d(), Transport::Radiance) {
                valid += 1;
                check_sample(&m, wo, n, &bs)?;
            }
        }
        let frac = valid as f64 / COUNT as f64;
        let se = (frac * (1.0 - frac) / COUNT as f64).sqrt();
        prop_assert!(total <= 1.0 + 2e-3, "{:?}: pdf integrates to {}", m, total);
        match m {
            Material::Diffuse { albedo } => {
                prop_assert!((total - 1.0).abs() < 2e-3, "{:?}: pdf integrates to {}", m, total);
                // A black diffuse surface samples nothing (documented: None for a black
                // material); otherwise every sample is valid.
                let want = if albedo == Rgb::ZERO { 0.0 } else { 1.0 };
                prop_assert!((frac - want).abs() < 1e-3, "{:?}: {} of samples valid", m, frac);
            }
            _ => prop_assert!(
                (total - frac).abs() < 5.0 * se + 2e-3,
                "{:?}: pdf integrates to {} but {} of samples are valid", m, total, frac
            ),
        }
    }

    /// The warps' pdfs integrate to 1 over the sphere, and the warped directions follow
    /// them: the polar angle's empirical distribution (2^14 samples) is within a KS bound of
    /// the one obtained by integrating the pdf. The cone's pdf is the documented constant
    /// 1/(2 pi (1 - cos_max)) on the cap (it has no function): its samples stay in the cap
    /// and are uniform there. The cosine-weighted directions' azimuth is uniform.
    #[test]
    fn warps_follow_their_pdfs(
        e in exponent(),
        one_minus_cos_max in prop_oneof![
            Just(2.0f32),
            Just(1e-6f32),
            (-6.0f32..=0.3).prop_map(|x| 10f32.powf(x)),
        ],
        seed in any::<u64>(),
    ) {
        const COUNT: usize = 1 << 14;
        let mut s = Sampler::new(seed, Stream::GlobalPhotons, 7);
        let us: Vec<Vec2> = (0..COUNT).map(|_| s.next_2d()).collect();
        let bound = ks_bound(COUNT);

        let cosine = radial_cdf(cosine_hemisphere_pdf, 4000);
        let total = cosine.last().unwrap().1;
        prop_assert!((total - 1.0).abs() < 1e-4, "cosine_hemisphere_pdf integrates to {}", total);
        let dirs: Vec<Vec3A> = us.iter().map(|&u| cosine_hemisphere(u)).collect();
        for d in &dirs {
            prop_assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-5, "{:?}", d);
        }
        let ks = ks_distance(dirs.iter().map(|&d| polar(d)).collect(), |t| cdf_at(&cosine, t));
        prop_assert!(ks < bound, "cosine_hemisphere: KS {} >= {}", ks, bound);
        let ks = ks_distance(
            dirs.iter().map(|d| (d.y as f64).atan2(d.x as f64)).collect(),
            |a| (a + PI) / (2.0 * PI),
        );
        prop_assert!(ks < bound, "cosine_hemisphere azimuth: KS {} >= {}", ks, bound);

        let lobe = radial_cdf(|c| power_cosine_pdf(c, e), 4000);
        let total = lobe.last().unwrap().1;
        prop_assert!(
            (total - 1.0).abs() < 1e-3,
            "power_cosine_pdf(e = {}) integrates to {}", e, total
        );
        let dirs: Vec<Vec3A> = us.iter().map(|&u| power_cosine(u, e)).collect();
        for d in &dirs {
            prop_assert!(d.z >= 0.0 && (d.length() - 1.0).abs() < 1e-4, "{:?}", d);
        }
        let ks = ks_distance(dirs.iter().map(|&d| polar(d)).collect(), |t| cdf_at(&lobe, t));
        prop_assert!(ks < bound + 1e-3, "power_cosine(e = {}): KS {} >= {}", e, ks, bound);

        let omc = one_minus_cos_max as f64;
        let theta_max = 2.0 * (omc / 2.0).sqrt().asin();
        let dirs: Vec<Vec3A> = us.iter().map(|&u| uniform_cone(u, one_minus_cos_max)).collect();
        for d in &dirs {
            prop_assert!((d.length() - 1.0).abs() < 1e-5, "{:?}", d);
            prop_assert!(
                polar(*d) <= theta_max * (1.0 + 1e-4) + 1e-6,
                "{:?} outside the cone {}", d, theta_max
            );
        }
        // 1 - cos theta = 2 sin^2(theta / 2), exact for small cones.
        let ks = ks_distance(dirs.iter().map(|&d| polar(d)).collect(), |t| {
            (2.0 * (t / 2.0).sin().powi(2) / omc).min(1.0)
        });
        prop_assert!(ks < bound, "uniform_cone({}): KS {} >= {}", omc, ks, bound);

        let sphere: Vec<Vec3A> = us.iter().map(|&u| uniform_sphere(u)).collect();
        for d in &sphere {
            prop_assert!((d.length() - 1.0).abs() < 1e-5, "{:?}", d);
        }
        let ks = ks_distance(sphere.iter().map(|&d| polar(d)).collect(), |t| (1.0 - t.cos()) / 2.0);
        prop_assert!(ks < bound, "uniform_sphere: KS {} >= {}", ks, bound);
    }

    /// The shading frame is orthonormal and right-handed for any unit normal, and
    /// reflection is an involution that keeps length.
    #[test]
    fn frames_are_orthonormal(n in unit(), v in unit()) {
        let f = Frame::from_normal(n);
        for (a, b) in [(f.s, f.t), (f.t, f.n), (f.n, f.s)] {
            prop_assert!(a.dot(b).abs() < 1e-5, "{:?}", f);
        }
        for a in [f.s, f.t, f.n] {
            prop_assert!((a.length() - 1.0).abs() < 1e-5, "{:?}", f);
        }
        prop_assert!((f.s.cross(f.t) - f.n).length() < 1e-5, "{:?} left-handed", f);
        prop_assert!((f.to_world(v).length() - 1.0).abs() < 1e-5);
        prop_assert!((f.to_world(Vec3A::Z) - n).length() < 1e-6);
        let r = reflect(v, n);
        prop_assert!((r.length() - 1.0).abs() < 1e-5);
        prop_assert!((reflect(r, n) - v).length() < 1e-5);
        prop_assert!((r.dot(n) - v.dot(n)).abs() < 1e-5);
    }
}

//! The tests Mitsuba 3 and pbrt-v4 run on their BSDFs: sampled directions follow `pdf` (a
//! chi-square test over the sphere), `pdf` integrates to the fraction of samples returned, the
//! sample weight is `eval·cos/pdf`, reflection is reciprocal, and the albedo stays ≤ 1 (= the
//! Fresnel reflectance for a mirror). Seeds are fixed.
use super::microfacet::{Distribution, Masking};
use super::*;
use crate::sampler::SampleStream;
use crate::stats::chi_square_critical;
use std::f32::consts::TAU;

fn dir(theta: f32, phi: f32) -> Vec3A {
    Vec3A::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// A direction from a bin coordinate: `cos θ ∈ [−1, 1]`, `φ ∈ [0, 2π)` (equal-area bins).
fn from_bin(c: f64, p: f64) -> Vec3A {
    let s = (1.0 - c * c).max(0.0).sqrt();
    Vec3A::new((s * p.cos()) as f32, (s * p.sin()) as f32, c as f32)
}

const N_COS: usize = 16;
const N_PHI: usize = 32;

/// `pdf` integrated over one bin by a midpoint rule of `steps` × `steps`: in the two polar
/// bins with `cos θ = ±(1 − t²·Δ)`, `t` uniform (points crowd at the pole, where the lobes of
/// near-normal incidence peak).
fn bin_integral(pdf: &impl Fn(Vec3A) -> f32, i: usize, j: usize, steps: usize) -> f64 {
    let (dc, dp) = (2.0 / N_COS as f64, f64::from(TAU) / N_PHI as f64);
    let mut e = 0.0;
    for si in 0..steps {
        let x = (si as f64 + 0.5) / steps as f64;
        let (c, w) = match i {
            0 => (-1.0 + dc * x * x, 2.0 * dc * x / steps as f64),
            _ if i == N_COS - 1 => (1.0 - dc * x * x, 2.0 * dc * x / steps as f64),
            _ => (-1.0 + dc * (i as f64 + x), dc / steps as f64),
        };
        for sj in 0..steps {
            let p = dp * (j as f64 + (sj as f64 + 0.5) / steps as f64);
            e += f64::from(pdf(from_bin(c, p))) * w * dp / steps as f64;
        }
    }
    e
}

/// Expected share of samples per bin: each bin's integral refined (8, 16, … up to 512 steps
/// a side) until two refinements agree to 0.2% (or 1e-7 absolute). Glass pdfs jump to zero
/// where the refracting microfacet would turn below the horizon: there a fixed 12×12 rule
/// was 25% off in a bin the samples fill 730 times in 400k (checked against 4M samples).
fn expected(pdf: impl Fn(Vec3A) -> f32) -> Vec<f64> {
    let mut out = vec![0.0; N_COS * N_PHI];
    for (b, e) in out.iter_mut().enumerate() {
        let (i, j) = (b / N_PHI, b % N_PHI);
        let mut steps = 8;
        let mut last = bin_integral(&pdf, i, j, steps);
        loop {
            steps *= 2;
            let next = bin_integral(&pdf, i, j, steps);
            if (next - last).abs() <= 2e-3 * next.abs() + 1e-7 || steps >= 512 {
                *e = next;
                break;
            }
            last = next;
        }
    }
    out
}

/// Histogram of `n` sampled directions and how many samples returned one.
fn histogram(bsdf: &Bsdf, wi: Vec3A, n: u32, seed: u64) -> (Vec<f64>, u32) {
    let mut h = vec![0.0; N_COS * N_PHI];
    let mut got = 0;
    let mut rng = SampleStream::new(seed, 0, 0);
    for _ in 0..n {
        let u_lobe = rng.next_f32();
        let Some(s) = bsdf.sample(wi, u_lobe, rng.next_2d()) else { continue };
        if s.delta {
            continue;
        }
        got += 1;
        let c = ((f64::from(s.wo.z) + 1.0) / 2.0 * N_COS as f64).clamp(0.0, N_COS as f64 - 1.0) as usize;
        let mut phi = f64::from(s.wo.y).atan2(f64::from(s.wo.x));
        if phi < 0.0 {
            phi += f64::from(TAU);
        }
        let p = (phi / f64::from(TAU) * N_PHI as f64).clamp(0.0, N_PHI as f64 - 1.0) as usize;
        h[c * N_PHI + p] += 1.0;
    }
    (h, got)
}

/// Pearson's statistic over the bins (bins expecting fewer than 5 samples pooled) and its
/// degrees of freedom.
fn chi2(observed: &[f64], expected_share: &[f64], n: u32) -> (f64, usize) {
    let (mut stat, mut bins) = (0.0, 0);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (o, e) in observed.iter().zip(expected_share) {
        let e = e * f64::from(n);
        if e < 5.0 {
            pool_o += o;
            pool_e += e;
        } else {
            stat += (o - e) * (o - e) / e;
            bins += 1;
        }
    }
    if pool_e >= 5.0 {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        bins += 1;
    } else {
        // Samples where `pdf` expects (nearly) none are a failure in themselves.
        stat += (pool_o - pool_e).max(0.0) * 10.0;
    }
    (stat, bins.max(2) - 1)
}

/// Runs the chi-square test of `bsdf`'s sampling against `pdf` for `wi`; returns the
/// statistic and its critical value at the family-wise level `alpha`.
fn chi2_test(bsdf: &Bsdf, pdf: &Bsdf, wi: Vec3A, alpha: f64) -> (f64, f64) {
    let n = 400_000;
    let (h, _) = histogram(bsdf, wi, n, 17);
    let e = expected(|wo| pdf.pdf(wi, wo));
    let (stat, dof) = chi2(&h, &e, n);
    (stat, chi_square_critical(dof, alpha))
}

fn models() -> Vec<(&'static str, Bsdf)> {
    let gold = (Vec3A::new(0.143, 0.375, 1.442), Vec3A::new(3.983, 2.386, 1.603));
    vec![
        ("diffuse", Bsdf::Diffuse { reflectance: Vec3A::new(0.8, 0.5, 0.2) }),
        ("conductor α=0.2", Bsdf::conductor(gold.0, gold.1, Microfacet::ggx(0.2))),
        ("conductor α=0.5", Bsdf::conductor(gold.0, gold.1, Microfacet::ggx(0.5))),
        ("conductor α=1", Bsdf::conductor(gold.0, gold.1, Microfacet::ggx(1.0))),
        ("glass α=0.2", Bsdf::dielectric(1.5, Microfacet::ggx(0.2))),
        ("glass α=0.6", Bsdf::dielectric(1.5, Microfacet::ggx(0.6))),
        ("plastic", Bsdf::plastic(Vec3A::new(0.5, 0.3, 0.1), 1.49, false)),
        ("rough plastic α=0.1", Bsdf::plastic_with(Vec3A::new(0.5, 0.3, 0.1), 1.49, Microfacet::ggx(0.1), false)),
        ("rough plastic α=0.5", Bsdf::plastic_with(Vec3A::new(0.2, 0.6, 0.3), 1.6, Microfacet::ggx(0.5), true)),
        ("Beckmann conductor α=0.1", Bsdf::conductor(gold.0, gold.1, beckmann(0.1))),
        ("Beckmann conductor α=0.5", Bsdf::conductor(gold.0, gold.1, beckmann(0.5))),
        ("Beckmann conductor α=1", Bsdf::conductor(gold.0, gold.1, beckmann(1.0))),
        ("Beckmann glass α=0.3", Bsdf::dielectric(1.5, beckmann(0.3))),
        ("Beckmann rough plastic α=0.2", Bsdf::plastic_with(Vec3A::new(0.5, 0.3, 0.1), 1.49, beckmann(0.2), false)),
        ("GGX separable conductor α=0.4", Bsdf::conductor(gold.0, gold.1, separable(Distribution::Ggx, 0.4))),
        ("GGX separable glass α=0.4", Bsdf::dielectric(1.5, separable(Distribution::Ggx, 0.4))),
        // A relative index below 1: ice seen from water (pbrt's `AirIce`, 0.763).
        ("interface below 1 α=0.2", Bsdf::dielectric(0.763, Microfacet::ggx(0.2))),
        ("Beckmann interface below 1 α=0.5", Bsdf::dielectric(0.763, beckmann(0.5))),
        ("Beckmann glass α=0.5", Bsdf::dielectric(1.5, beckmann(0.5))),
    ]
}

/// Beckmann microfacets of roughness `alpha`, masking as Mitsuba 3 combines it.
fn beckmann(alpha: f32) -> Microfacet {
    separable(Distribution::Beckmann, alpha)
}

fn separable(distribution: Distribution, alpha: f32) -> Microfacet {
    Microfacet::new(distribution, Masking::Separable, alpha)
}

/// Incident angles: from outside, and for glass from inside too (π − θ).
const ANGLES: [f32; 4] = [0.1, 0.7, 1.2, 1.5];

fn incident(b: &Bsdf) -> Vec<f32> {
    let mut a = ANGLES.to_vec();
    if b.transmits() {
        a.extend(ANGLES.iter().map(|t| std::f32::consts::PI - t));
    }
    a
}

/// Sampling follows `pdf`: the chi-square statistic stays below its critical value at a
/// family-wise false-alarm rate of 1e-3 over the (model, angle) pairs (Šidák-corrected).
/// (Delta samples land in the bin of the mirror direction with an expected count of 0 from
/// `pdf`: they are left out here, and `pdf_integrates_to_the_sampled_fraction` accounts
/// for them.)
#[test]
fn sampling_follows_pdf() {
    let pairs: usize = models().iter().map(|(_, b)| incident(b).len()).sum();
    let alpha = 1.0 - (1.0 - 1e-3f64).powf(1.0 / pairs as f64);
    for (name, b) in models() {
        for theta in incident(&b) {
            let wi = dir(theta, 0.3);
            let (stat, critical) = chi2_test(&b, &b, wi, alpha);
            assert!(stat < critical, "{name}, θi {theta}: χ² {stat:.1} ≥ {critical:.1}");
        }
    }
}

/// The test has power: a pdf 10% too rough for the samples (α 0.55 against 0.5) fails it.
#[test]
fn chi_square_rejects_a_wrong_pdf() {
    let gold = (Vec3A::new(0.143, 0.375, 1.442), Vec3A::new(3.983, 2.386, 1.603));
    let sampled = Bsdf::conductor(gold.0, gold.1, Microfacet::ggx(0.5));
    let claimed = Bsdf::conductor(gold.0, gold.1, Microfacet::ggx(0.55));
    let (stat, critical) = chi2_test(&sampled, &claimed, dir(0.7, 0.3), 1e-3);
    assert!(stat > critical, "χ² {stat:.1} below {critical:.1}");
    // Beckmann's samples against GGX's density of the same α, and against Beckmann's with
    // the visible normals' density replaced by the plain `D(m)·m.z` (α 0.5 at 70°).
    let beck = Bsdf::conductor(gold.0, gold.1, beckmann(0.5));
    let ggx = Bsdf::conductor(gold.0, gold.1, separable(Distribution::Ggx, 0.5));
    let (stat, critical) = chi2_test(&beck, &ggx, dir(0.7, 0.3), 1e-3);
    assert!(stat > critical, "Beckmann against GGX: χ² {stat:.1} below {critical:.1}");
    let wi = dir(1.2, 0.3);
    let (h, _) = histogram(&beck, wi, 400_000, 17);
    let mf = beckmann(0.5);
    let e = expected(|wo| {
        let m = (wi + wo).normalize_or_zero();
        if wo.z <= 0.0 || m == Vec3A::ZERO { 0.0 } else { mf.d(m) * m.z / (4.0 * wo.dot(m)) }
    });
    let (stat, dof) = chi2(&h, &e, 400_000);
    let critical = chi_square_critical(dof, 1e-3);
    assert!(stat > critical, "Beckmann against D·cos: χ² {stat:.1} below {critical:.1}");
}

/// `∫ pdf dω` equals the fraction of calls that return a non-delta direction (within 1%
/// absolute: the integration's error, and 3σ of the fraction's binomial noise at 400k samples
/// ≈ 0.2%).
#[test]
fn pdf_integrates_to_the_sampled_fraction() {
    for (name, b) in models() {
        for theta in incident(&b) {
            let wi = dir(theta, 0.3);
            let total: f64 = expected(|wo| b.pdf(wi, wo)).iter().sum();
            let (_, got) = histogram(&b, wi, 400_000, 5);
            let fraction = f64::from(got) / 400_000.0;
            assert!((total - fraction).abs() < 0.01, "{name}, θi {theta}: ∫pdf {total:.4}, sampled {fraction:.4}");
        }
    }
}

/// Each non-delta sample's weight is `eval·cos θo / pdf`, to 1e-3 relative.
#[test]
fn weights_are_eval_cos_over_pdf() {
    let mut rng = SampleStream::new(9, 0, 0);
    for (name, b) in models() {
        for theta in incident(&b) {
            let wi = dir(theta, 1.1);
            for _ in 0..2000 {
                let u_lobe = rng.next_f32();
                let Some(s) = b.sample(wi, u_lobe, rng.next_2d()) else { continue };
                // (Delta samples' weights: `energy_is_conserved`.)
                if s.delta {
                    continue;
                }
                let want = b.eval(wi, s.wo) * s.wo.z.abs() / s.pdf;
                assert!(
                    (s.pdf - b.pdf(wi, s.wo)).abs() <= 1e-3 * s.pdf,
                    "{name}: pdf {} vs {}",
                    s.pdf,
                    b.pdf(wi, s.wo)
                );
                let err = (s.weight - want).abs().max_element();
                assert!(err <= 1e-3 * want.max_element().max(1e-6), "{name}: weight {} vs {want}", s.weight);
            }
        }
    }
}

/// `f(wi, wo) = f(wo, wi)` for reflection; through glass, with radiance scaled by `1/η²`,
/// `f(wi, wo)·n(wo)² = f(wo, wi)·n(wi)²` (`n` the index of the side a direction lies on).
#[test]
fn scattering_is_reciprocal() {
    let mut rng = SampleStream::new(4, 0, 0);
    let sphere = |rng: &mut SampleStream| {
        let w = crate::geometry::warp::cosine_hemisphere(rng.next_2d());
        if rng.next_f32() < 0.5 { w } else { -w }
    };
    for (name, b) in models() {
        let eta = if let Bsdf::Dielectric { eta, .. } = b { eta } else { 1.0 };
        let n = |w: Vec3A| if w.z > 0.0 { 1.0 } else { eta };
        for _ in 0..5000 {
            let (wi, wo) = if b.transmits() {
                (sphere(&mut rng), sphere(&mut rng))
            } else {
                (
                    crate::geometry::warp::cosine_hemisphere(rng.next_2d()),
                    crate::geometry::warp::cosine_hemisphere(rng.next_2d()),
                )
            };
            let (a, c) = (b.eval(wi, wo) * n(wo) * n(wo), b.eval(wo, wi) * n(wi) * n(wi));
            // f32 rounding of the half vector: 1e-3 relative.
            assert!((a - c).abs().max_element() <= 1e-3 * a.max_element().max(1e-3), "{name}: {a} vs {c} ({wi}, {wo})");
        }
    }
}

/// A white furnace per incident direction: the albedo (mean weight) is at most 1 (3σ), a
/// white diffuse surface's is 1, and a smooth conductor's is its Fresnel reflectance exactly
/// (1 for a perfect reflector).
#[test]
fn energy_is_conserved() {
    let white = Bsdf::Diffuse { reflectance: Vec3A::ONE };
    let perfect =
        Bsdf::Conductor { eta: Vec3A::splat(1e-4), k: Vec3A::splat(1e4), specular: Vec3A::ONE, roughness: None };
    let white_metal = |rough| Bsdf::conductor(Vec3A::splat(1e-4), Vec3A::splat(1e4), rough);
    let mut rng = SampleStream::new(8, 0, 0);
    for theta in [0.0, 0.4, 0.8, 1.2, 1.5] {
        let wi = dir(theta, 0.0);
        let glass = [
            ("glass α 0.3", Bsdf::dielectric(1.5, Microfacet::ggx(0.3))),
            ("glass α 0.3 inside", Bsdf::dielectric(1.0 / 1.5, Microfacet::ggx(0.3))),
            ("white plastic", Bsdf::plastic(Vec3A::ONE, 1.49, false)),
            ("white plastic, nonlinear", Bsdf::plastic(Vec3A::ONE, 1.49, true)),
            ("white rough plastic", Bsdf::plastic_with(Vec3A::ONE, 1.49, Microfacet::ggx(0.3), false)),
            ("white rough plastic, nonlinear", Bsdf::plastic_with(Vec3A::ONE, 1.49, Microfacet::ggx(0.3), true)),
            ("Beckmann α 0.3", white_metal(beckmann(0.3))),
            ("Beckmann α 1", white_metal(beckmann(1.0))),
            ("Beckmann glass α 0.5", Bsdf::dielectric(1.5, beckmann(0.5))),
            ("Beckmann glass α 0.5 inside", Bsdf::dielectric(1.0 / 1.5, beckmann(0.5))),
        ];
        for (name, b) in
            [("white", white), ("α 0.3", white_metal(Microfacet::ggx(0.3))), ("α 1", white_metal(Microfacet::ggx(1.0)))]
                .into_iter()
                .chain(glass)
        {
            let n = 100_000;
            let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
            // Energy, not radiance: a refracted sample's 1/η² scaling is undone.
            let eta = if let Bsdf::Dielectric { eta, .. } = b { eta } else { 1.0 };
            for _ in 0..n {
                let u_lobe = rng.next_f32();
                let w = b.sample(wi, u_lobe, rng.next_2d()).map_or(0.0, |s| {
                    let unscale = if s.wo.z < 0.0 { eta * eta } else { 1.0 };
                    f64::from(s.weight.max_element() * unscale)
                });
                sum += w;
                sum_sq += w * w;
            }
            let mean = sum / f64::from(n);
            let se = ((sum_sq / f64::from(n) - mean * mean).max(0.0) / f64::from(n)).sqrt();
            assert!(mean <= 1.0 + 3.0 * se + 1e-6, "{name}, θi {theta}: albedo {mean} ± {se}");
            if name == "white" {
                assert!((mean - 1.0).abs() < 1e-5, "white diffuse albedo {mean}");
            }
            // A white base under a clear coat loses nothing: F + (1 − F)·1, since the
            // inter-reflections under the coat satisfy 1 − Fdr(1/η) = (1 − Fdr(η))/η².
            if name.starts_with("white plastic") {
                assert!((mean - 1.0).abs() < 4.0 * se + 1e-3, "{name}, θi {theta}: albedo {mean} ± {se}");
            }
        }
        let s = perfect.sample(wi, 0.5, Vec2::new(0.3, 0.6)).unwrap();
        assert!(s.delta && (s.weight - Vec3A::ONE).abs().max_element() < 1e-3, "{}", s.weight);
        assert!((s.wo.z - wi.z).abs() < 1e-6 && (s.wo.x + wi.x).abs() < 1e-6);
        // Smooth glass: Fresnel splits the energy exactly; refraction obeys Snell's law.
        let smooth = Bsdf::dielectric(1.5, Microfacet::ggx(0.0));
        let (f, _, _) = fresnel::dielectric(wi.z, 1.5);
        let r = smooth.sample(wi, f * 0.999, Vec2::ZERO).unwrap();
        let t = smooth.sample(wi, f + (1.0 - f) * 0.5, Vec2::ZERO).unwrap();
        assert!(r.delta && r.wo.z > 0.0 && (r.weight - Vec3A::ONE).abs().max_element() < 1e-6);
        assert!(t.delta && t.wo.z < 0.0 && (t.weight.x * 2.25 - 1.0).abs() < 1e-5, "{}", t.weight);
        let sin_i = (1.0 - wi.z * wi.z).max(0.0).sqrt();
        let sin_t = (1.0 - t.wo.z * t.wo.z).max(0.0).sqrt();
        assert!((sin_i - 1.5 * sin_t).abs() < 1e-5, "Snell: {sin_i} vs 1.5 × {sin_t}");
    }
}

/// A rough coat's transmittance table tends to the smooth coat's `1 − F(θ)` as the roughness
/// vanishes (within 1% up to 80°, where the table is exact but roughness still spreads the
/// grazing lobe), stays in [0, 1] when rough, and its internal reflectance tends to the
/// smooth interface's diffuse Fresnel reflectance.
#[test]
fn rough_coat_tends_to_the_smooth_one() {
    let Bsdf::Plastic { coat: Some(coat), fdr_int, .. } =
        Bsdf::plastic_with(Vec3A::ONE, 1.49, Microfacet::ggx(0.002), false)
    else {
        panic!("a rough plastic has a coat");
    };
    for i in 0..=20 {
        let mu = (f32::from(i as u8) / 20.0).max(0.17);
        let smooth = 1.0 - fresnel::dielectric(mu, 1.49).0;
        let t = coat.transmittance(mu);
        assert!((t - smooth).abs() < 0.01, "cos {mu}: T {t} vs 1 − F {smooth}");
    }
    // Mitsuba's sum over 64 equally spaced cosines (both ends included, divided by 64) is a
    // coarse rule for ∫ 2Rμ dμ: 0.580 against 0.590 here, which we keep to match it.
    assert!((fdr_int - diffuse_fresnel(1.0 / 1.49)).abs() < 0.02, "{fdr_int} vs {}", diffuse_fresnel(1.0 / 1.49));
    let Bsdf::Plastic { coat: Some(rough), .. } = Bsdf::plastic_with(Vec3A::ONE, 1.49, Microfacet::ggx(0.6), false)
    else {
        panic!("a rough plastic has a coat");
    };
    assert!(rough.transmittance.iter().all(|t| (0.0..=1.0).contains(t)));
    // The same (α, η) shares one table.
    let Bsdf::Plastic { coat: Some(again), .. } = Bsdf::plastic_with(Vec3A::ZERO, 1.49, Microfacet::ggx(0.6), true)
    else {
        panic!("a rough plastic has a coat");
    };
    assert!(std::ptr::eq(rough.transmittance, again.transmittance));
}

/// Every hit copies a `Bsdf` (inside its material): the field order of the variants keeps it
/// at 64 bytes with its explicit tag.
#[test]
fn bsdf_stays_64_bytes() {
    assert_eq!(std::mem::size_of::<Bsdf>(), 64);
}

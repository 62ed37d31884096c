//! Participating media: homogeneous media (absorption and scattering coefficients per
//! channel, a Henyey–Greenstein phase function), the distances a path travels through them
//! and the transmittance along a segment. Which medium a ray is in is decided at surfaces by
//! their [`MediumInterface`] (pbrt-v4's and Mitsuba 3's model: a surface names the medium on
//! each side of it; a surface that names none leaves the ray's medium as it is).
//!
//! Free-flight distances are sampled per channel with one-sample multiple importance sampling
//! over the three channels (the balance heuristic: the density is the mean of the channels'
//! densities), so chromatic media stay unbiased and no channel's weight blows up where its
//! coefficient is far from the one sampled (pbrt-v4's hero-wavelength MIS for RGB).
use crate::geometry::{Frame, Vec2, Vec3A};

/// A homogeneous medium: absorption `sigma_a` and scattering `sigma_s` per unit length per
/// channel, and the Henyey–Greenstein asymmetry `g` of its phase function (0 isotropic,
/// towards 1 forward scattering).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// Absorption coefficient per channel.
    pub sigma_a: Vec3A,
    /// Scattering coefficient per channel.
    pub sigma_s: Vec3A,
    /// Henyey–Greenstein asymmetry, in `(-1, 1)`.
    pub g: f32,
}

/// The media on the two sides of a surface (indices into the scene's media; `None`: vacuum).
/// `inside` lies against the surface's geometric normal, `outside` along it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct MediumInterface {
    /// The medium behind the surface.
    pub inside: Option<u16>,
    /// The medium in front of it.
    pub outside: Option<u16>,
}

impl MediumInterface {
    /// Whether crossing the surface changes the medium. A surface that separates nothing
    /// (both sides alike) leaves a ray in whatever medium it was, as in pbrt-v4.
    #[inline]
    #[must_use]
    pub fn is_transition(&self) -> bool {
        self.inside != self.outside
    }

    /// The medium a ray leaving the surface along `dir` travels in, given the geometric normal
    /// `ng` and the medium `current` the arriving ray was in.
    #[inline]
    #[must_use]
    pub fn after(&self, ng: Vec3A, dir: Vec3A, current: Option<u16>) -> Option<u16> {
        if !self.is_transition() {
            current
        } else if ng.dot(dir) > 0.0 {
            self.outside
        } else {
            self.inside
        }
    }
}

/// The outcome of sampling a free-flight distance along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flight {
    /// The distance travelled: where the ray scatters, or the surface's distance.
    pub t: f32,
    /// Whether the ray scatters in the medium at `t` (otherwise it reaches the surface).
    pub scattered: bool,
    /// The throughput's factor: `σs·T(t)/p(t)` at a scattering point, `T(t)/P(t ≥ t_max)` at
    /// the surface (zero where the sampled channel cannot occur).
    pub weight: Vec3A,
}

impl Medium {
    /// The extinction coefficient `σt = σa + σs`.
    #[inline]
    #[must_use]
    pub fn sigma_t(&self) -> Vec3A {
        self.sigma_a + self.sigma_s
    }

    /// The transmittance `exp(−σt·d)` over a distance `d` (1 at `d = 0`; 0 at an infinite
    /// distance where `σt > 0`).
    #[inline]
    #[must_use]
    pub fn transmittance(&self, d: f32) -> Vec3A {
        let s = self.sigma_t();
        // `0·∞` would be NaN: a channel that does not attenuate passes everything.
        let e = |s: f32| if s == 0.0 { 1.0 } else { (-s * d).exp() };
        Vec3A::new(e(s.x), e(s.y), e(s.z))
    }

    /// Samples a distance along a ray whose next surface lies at `t_max` (infinite if none):
    /// `u_channel` picks a channel uniformly, `u` an exponential distance of its extinction.
    /// The weight divides by the mean of the three channels' densities (one-sample MIS), so it
    /// is unbiased for every channel at once.
    #[inline]
    #[must_use]
    pub fn sample_flight(&self, t_max: f32, u_channel: f32, u: f32) -> Flight {
        let sigma_t = self.sigma_t();
        let c = ((u_channel * 3.0) as usize).min(2);
        let s = sigma_t[c];
        // `1 − u` lies in (0, 1]: the logarithm is finite.
        let t = if s > 0.0 { -(1.0 - u).ln() / s } else { f32::INFINITY };
        if t < t_max {
            let tr = self.transmittance(t);
            let pdf = (sigma_t * tr).element_sum() / 3.0;
            let weight = if pdf > 0.0 { self.sigma_s * tr / pdf } else { Vec3A::ZERO };
            Flight { t, scattered: true, weight }
        } else {
            let tr = self.transmittance(t_max);
            let p = tr.element_sum() / 3.0;
            let weight = if p > 0.0 { tr / p } else { Vec3A::ZERO };
            Flight { t: t_max, scattered: false, weight }
        }
    }

    /// The phase function's value for directions `wo` (towards where the light goes next)
    /// and `wi` (towards where the path came from), both unit, pointing away from the point:
    /// forward scattering (`wo = −wi`) is favoured by `g > 0`.
    #[inline]
    #[must_use]
    pub fn phase(&self, wi: Vec3A, wo: Vec3A) -> f32 {
        henyey_greenstein(-wi.dot(wo), self.g)
    }

    /// A direction `wo` drawn from the phase function at a point reached from `wi` (pointing
    /// back along the arriving ray), and its density; the weight `phase/pdf` is 1.
    #[inline]
    #[must_use]
    pub fn sample_phase(&self, wi: Vec3A, u: Vec2) -> (Vec3A, f32) {
        let g = self.g;
        // The cosine to the forward direction `−wi`, by inverting the HG distribution.
        let cos = if g.abs() < 1e-3 {
            1.0 - 2.0 * u.x
        } else {
            let s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
            ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
        };
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        let frame = Frame::from_normal(-wi);
        let wo = frame.to_world(Vec3A::new(sin * phi.cos(), sin * phi.sin(), cos)).normalize();
        (wo, henyey_greenstein(cos, g))
    }
}

/// The Henyey–Greenstein phase function of the cosine between the forward direction and the
/// scattered one, normalised over the sphere.
#[inline]
#[must_use]
pub fn henyey_greenstein(cos: f32, g: f32) -> f32 {
    let denom = 1.0 + g * g - 2.0 * g * cos;
    std::f32::consts::FRAC_1_PI * 0.25 * (1.0 - g * g) / (denom * denom.max(0.0).sqrt()).max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;

    /// The phase function integrates to 1 over the sphere for any asymmetry (midpoint rule
    /// in the cosine, exact in the azimuth), and its sampler's weight is 1 with the density
    /// it reports equal to the function.
    #[test]
    fn henyey_greenstein_is_normalised_and_sampled_by_its_value() {
        for g in [-0.7, 0.0, 0.3, 0.9] {
            let n = 200_000;
            let total: f64 = (0..n)
                .map(|i| {
                    let cos = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                    f64::from(henyey_greenstein(cos as f32, g)) * 2.0 / n as f64
                })
                .sum::<f64>()
                * 2.0
                * std::f64::consts::PI;
            assert!((total - 1.0).abs() < 2e-3, "g {g}: integral {total}");
            let m = Medium { sigma_a: Vec3A::ZERO, sigma_s: Vec3A::ONE, g };
            let wi = Vec3A::new(0.3, -0.5, 0.81).normalize();
            let mut rng = SampleStream::new(7, 0, 0);
            // The mean cosine to the forward direction is g for HG: a moment of the sampler.
            let (mut mean, k) = (0.0f64, 200_000);
            for _ in 0..k {
                let (wo, pdf) = m.sample_phase(wi, rng.next_2d());
                assert!((wo.length() - 1.0).abs() < 1e-4);
                assert!((pdf - m.phase(wi, wo)).abs() <= 1e-3 * pdf.max(1.0), "g {g}: {pdf} vs {}", m.phase(wi, wo));
                mean += f64::from(-wi.dot(wo));
            }
            mean /= f64::from(k);
            // Standard error of the mean cosine is below 1/√(3k) ≈ 0.0013: 5 of them.
            assert!((mean - f64::from(g)).abs() < 0.0065, "g {g}: mean cosine {mean}");
        }
    }

    /// Free flights are unbiased per channel: the expected weight of scattering before
    /// `t_max` is `σs/σt·(1 − T(t_max))` and of reaching the surface `T(t_max)`, for
    /// coefficients that differ by channel (one of them zero).
    #[test]
    fn free_flights_are_unbiased_per_channel() {
        let m = Medium { sigma_a: Vec3A::new(0.2, 0.0, 1.0), sigma_s: Vec3A::new(0.5, 0.0, 2.0), g: 0.0 };
        let t_max = 1.3;
        let mut rng = SampleStream::new(3, 0, 0);
        let n = 400_000;
        let (mut scatter, mut pass) = (Vec3A::ZERO, Vec3A::ZERO);
        let (mut scatter2, mut pass2) = (Vec3A::ZERO, Vec3A::ZERO);
        for _ in 0..n {
            let f = m.sample_flight(t_max, rng.next_f32(), rng.next_f32());
            if f.scattered {
                assert!(f.t < t_max);
                scatter += f.weight / m.sigma_s.max(Vec3A::splat(1e-30)) * m.sigma_t();
                scatter2 += (f.weight / m.sigma_s.max(Vec3A::splat(1e-30)) * m.sigma_t()).powf(2.0);
            } else {
                pass += f.weight;
                pass2 += f.weight * f.weight;
            }
        }
        let n = n as f32;
        let tr = m.transmittance(t_max);
        let sigma_t = m.sigma_t();
        for c in 0..3 {
            // Scattering, weighted by σt/σs: expectation 1 − T where the channel scatters.
            let expect_s = if sigma_t[c] > 0.0 { 1.0 - tr[c] } else { 0.0 };
            let (mean_s, mean_p) = (scatter[c] / n, pass[c] / n);
            let se_s = ((scatter2[c] / n - mean_s * mean_s).max(0.0) / n).sqrt();
            let se_p = ((pass2[c] / n - mean_p * mean_p).max(0.0) / n).sqrt();
            // |z| < 5: a false alarm about once in 1.7 million runs per check.
            assert!((mean_s - expect_s).abs() <= 5.0 * se_s + 1e-6, "channel {c}: scatter {mean_s} vs {expect_s}");
            assert!((mean_p - tr[c]).abs() <= 5.0 * se_p + 1e-6, "channel {c}: pass {mean_p} vs {}", tr[c]);
        }
    }

    /// A surface that separates two media hands a ray the medium on the side it leaves to;
    /// one that separates nothing keeps the ray's.
    #[test]
    fn interfaces_choose_by_side() {
        let mi = MediumInterface { inside: Some(0), outside: None };
        assert_eq!(mi.after(Vec3A::Z, -Vec3A::Z, None), Some(0));
        assert_eq!(mi.after(Vec3A::Z, Vec3A::Z, Some(0)), None);
        let same = MediumInterface { inside: Some(1), outside: Some(1) };
        assert_eq!(same.after(Vec3A::Z, Vec3A::Z, Some(0)), Some(0));
        assert!(!MediumInterface::default().is_transition());
    }
}

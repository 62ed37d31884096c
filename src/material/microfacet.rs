//! The isotropic GGX (Trowbridge–Reitz) microfacet distribution in the local shading frame
//! (+z the normal): normal density `D`, Smith's masking `G1` and height-correlated `G`, and
//! sampling of the normals visible from a direction (Heitz 2018, "Sampling the GGX
//! Distribution of Visible Normals"), whose density is `G1(wi)·max(0, wi·m)·D(m) / wi.z`.
use crate::geometry::{Vec2, Vec3A};
use std::f32::consts::{PI, TAU};

/// GGX with roughness `alpha` (the `α` of Walter et al. 2007; Mitsuba's `alpha`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// Roughness below which a surface is treated as smooth (a delta lobe) by the materials.
    pub const MIN_ALPHA: f32 = 1e-3;

    #[must_use]
    pub fn new(alpha: f32) -> Self {
        Self { alpha: alpha.max(Self::MIN_ALPHA) }
    }

    /// Density of microfacet normals `m` per projected area: `∫ D(m)·m.z dm = 1`.
    #[inline]
    #[must_use]
    pub fn d(&self, m: Vec3A) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let cos2 = m.z * m.z;
        let t = (m.x * m.x + m.y * m.y) / a2 + cos2;
        1.0 / (PI * a2 * t * t)
    }

    /// Smith's `Λ(w)`.
    #[inline]
    #[must_use]
    pub fn lambda(&self, w: Vec3A) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (w.x * w.x + w.y * w.y) / cos2;
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    /// Smith's masking of `w`, seen through microfacet `m`.
    #[inline]
    #[must_use]
    pub fn g1(&self, w: Vec3A, m: Vec3A) -> f32 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking–shadowing of `wi` and `wo` (both on the side `m` faces).
    #[inline]
    #[must_use]
    pub fn g(&self, wi: Vec3A, wo: Vec3A, m: Vec3A) -> f32 {
        if wi.dot(m) * wi.z <= 0.0 || wo.dot(m) * wo.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(wi) + self.lambda(wo))
    }

    /// A microfacet normal visible from `wi` (`wi.z > 0`), with density
    /// [`Ggx::visible_pdf`].
    #[must_use]
    pub fn sample_visible(&self, wi: Vec3A, u: Vec2) -> Vec3A {
        // Stretch to the unit-roughness configuration.
        let vh = Vec3A::new(self.alpha * wi.x, self.alpha * wi.y, wi.z).normalize();
        // An orthonormal basis around vh.
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3A::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3A::X };
        let t2 = vh.cross(t1);
        // A point on the projected disc, its far half compressed by the view.
        let r = u.x.sqrt();
        let (s, c) = (TAU * u.y).sin_cos();
        let p1 = r * c;
        let mut p2 = r * s;
        let h = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - h) * (1.0 - p1 * p1).max(0.0).sqrt() + h * p2;
        let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let nh = p1 * t1 + p2 * t2 + p3 * vh;
        // Unstretch.
        Vec3A::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(1e-7)).normalize()
    }

    /// Density (solid angle of `m`) of [`Ggx::sample_visible`] from `wi`.
    #[inline]
    #[must_use]
    pub fn visible_pdf(&self, wi: Vec3A, m: Vec3A) -> f32 {
        if wi.z <= 0.0 {
            return 0.0;
        }
        self.g1(wi, m) * wi.dot(m).max(0.0) * self.d(m) / wi.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;

    fn dir(theta: f32, phi: f32) -> Vec3A {
        Vec3A::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
    }

    /// `∫ D(m) m.z dm = 1` and `∫ visible_pdf dm = 1`, by a midpoint rule in (cos θ, φ)
    /// (errors of the rule: below 1e-3 at these grids for α ≥ 0.1).
    #[test]
    fn densities_integrate_to_one() {
        for alpha in [0.1, 0.3, 0.7, 1.0] {
            let ggx = Ggx::new(alpha);
            let wi = dir(1.0, 0.4);
            let (n_t, n_p) = (4000, 64);
            let (mut proj, mut vis) = (0.0f64, 0.0f64);
            for i in 0..n_t {
                // Fine near the pole, where D peaks: cosθ = 1 − x², x uniform.
                let x = (i as f64 + 0.5) / n_t as f64;
                let cos = 1.0 - x * x;
                let jac = 2.0 * x / n_t as f64;
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                for j in 0..n_p {
                    let phi = TAU as f64 * (j as f64 + 0.5) / n_p as f64;
                    let m = Vec3A::new((sin * phi.cos()) as f32, (sin * phi.sin()) as f32, cos as f32);
                    let dw = jac * TAU as f64 / n_p as f64;
                    proj += f64::from(ggx.d(m)) * cos * dw;
                    vis += f64::from(ggx.visible_pdf(wi, m)) * dw;
                }
            }
            assert!((proj - 1.0).abs() < 2e-3, "alpha {alpha}: ∫D cos = {proj}");
            assert!((vis - 1.0).abs() < 2e-3, "alpha {alpha}: ∫ visible pdf = {vis}");
        }
    }

    /// Visible normals face the viewer and lie in the upper hemisphere.
    #[test]
    fn visible_normals_are_visible() {
        let mut rng = SampleStream::new(3, 0, 0);
        for alpha in [0.01, 0.2, 1.0] {
            let ggx = Ggx::new(alpha);
            for k in 0..2000 {
                let wi = dir(1.5 * (k as f32 / 2000.0), 6.0 * rng.next_f32());
                let m = ggx.sample_visible(wi, rng.next_2d());
                assert!(m.z > 0.0 && wi.dot(m) >= -1e-5 && m.is_normalized(), "{wi} {m}");
            }
        }
    }
}

//! Fresnel reflectance: dielectric interfaces (real relative index) and conductors (complex
//! index `eta + i·k` per channel), for unpolarised light.
use crate::geometry::Vec3A;

/// Reflectance of a dielectric interface for a ray arriving at `cos_i` (signed: negative from
/// inside) with relative index `eta` (inside over outside). Returns the reflectance, the
/// cosine of the refracted direction (negative sign convention of the arriving side flipped)
/// and the relative index the refracted ray crosses (`eta` or `1/eta`). Total internal
/// reflection gives reflectance 1 and cosine 0.
#[must_use]
pub fn dielectric(cos_i: f32, eta: f32) -> (f32, f32, f32) {
    let (cos_i_abs, eta_it) = if cos_i >= 0.0 { (cos_i, eta) } else { (-cos_i, 1.0 / eta) };
    let sin2_t = (1.0 - cos_i_abs * cos_i_abs).max(0.0) / (eta_it * eta_it);
    if sin2_t >= 1.0 {
        return (1.0, 0.0, eta_it);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i_abs - eta_it * cos_t) / (cos_i_abs + eta_it * cos_t);
    let rp = (eta_it * cos_i_abs - cos_t) / (eta_it * cos_i_abs + cos_t);
    let r = 0.5 * (rs * rs + rp * rp);
    // The transmitted direction leaves on the other side.
    (r, if cos_i >= 0.0 { -cos_t } else { cos_t }, eta_it)
}

/// Unpolarised reflectance of a dielectric interface of relative index `eta` for a known
/// refraction: incident and transmitted cosines `cos_i`, `cos_t` (both ≥ 0, from the same
/// microfacet). Equals [`dielectric`]`(cos_i, eta).0`, without Snell's cancellation near the
/// critical angle.
#[inline]
#[must_use]
pub fn dielectric_cosines(cos_i: f32, cos_t: f32, eta: f32) -> f32 {
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    (0.5 * (rs * rs + rp * rp)).min(1.0)
}

/// Reflectance of a conductor with complex index `eta + i·k` (relative to the outside) at
/// incident cosine `cos_i` (≥ 0), per channel.
#[must_use]
pub fn conductor(cos_i: f32, eta: Vec3A, k: Vec3A) -> Vec3A {
    let c = cos_i.clamp(0.0, 1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let eta2 = eta * eta;
    let k2 = k * k;
    let t0 = eta2 - k2 - Vec3A::splat(s2);
    let a2b2 = (t0 * t0 + 4.0 * eta2 * k2).max(Vec3A::ZERO);
    let a2b2 = Vec3A::new(a2b2.x.sqrt(), a2b2.y.sqrt(), a2b2.z.sqrt());
    let a = (0.5 * (a2b2 + t0)).max(Vec3A::ZERO);
    let a = Vec3A::new(a.x.sqrt(), a.y.sqrt(), a.z.sqrt());
    let t1 = a2b2 + Vec3A::splat(c2);
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + Vec3A::splat(s2 * s2);
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    (0.5 * (rp + rs)).clamp(Vec3A::ZERO, Vec3A::ONE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_limits() {
        // Normal incidence: ((η−1)/(η+1))², from either side.
        let (r, cos_t, _) = dielectric(1.0, 1.5);
        assert!((r - 0.04).abs() < 1e-6 && (cos_t + 1.0).abs() < 1e-6);
        let (r, cos_t, eta) = dielectric(-1.0, 1.5);
        assert!((r - 0.04).abs() < 1e-6 && (cos_t - 1.0).abs() < 1e-6 && (eta - 1.0 / 1.5).abs() < 1e-6);
        // Grazing: 1. Beyond the critical angle from inside: total internal reflection.
        assert!((dielectric(1e-6, 1.5).0 - 1.0).abs() < 1e-4);
        assert_eq!(dielectric(-0.5, 1.5).0, 1.0);
        // Index 1: no interface.
        assert!(dielectric(0.3, 1.0).0.abs() < 1e-7);
    }

    #[test]
    fn conductor_matches_the_dielectric_formula_without_absorption() {
        for cos in [0.05f32, 0.3, 0.7, 1.0] {
            let c = conductor(cos, Vec3A::splat(1.5), Vec3A::ZERO);
            let d = dielectric(cos, 1.5).0;
            assert!((c - Vec3A::splat(d)).abs().max_element() < 1e-5, "{cos}: {c} vs {d}");
        }
        // Normal incidence: ((η−1)² + k²) / ((η+1)² + k²).
        let (eta, k) = (0.2f32, 3.9f32);
        let want = ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k);
        assert!((conductor(1.0, Vec3A::splat(eta), Vec3A::splat(k)).x - want).abs() < 1e-5);
    }
}

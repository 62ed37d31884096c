use super::{Hit, Ray};
use glam::Vec3A;

/// Möller–Trumbore ray/triangle intersection returning `(t, u, v)` for `t ∈ (0, t_max)`.
/// Used by the brute-force reference backend and to compute barycentrics after traversal.
#[inline]
#[must_use]
pub fn intersect_triangle(ray: &Ray, v: &[Vec3A; 3], t_max: f32) -> Option<(f32, f32, f32)> {
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - v[0];
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let w = ray.dir.dot(q) * inv;
    if w < 0.0 || u + w > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > 0.0 && t < t_max).then_some((t, u, w))
}

impl Hit {
    /// Builds a hit on triangle `prim` at distance `t`, computing barycentrics from the ray.
    #[inline]
    #[must_use]
    pub fn on_triangle(ray: &Ray, v: &[Vec3A; 3], prim: u32, t: f32) -> Hit {
        let e1 = v[1] - v[0];
        let e2 = v[2] - v[0];
        let p = ray.dir.cross(e2);
        let inv = 1.0 / e1.dot(p);
        let s = ray.origin - v[0];
        let u = (s.dot(p) * inv).clamp(0.0, 1.0);
        let w = (ray.dir.dot(s.cross(e1)) * inv).clamp(0.0, 1.0 - u);
        Hit { t, prim, u, v: w }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_centre_and_misses_outside() {
        let tri = [Vec3A::ZERO, Vec3A::X, Vec3A::Y];
        let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
        let (t, u, v) = intersect_triangle(&ray, &tri, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (u - 0.25).abs() < 1e-6 && (v - 0.25).abs() < 1e-6);
        let h = Hit::on_triangle(&ray, &tri, 7, t);
        assert!((h.u - u).abs() < 1e-6 && (h.v - v).abs() < 1e-6 && h.prim == 7);
        let miss = Ray::new(Vec3A::new(0.75, 0.75, 1.0), -Vec3A::Z);
        assert!(intersect_triangle(&miss, &tri, f32::INFINITY).is_none());
        assert!(intersect_triangle(&ray, &tri, 0.5).is_none(), "t_max respected");
    }
}

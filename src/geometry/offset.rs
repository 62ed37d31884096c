//! Self-intersection avoidance by conservative floating-point error bounds (pbrt-v4's
//! approach): the hit point is reconstructed from barycentrics, its absolute error is bounded,
//! and the ray origin is pushed out along the geometric normal by just that bound.
use glam::Vec3A;

/// `γ(n) = n·ε / (1 − n·ε)` with `ε` half an ULP of one (Higham's bound, as pbrt uses).
const fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n * e) / (1.0 - n * e)
}

/// Absolute error bound of `p = b0·p0 + b1·p1 + b2·p2` computed in f32.
#[inline]
#[must_use]
pub fn barycentric_error(b: [f32; 3], v: &[Vec3A; 3]) -> Vec3A {
    ((v[0] * b[0]).abs() + (v[1] * b[1]).abs() + (v[2] * b[2]).abs()) * gamma(7.0)
}

/// Moves `p` (with error bound `p_err`) off the surface with geometric normal `ng`, onto the
/// side `w` points to, far enough that a ray leaving from there cannot re-hit the surface.
#[inline]
#[must_use]
pub fn offset_ray_origin(p: Vec3A, p_err: Vec3A, ng: Vec3A, w: Vec3A) -> Vec3A {
    let d = ng.abs().dot(p_err);
    let mut offset = ng * d;
    if w.dot(ng) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    // Round away from p so that the rounding of the addition cannot undo the offset.
    let bump = |x: f32, o: f32| {
        if o > 0.0 {
            x.next_up()
        } else if o < 0.0 {
            x.next_down()
        } else {
            x
        }
    };
    Vec3A::new(bump(po.x, offset.x), bump(po.y, offset.y), bump(po.z, offset.z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Ray, intersect_triangle};

    /// A ray leaving an offset point never re-hits the triangle it left, even far from the
    /// origin where a fixed epsilon would fail.
    #[test]
    fn offset_origin_does_not_self_intersect() {
        let mut misses = 0;
        for k in 0..2000u32 {
            let scale = 10f32.powi((k % 7) as i32 - 2);
            let base = Vec3A::new(1.3, -0.7, 2.1) * scale * (1.0 + k as f32 * 1e-3);
            let tri = [base, base + Vec3A::new(0.9, 0.1, 0.05) * scale, base + Vec3A::new(0.2, 1.0, -0.3) * scale];
            let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let b1 = ((k * 7919) % 1000) as f32 / 2000.0;
            let b2 = ((k * 104729) % 1000) as f32 / 2000.0;
            let b = [1.0 - b1 - b2, b1, b2];
            let p = tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2];
            let w = (ng + Vec3A::new(0.9, -0.4, 0.2) * ((k % 5) as f32 * 0.5)).normalize();
            let w = if w.dot(ng) <= 0.0 { ng } else { w };
            let o = offset_ray_origin(p, barycentric_error(b, &tri), ng, w);
            if intersect_triangle(&Ray::new(o, w), &tri, f32::INFINITY).is_some() {
                misses += 1;
            }
        }
        assert_eq!(misses, 0);
    }
}

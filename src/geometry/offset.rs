//! Self-intersection avoidance by conservative floating-point error bounds (pbrt-v4's
//! approach): the hit point is reconstructed from barycentrics, its absolute error is bounded,
//! and the ray origin is pushed out along the geometric normal by just that bound.
use glam::Vec3A;

/// `γ(n) = n·ε / (1 − n·ε)` with `ε` half an ULP of one (Higham's bound, as pbrt uses).
const fn gamma(n: f32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n * e) / (1.0 - n * e)
}

/// Absolute error bound of `p = b0·p0 + b1·p1 + b2·p2` computed in f32, made the same in
/// every axis (the largest component's).
///
/// Per component, the bound is tiny along an axis in which the triangle's coordinates are
/// tiny; but the intersection test that may re-hit the triangle works in all coordinates at
/// once (and has no conservative lower bound on `t`, unlike pbrt's). A plane at `y ≈ 0`
/// tilted by 1e-7 over ±3 in x and z (a rectangle rotated by 90° in f32) re-hit itself at
/// `t ≈ 1e-7` from half its points with the per-component bound: the sun's shadow rays
/// failed in bands across the `sky` scene's ground plate.
#[inline]
#[must_use]
pub fn barycentric_error(b: [f32; 3], v: &[Vec3A; 3]) -> Vec3A {
    let e = ((v[0] * b[0]).abs() + (v[1] * b[1]).abs() + (v[2] * b[2]).abs()) * gamma(7.0);
    Vec3A::splat(e.max_element())
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
    use crate::geometry::{Ray, WatertightRay, intersect_triangle};

    /// A plane nearly perpendicular to an axis (`y` within ±1.3e-7 over ±3 in x and z, as a
    /// rectangle rotated by 90° in f32 comes out): rays leaving 2,000 of its points in
    /// directions all over its upper side never re-hit it (with a per-component error bound,
    /// 591 of them did, at `t ≈ 1e-7`).
    #[test]
    fn nearly_axis_aligned_plane_does_not_self_intersect() {
        let h = 1.311_341_6e-7;
        let tri = [Vec3A::new(-3.0, h, 3.0), Vec3A::new(3.0, -h, -3.0), Vec3A::new(-3.0, -h, -3.0)];
        let ng = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
        let ng = if ng.y > 0.0 { ng } else { -ng };
        let mut hits = 0;
        for k in 0..2000u32 {
            let b1 = ((k * 7919) % 997) as f32 / 2000.0;
            let b2 = ((k * 104_729) % 991) as f32 / 2000.0;
            let b = [1.0 - b1 - b2, b1, b2];
            let p = tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2];
            let phi = k as f32 * 2.399;
            let up = 0.05 + 0.9 * ((k % 13) as f32 / 13.0);
            let dir = Vec3A::new(phi.cos() * (1.0 - up * up).sqrt(), up, phi.sin() * (1.0 - up * up).sqrt());
            let origin = offset_ray_origin(p, barycentric_error(b, &tri), ng, dir);
            let ray = Ray::new(origin, dir);
            if WatertightRay::new(&ray).intersect(&tri, f32::INFINITY).is_some() {
                hits += 1;
            }
        }
        assert_eq!(hits, 0, "{hits} of 2000 rays re-hit the plane");
    }

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

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

/// A ray prepared for the watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013):
/// vertices are translated to the ray origin, permuted so the ray's largest direction
/// component is z, and sheared so the ray becomes the +z axis. The 2-D edge functions are then
/// computed identically for an edge shared by two triangles, so a ray cannot slip between them;
/// where one is exactly zero it is recomputed in f64, which keeps vertices closed too.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: Vec3A,
    /// Permutation and shear as one matrix: `(x', y', z') = M·(p − o)` with
    /// `x' = p[kx] − sx·p[kz]`, `y' = p[ky] − sy·p[kz]`, `z' = sz·p[kz]` (three SIMD
    /// multiply-adds per vertex; every vertex is transformed the same way whichever triangle
    /// it belongs to, which is what keeps shared edges closed).
    m: glam::Mat3A,
}

impl WatertightRay {
    #[inline]
    #[must_use]
    pub fn new(ray: &Ray) -> Self {
        let a = ray.dir.abs();
        let kz = if a.x > a.y {
            if a.x > a.z { 0 } else { 2 }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        // Keep the winding (and so the sign of the edge functions) for negative directions.
        if ray.dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let d = ray.dir;
        let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        // Row r of M picks and shears output component r; build it by columns.
        let mut cols = [Vec3A::ZERO; 3];
        cols[kx].x = 1.0;
        cols[ky].y = 1.0;
        cols[kz] = Vec3A::new(-sx, -sy, sz);
        Self { origin: ray.origin, m: glam::Mat3A::from_cols(cols[0], cols[1], cols[2]) }
    }

    /// `(t, u, v)` for a hit with `t ∈ (0, t_max)`; `u`, `v` weigh `v[1]`, `v[2]`.
    #[inline]
    #[must_use]
    pub fn intersect(&self, v: &[Vec3A; 3], t_max: f32) -> Option<(f32, f32, f32)> {
        let (a, b, c) = (self.m * (v[0] - self.origin), self.m * (v[1] - self.origin), self.m * (v[2] - self.origin));
        let (ax, ay, bx, by, cx, cy) = (a.x, a.y, b.x, b.y, c.x, c.y);
        let mut e0 = cx * by - cy * bx;
        let mut e1 = ax * cy - ay * cx;
        let mut e2 = bx * ay - by * ax;
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            let f = |p: f32, q: f32, r: f32, s: f32| (p as f64 * q as f64 - r as f64 * s as f64) as f32;
            e0 = f(cx, by, cy, bx);
            e1 = f(ax, cy, ay, cx);
            e2 = f(bx, ay, by, ax);
        }
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        let t_scaled = e0 * a.z + e1 * b.z + e2 * c.z;
        let inv = 1.0 / det;
        let t = t_scaled * inv;
        (t > 0.0 && t < t_max).then_some((t, e1 * inv, e2 * inv))
    }
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
    fn watertight_matches_moller_away_from_edges() {
        let tri = [Vec3A::new(-1.0, -1.0, 0.0), Vec3A::new(2.0, -0.5, 0.3), Vec3A::new(0.1, 1.7, -0.2)];
        let mut rng = crate::sampler::SampleStream::new(5, 0, 0);
        for _ in 0..10_000 {
            let o = Vec3A::new(
                rng.next_f32() * 4.0 - 2.0,
                rng.next_f32() * 4.0 - 2.0,
                3.0 * (rng.next_f32() - 0.5).signum(),
            );
            let ray =
                Ray::new(o, (Vec3A::new(rng.next_f32() * 3.0 - 1.5, rng.next_f32() * 3.0 - 1.5, 0.0) - o).normalize());
            let (a, b) = (
                WatertightRay::new(&ray).intersect(&tri, f32::INFINITY),
                intersect_triangle(&ray, &tri, f32::INFINITY),
            );
            match (a, b) {
                (Some(a), Some(b)) => {
                    assert!((a.0 - b.0).abs() < 1e-4 && (a.1 - b.1).abs() < 1e-4 && (a.2 - b.2).abs() < 1e-4)
                }
                (None, None) => {}
                (x, y) => {
                    let h = x.or(y).unwrap();
                    assert!(h.1.min(h.2).min(1.0 - h.1 - h.2) < 1e-5, "disagree away from an edge: {x:?} {y:?}");
                }
            }
        }
    }

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

//! Uniform sampling of the solid angle a triangle subtends (Arvo 1995, "Stratified sampling of
//! spherical triangles"), for next event estimation close to an emitter, where a uniform point
//! on the emitter's *area* gives `cosθx·cosθy/d²` an unbounded spread.
//!
//! The arithmetic is done in f64: the construction subtracts nearly equal quantities when the
//! triangle is small or seen edge-on, and a sample must land inside the triangle for its
//! density `1/Ω` to be the right one. Callers fall back to area sampling below
//! [`MIN_SOLID_ANGLE`], where `cosθx·cosθy/d²` is nearly constant anyway.
use super::fastmath;
use glam::{DVec3, Vec2, Vec3A};

/// Below this solid angle (steradians) a triangle is sampled by area instead: Arvo's
/// construction loses digits there and area sampling is already close to ideal.
pub const MIN_SOLID_ANGLE: f64 = 1e-4;

/// A triangle as seen from a point: the unit directions to its corners and what Arvo's
/// construction needs about them.
#[derive(Clone, Copy, Debug)]
pub struct SphericalTriangle {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    /// Unit tangent at `a` towards `c` (the great circle through `a` and `c`).
    t_ac: DVec3,
    /// The corner angle α at `a`, as its cosine and sine.
    cos_alpha: f64,
    sin_alpha: f64,
    /// `cos c`, c being the side opposite `c` (the arc from `a` to `b`).
    cos_c: f64,
    area: f64,
}

/// The unit directions from `x` to the corners of `v`; `None` when `x` is on a corner.
#[inline]
fn corners(x: Vec3A, v: &[Vec3A; 3]) -> Option<[DVec3; 3]> {
    let x = x.as_dvec3();
    let dir = |p: Vec3A| (p.as_dvec3() - x).try_normalize();
    Some([dir(v[0])?, dir(v[1])?, dir(v[2])?])
}

/// Van Oosterom and Strackee's solid angle of the triangle with unit corner directions
/// `a, b, c`: `tan(Ω/2) = |a·(b×c)| / (1 + a·b + b·c + c·a)`.
#[inline]
fn area(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    2.0 * a.dot(b.cross(c)).abs().atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a))
}

/// What choosing among parts of an emitter needs about one part.
#[derive(Clone, Copy, Debug)]
pub struct PartStats {
    /// `∫ n·ω dω` over the part (Lambert's formula, signed).
    pub projected: f32,
    /// Solid angle.
    pub omega: f32,
    /// `n·ω` at the corner directions.
    pub cosines: [f32; 3],
}

/// [`PartStats`] of triangle `v` seen from `x` with normal `n`; `None` on a corner.
#[inline]
#[must_use]
pub fn part_stats(x: Vec3A, v: &[Vec3A; 3], n: Vec3A) -> Option<PartStats> {
    let [a, b, c] = unit_corners(x, v)?;
    stats_from([a, b, c], [edge_term(a, b, n), edge_term(b, c, n), edge_term(c, a, n)], n)
}

/// The unit directions from `x` to the corners of `v` in f32; `None` on a corner.
#[inline]
#[must_use]
pub fn unit_corners(x: Vec3A, v: &[Vec3A; 3]) -> Option<[Vec3A; 3]> {
    Some([(v[0] - x).try_normalize()?, (v[1] - x).try_normalize()?, (v[2] - x).try_normalize()?])
}

/// Lambert's term of the arc from unit `p` to unit `q` for normal `n`: the arc's angle times
/// `n` · the unit normal of its great circle (half the sum over a triangle's edges is its
/// projected solid angle). Reversing the arc negates it.
//
// f32 (the choice's probabilities need only be computed the same way each time, not exactly;
// f64 atan2 made this a quarter of a path tracer's time on cornell-paper), with a degree-15
// polynomial atan2 accurate to 3e-7 rad (glibc's atan2f was a fifth of zvidpt's time). A cubic
// one (~1e-4 rad) raised one NEE sample's deviation at (0.3, 0.999, 0.25) from < 0.05 to 0.08:
// the tests caught it.
#[inline]
fn edge_term(p: Vec3A, q: Vec3A, n: Vec3A) -> f32 {
    let cross = p.cross(q);
    let len = cross.length();
    if len > 0.0 { fastmath::atan2(len, p.dot(q)) * n.dot(cross) / len } else { 0.0 }
}

/// [`PartStats`] of the triangle with unit corner directions `d` from the Lambert terms of its
/// edges `d0→d1`, `d1→d2`, `d2→d0`.
#[inline]
fn stats_from([a, b, c]: [Vec3A; 3], edges: [f32; 3], n: Vec3A) -> Option<PartStats> {
    let triple = a.dot(b.cross(c));
    let omega = 2.0 * fastmath::atan2(triple.abs(), 1.0 + a.dot(b) + b.dot(c) + c.dot(a));
    let projected = 0.5 * (edges[0] + edges[1] + edges[2]) * triple.signum();
    (omega.is_finite() && projected.is_finite()).then_some(PartStats {
        projected,
        omega,
        cosines: [n.dot(a), n.dot(b), n.dot(c)],
    })
}

/// Four parts of a triangle: their corners, unit corner directions and [`PartStats`].
pub type Subdivision = ([[Vec3A; 3]; 4], [[Vec3A; 3]; 4], [Option<PartStats>; 4]);

/// Triangle `v` (unit corner directions `d` from `x`) cut in four by its edge midpoints: the
/// parts `[v0, m01, m20]`, `[m01, v1, m12]`, `[m20, m12, v2]`, `[m01, m12, m20]`, their unit
/// corner directions, and their [`PartStats`] (`None` for a part `x` is a corner of). The nine
/// arcs the parts share are each evaluated once.
#[must_use]
pub fn subdivide(x: Vec3A, v: &[Vec3A; 3], d: &[Vec3A; 3], n: Vec3A) -> Subdivision {
    let (m01, m12, m20) = ((v[0] + v[1]) * 0.5, (v[1] + v[2]) * 0.5, (v[2] + v[0]) * 0.5);
    let parts = [[v[0], m01, m20], [m01, v[1], m12], [m20, m12, v[2]], [m01, m12, m20]];
    let dir = |p: Vec3A| (p - x).try_normalize();
    let (Some(e01), Some(e12), Some(e20)) = (dir(m01), dir(m12), dir(m20)) else {
        return (parts, [*d; 4], [None; 4]);
    };
    let [d0, d1, d2] = *d;
    let dirs = [[d0, e01, e20], [e01, d1, e12], [e20, e12, d2], [e01, e12, e20]];
    // Halves of the outer edges, and the three inner arcs (shared by the middle part and,
    // reversed, by one corner part each).
    let (a0, a1) = (edge_term(d0, e01, n), edge_term(e01, d1, n));
    let (b0, b1) = (edge_term(d1, e12, n), edge_term(e12, d2, n));
    let (c0, c1) = (edge_term(d2, e20, n), edge_term(e20, d0, n));
    let (i01_12, i12_20, i20_01) = (edge_term(e01, e12, n), edge_term(e12, e20, n), edge_term(e20, e01, n));
    let stats = [
        stats_from(dirs[0], [a0, -i20_01, c1], n),
        stats_from(dirs[1], [a1, b0, -i01_12], n),
        stats_from(dirs[2], [-i12_20, b1, c0], n),
        stats_from(dirs[3], [i01_12, i12_20, i20_01], n),
    ];
    (parts, dirs, stats)
}

/// Corner weights for [`crate::geometry::warp::bilinear`] in the layout of
/// [`SphericalTriangle::sample`]'s square (`(0,0)` and `(1,0)` map to `b`, `(0,1)` to `a`,
/// `(1,1)` to `c`) from the cosines at corners `a, b, c`, approximating the cosine factor of the
/// shading point (floored at 1% of the largest so that no direction the cosine can reach gets
/// zero density); `None` when the whole triangle lies below the shading point's horizon (a
/// direction inside it is a positive combination of the corners).
#[inline]
#[must_use]
pub fn cosine_warp_weights([ca, cb, cc]: [f32; 3]) -> Option<[f32; 4]> {
    let top = ca.max(cb).max(cc);
    if top.is_nan() || top <= 0.0 {
        return None;
    }
    let floor = 0.01 * top;
    Some([cb.max(floor), cb.max(floor), ca.max(floor), cc.max(floor)])
}

impl SphericalTriangle {
    /// The triangle `v` seen from `x`; `None` when `x` lies in its plane or on a corner (no
    /// solid angle), or when anything is not finite.
    #[must_use]
    pub fn new(x: Vec3A, v: &[Vec3A; 3]) -> Option<Self> {
        let [a, b, c] = corners(x, v)?;
        // The corner angle α between the great circles a–b and a–c: with unit a,
        // (a×b)·(a×c) = |a×b||a×c| cos α and |(a×b)×(a×c)| = |a·(b×c)| = |a×b||a×c| sin α,
        // so no inverse trigonometry is needed.
        let (ab, ac) = (a.cross(b), a.cross(c));
        let triple = a.dot(b.cross(c)).abs();
        let inv = 1.0 / (ab.length() * ac.length());
        let (cos_alpha, sin_alpha) = (ab.dot(ac) * inv, triple * inv);
        let area = area(a, b, c);
        let t_ac = (c - a * c.dot(a)).try_normalize()?;
        (area.is_finite() && area > 0.0 && cos_alpha.is_finite() && sin_alpha.is_finite()).then_some(Self {
            a,
            b,
            c,
            t_ac,
            cos_alpha,
            sin_alpha,
            cos_c: a.dot(b),
            area,
        })
    }

    /// The solid angle `Ω` in steradians; the sampling density is `1/Ω`.
    #[inline]
    #[must_use]
    pub fn solid_angle(&self) -> f64 {
        self.area
    }

    /// `n·a`, `n·b`, `n·c` for the unit directions to the corners: the cosine factor a shading
    /// point with normal `n` applies at each.
    #[inline]
    #[must_use]
    pub fn corner_cosines(&self, n: Vec3A) -> [f32; 3] {
        let n = n.as_dvec3();
        [n.dot(self.a) as f32, n.dot(self.b) as f32, n.dot(self.c) as f32]
    }

    /// [`cosine_warp_weights`] for a shading point with normal `n`.
    #[inline]
    #[must_use]
    pub fn cosine_warp_weights(&self, n: Vec3A) -> Option<[f32; 4]> {
        cosine_warp_weights(self.corner_cosines(n))
    }

    /// A direction uniformly distributed over the triangle's solid angle. Arvo's map: `u.x`
    /// picks the sub-triangle `a, b, ĉ` of area `u.x·Ω` (ĉ on the arc `a c`), `u.y` a point on
    /// the arc from `b` to `ĉ` with the density that makes the whole map uniform.
    #[must_use]
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let (sin_area, cos_area) = (f64::from(u.x) * self.area).sin_cos();
        // sin and cos of (Â − α).
        let s = sin_area * self.cos_alpha - cos_area * self.sin_alpha;
        let t = cos_area * self.cos_alpha + sin_area * self.sin_alpha;
        let uu = t - self.cos_alpha;
        let vv = s + self.sin_alpha * self.cos_c;
        let den = (vv * s + uu * t) * self.sin_alpha;
        let q = if den.abs() > 0.0 { (((vv * t - uu * s) * self.cos_alpha - vv) / den).clamp(-1.0, 1.0) } else { 1.0 };
        let c_hat = self.a * q + self.t_ac * (1.0 - q * q).max(0.0).sqrt();
        let z = 1.0 - f64::from(u.y) * (1.0 - c_hat.dot(self.b));
        let w = match (c_hat - self.b * c_hat.dot(self.b)).try_normalize() {
            Some(t_bc) => self.b * z + t_bc * (1.0 - z * z).max(0.0).sqrt(),
            None => self.b,
        };
        w.as_vec3a()
    }

    /// The square's point that [`SphericalTriangle::sample`] maps to the unit direction `w`
    /// (inside the triangle): `ĉ` is where the great circle through `b` and `w` meets the
    /// arc `a c`, `u.x` the share of `Ω` the sub-triangle `a, b, ĉ` covers, and `u.y` how far
    /// `w` lies from `b` towards `ĉ` in `1 − cos`.
    #[must_use]
    pub fn invert(&self, w: Vec3A) -> Vec2 {
        let w = w.as_dvec3();
        let Some(mut c_hat) = self.b.cross(w).cross(self.a.cross(self.c)).try_normalize() else {
            return Vec2::splat(0.5);
        };
        if c_hat.dot(self.a + self.c) < 0.0 {
            c_hat = -c_hat;
        }
        let ux = area(self.a, self.b, c_hat) / self.area;
        let den = 1.0 - c_hat.dot(self.b);
        let uy = if den > 0.0 { (1.0 - w.dot(self.b)) / den } else { 0.5 };
        Vec2::new(ux.clamp(0.0, 1.0) as f32, uy.clamp(0.0, 1.0) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `invert` undoes `sample`: over triangles of all shapes (small, large, edge-on) and a
    /// grid of points of the square, the direction of the inverted point is the sampled one
    /// within 1e-4 rad, and the point itself is recovered within 1e-3 where the map is not
    /// degenerate (away from `u.y = 0`, where all `u.x` map to `b`).
    #[test]
    fn invert_undoes_sample() {
        let cases = [
            (Vec3A::ZERO, [Vec3A::new(-1.0, 1.0, -3.0), Vec3A::new(2.0, 0.5, -3.0), Vec3A::new(0.0, 2.0, -2.5)]),
            (Vec3A::ZERO, [Vec3A::new(-1.0, -1.0, 0.2), Vec3A::new(1.0, -1.0, 0.2), Vec3A::new(0.0, 1.0, 0.2)]),
            (
                Vec3A::new(0.1, 0.999, 0.1),
                [Vec3A::new(-0.2, 0.97, -0.2), Vec3A::new(0.2, 0.97, -0.2), Vec3A::new(0.2, 0.97, 0.2)],
            ),
            (Vec3A::ZERO, [Vec3A::new(10.0, 0.0, 0.0), Vec3A::new(10.0, 0.1, 0.0), Vec3A::new(10.0, 0.0, 0.1)]),
        ];
        for (x, v) in cases {
            let st = SphericalTriangle::new(x, &v).unwrap();
            for i in 0..20 {
                for j in 1..20 {
                    let u = Vec2::new((i as f32 + 0.5) / 20.0, j as f32 / 20.0);
                    let w = st.sample(u);
                    let back = st.invert(w);
                    let w2 = st.sample(back);
                    assert!((w - w2).length() < 1e-4, "{x} {v:?}: {u} -> {back}");
                    assert!((back - u).abs().max_element() < 1e-3, "{x} {v:?}: {u} -> {back}");
                }
            }
        }
    }
    use crate::geometry::{Ray, intersect_triangle};
    use crate::sampler::SampleStream;
    use crate::stats::chi_square_critical;

    /// Solid angle by Girard's theorem (corner angles by `acos`, minus π): independent of the
    /// formulas the sampler uses.
    fn solid_angle(x: Vec3A, v: &[Vec3A; 3]) -> f64 {
        let [a, b, c] = v.map(|p| (p.as_dvec3() - x.as_dvec3()).normalize());
        let corner = |p: glam::DVec3, q: glam::DVec3, r: glam::DVec3| {
            p.cross(q).normalize().dot(p.cross(r).normalize()).clamp(-1.0, 1.0).acos()
        };
        corner(a, b, c) + corner(b, c, a) + corner(c, a, b) - std::f64::consts::PI
    }

    fn tri() -> [Vec3A; 3] {
        [Vec3A::new(-0.25, 0.97, 0.2), Vec3A::new(0.25, 0.97, 0.2), Vec3A::new(0.25, 0.97, -0.2)]
    }

    #[test]
    fn solid_angle_matches_the_corner_angles() {
        let v = tri();
        for x in [
            Vec3A::new(0.0, 1.0, 0.0),
            Vec3A::new(0.3, 1.0, 0.1),
            Vec3A::new(0.1, -1.0, 0.3),
            Vec3A::new(5.0, 3.0, -2.0),
            Vec3A::new(0.1, 0.9701, 0.0),
        ] {
            let st = SphericalTriangle::new(x, &v).unwrap();
            let reference = solid_angle(x, &v);
            assert!(
                (st.solid_angle() - reference).abs() <= 1e-9 * reference.max(1.0),
                "{x}: {} vs {reference}",
                st.solid_angle()
            );
        }
        // Seen from its own plane a triangle has no solid angle.
        assert!(SphericalTriangle::new(Vec3A::new(3.0, 0.97, 0.0), &v).is_none());
    }

    /// Uniformity: the triangle is cut into 16 congruent sub-triangles (midpoint subdivision
    /// twice); each receives a share of samples equal to its solid angle over the whole's. The
    /// counts pass a chi-square test at 1e-4 (so a correct sampler fails it once in 10,000 seeds);
    /// every sample hits the triangle.
    #[test]
    fn samples_are_uniform_in_solid_angle() {
        let v = tri();
        let mut subs = vec![v];
        for _ in 0..2 {
            subs = subs
                .iter()
                .flat_map(|t| {
                    let m01 = (t[0] + t[1]) * 0.5;
                    let m12 = (t[1] + t[2]) * 0.5;
                    let m20 = (t[2] + t[0]) * 0.5;
                    [[t[0], m01, m20], [m01, t[1], m12], [m20, m12, t[2]], [m01, m12, m20]]
                })
                .collect();
        }
        for x in [Vec3A::new(0.1, 1.0, 0.05), Vec3A::new(-0.6, 0.99, 0.3), Vec3A::new(0.2, 3.0, -1.0)] {
            let st = SphericalTriangle::new(x, &v).unwrap();
            let n = 200_000;
            let mut counts = vec![0u32; subs.len()];
            let mut rng = SampleStream::new(7, 0, 0);
            let mut misses = 0;
            for _ in 0..n {
                let w = st.sample(rng.next_2d());
                let ray = Ray::new(x, w);
                misses += u32::from(intersect_triangle(&ray, &v, f32::INFINITY).is_none());
                let cell = subs.iter().position(|t| intersect_triangle(&ray, t, f32::INFINITY).is_some());
                if let Some(c) = cell {
                    counts[c] += 1;
                }
            }
            // Rounding may put a sample on the wrong side of an edge, nothing more.
            assert!(misses <= n / 10_000, "{x}: {misses} of {n} samples miss the triangle");
            let hit: u32 = counts.iter().sum();
            assert!(f64::from(hit) > 0.9999 * f64::from(n), "{x}: only {hit} of {n} samples found a sub-triangle");
            let chi2: f64 = subs
                .iter()
                .zip(&counts)
                .map(|(t, &c)| {
                    let e = f64::from(hit) * solid_angle(x, t) / st.solid_angle();
                    (f64::from(c) - e).powi(2) / e
                })
                .sum();
            let bound = chi_square_critical(subs.len() - 1, 1e-4);
            assert!(chi2 < bound, "{x}: chi-square {chi2} ≥ {bound}, counts {counts:?}");
        }
    }
}

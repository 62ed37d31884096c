//! Emitting triangles: the choice between them (by power, or among a few by their estimated
//! contribution at the shading point) and next event estimation on the chosen one, by area or
//! by solid angle (cut into parts where a light is near); the densities MIS weighs by; photon
//! emission.

use super::{Light, LightSample, LightSampling, Receiver};
use crate::geometry::spherical::{self, SphericalTriangle};
use crate::geometry::{Frame, Ray, Vec2, Vec3A, barycentric_error, luminance, offset_ray_origin, warp};
use std::f32::consts::PI;

/// A scene's emitting triangles, picked with probability ∝ power (`π · area · lum(Le)`).
#[derive(Clone, Debug, Default)]
pub struct AreaLights {
    /// Per emitter, its triangle in the scene.
    pub(crate) prims: Vec<u32>,
    areas: Vec<f32>,
    /// Per emitter, its corners and unit geometric normal.
    vertices: Vec<[Vec3A; 3]>,
    normals: Vec<Vec3A>,
    choice: Option<warp::Discrete>,
    /// The sum of the emitters' powers the choice is proportional to.
    luminous_power: f32,
    /// Per triangle of the scene, its index among the emitters (`u32::MAX` for none).
    index_of: Vec<u32>,
    /// Per emitter, whether it emits on both sides.
    two_sided: Vec<bool>,
    /// Per emitter, its radiance and that radiance's luminance (NEE reads them for every
    /// emitter it weighs: kept here, beside the other per-emitter data, not behind the
    /// triangle's material).
    emission: Vec<Vec3A>,
    luminance: Vec<f32>,
    /// Per emitter, what deciding its weight at a shading point reads first (most points in
    /// a scene lie behind most one-sided emitters): one record, not five arrays.
    planes: Vec<EmitterPlane>,
}

/// An emitter triangle's plane, and what [`AreaLights::in_front`] and [`AreaLights::far`]
/// read with it.
#[derive(Clone, Copy, Debug)]
struct EmitterPlane {
    v0: Vec3A,
    normal: Vec3A,
    centroid: Vec3A,
    /// Largest centroid–corner distance.
    radius: f32,
    /// `v0`'s largest absolute coordinate (the scale of its rounding).
    v0_scale: f32,
    two_sided: bool,
}

impl EmitterPlane {
    /// The signed height of `x` above the emitting side (both sides count when two-sided).
    #[inline(always)]
    fn facing(&self, height: f32) -> f32 {
        if self.two_sided { height.abs() } else { height }
    }
}

impl AreaLights {
    /// The emitters among `triangles` (unit geometric normals `normals`): `emission(i)` gives
    /// triangle `i`'s radiance and whether it emits on both sides, `None` when it does not emit.
    pub fn new(
        triangles: &[[Vec3A; 3]],
        normals: &[Vec3A],
        mut emission: impl FnMut(usize) -> Option<(Vec3A, bool)>,
    ) -> Self {
        let mut lights = Self { index_of: vec![u32::MAX; triangles.len()], ..Self::default() };
        let mut power = Vec::new();
        for (i, t) in triangles.iter().enumerate() {
            let Some((le, two_sided)) = emission(i) else { continue };
            lights.index_of[i] = lights.prims.len() as u32;
            let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
            lights.prims.push(i as u32);
            lights.areas.push(area);
            lights.vertices.push(*t);
            lights.normals.push(normals[i]);
            lights.two_sided.push(two_sided);
            lights.emission.push(le);
            lights.luminance.push(luminance(le));
            let centroid = (t[0] + t[1] + t[2]) / 3.0;
            let radius = t.iter().map(|&v| (v - centroid).length()).fold(0.0f32, f32::max);
            lights.planes.push(EmitterPlane {
                v0: t[0],
                normal: normals[i],
                centroid,
                radius,
                v0_scale: t[0].abs().max_element(),
                two_sided,
            });
            let sides = if two_sided { 2.0 } else { 1.0 };
            power.push(sides * PI * area * luminance(le).max(1e-6 * le.max_element()));
        }
        lights.choice = warp::Discrete::new(&power);
        lights.luminous_power = power.iter().sum::<f32>();
        lights
    }

    /// Total power, `Σ π · area · Le` (twice for two-sided emitters), RGB.
    #[must_use]
    pub fn power(&self) -> Vec3A {
        (0..self.prims.len())
            .map(|i| {
                let sides = if self.two_sided[i] { 2.0 } else { 1.0 };
                self.emission[i] * (sides * PI * self.areas[i])
            })
            .sum()
    }

    /// [`Self::sample_area`]'s density at `p`, in solid angle at `x`.
    fn area_pdf(&self, i: usize, pmf: f32, x: Vec3A, p: Vec3A) -> f32 {
        let ng = self.normals[i];
        let to = p - x;
        let dist2 = to.length_squared();
        let cos_y = self.facing(i, -ng.dot(to) / dist2.sqrt());
        if cos_y <= 0.0 {
            return 0.0;
        }
        pmf * dist2 / (cos_y * self.areas[i])
    }

    /// Emitter `i` as seen from `x` when NEE samples it by solid angle; `None` when it is far
    /// (see [`Self::far`]) or too small a solid angle, and so sampled by area.
    #[inline]
    fn spherical_triangle(&self, i: usize, x: Vec3A) -> Option<SphericalTriangle> {
        if self.far(i, x).is_some() {
            return None;
        }
        let v = &self.vertices[i];
        SphericalTriangle::new(x, v).filter(|st| st.solid_angle() >= spherical::MIN_SOLID_ANGLE)
    }

    /// [`Self::sample_solid_angle`]'s density at `p`: the same steps, each cut taking the part
    /// that contains `p`.
    fn solid_angle_pdf(&self, i: usize, pmf: f32, x: Vec3A, n: Vec3A, p: Vec3A) -> f32 {
        let v = &self.vertices[i];
        let Some(st) = self.spherical_triangle(i, x) else {
            return self.area_pdf(i, pmf, x, p);
        };
        let Some(dir) = (p - x).try_normalize() else {
            return 0.0;
        };
        // The descent, each cut taking the part that holds `p` (by its barycentrics in the
        // current triangle: a corner part where one exceeds ½).
        let holding = |tri: &[Vec3A; 3], weights: &[f32; 4], total: f32| {
            let b = barycentrics_along(x, dir, tri)?;
            let k = (0..3).find(|&c| b[c] > 0.5).unwrap_or(3);
            (total > 0.0 && weights[k] > 0.0).then(|| (k, weights[k] / total))
        };
        let Some((_, st, pmf)) = self.descend(x, n, v, st, pmf, holding) else {
            return 0.0;
        };
        let Some(w) = st.cosine_warp_weights(n) else {
            return 0.0;
        };
        let u = st.invert(dir);
        (f64::from(pmf * warp::bilinear_pdf(u, w)) / st.solid_angle()) as f32
    }

    /// Whether emitter `i` is far from `x`: its bounding radius below [`NEAR_RATIO`] of the
    /// distance to its centroid, and `x` at least that radius away from the emitter's plane
    /// (not grazing). Then `cosθx·cosθy/d²` varies little over the emitter, and area sampling
    /// is about as good as solid-angle sampling and far cheaper. Returns the centroid offset,
    /// its squared length and the radius, for the caller's weight.
    #[inline]
    fn far(&self, i: usize, x: Vec3A) -> Option<(Vec3A, f32, f32)> {
        let e = &self.planes[i];
        let to = e.centroid - x;
        let d2 = to.length_squared();
        let height = e.facing(-e.normal.dot(to));
        (e.radius * e.radius < NEAR_RATIO * NEAR_RATIO * d2 && height >= e.radius).then_some((to, d2, e.radius))
    }

    /// The cosine at emitter `i` towards a receiver, counted on either side when it emits on
    /// both.
    #[inline]
    fn facing(&self, i: usize, cos: f32) -> f32 {
        self.planes[i].facing(cos)
    }

    /// Whether `x` lies on the emitting side of emitter `i` (one-sided emitters: nothing
    /// reaches a point behind, or in, the emitting plane).
    #[inline]
    pub(crate) fn in_front(&self, i: usize, x: Vec3A) -> bool {
        let e = &self.planes[i];
        // Not within rounding of the plane: a point on the emitter itself (its hit point may
        // sit a few ulps in front) sees it edge-on, i.e. gets nothing from it, but sampling it
        // from there gave a point ~1e-7 away with a weight of 5e5 (the furnace, 1 sample in
        // 10⁷). The margin is far below any distance a scene resolves.
        let height = e.facing((x - e.v0).dot(e.normal));
        height > IN_FRONT_MARGIN * (1.0 + x.abs().max_element().max(e.v0_scale))
    }

    /// A weight for emitter `i` at `x` (normal `n`) proportional to an estimate of its
    /// unoccluded contribution there, zero only where the contribution is zero: `lum(Le)` times
    /// `∫ cosθ dω` over the triangle, estimated as Ω times the mean cosine warp weight (or, below
    /// [`spherical::MIN_SOLID_ANGLE`], as `A·cosθy/d²` at the centroid times the largest corner
    /// cosine).
    #[inline(always)]
    fn weight(&self, i: usize, x: Vec3A, n: Vec3A) -> f32 {
        if !self.in_front(i, x) {
            return 0.0;
        }
        let v = &self.vertices[i];
        let lum = self.luminance[i];
        if let Some((to, d2, radius)) = self.far(i, x) {
            // A ≈ A·cosθy/d²·cosθx at the centroid; every direction to the triangle is within
            // radius/d (in sine) of the centroid's, so its cosine at x is below
            // cosθx + radius/d: zero weight only when that bound is not positive.
            let d = d2.sqrt();
            let cos_y = self.facing(i, -self.planes[i].normal.dot(to) / d);
            let cos_x = n.dot(to) / d;
            if cos_x + radius / d <= 0.0 {
                return 0.0;
            }
            let weight = lum * self.areas[i] * cos_y.max(0.0) / d2 * cos_x.max(0.1 * radius / d);
            return if weight.is_finite() && weight > 0.0 { weight } else { f32::MIN_POSITIVE };
        }
        let Some(part) = spherical::part_stats(x, v, n) else {
            return 0.0;
        };
        let cosines = part.cosines;
        if spherical::cosine_warp_weights(cosines).is_none() {
            return 0.0;
        }
        if f64::from(part.omega) >= spherical::MIN_SOLID_ANGLE {
            // The unoccluded ∫cosθ dω (Lambert), floored at 1% of Ω where the triangle
            // straddles the horizon.
            return lum * part.projected.max(0.01 * part.omega);
        }
        let to = self.planes[i].centroid - x;
        let d2 = to.length_squared();
        let cos_y = self.facing(i, -self.planes[i].normal.dot(to) / d2.sqrt()).max(0.0);
        let weight = lum * self.areas[i] * cos_y / d2 * cosines[0].max(cosines[1]).max(cosines[2]);
        if weight.is_finite() && weight > 0.0 { weight } else { f32::MIN_POSITIVE }
    }

    /// A point on emitter `i` (chosen with probability `pmf`) by solid angle: Arvo's uniform
    /// direction warped bilinearly towards the corners with the larger cosine at `x`, so that
    /// the weight `cosθx/pdf` is nearly constant; by area below [`spherical::MIN_SOLID_ANGLE`].
    fn sample_solid_angle(&self, i: usize, pmf: f32, x: Vec3A, n: Vec3A, mut u_point: Vec2) -> Option<LightSample> {
        let prim = self.prims[i];
        let v = &self.vertices[i];
        let Some(st) = self.spherical_triangle(i, x) else {
            return self.sample_area(i, pmf, x, u_point);
        };
        // Cut the emitter where the cosine varies much (see `descend`).
        let pick = |_: &[Vec3A; 3], weights: &[f32; 4], total: f32| {
            // `u.x` picks the part; rescaled, it is uniform again for what follows.
            let (k, p, ux) = warp::pick_by_weight_reusing(weights, total, u_point.x)?;
            u_point.x = ux;
            Some((k, p))
        };
        let (tri, st, pmf) = self.descend(x, n, v, st, pmf, pick)?;
        let w = st.cosine_warp_weights(n)?;
        let u = warp::bilinear(u_point, w);
        let pdf_u = warp::bilinear_pdf(u, w);
        let dir = st.sample(u);
        // Where the sampled direction meets the triangle, as barycentrics (clamped into the
        // triangle against rounding) so that the point carries the usual error bound.
        let b = barycentrics_along(x, dir, &tri)?;
        let inv_pdf = (st.solid_angle() / f64::from(pmf * pdf_u)) as f32;
        let (p, p_err) = point_on(&tri, b);
        (inv_pdf.is_finite() && inv_pdf > 0.0).then(|| LightSample {
            prim,
            delta: false,
            infinite: false,
            p,
            p_err,
            ng: self.normals[i],
            emission: self.emission[i],
            inv_pdf,
        })
    }

    /// NEE's descent into emitter triangle `v` seen from `x` (normal `n`; `st` its spherical
    /// triangle, `pmf` the probability of having chosen it). Where the cosine at `x` varies
    /// much over the triangle (it can peak inside, away from the corners the warp
    /// interpolates: on the ceiling 0.03 above the light, next to its edge), the triangle is
    /// cut in four by its edge midpoints, again and again, each time descending into one part,
    /// until the cosine varies little over the part. `choose` picks the part from the current
    /// triangle and the parts' weights (their unoccluded contribution `∫cosθ dω`, floored at
    /// 1% of their `Ω` so that no part the cosine reaches is left out) and returns it with its
    /// probability: by a random number when sampling, as the part holding a given point when
    /// replaying. The parts tile the emitter exactly, so the density is the product of the
    /// choices' probabilities (returned with the final part) times the warp's density in it.
    #[inline]
    fn descend(
        &self,
        x: Vec3A,
        n: Vec3A,
        v: &[Vec3A; 3],
        st: SphericalTriangle,
        mut pmf: f32,
        mut choose: impl FnMut(&[Vec3A; 3], &[f32; 4], f32) -> Option<(usize, f32)>,
    ) -> Option<([Vec3A; 3], SphericalTriangle, f32)> {
        let mut tri = *v;
        let mut part =
            spherical::PartStats { projected: 0.0, omega: st.solid_angle() as f32, cosines: st.corner_cosines(n) };
        let mut cut = false;
        let mut dirs = None;
        for _ in 0..MAX_NEE_SUBDIVISIONS {
            // Stop on what is known of the current part only (never on the part a number
            // picks), so that the density is the one sampled.
            let c = part.cosines;
            let (lo, hi) = (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]));
            let smooth = part.omega < SUBDIVIDE_SOLID_ANGLE as f32 && lo > 0.0 && hi < COSINE_SPREAD * lo;
            if smooth || part.omega < 0.01 {
                break;
            }
            let d = match dirs {
                Some(d) => d,
                None => spherical::unit_corners(x, &tri)?,
            };
            let (parts, part_dirs, stats) = spherical::subdivide(x, &tri, &d, n);
            // Lambert's ∫cosθ dω in f32: only the choice depends on it.
            let weights = stats.map(|ps| ps.map_or(0.0, |ps| ps.projected.max(0.01 * ps.omega)));
            let total = weights.iter().sum();
            let (k, p) = choose(&tri, &weights, total)?;
            let chosen = stats[k]?;
            (tri, part, pmf, cut, dirs) = (parts[k], chosen, pmf * p, true, Some(part_dirs[k]));
        }
        // A part of at least 64·MIN_SOLID_ANGLE / 4 steradians: Arvo's construction is sound.
        let st = if cut { SphericalTriangle::new(x, &tri)? } else { st };
        Some((tri, st, pmf))
    }

    /// A uniform point on the area of emitter `i` (chosen with probability `pmf`).
    fn sample_area(&self, i: usize, pmf: f32, x: Vec3A, u_point: Vec2) -> Option<LightSample> {
        let prim = self.prims[i];
        let v = &self.vertices[i];
        let ng = self.normals[i];
        let (p, p_err) = point_on(v, warp::uniform_triangle(u_point));
        let to = p - x;
        let dist2 = to.length_squared();
        let cos_y = self.facing(i, -ng.dot(to) / dist2.sqrt());
        let inv_pdf = cos_y * self.areas[i] / (dist2 * pmf);
        (inv_pdf.is_finite() && inv_pdf > 0.0).then(|| LightSample {
            prim,
            delta: false,
            infinite: false,
            p,
            p_err,
            ng,
            emission: self.emission[i],
            inv_pdf,
        })
    }
}

impl Light for AreaLights {
    /// With [`LightSampling::Area`] the triangle is chosen by power (ALGORITHM.md §3). With
    /// [`LightSampling::SolidAngle`] and at most [`FEW_EMITTERS`] emitter triangles, it is
    /// chosen by an estimate of its unoccluded contribution at `x` instead (a quad light seen
    /// from beside one edge gets nearly all of it from one of its two triangles); with more,
    /// by power. `None` when the chosen triangle cannot light `x` (`x` behind its emitting
    /// side, or the triangle below `x`'s horizon).
    fn sample_from(&self, at: &Receiver, u_pick: f32, u_point: Vec2, pick: f32) -> Option<LightSample> {
        let (x, n) = (at.x, at.n);
        let choice = self.choice.as_ref()?;
        match at.strategy {
            LightSampling::Area => {
                let (i, pmf) = choice.sample(u_pick);
                self.in_front(i, x).then(|| self.sample_area(i, pick * pmf, x, u_point))?
            }
            LightSampling::SolidAngle if self.prims.len() <= FEW_EMITTERS => {
                let count = self.prims.len();
                let mut weights = [0.0f32; FEW_EMITTERS];
                let mut total = 0.0;
                for (i, w) in weights.iter_mut().enumerate().take(count) {
                    *w = self.weight(i, x, n);
                    total += *w;
                }
                let (i, pmf) = warp::pick_by_weight(&weights[..count], total, u_pick)?;
                self.sample_solid_angle(i, pick * pmf, x, n, u_point)
            }
            LightSampling::SolidAngle => {
                let (i, pmf) = choice.sample(u_pick);
                self.in_front(i, x).then(|| self.sample_solid_angle(i, pick * pmf, x, n, u_point))?
            }
        }
    }

    /// Replays the sampler's choices: the emitter, each cut part containing `p`, the cosine
    /// warp inverted at `p`'s direction. 0 where the sampler cannot reach `p` (and for a
    /// triangle that does not emit).
    fn pdf_from(&self, at: &Receiver, prim: u32, p: Vec3A) -> f32 {
        let (x, n) = (at.x, at.n);
        let Some(choice) = self.choice.as_ref() else {
            return 0.0;
        };
        let i = match self.index_of.get(prim as usize) {
            Some(&i) if i != u32::MAX => i as usize,
            _ => return 0.0,
        };
        match at.strategy {
            LightSampling::Area => {
                if !self.in_front(i, x) {
                    return 0.0;
                }
                self.area_pdf(i, choice.pmf(i), x, p)
            }
            LightSampling::SolidAngle if self.prims.len() <= FEW_EMITTERS => {
                let mut total = 0.0;
                let mut mine = 0.0;
                for k in 0..self.prims.len() {
                    let w = self.weight(k, x, n);
                    total += w;
                    if k == i {
                        mine = w;
                    }
                }
                if mine <= 0.0 || total.is_nan() || total <= 0.0 {
                    return 0.0;
                }
                self.solid_angle_pdf(i, mine / total, x, n, p)
            }
            LightSampling::SolidAngle => {
                if !self.in_front(i, x) {
                    return 0.0;
                }
                self.solid_angle_pdf(i, choice.pmf(i), x, n, p)
            }
        }
    }

    fn luminous_power(&self, _radius: f32) -> f32 {
        self.luminous_power
    }

    /// A triangle by power, a uniform point on it and a cosine direction on its emitting
    /// side (a side picked at random on a two-sided one).
    fn emit_photon(&self, u_pick: f32, u_point: Vec2, u_dir: Vec2, _: (Vec3A, f32), pick: f32) -> Option<(Ray, Vec3A)> {
        let (i, pmf, u_side) = self.choice.as_ref()?.sample_reusing(u_pick);
        let (p, p_err) = point_on(&self.vertices[i], warp::uniform_triangle(u_point));
        let mut ng = self.normals[i];
        let mut sides = 1.0;
        if self.two_sided[i] {
            sides = 2.0;
            if u_side < 0.5 {
                ng = -ng;
            }
        }
        let dir = Frame::from_normal(ng).to_world(warp::cosine_hemisphere(u_dir));
        let pdf_area = pick * pmf / self.areas[i];
        let flux = self.emission[i] * (sides * PI / pdf_area);
        Some((Ray::new(offset_ray_origin(p, p_err, ng, dir), dir), flux))
    }
}

/// Solid-angle sampling is used for an emitter whose bounding radius is at least this fraction
/// of its distance, or whose plane is closer to the shading point than that radius (grazing
/// light, as under cornell-paper's ceiling); others are sampled by area: same estimate, far
/// cheaper. On cornell-classic, whose light most points see from afar, solid-angle sampling
/// everywhere doubled the render time for the same variance.
pub const NEAR_RATIO: f32 = 0.5;

/// Up to this many emitter triangles, solid-angle light sampling weighs every emitter at every
/// shading point (a few Arvo set-ups); beyond it, emitters are chosen by power.
pub const FEW_EMITTERS: usize = 8;

/// The point of triangle `v` at barycentrics `b`, with its error bound.
#[inline]
fn point_on(v: &[Vec3A; 3], b: [f32; 3]) -> (Vec3A, Vec3A) {
    (v[0] * b[0] + v[1] * b[1] + v[2] * b[2], barycentric_error(b, v))
}

/// Relative distance in front of an emitter's plane below which a point gets nothing from it.
pub const IN_FRONT_MARGIN: f32 = 1e-5;

/// NEE keeps cutting an emitter triangle (see [`AreaLights`]) while its solid
/// angle exceeds this (steradians) or its corner cosines differ by more than [`COSINE_SPREAD`]×,
/// at most [`MAX_NEE_SUBDIVISIONS`] times. 0.2 sr and 3× against 0.05 sr and 1.5×: zvidpt on
/// cornell-paper at 32 spp MSE×s 0.206 vs 0.232 (same MSE, fewer cuts); path 64 spp 8% faster
/// for +0.6% MSE. (0.4 sr and 4×: 0.243; at most 2 cuts: 0.40; none: 0.90.)
pub const SUBDIVIDE_SOLID_ANGLE: f64 = 0.2;
pub const COSINE_SPREAD: f32 = 3.0;
pub const MAX_NEE_SUBDIVISIONS: u32 = 6;

/// Barycentrics of the point where the ray from `x` along `w` meets the plane of `v`, clamped
/// into the triangle; `None` if the ray is parallel to the plane.
fn barycentrics_along(x: Vec3A, w: Vec3A, v: &[Vec3A; 3]) -> Option<[f32; 3]> {
    let (x, w) = (x.as_dvec3(), w.as_dvec3());
    let [v0, v1, v2] = v.map(|p| p.as_dvec3());
    let (e1, e2) = (v1 - v0, v2 - v0);
    let n = e1.cross(e2);
    let t = (v0 - x).dot(n) / w.dot(n);
    if !t.is_finite() {
        return None;
    }
    let d = x + w * t - v0;
    let inv = 1.0 / n.length_squared();
    let b1 = d.cross(e2).dot(n) * inv;
    let b2 = e1.cross(d).dot(n) * inv;
    let b = [(1.0 - b1 - b2).max(0.0), b1.max(0.0), b2.max(0.0)];
    let sum = b[0] + b[1] + b[2];
    (sum > 0.0).then(|| b.map(|c| (c / sum) as f32))
}

//! Light sampling over all of a scene's lights: the choice between light groups (emitting
//! triangles, point and spot lights, distant lights, the environment) by power; next event
//! estimation on emitting triangles by area or by solid angle (a triangle chosen by power, or
//! among a few by its estimated contribution at the shading point; cut into parts where a
//! light is near); the densities MIS weighs by; emitted power; and photon emission.

use crate::geometry::spherical::{self, SphericalTriangle};
use crate::geometry::{Frame, Ray, Vec2, Vec3A, barycentric_error, offset_ray_origin, warp};
use crate::light::envmap::Environment;
use crate::light::point::PointLight;
use std::f32::consts::PI;

use super::*;

/// Emitter triangles picked with probability ∝ power (`π · area · lum(Le)`).
#[derive(Clone, Debug, Default)]
pub(super) struct Emitters {
    pub(super) prims: Vec<u32>,
    pub(super) areas: Vec<f32>,
    /// Centroid and bounding radius (largest centroid–corner distance) of each emitter: what
    /// decides whether a shading point is near enough for solid-angle sampling to pay.
    pub(super) bounds: Vec<(Vec3A, f32)>,
    pub(super) choice: Option<warp::Discrete>,
    /// Per triangle, its index among the emitters (`u32::MAX` for none).
    pub(super) index_of: Vec<u32>,
    /// Per emitter, whether it emits on both sides.
    pub(super) two_sided: Vec<bool>,
    /// Per emitter, its radiance and that radiance's luminance (NEE reads them for every
    /// emitter it weighs: kept here, beside the other per-emitter data, not behind the
    /// triangle's material).
    pub(super) emission: Vec<Vec3A>,
    pub(super) luminance: Vec<f32>,
    /// Per emitter, what deciding its weight at a shading point reads first (most points in
    /// a scene lie behind most one-sided emitters): one record, not five arrays.
    pub(super) planes: Vec<EmitterPlane>,
}

/// An emitter triangle's plane, and what [`Scene::in_front`] and [`Scene::far`] read with it.
#[derive(Clone, Copy, Debug)]
pub(super) struct EmitterPlane {
    pub(super) v0: Vec3A,
    pub(super) normal: Vec3A,
    pub(super) centroid: Vec3A,
    /// Largest centroid–corner distance.
    pub(super) radius: f32,
    /// `v0`'s largest absolute coordinate (the scale of its rounding).
    pub(super) v0_scale: f32,
    pub(super) two_sided: bool,
}

impl EmitterPlane {
    /// The signed height of `x` above the emitting side (both sides count when two-sided).
    #[inline(always)]
    fn facing(&self, height: f32) -> f32 {
        if self.two_sided { height.abs() } else { height }
    }
}

/// Lights that are not emitting surfaces.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Point and spot lights.
    pub points: Vec<PointLight>,
    /// Distant (directional) lights.
    pub distant: Vec<crate::light::DistantLight>,
    /// The environment, if any.
    pub environment: Option<Environment>,
}

/// Which kind of light a [`Scene`]'s light choice picked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Group {
    Triangles,
    Point(usize),
    Distant(usize),
    Environment,
}

/// How next event estimation picks a point on the chosen emitter triangle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LightSampling {
    /// A uniform point on the triangle's area (ALGORITHM.md §3).
    Area,
    /// A direction in the solid angle the triangle subtends (Arvo 1995), warped bilinearly by
    /// the cosine at the shading point's corners (as pbrt-v4 does), for emitters within reach
    /// (bounding radius ≥ [`NEAR_RATIO`] × distance, or grazing); others, and any below
    /// [`spherical::MIN_SOLID_ANGLE`], by area. Bounded weights next to an emitter, where area
    /// sampling's `cosθx·cosθy/d²` is unbounded.
    #[default]
    SolidAngle,
}

/// A point on an emitter chosen for one shading point, with the inverse of its density with
/// respect to solid angle at that point.
#[derive(Clone, Copy, Debug)]
pub struct DirectSample {
    /// The emitter triangle (`u32::MAX` for other lights).
    pub prim: u32,
    /// A point or spot light (no density: never weighed against BSDF sampling).
    pub delta: bool,
    /// The environment: `p` is then the unit direction towards it, and nothing is in the way
    /// unless a surface is.
    pub infinite: bool,
    /// The point sampled (for the environment, the direction to it).
    pub p: Vec3A,
    /// Bound on the error of `p`.
    pub p_err: Vec3A,
    /// The emitter's geometric normal there.
    pub ng: Vec3A,
    /// Radiance emitted towards the shading point.
    pub emission: Vec3A,
    /// `1/pdf(ω)` in steradians: `cosθy/(d²·pdf_area)` for area sampling, `Ω/P(triangle)` for
    /// solid-angle sampling.
    pub inv_pdf: f32,
}

impl Scene {
    /// Whether anything emits (surfaces, point lights, the environment).
    #[must_use]
    pub fn has_emitters(&self) -> bool {
        self.groups.is_some()
    }

    /// The light group of index `g` in [`Scene::groups`].
    #[inline]
    pub(super) fn group(&self, g: usize) -> Group {
        match g {
            0 => Group::Triangles,
            g if g <= self.lights.points.len() => Group::Point(g - 1),
            g if g <= self.lights.points.len() + self.lights.distant.len() => {
                Group::Distant(g - 1 - self.lights.points.len())
            }
            _ => Group::Environment,
        }
    }

    /// Probability that the light choice picks the emitting triangles (as a group).
    #[inline]
    pub(super) fn triangles_pmf(&self) -> f32 {
        self.groups.as_ref().map_or(0.0, |g| g.pmf(0))
    }

    /// Radiance arriving from the environment along unit direction `d` (zero without one).
    #[inline]
    #[must_use]
    pub fn environment(&self, d: Vec3A) -> Vec3A {
        self.lights.environment.as_ref().map_or(Vec3A::ZERO, |e| e.eval(d))
    }

    /// The density (solid angle) with which NEE picks environment direction `d`.
    #[inline]
    #[must_use]
    pub fn environment_pdf(&self, d: Vec3A) -> f32 {
        match (&self.lights.environment, &self.groups) {
            (Some(env), Some(g)) => g.pmf(g.len() - 1) * env.pdf(d),
            _ => 0.0,
        }
    }

    /// Total power emitted by surfaces, `Σ π · area · Le` (twice for two-sided ones), and
    /// point lights (RGB).
    #[must_use]
    pub fn emitted_power(&self) -> Vec3A {
        let surfaces: Vec3A = (0..self.emitters.prims.len())
            .map(|i| {
                let sides = if self.emitters.two_sided[i] { 2.0 } else { 1.0 };
                self.material_of(self.emitters.prims[i]).emission * (sides * PI * self.emitters.areas[i])
            })
            .sum();
        surfaces
            + self.lights.points.iter().map(PointLight::power).sum::<Vec3A>()
            + self.lights.distant.iter().map(|l| l.power_through(self.bounds.1)).sum::<Vec3A>()
    }

    /// The start of a photon path: a light by power (`u_pick`), then a point on it
    /// (`u_point`) and a direction (`u_dir`): on an emitting triangle (chosen by power) a
    /// uniform point and a cosine direction on its emitting side (a side picked at random on a
    /// two-sided one); from a point or spot light its [`PointLight::emit`]; from the
    /// environment a direction by its sampling, entering through a uniform point of the disc
    /// of the bounding sphere facing it. Returns the ray and its flux (`None` when nothing
    /// emits).
    #[must_use]
    pub fn emit_photon(&self, u_pick: f32, u_point: Vec2, u_dir: Vec2) -> Option<(Ray, Vec3A)> {
        let groups = self.groups.as_ref()?;
        let (g, group_pmf, u_pick) = groups.sample_reusing(u_pick);
        match self.group(g) {
            Group::Triangles => {
                let (i, pmf, u_side) = self.emitters.choice.as_ref()?.sample_reusing(u_pick);
                let prim = self.emitters.prims[i];
                let (p, p_err) = point_on(&self.triangles[prim as usize], warp::uniform_triangle(u_point));
                let mut ng = self.normals[prim as usize];
                let mut sides = 1.0;
                if self.emitters.two_sided[i] {
                    sides = 2.0;
                    if u_side < 0.5 {
                        ng = -ng;
                    }
                }
                let dir = Frame::from_normal(ng).to_world(warp::cosine_hemisphere(u_dir));
                let pdf_area = group_pmf * pmf / self.emitters.areas[i];
                let flux = self.material_of(prim).emission * (sides * PI / pdf_area);
                Some((Ray::new(offset_ray_origin(p, p_err, ng, dir), dir), flux))
            }
            Group::Point(k) => {
                let e = self.lights.points[k].emit(u_dir);
                Some((Ray::new(e.origin, e.direction), e.weight / group_pmf))
            }
            Group::Distant(k) => {
                let (origin, dir, flux) = self.lights.distant[k].emit(self.bounds.0, self.bounds.1, u_point);
                Some((Ray::new(origin, dir), flux / group_pmf))
            }
            Group::Environment => {
                let env = self.lights.environment.as_ref()?;
                let s = env.sample(u_dir)?;
                let (centre, radius) = self.bounds;
                let disc = warp::uniform_disk(u_point) * radius;
                let frame = Frame::from_normal(s.direction);
                let origin = centre + s.direction * radius + frame.s * disc.x + frame.t * disc.y;
                let flux = s.radiance * (PI * radius * radius / (s.pdf * group_pmf));
                Some((Ray::new(origin, -s.direction), flux))
            }
        }
    }

    /// A point on an emitter for next event estimation at `x` (shading normal `n`), by
    /// `strategy`. `None` when the chosen triangle cannot light `x` (`x` behind its emitting
    /// side, or the triangle below `x`'s horizon) or nothing emits.
    ///
    /// With [`LightSampling::Area`] the triangle is chosen by power (ALGORITHM.md §3). With
    /// [`LightSampling::SolidAngle`] and at most [`FEW_EMITTERS`] emitter triangles, it is
    /// chosen by an estimate of its unoccluded contribution at `x` instead (a quad light seen
    /// from beside one edge gets nearly all of it from one of its two triangles); with more,
    /// by power.
    #[must_use]
    pub fn sample_emitter_from(
        &self,
        x: Vec3A,
        n: Vec3A,
        strategy: LightSampling,
        u_pick: f32,
        u_point: Vec2,
    ) -> Option<DirectSample> {
        let groups = self.groups.as_ref()?;
        // Emitting triangles alone (the common case) need no choice of group.
        let (g, group_pmf, u_pick) = if groups.len() == 1 { (0, 1.0, u_pick) } else { groups.sample_reusing(u_pick) };
        match self.group(g) {
            Group::Triangles => {}
            Group::Point(k) => {
                let l = self.lights.points[k].sample_from(x)?;
                return Some(DirectSample {
                    prim: u32::MAX,
                    delta: true,
                    infinite: false,
                    p: self.lights.points[k].position,
                    p_err: Vec3A::ZERO,
                    ng: -l.direction,
                    emission: l.irradiance,
                    inv_pdf: 1.0 / group_pmf,
                });
            }
            Group::Distant(k) => {
                let l = &self.lights.distant[k];
                // As an infinite light: `p` is the direction towards it.
                return Some(DirectSample {
                    prim: u32::MAX,
                    delta: true,
                    infinite: true,
                    p: -l.direction,
                    p_err: Vec3A::ZERO,
                    ng: l.direction,
                    emission: l.irradiance,
                    inv_pdf: 1.0 / group_pmf,
                });
            }
            Group::Environment => {
                let s = self.lights.environment.as_ref()?.sample(u_point)?;
                return Some(DirectSample {
                    prim: u32::MAX,
                    delta: false,
                    infinite: true,
                    p: s.direction,
                    p_err: Vec3A::ZERO,
                    ng: -s.direction,
                    emission: s.radiance,
                    inv_pdf: 1.0 / (group_pmf * s.pdf),
                });
            }
        }
        let choice = self.emitters.choice.as_ref()?;
        match strategy {
            LightSampling::Area => {
                let (i, pmf) = choice.sample(u_pick);
                self.in_front(i, x).then(|| self.sample_area(i, group_pmf * pmf, x, u_point))?
            }
            LightSampling::SolidAngle if self.emitters.prims.len() <= FEW_EMITTERS => {
                let count = self.emitters.prims.len();
                let mut weights = [0.0f32; FEW_EMITTERS];
                let mut total = 0.0;
                for (i, w) in weights.iter_mut().enumerate().take(count) {
                    *w = self.weight(i, x, n);
                    total += *w;
                }
                let (i, pmf) = warp::pick_by_weight(&weights[..count], total, u_pick)?;
                self.sample_solid_angle(i, group_pmf * pmf, x, n, u_point)
            }
            LightSampling::SolidAngle => {
                let (i, pmf) = choice.sample(u_pick);
                self.in_front(i, x).then(|| self.sample_solid_angle(i, group_pmf * pmf, x, n, u_point))?
            }
        }
    }

    /// The density, in solid angle at `x`, with which [`Scene::sample_emitter_from`] (same
    /// `x`, `n` and `strategy`) picks the point `p` of emitter triangle `prim`: what multiple
    /// importance sampling weighs a direction that hit `p` by. Replays the sampler's choices:
    /// the emitter, each cut part containing `p`, the cosine warp inverted at `p`'s direction.
    /// 0 where the sampler cannot reach `p` (and for a triangle that does not emit).
    #[must_use]
    pub fn emitter_pdf(&self, x: Vec3A, n: Vec3A, strategy: LightSampling, prim: u32, p: Vec3A) -> f32 {
        let Some(choice) = self.emitters.choice.as_ref() else {
            return 0.0;
        };
        let i = match self.emitters.index_of.get(prim as usize) {
            Some(&i) if i != u32::MAX => i as usize,
            _ => return 0.0,
        };
        let group_pmf = self.triangles_pmf();
        let pdf = group_pmf
            * match strategy {
                LightSampling::Area => {
                    if !self.in_front(i, x) {
                        return 0.0;
                    }
                    self.area_pdf(i, choice.pmf(i), x, p)
                }
                LightSampling::SolidAngle if self.emitters.prims.len() <= FEW_EMITTERS => {
                    let mut total = 0.0;
                    let mut mine = 0.0;
                    for k in 0..self.emitters.prims.len() {
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
            };
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    /// [`Scene::sample_area`]'s density at `p`, in solid angle at `x`.
    pub(super) fn area_pdf(&self, i: usize, pmf: f32, x: Vec3A, p: Vec3A) -> f32 {
        let ng = self.normals[self.emitters.prims[i] as usize];
        let to = p - x;
        let dist2 = to.length_squared();
        let cos_y = self.facing(i, -ng.dot(to) / dist2.sqrt());
        if cos_y <= 0.0 {
            return 0.0;
        }
        pmf * dist2 / (cos_y * self.emitters.areas[i])
    }

    /// Emitter `i` as seen from `x` when NEE samples it by solid angle; `None` when it is far
    /// (see [`Scene::far`]) or too small a solid angle, and so sampled by area.
    #[inline]
    pub(super) fn spherical_triangle(&self, i: usize, x: Vec3A) -> Option<SphericalTriangle> {
        if self.far(i, x).is_some() {
            return None;
        }
        let v = &self.triangles[self.emitters.prims[i] as usize];
        SphericalTriangle::new(x, v).filter(|st| st.solid_angle() >= spherical::MIN_SOLID_ANGLE)
    }

    /// [`Scene::sample_solid_angle`]'s density at `p`: the same steps, each cut taking the part
    /// that contains `p`.
    pub(super) fn solid_angle_pdf(&self, i: usize, pmf: f32, x: Vec3A, n: Vec3A, p: Vec3A) -> f32 {
        let v = &self.triangles[self.emitters.prims[i] as usize];
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
    pub(super) fn far(&self, i: usize, x: Vec3A) -> Option<(Vec3A, f32, f32)> {
        let e = &self.emitters.planes[i];
        let to = e.centroid - x;
        let d2 = to.length_squared();
        let height = e.facing(-e.normal.dot(to));
        (e.radius * e.radius < NEAR_RATIO * NEAR_RATIO * d2 && height >= e.radius).then_some((to, d2, e.radius))
    }

    /// The cosine at emitter `i` towards a receiver, counted on either side when it emits on
    /// both.
    #[inline]
    pub(super) fn facing(&self, i: usize, cos: f32) -> f32 {
        self.emitters.planes[i].facing(cos)
    }

    /// Whether `x` lies on the emitting side of emitter `i` (one-sided emitters: nothing
    /// reaches a point behind, or in, the emitting plane).
    #[inline]
    pub(super) fn in_front(&self, i: usize, x: Vec3A) -> bool {
        let e = &self.emitters.planes[i];
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
    pub(super) fn weight(&self, i: usize, x: Vec3A, n: Vec3A) -> f32 {
        if !self.in_front(i, x) {
            return 0.0;
        }
        let prim = self.emitters.prims[i];
        let v = &self.triangles[prim as usize];
        let lum = self.emitters.luminance[i];
        if let Some((to, d2, radius)) = self.far(i, x) {
            // A ≈ A·cosθy/d²·cosθx at the centroid; every direction to the triangle is within
            // radius/d (in sine) of the centroid's, so its cosine at x is below
            // cosθx + radius/d: zero weight only when that bound is not positive.
            let d = d2.sqrt();
            let cos_y = self.facing(i, -self.emitters.planes[i].normal.dot(to) / d);
            let cos_x = n.dot(to) / d;
            if cos_x + radius / d <= 0.0 {
                return 0.0;
            }
            let weight = lum * self.emitters.areas[i] * cos_y.max(0.0) / d2 * cos_x.max(0.1 * radius / d);
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
        let to = self.emitters.planes[i].centroid - x;
        let d2 = to.length_squared();
        let cos_y = self.facing(i, -self.emitters.planes[i].normal.dot(to) / d2.sqrt()).max(0.0);
        let weight = lum * self.emitters.areas[i] * cos_y / d2 * cosines[0].max(cosines[1]).max(cosines[2]);
        if weight.is_finite() && weight > 0.0 { weight } else { f32::MIN_POSITIVE }
    }

    /// A point on emitter `i` (chosen with probability `pmf`) by solid angle: Arvo's uniform
    /// direction warped bilinearly towards the corners with the larger cosine at `x`, so that
    /// the weight `cosθx/pdf` is nearly constant; by area below [`spherical::MIN_SOLID_ANGLE`].
    pub(super) fn sample_solid_angle(
        &self,
        i: usize,
        pmf: f32,
        x: Vec3A,
        n: Vec3A,
        mut u_point: Vec2,
    ) -> Option<DirectSample> {
        let prim = self.emitters.prims[i];
        let v = &self.triangles[prim as usize];
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
        (inv_pdf.is_finite() && inv_pdf > 0.0).then(|| DirectSample {
            prim,
            delta: false,
            infinite: false,
            p,
            p_err,
            ng: self.normals[prim as usize],
            emission: self.emitters.emission[i],
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
    pub(super) fn descend(
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
    pub(super) fn sample_area(&self, i: usize, pmf: f32, x: Vec3A, u_point: Vec2) -> Option<DirectSample> {
        let prim = self.emitters.prims[i];
        let v = &self.triangles[prim as usize];
        let ng = self.normals[prim as usize];
        let (p, p_err) = point_on(v, warp::uniform_triangle(u_point));
        let to = p - x;
        let dist2 = to.length_squared();
        let cos_y = self.facing(i, -ng.dot(to) / dist2.sqrt());
        let inv_pdf = cos_y * self.emitters.areas[i] / (dist2 * pmf);
        (inv_pdf.is_finite() && inv_pdf > 0.0).then(|| DirectSample {
            prim,
            delta: false,
            infinite: false,
            p,
            p_err,
            ng,
            emission: self.emitters.emission[i],
            inv_pdf,
        })
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
pub(super) fn point_on(v: &[Vec3A; 3], b: [f32; 3]) -> (Vec3A, Vec3A) {
    (v[0] * b[0] + v[1] * b[1] + v[2] * b[2], barycentric_error(b, v))
}

/// Relative distance in front of an emitter's plane below which a point gets nothing from it.
pub const IN_FRONT_MARGIN: f32 = 1e-5;

/// NEE keeps cutting an emitter triangle (see [`Scene::sample_solid_angle`]) while its solid
/// angle exceeds this (steradians) or its corner cosines differ by more than [`COSINE_SPREAD`]×,
/// at most [`MAX_NEE_SUBDIVISIONS`] times. 0.2 sr and 3× against 0.05 sr and 1.5×: zvidpt on
/// cornell-paper at 32 spp MSE×s 0.206 vs 0.232 (same MSE, fewer cuts); path 64 spp 8% faster
/// for +0.6% MSE. (0.4 sr and 4×: 0.243; at most 2 cuts: 0.40; none: 0.90.)
pub const SUBDIVIDE_SOLID_ANGLE: f64 = 0.2;
pub const COSINE_SPREAD: f32 = 3.0;
pub const MAX_NEE_SUBDIVISIONS: u32 = 6;

/// Barycentrics of the point where the ray from `x` along `w` meets the plane of `v`, clamped
/// into the triangle; `None` if the ray is parallel to the plane.
pub(super) fn barycentrics_along(x: Vec3A, w: Vec3A, v: &[Vec3A; 3]) -> Option<[f32; 3]> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::SampleStream;
    use glam::DVec3;

    /// `∫ max(0, n·ω) dω` over the emitting triangles of `scene` seen from `x` (Lambert's exact
    /// formula for a polygon: ½ Σ over edges of the edge's angle times `n` dotted with the unit
    /// normal of the plane through `x` and the edge).
    fn projected_solid_angle(scene: &Scene, x: Vec3A, n: Vec3A) -> f64 {
        let (x, n) = (x.as_dvec3(), n.as_dvec3());
        scene
            .emitters
            .prims
            .iter()
            .map(|&prim| {
                let r = scene.triangles[prim as usize].map(|p| (p.as_dvec3() - x).normalize());
                let sum: f64 = (0..3)
                    .map(|i| {
                        let (a, b): (DVec3, DVec3) = (r[i], r[(i + 1) % 3]);
                        a.dot(b).clamp(-1.0, 1.0).acos() * a.cross(b).normalize().dot(n)
                    })
                    .sum();
                0.5 * sum.abs()
            })
            .sum()
    }

    /// Both light-sampling strategies estimate `∫ max(0, n·ω) dω` over the cornell-paper light
    /// (unoccluded from the ceiling and the top of the walls) without bias: the mean of
    /// `max(0, n·ω)/pdf(ω)` over 400k samples lies within 4.5 standard errors of Lambert's exact
    /// value (one false alarm in ~150,000 per check). Where area sampling's weights are unbounded
    /// (right above the light) only solid-angle sampling is checked; it is also checked to be the
    /// less noisy of the two everywhere.
    #[test]
    fn light_sampling_strategies_agree_with_the_exact_integral() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let ceiling = Vec3A::NEG_Y;
        let cases = [
            (Vec3A::new(0.1, 1.0, 0.05), ceiling, false),
            (Vec3A::new(0.5, 1.0, 0.3), ceiling, true),
            (Vec3A::new(-0.9, 1.0, -0.8), ceiling, true),
            (Vec3A::new(-1.0, 0.985, 0.0), Vec3A::X, true),
        ];
        for (x, n, check_area) in cases {
            let exact = projected_solid_angle(&scene, x, n);
            let mut sd = [0.0; 2];
            for (k, strategy) in [LightSampling::SolidAngle, LightSampling::Area].into_iter().enumerate() {
                let mut rng = SampleStream::new(11, k as u32, 0);
                let count = 400_000;
                let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
                for _ in 0..count {
                    let (u_pick, u_point) = (rng.next_f32(), rng.next_2d());
                    let value = scene.sample_emitter_from(x, n, strategy, u_pick, u_point).map_or(0.0, |s| {
                        let w = (s.p - x).normalize();
                        f64::from(n.dot(w).max(0.0) * s.inv_pdf)
                    });
                    sum += value;
                    sum_sq += value * value;
                }
                let mean = sum / f64::from(count);
                let var = (sum_sq / f64::from(count) - mean * mean).max(0.0);
                sd[k] = var.sqrt();
                let se = (var / f64::from(count)).sqrt();
                if strategy == LightSampling::SolidAngle || check_area {
                    let z = (mean - exact) / se.max(1e-12 * exact);
                    assert!(z.abs() < 4.5, "{strategy:?} at {x}: {mean} vs exact {exact} (z {z})");
                }
            }
            assert!(sd[0] < sd[1], "at {x}: solid-angle sd {} not below area sd {}", sd[0], sd[1]);
        }
    }

    /// Many emitters (the furnace's 81,920 triangles, chosen by power): seen from a point on the
    /// closed sphere, the emitters' projected solid angles add up to exactly π. Both strategies'
    /// means over 200k samples lie within 4.5 standard errors of π.
    #[test]
    fn light_sampling_over_many_emitters_sums_to_pi() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace")).unwrap();
        assert!(scene.emitters.prims.len() > FEW_EMITTERS);
        for prim in [0usize, 1234, 4000] {
            let v = scene.triangles[prim];
            let x = (v[0] + v[1] + v[2]) / 3.0;
            let n = scene.normals[prim];
            for (k, strategy) in [LightSampling::SolidAngle, LightSampling::Area].into_iter().enumerate() {
                let mut rng = SampleStream::new(13, k as u32, prim as u32);
                let count = 200_000;
                let (mut sum, mut sum_sq) = (0.0f64, 0.0f64);
                for _ in 0..count {
                    let (u_pick, u_point) = (rng.next_f32(), rng.next_2d());
                    let value = scene
                        .sample_emitter_from(x, n, strategy, u_pick, u_point)
                        .map_or(0.0, |s| f64::from(n.dot((s.p - x).normalize()).max(0.0) * s.inv_pdf));
                    sum += value;
                    sum_sq += value * value;
                }
                let mean = sum / f64::from(count);
                let se = ((sum_sq / f64::from(count) - mean * mean).max(0.0) / f64::from(count)).sqrt();
                let z = (mean - std::f64::consts::PI) / se;
                assert!(z.abs() < 4.5, "{strategy:?} at triangle {prim}: {mean} ± {se} vs π (z {z})");
            }
        }
    }

    /// Next to the light, where the cosine at the shading point peaks between the emitter's
    /// corners, solid-angle NEE cuts the emitter down to parts the cosine warp can follow: one
    /// sample's relative deviation on the ceiling beside and above the cornell-paper light
    /// stays below 0.06 (measured 0.038–0.050 with the cut limits 0.2 sr and 3×, 0.014–0.021
    /// with 0.05 sr and 1.5×; it was 0.42 and 0.41 with the corner warp over whole triangles
    /// and 0.08 with a cubic atan2 in the part weights; 200k samples, fixed seed), and the mean
    /// stays Lambert's exact value within 5 standard errors.
    #[test]
    fn solid_angle_nee_is_nearly_exact_beside_the_light() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let n = -Vec3A::Y;
        for x in [Vec3A::new(0.0, 0.999, 0.21), Vec3A::new(0.1, 0.999, 0.1), Vec3A::new(0.3, 0.999, 0.25)] {
            let mut rng = SampleStream::new(1, 2, 3);
            let (mut sum, mut sum_sq, m) = (0.0f64, 0.0f64, 200_000);
            for _ in 0..m {
                let (u, v) = (rng.next_f32(), rng.next_2d());
                let value = scene
                    .sample_emitter_from(x, n, LightSampling::SolidAngle, u, v)
                    .map_or(0.0, |l| f64::from(n.dot((l.p - x).normalize()).max(0.0) * l.inv_pdf));
                sum += value;
                sum_sq += value * value;
            }
            let mean = sum / m as f64;
            let sd = (sum_sq / m as f64 - mean * mean).max(0.0).sqrt();
            let exact = projected_solid_angle(&scene, x, n);
            eprintln!("{x}: {mean:.4} (exact {exact:.4}), relative deviation {:.3}", sd / mean);
            assert!(sd / mean < 0.06, "{x}: relative deviation {}", sd / mean);
            assert!((mean - exact).abs() < 5.0 * sd / (m as f64).sqrt(), "{x}: {mean} vs {exact}");
        }
    }

    /// `emitter_pdf` replays the sampler: at points where NEE uses every path of the sampler
    /// (far emitters by area, near ones by solid angle with up to six cuts, the furnace's many
    /// emitters chosen by power), the density it gives for each sampled point equals the
    /// sampler's own `1/inv_pdf` within 0.5% for at least 99.9% of 20k samples per point
    /// (cut boundaries decide a few in f32), with both strategies.
    #[test]
    fn emitter_pdf_is_the_density_nee_samples_with() {
        let cornell = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let furnace = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace")).unwrap();
        let cases = [
            (&cornell, Vec3A::new(0.1, 0.999, 0.1), Vec3A::NEG_Y),
            (&cornell, Vec3A::new(0.3, 0.999, 0.25), Vec3A::NEG_Y),
            (&cornell, Vec3A::new(-0.9, 1.0, -0.8), Vec3A::NEG_Y),
            (&cornell, Vec3A::new(0.9, 0.999, 0.9), Vec3A::NEG_Y),
            (&cornell, Vec3A::new(-1.0, 0.985, 0.0), Vec3A::X),
            (&furnace, Vec3A::new(0.0, 0.0, -0.99), Vec3A::Z),
        ];
        for (scene, x, n) in cases {
            for strategy in [LightSampling::SolidAngle, LightSampling::Area] {
                let mut rng = SampleStream::new(5, 6, 7);
                let (mut count, mut bad) = (0, 0);
                for _ in 0..20_000 {
                    let (u, v) = (rng.next_f32(), rng.next_2d());
                    let Some(s) = scene.sample_emitter_from(x, n, strategy, u, v) else { continue };
                    let prim = s.prim;
                    count += 1;
                    let pdf = scene.emitter_pdf(x, n, strategy, prim, s.p);
                    let expected = 1.0 / s.inv_pdf;
                    if ((pdf - expected) / expected).abs() > 5e-3 {
                        bad += 1;
                    }
                }
                assert!(count > 1000, "{x} {strategy:?}: {count} samples");
                assert!(bad * 1000 <= count, "{x} {strategy:?}: {bad} of {count} densities differ");
            }
        }
    }

    /// A scene of the cornell-paper box with a point light, a spot light, a two-sided copy of
    /// the light and a small environment map, for the light tests below.
    fn lit_box() -> Scene {
        let mut s = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper")).unwrap();
        let texels = (0..32).map(|i| Vec3A::new(1.0 + (i % 5) as f32, 0.5, (i / 8) as f32)).collect();
        let lights = Lights {
            points: vec![
                PointLight::point(Vec3A::new(0.3, 0.5, 0.2), Vec3A::new(2.0, 1.0, 0.5)).unwrap(),
                PointLight::spot(Vec3A::new(-0.5, 0.9, 0.0), Vec3A::NEG_Y, Vec3A::ONE, 30.0, None).unwrap(),
            ],
            distant: vec![
                crate::light::DistantLight::new(Vec3A::new(0.2, -1.0, 0.1), Vec3A::new(0.5, 0.4, 0.3)).unwrap(),
            ],
            environment: Some(Environment::from_texels(8, 4, texels).unwrap()),
        };
        let mut materials = s.materials.clone();
        for m in materials.iter_mut().filter(|m| m.is_emitter()) {
            m.two_sided_emission = true;
        }
        s = Scene::from_parts(
            s.name.clone(),
            s.path.clone(),
            s.camera,
            s.triangles.clone(),
            s.triangle_material.clone(),
            materials,
            lights,
            Vec::new(),
        );
        s
    }

    /// With several kinds of light, NEE's density for every sampled environment direction and
    /// every sampled point on an emitting triangle (two-sided now, seen from below) is the one
    /// `environment_pdf` and `emitter_pdf` give, within 0.5% (all but 0.1% of 20k samples);
    /// point and distant lights are chosen with their share of the power.
    #[test]
    fn nee_densities_with_every_kind_of_light() {
        let scene = lit_box();
        let groups = scene.groups.as_ref().unwrap();
        assert_eq!(groups.len(), 5);
        for (x, n) in [(Vec3A::new(0.1, 0.0, 0.1), Vec3A::Y), (Vec3A::new(0.1, 0.999, 0.1), Vec3A::NEG_Y)] {
            let mut rng = SampleStream::new(1, 2, 3);
            let (mut count, mut bad, mut points) = (0, 0, 0);
            for _ in 0..20_000 {
                let (u, v) = (rng.next_f32(), rng.next_2d());
                let Some(s) = scene.sample_emitter_from(x, n, LightSampling::SolidAngle, u, v) else { continue };
                let expected = 1.0 / s.inv_pdf;
                let pdf = if s.delta && s.infinite {
                    points += 1;
                    assert_eq!(s.p, -scene.lights.distant[0].direction, "towards the distant light");
                    groups.pmf(3)
                } else if s.delta {
                    points += 1;
                    let k = (0..2).find(|&k| scene.lights.points[k].position == s.p).unwrap();
                    groups.pmf(1 + k)
                } else if s.infinite {
                    scene.environment_pdf(s.p)
                } else {
                    scene.emitter_pdf(x, n, LightSampling::SolidAngle, s.prim, s.p)
                };
                count += 1;
                if ((pdf - expected) / expected).abs() > 5e-3 {
                    bad += 1;
                }
            }
            assert!(count > 10_000 && points > 0, "{x}: {count} samples, {points} from point lights");
            assert!(bad * 1000 <= count, "{x}: {bad} of {count} densities differ");
        }
    }

    /// Photons carry each light's power: the mean flux of photon paths from `emit_photon` is the
    /// emitted power of the surfaces (both sides) and point lights, plus the distant light's and
    /// the environment's flux through the bounding sphere's disc (`E π r²`, `π r² ∫L dω`), per
    /// channel within 5 standard errors.
    #[test]
    fn photons_carry_the_power_of_every_light() {
        let scene = lit_box();
        // ∫ L dω per channel, from the map's texels and their solid angles (rows by cos θ).
        let mut env_integral = Vec3A::ZERO;
        for (i, t) in (0..32).map(|i| (i, Vec3A::new(1.0 + (i % 5) as f32, 0.5, (i / 8) as f32))) {
            let row = i / 8;
            let (c0, c1) = ((PI * row as f32 / 4.0).cos(), (PI * (row + 1) as f32 / 4.0).cos());
            env_integral += t * (std::f32::consts::TAU / 8.0 * (c0 - c1));
        }
        let r = scene.bounds.1;
        let expected = scene.emitted_power() + env_integral * (PI * r * r);
        let mut rng = SampleStream::new(9, 9, 9);
        let n = 400_000;
        let (mut sum, mut sum_sq) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for _ in 0..n {
            let (u, v, w) = (rng.next_f32(), rng.next_2d(), rng.next_2d());
            let flux = scene.emit_photon(u, v, w).map_or(Vec3A::ZERO, |(_, f)| f).as_dvec3();
            sum += flux;
            sum_sq += flux * flux;
        }
        let mean = sum / f64::from(n);
        let se = ((sum_sq / f64::from(n) - mean * mean) / f64::from(n)).max(glam::DVec3::ZERO);
        for c in 0..3 {
            let z = (mean[c] - f64::from(expected[c])) / se[c].sqrt();
            assert!(z.abs() < 5.0, "channel {c}: {} vs {} (z {z})", mean[c], expected[c]);
        }
    }

    /// A point on an emitter (its hit point a few ulps in front of the plane) gets nothing from
    /// that emitter: sampling it from there once gave a weight of 5e5 in the furnace.
    #[test]
    fn an_emitter_does_not_light_points_on_itself() {
        let scene = Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/furnace")).unwrap();
        let prim = scene.emitters.prims[57706 % scene.emitters.prims.len()] as usize;
        let i = scene.emitters.prims.iter().position(|&p| p as usize == prim).unwrap();
        let v = scene.triangles[prim];
        let x = (v[0] + v[1] + v[2]) / 3.0 + scene.normals[prim] * 1e-7;
        assert!(!scene.in_front(i, x));
        assert!(scene.in_front(i, x + scene.normals[prim] * 1e-3));
    }
}

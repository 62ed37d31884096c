//! A scene's lights and the choice between them: the emitting triangles as one light, each
//! point, spot and distant light, and the environment, chosen by luminous power; what next
//! event estimation, MIS and the photon pass ask of the lights as a whole.

use super::{AreaLights, DistantLight, Environment, Light, LightSample, PointLight, Receiver};
use crate::geometry::{Ray, Vec2, Vec3A, warp};

/// Lights that are not emitting surfaces, as a scene description gives them.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Point and spot lights.
    pub points: Vec<PointLight>,
    /// Distant (directional) lights.
    pub distant: Vec<DistantLight>,
    /// The environment, if any.
    pub environment: Option<Environment>,
}

/// Which light of a [`LightSet`] its choice picked: the set dispatches on it to the kind's
/// [`Light`] implementation (static dispatch).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightId {
    /// The emitting triangles (as one light).
    Area,
    /// A point or spot light, by index.
    Point(usize),
    /// A distant light, by index.
    Distant(usize),
    /// The environment.
    Environment,
}

/// Every light of a scene, and the choice between them by power.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    /// The emitting triangles.
    pub area: AreaLights,
    /// Point and spot lights.
    pub points: Vec<PointLight>,
    /// Distant (directional) lights.
    pub distant: Vec<DistantLight>,
    /// The environment, if any.
    pub environment: Option<Environment>,
    /// The choice between the emitting triangles (as one), each point light, each distant
    /// light and the environment, in that order, by power; `None` when nothing emits.
    choice: Option<warp::Discrete>,
    /// A sphere around the scene (centre, radius): lights at infinity are measured through it.
    bounds: (Vec3A, f32),
}

impl LightSet {
    /// The set of `area` and `lights` for a scene within the sphere `bounds` (centre, radius):
    /// each light weighed by its luminous power (the environment as seen by a disc of the
    /// bounding sphere, π r² ∫ L dω, pbrt's measure).
    #[must_use]
    pub fn new(area: AreaLights, lights: Lights, bounds: (Vec3A, f32)) -> Self {
        let radius = bounds.1;
        let mut power = vec![area.luminous_power(radius)];
        power.extend(lights.points.iter().map(|l| l.luminous_power(radius)));
        power.extend(lights.distant.iter().map(|l| l.luminous_power(radius)));
        if let Some(env) = &lights.environment {
            power.push(env.luminous_power(radius));
        }
        let choice = warp::Discrete::new(&power);
        Self { area, points: lights.points, distant: lights.distant, environment: lights.environment, choice, bounds }
    }

    /// Whether anything emits (surfaces, point lights, the environment).
    #[must_use]
    pub fn has_emitters(&self) -> bool {
        self.choice.is_some()
    }

    /// The choice between lights (index 0 the emitting triangles, then the point lights, the
    /// distant lights and the environment); `None` when nothing emits.
    #[must_use]
    pub fn choice(&self) -> Option<&warp::Discrete> {
        self.choice.as_ref()
    }

    /// The light of index `g` in [`LightSet::choice`].
    #[inline]
    #[must_use]
    pub fn id(&self, g: usize) -> LightId {
        match g {
            0 => LightId::Area,
            g if g <= self.points.len() => LightId::Point(g - 1),
            g if g <= self.points.len() + self.distant.len() => LightId::Distant(g - 1 - self.points.len()),
            _ => LightId::Environment,
        }
    }

    /// A point on a light for next event estimation at `at`: a light by power (`u_pick`,
    /// reused within it), then a point on it ([`Light::sample_from`]). `None` when the chosen
    /// light sends nothing to `at` or nothing emits.
    #[inline]
    #[must_use]
    pub fn sample(&self, at: &Receiver, u_pick: f32, u_point: Vec2) -> Option<LightSample> {
        let choice = self.choice.as_ref()?;
        // Emitting triangles alone (the common case) need no choice of light.
        let (g, pick, u_pick) = if choice.len() == 1 { (0, 1.0, u_pick) } else { choice.sample_reusing(u_pick) };
        match self.id(g) {
            LightId::Area => self.area.sample_from(at, u_pick, u_point, pick),
            LightId::Point(k) => self.points[k].sample_from(at, u_pick, u_point, pick),
            LightId::Distant(k) => self.distant[k].sample_from(at, u_pick, u_point, pick),
            LightId::Environment => self.environment.as_ref()?.sample_from(at, u_pick, u_point, pick),
        }
    }

    /// The density, in solid angle at `at`, with which [`LightSet::sample`] picks the point
    /// `p` of emitter triangle `prim`: what multiple importance sampling weighs a direction
    /// that hit `p` by. 0 where the sampler cannot reach `p` (and for a triangle that does not
    /// emit).
    #[inline]
    #[must_use]
    pub fn triangle_pdf(&self, at: &Receiver, prim: u32, p: Vec3A) -> f32 {
        let pdf = self.pick(0) * self.area.pdf_from(at, prim, p);
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    /// Radiance arriving from the environment along unit direction `d` (zero without one).
    #[inline]
    #[must_use]
    pub fn environment(&self, d: Vec3A) -> Vec3A {
        self.environment.as_ref().map_or(Vec3A::ZERO, |e| e.eval(d))
    }

    /// The density (solid angle) with which next event estimation picks environment
    /// direction `d`.
    #[inline]
    #[must_use]
    pub fn environment_pdf(&self, d: Vec3A) -> f32 {
        match (&self.environment, &self.choice) {
            (Some(env), Some(c)) => c.pmf(c.len() - 1) * env.pdf(d),
            _ => 0.0,
        }
    }

    /// The probability that the choice picks light `g` (0 when nothing emits).
    #[inline]
    fn pick(&self, g: usize) -> f32 {
        self.choice.as_ref().map_or(0.0, |c| c.pmf(g))
    }

    /// Total power emitted by surfaces, `Σ π · area · Le` (twice for two-sided ones), point
    /// lights and distant lights (through the bounding sphere's disc), RGB.
    #[must_use]
    pub fn emitted_power(&self) -> Vec3A {
        self.area.power()
            + self.points.iter().map(PointLight::power).sum::<Vec3A>()
            + self.distant.iter().map(|l| l.power_through(self.bounds.1)).sum::<Vec3A>()
    }

    /// The start of a photon path: a light by power (`u_pick`, reused within it), then its
    /// [`Light::emit_photon`]. Returns the ray and its flux (`None` when nothing emits).
    #[must_use]
    pub fn emit_photon(&self, u_pick: f32, u_point: Vec2, u_dir: Vec2) -> Option<(Ray, Vec3A)> {
        let (g, pick, u_pick) = self.choice.as_ref()?.sample_reusing(u_pick);
        let bounds = self.bounds;
        match self.id(g) {
            LightId::Area => self.area.emit_photon(u_pick, u_point, u_dir, bounds, pick),
            LightId::Point(k) => self.points[k].emit_photon(u_pick, u_point, u_dir, bounds, pick),
            LightId::Distant(k) => self.distant[k].emit_photon(u_pick, u_point, u_dir, bounds, pick),
            LightId::Environment => self.environment.as_ref()?.emit_photon(u_pick, u_point, u_dir, bounds, pick),
        }
    }
}

//! Lights. One interface, [`Light`] — sample a point or direction for next event estimation
//! from a shading point, the density of that choice, the power the light set chooses by, and
//! a photon leaving the light — implemented by each kind in its own file:
//!
//! - [`area`]: emitting triangles (by area or by solid angle, with the choice among them);
//! - [`point`]: point and spot lights;
//! - [`distant`]: distant (directional) lights;
//! - [`envmap`]: the environment, constant or an equirectangular map, importance-sampled.
//!
//! [`choice::LightSet`] holds a scene's lights and chooses between them by power; it dispatches
//! through an enum of the kinds ([`choice::LightId`]), so no ray goes through dynamic dispatch.
//! Adding a kind of light: its file with an `impl Light`, a variant of `LightId`, and an arm
//! in each of the set's matches.
pub mod area;
pub mod choice;
pub mod distant;
pub mod envmap;
pub mod point;

pub use area::{AreaLights, FEW_EMITTERS, IN_FRONT_MARGIN, NEAR_RATIO};
pub use choice::{LightSet, Lights};
pub use distant::DistantLight;
pub use envmap::{EnvSample, Environment};
pub use point::{Emission, PointLight, PointSample, Spot};

#[cfg(doc)]
use crate::geometry::spherical;
use crate::geometry::{Ray, Vec2, Vec3A};

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

/// The shading point a light is sampled from: its position, the normal on the side light is
/// gathered on, and how emitter triangles are sampled there.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// The shading point.
    pub x: Vec3A,
    /// Its normal (the side light is gathered on).
    pub n: Vec3A,
    /// How a point on an emitter triangle is picked.
    pub strategy: LightSampling,
}

/// A point on a light chosen for one shading point, with the inverse of its density with
/// respect to solid angle at that point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The emitter triangle (`u32::MAX` for other lights).
    pub prim: u32,
    /// A point, spot or distant light (no density: never weighed against BSDF sampling).
    pub delta: bool,
    /// The environment or a distant light: `p` is then the unit direction towards it, and
    /// nothing is in the way unless a surface is.
    pub infinite: bool,
    /// The point sampled (for lights at infinity, the direction to them).
    pub p: Vec3A,
    /// Bound on the error of `p`.
    pub p_err: Vec3A,
    /// The emitter's geometric normal there.
    pub ng: Vec3A,
    /// Radiance emitted towards the shading point (irradiance for delta lights).
    pub emission: Vec3A,
    /// `1/pdf(ω)` in steradians, the probability of having chosen this light included:
    /// `cosθy/(d²·pdf_area)` for area sampling, `Ω/P(triangle)` for solid-angle sampling,
    /// `1/P(light)` for delta lights.
    pub inv_pdf: f32,
}

/// What every kind of light does. `pick` is the probability with which the light set chose
/// this light; samples and photons fold it into their weights.
pub trait Light {
    /// A point on the light (or the direction to it) for next event estimation at `at`, from
    /// the random numbers `u_pick` (a choice within the light, e.g. of a triangle) and
    /// `u_point`; `None` where the light sends nothing to `at`.
    fn sample_from(&self, at: &Receiver, u_pick: f32, u_point: Vec2, pick: f32) -> Option<LightSample>;

    /// The density, in solid angle at `at` and without `pick`, with which
    /// [`Light::sample_from`] picks the point `p` of triangle `prim` (for lights at infinity:
    /// the direction `p`); 0 for delta lights, which nothing hits by chance.
    fn pdf_from(&self, at: &Receiver, prim: u32, p: Vec3A) -> f32;

    /// The luminous power the light set chooses by, for a scene within a sphere of radius
    /// `radius` (lights at infinity: what crosses a disc of it).
    fn luminous_power(&self, radius: f32) -> f32;

    /// A photon leaving the light: its ray and flux, from `u_pick`, `u_point` and `u_dir`, for
    /// a scene within the sphere `bounds` (centre, radius).
    fn emit_photon(
        &self,
        u_pick: f32,
        u_point: Vec2,
        u_dir: Vec2,
        bounds: (Vec3A, f32),
        pick: f32,
    ) -> Option<(Ray, Vec3A)>;
}

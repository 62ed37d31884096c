//! Lights other than emitting triangles: the environment (constant or an equirectangular map,
//! importance-sampled), point and spot lights, and distant (directional) lights. Scenes hold
//! them in [`crate::scene::Lights`]; next event estimation and the photon pass choose between
//! them and the emitting triangles by power.
pub mod distant;
pub mod envmap;
pub mod point;

pub use distant::DistantLight;
pub use envmap::{EnvSample, Environment};
pub use point::{Emission, PointLight, PointSample, Spot};

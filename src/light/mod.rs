//! Lights other than emitting triangles (issue "Materials, textures and lights"): so far the
//! environment (constant or an equirectangular map, importance-sampled) and point and spot
//! lights. Not yet wired into scenes or integrators.
pub mod envmap;
pub mod point;

pub use envmap::{EnvSample, Environment};
pub use point::{Emission, PointLight, PointSample, Spot};

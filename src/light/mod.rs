//! Lights other than emitting triangles (issue "Materials, textures and lights"): so far the
//! environment (constant or an equirectangular map, importance-sampled). Not yet wired into
//! scenes or integrators.
pub mod envmap;

pub use envmap::{EnvSample, Environment};

//! Rays, preliminary hits, local frames, robust ray offsets and sampling warps.
pub mod fastmath;
mod frame;
mod offset;
pub mod polygon;
mod ray;
pub mod spherical;
mod triangle;
pub mod warp;

pub use frame::Frame;
pub use offset::{barycentric_error, offset_ray_origin};
pub use ray::{Hit, Ray};
pub use triangle::{WatertightRay, intersect_triangle};

pub use glam::{UVec2, Vec2, Vec3, Vec3A};

/// Rec. 709 luminance of a linear RGB value (ALGORITHM.md `lum`).
#[inline]
#[must_use]
pub fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

//! Limits on what a scene may ask for, checked before anything is allocated.
use crate::Result;

/// Largest accepted image side, in pixels.
pub const MAX_RESOLUTION: u32 = 16384;
/// Largest scene file (TOML) read.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ or MTL file read.
pub const MAX_MESH_BYTES: u64 = 2 << 30;
/// Most triangles a scene may hold: about 500 bytes each at the peak of loading and the BVH
/// build (81,920 triangles took 41 MB), so 2^25 need about 17 GB of this machine's 24 GiB.
pub const MAX_TRIANGLES: usize = 1 << 25;
/// Bytes a triangle takes at the peak of loading and the BVH build (see [`MAX_TRIANGLES`]):
/// shapes that would need more than the memory left are refused before they are tessellated.
pub const BYTES_PER_TRIANGLE: u64 = 500;
/// Largest emitted radiance per channel (the sun's is about 1.6e9 W/(m²·sr)).
pub const MAX_EMISSION: f32 = 1e12;
/// Most vertices of one polygon (ear clipping is quadratic in it).
pub const MAX_POLYGON_VERTICES: usize = 4096;

pub(crate) fn check_resolution(width: u32, height: u32) -> Result<(), String> {
    if width == 0 || height == 0 {
        return Err(format!("resolution {width}x{height}: width and height must be at least 1"));
    }
    if width > MAX_RESOLUTION || height > MAX_RESOLUTION {
        return Err(format!("resolution {width}x{height} exceeds the maximum of {MAX_RESOLUTION} per side"));
    }
    if u64::from(width) * u64::from(height) > crate::film::MAX_PIXELS {
        return Err(format!(
            "resolution {width}x{height} exceeds the maximum of {} pixels (a render's memory grows with them)",
            crate::film::MAX_PIXELS
        ));
    }
    Ok(())
}

use crate::geometry::{Ray, Vec2, Vec3A};

/// A pinhole camera. Pixel `(i, j)` (row `j` from the top) covers film `[i,i+1]×[j,j+1]`; the
/// ray through film point `(u, v)` follows SCENES.md exactly.
#[derive(Clone, Debug)]
pub struct Camera {
    pub eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    tan_half_fov: f32,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    /// `None` when the frame is degenerate (eye on the target, up parallel to the view).
    #[must_use]
    pub fn new(eye: Vec3A, look_at: Vec3A, up: Vec3A, fov_y_deg: f32, width: u32, height: u32) -> Option<Self> {
        let forward = (look_at - eye).try_normalize()?;
        let right = forward.cross(up).try_normalize()?;
        let up = right.cross(forward);
        let tan_half_fov = (fov_y_deg.to_radians() * 0.5).tan();
        (tan_half_fov.is_finite() && tan_half_fov > 0.0).then_some(Self {
            eye,
            forward,
            right,
            up,
            tan_half_fov,
            width,
            height,
        })
    }

    #[must_use]
    pub fn with_resolution(&self, width: u32, height: u32) -> Self {
        Self { width, height, ..self.clone() }
    }

    /// The primary ray through film point `film` (in pixels).
    #[inline]
    #[must_use]
    pub fn ray(&self, film: Vec2) -> Ray {
        let aspect = self.width as f32 / self.height as f32;
        let x = (2.0 * film.x / self.width as f32 - 1.0) * self.tan_half_fov * aspect;
        let y = (1.0 - 2.0 * film.y / self.height as f32) * self.tan_half_fov;
        Ray::new(self.eye, (self.right * x + self.up * y + self.forward).normalize())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SCENES.md's formula for the paper's camera, evaluated at a few film points.
    #[test]
    fn matches_scenes_md_formula() {
        let cam = Camera::new(Vec3A::new(0.0, 0.0, 3.4), Vec3A::ZERO, Vec3A::Y, 45.0, 512, 384).unwrap();
        let t = 22.5f32.to_radians().tan();
        for (u, v) in [(0.0, 0.0), (256.0, 192.0), (511.5, 10.25), (3.0, 383.0)] {
            let d = Vec3A::new((2.0 * u / 512.0 - 1.0) * t * (512.0 / 384.0), (1.0 - 2.0 * v / 384.0) * t, -1.0)
                .normalize();
            let r = cam.ray(Vec2::new(u, v));
            assert!((r.dir - d).length() < 1e-6, "{u},{v}: {} vs {d}", r.dir);
            assert_eq!(r.origin, Vec3A::new(0.0, 0.0, 3.4));
        }
        assert!(Camera::new(Vec3A::ZERO, Vec3A::ZERO, Vec3A::Y, 45.0, 1, 1).is_none());
        assert!(Camera::new(Vec3A::ZERO, Vec3A::Y, Vec3A::Y, 45.0, 1, 1).is_none());
    }
}

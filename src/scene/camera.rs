use super::filter::PixelFilter;
use crate::geometry::{Ray, UVec2, Vec2, Vec3A};

/// A pinhole camera. Pixel `(i, j)` (row `j` from the top) covers film `[i,i+1]×[j,j+1]`; the
/// ray through film point `(u, v)` follows SCENES.md exactly.
#[derive(Clone, Debug)]
pub struct Camera {
    /// Where the camera is.
    pub eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    tan_half_fov: f32,
    /// Rendered image width in pixels.
    pub width: u32,
    /// Rendered image height in pixels.
    pub height: u32,
    /// The whole film's size and the rendered window's top-left corner in it (a crop): the
    /// image is `width`×`height` pixels of it.
    full: Vec2,
    offset: Vec2,
    /// How a pixel's film points spread around it (the one-pixel box unless set).
    pub filter: PixelFilter,
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
            full: Vec2::new(width as f32, height as f32),
            offset: Vec2::ZERO,
            filter: PixelFilter::default(),
        })
    }

    /// The same camera rendering only the window `[x, y, width, height]` (pixels from the top
    /// left) of its film; `None` unless the window is non-empty and inside the film.
    #[must_use]
    pub fn cropped(&self, [x, y, w, h]: [u32; 4]) -> Option<Self> {
        let inside = w > 0
            && h > 0
            && u64::from(x) + u64::from(w) <= u64::from(self.width)
            && u64::from(y) + u64::from(h) <= u64::from(self.height);
        inside.then(|| Self {
            width: w,
            height: h,
            offset: self.offset + Vec2::new(x as f32, y as f32) * self.full / self.size(),
            ..self.clone()
        })
    }

    /// The camera seen in a mirror: the image flipped left–right.
    #[must_use]
    pub fn mirrored(&self) -> Self {
        Self { right: -self.right, ..self.clone() }
    }

    fn size(&self) -> Vec2 {
        Vec2::new(self.width as f32, self.height as f32)
    }

    /// The same view at another resolution (a crop keeps its window of the film).
    #[must_use]
    pub fn with_resolution(&self, width: u32, height: u32) -> Self {
        let scale = Vec2::new(width as f32, height as f32) / self.size();
        Self { width, height, full: self.full * scale, offset: self.offset * scale, ..self.clone() }
    }

    /// The film point of pixel `pixel` for `u` in `[0, 1)²`, by the pixel filter (the plain
    /// `pixel + u` for the one-pixel box).
    #[inline]
    #[must_use]
    pub fn film_point(&self, pixel: UVec2, u: Vec2) -> Vec2 {
        self.filter.film_point(pixel, UVec2::new(self.width, self.height), u)
    }

    /// The primary ray through film point `film` (in pixels).
    #[inline]
    #[must_use]
    pub fn ray(&self, film: Vec2) -> Ray {
        let film = film + self.offset;
        let aspect = self.full.x / self.full.y;
        let x = (2.0 * film.x / self.full.x - 1.0) * self.tan_half_fov * aspect;
        let y = (1.0 - 2.0 * film.y / self.full.y) * self.tan_half_fov;
        Ray::new(self.eye, (self.right * x + self.up * y + self.forward).normalize())
    }
    /// The film point (in this image's pixels, as [`Self::ray`] takes them) whose ray passes
    /// through `p`; `None` behind the camera or within a millionth of its plane.
    #[must_use]
    pub fn project(&self, p: Vec3A) -> Option<Vec2> {
        let d = p - self.eye;
        let z = d.dot(self.forward);
        if z.is_nan() || z <= 1e-6 * d.length() {
            return None;
        }
        let aspect = self.full.x / self.full.y;
        let x = d.dot(self.right) / (z * self.tan_half_fov * aspect);
        let y = d.dot(self.up) / (z * self.tan_half_fov);
        let film = Vec2::new((x + 1.0) * 0.5 * self.full.x, (1.0 - y) * 0.5 * self.full.y) - self.offset;
        film.is_finite().then_some(film)
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
        // Projection inverts the ray, cropped or mirrored too, and refuses points behind.
        for cam in [cam.clone(), cam.cropped([100, 50, 64, 48]).unwrap(), cam.mirrored()] {
            for (u, v) in [(0.5, 0.25), (30.0, 20.0), (63.5, 47.0)] {
                let r = cam.ray(Vec2::new(u, v));
                let f = cam.project(r.origin + 2.5 * r.dir).unwrap();
                assert!((f - Vec2::new(u, v)).length() < 1e-3, "{u},{v}: {f}");
                assert!(cam.project(r.origin - r.dir).is_none());
            }
        }
        assert!(Camera::new(Vec3A::ZERO, Vec3A::Y, Vec3A::Y, 45.0, 1, 1).is_none());
    }

    /// A crop renders exactly the window's rays of the whole film, at any resolution; a
    /// mirrored camera swaps left and right.
    #[test]
    fn crops_and_mirrors() {
        let cam = Camera::new(Vec3A::new(0.0, 0.0, 3.4), Vec3A::ZERO, Vec3A::Y, 45.0, 512, 384).unwrap();
        let crop = cam.cropped([100, 50, 64, 32]).unwrap();
        assert_eq!((crop.width, crop.height), (64, 32));
        for (u, v) in [(0.0, 0.0), (10.5, 3.25), (64.0, 32.0)] {
            let (a, b) = (crop.ray(Vec2::new(u, v)).dir, cam.ray(Vec2::new(u + 100.0, v + 50.0)).dir);
            assert!((a - b).length() < 1e-6, "{u},{v}: {a} vs {b}");
            let half = crop.with_resolution(32, 16).ray(Vec2::new(u / 2.0, v / 2.0)).dir;
            assert!((half - b).length() < 1e-6, "{u},{v} at half resolution: {half} vs {b}");
        }
        assert!(cam.cropped([500, 0, 13, 1]).is_none());
        assert!(cam.cropped([0, 0, 0, 1]).is_none());
        let m = cam.mirrored().ray(Vec2::new(10.0, 20.0)).dir;
        let d = cam.ray(Vec2::new(502.0, 20.0)).dir;
        assert!((m - d).length() < 1e-6, "{m} vs {d}");
    }
}

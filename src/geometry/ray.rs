use glam::Vec3A;

/// A ray `origin + t·dir`, `t ∈ [0, ∞)`. `dir` is unit length wherever the renderer builds one.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    pub origin: Vec3A,
    pub dir: Vec3A,
}

impl Ray {
    #[inline]
    #[must_use]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        Self { origin, dir }
    }

    #[inline]
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }

    /// Rays with a NaN or infinite component, or a zero direction, hit nothing; backends check
    /// this once so that no traversal ever sees them.
    #[inline]
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.origin.is_finite() && self.dir.is_finite() && self.dir != Vec3A::ZERO
    }
}

/// The preliminary hit a backend returns: distance, primitive (triangle index in the scene's
/// order) and barycentrics `(u, v)` with `p = (1-u-v)·v0 + u·v1 + v·v2`. Everything else (point,
/// normals, material) is derived once by the scene (Mitsuba 3's split).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

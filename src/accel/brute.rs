//! The reference backend: every ray against every triangle. Slow, obviously right; the other
//! backends are tested against it.
use super::Accel;
use crate::geometry::{Hit, Ray, Vec3A, intersect_triangle};

pub struct BruteForce {
    pub triangles: Vec<[Vec3A; 3]>,
}

impl Accel for BruteForce {
    fn name(&self) -> &'static str {
        "brute-force"
    }

    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let mut best: Option<Hit> = None;
        for (i, t) in self.triangles.iter().enumerate() {
            let t_max = best.map_or(f32::INFINITY, |h| h.t);
            if let Some((t, u, v)) = intersect_triangle(ray, t, t_max) {
                best = Some(Hit { t, prim: i as u32, u, v });
            }
        }
        best
    }

    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        ray.is_valid() && self.triangles.iter().any(|t| intersect_triangle(ray, t, t_max).is_some())
    }
}

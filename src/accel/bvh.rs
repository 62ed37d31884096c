//! The pure-Rust backend: obvhs' compressed wide BVH (CWBVH, 8-wide) over triangles stored in
//! leaf order, so a leaf's primitive index reads its triangle directly.
use super::Accel;
use crate::geometry::{Hit, Ray};
use crate::scene::Scene;
use obvhs::BvhBuildParams;
use obvhs::cwbvh::{CwBvh, builder::build_cwbvh_from_tris};
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::rt_triangle::RtTriangle;
use obvhs::triangle::Triangle;
use std::time::Duration;

pub struct BvhAccel {
    bvh: CwBvh,
    /// Triangles in BVH leaf order.
    triangles: Vec<RtTriangle>,
    /// Scene primitive id of each triangle in leaf order.
    scene_prim: Vec<u32>,
}

impl BvhAccel {
    #[must_use]
    pub fn build(scene: &Scene) -> Self {
        Self::from_triangles(&scene.triangles)
    }

    /// Builds over raw triangles (benchmarks and tests use this without a scene).
    #[must_use]
    pub fn from_triangles(tris: &[[glam::Vec3A; 3]]) -> Self {
        let input: Vec<Triangle> = tris.iter().map(|t| Triangle { v0: t[0], v1: t[1], v2: t[2] }).collect();
        // Medium quality: a good SAH-like tree from PLOC plus a little reinsertion, without
        // spatial splits so that every triangle sits in exactly one leaf.
        let params = BvhBuildParams { pre_split: false, ..BvhBuildParams::medium_build() };
        let mut build_time = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&input, params, &mut build_time);
        let triangles = bvh.primitive_indices.iter().map(|&i| RtTriangle::from(&input[i as usize])).collect();
        let scene_prim = bvh.primitive_indices.clone();
        Self { bvh, triangles, scene_prim }
    }

    #[inline(always)]
    fn bvh_ray(ray: &Ray, t_max: f32) -> BvhRay {
        BvhRay::new(ray.origin, ray.dir, 0.0, t_max)
    }
}

impl Accel for BvhAccel {
    fn name(&self) -> &'static str {
        "bvh"
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let r = Self::bvh_ray(ray, f32::INFINITY);
        let mut hit = RayHit::none();
        if !self.bvh.ray_traverse(r, &mut hit, |r, i| self.triangles[i].intersect(r)) {
            return None;
        }
        let tri = &self.triangles[hit.primitive_id as usize];
        // obvhs' barycentrics weigh v1 and v2, matching our Hit convention.
        let b = tri.compute_barycentric(&r);
        Some(Hit { t: hit.t, prim: self.scene_prim[hit.primitive_id as usize], u: b.x, v: b.y })
    }

    #[inline]
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        if !ray.is_valid() || t_max.is_nan() || t_max <= 0.0 {
            return false;
        }
        !self.bvh.ray_traverse_miss(Self::bvh_ray(ray, t_max), |r, i| self.triangles[i].intersect(r))
    }
}

//! Scenes: triangles with diffuse materials and one-sided emitters, a pinhole camera, and the
//! full shading record built once from a backend's preliminary [`Hit`].
mod camera;
pub mod description;
mod load;

pub use camera::Camera;

use crate::geometry::{Hit, Ray, Vec2, Vec3A, barycentric_error, luminance, offset_ray_origin, warp};
use std::f32::consts::PI;
use std::path::PathBuf;

/// A two-sided Lambertian reflector (`f = ρ/π`) that may emit `emission` into the hemisphere
/// of its triangle's geometric normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub diffuse: Vec3A,
    pub emission: Vec3A,
}

impl Material {
    #[inline]
    #[must_use]
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// The BRDF value `ρ/π`.
    #[inline]
    #[must_use]
    pub fn brdf(&self) -> Vec3A {
        self.diffuse * std::f32::consts::FRAC_1_PI
    }
}

/// A renderable scene. Triangles are stored flat, in load order; `prim` indices from backends
/// refer to this order.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    /// The scene file this came from.
    pub path: PathBuf,
    pub camera: Camera,
    pub triangles: Vec<[Vec3A; 3]>,
    /// Unit geometric normal `normalize((v1−v0)×(v2−v0))` per triangle.
    pub normals: Vec<Vec3A>,
    pub triangle_material: Vec<u32>,
    pub materials: Vec<Material>,
    emitters: Emitters,
    /// Non-fatal findings while loading (no emitter, degenerate triangles skipped).
    pub warnings: Vec<String>,
}

/// Emitter triangles picked with probability ∝ power (`π · area · lum(Le)`).
#[derive(Clone, Debug, Default)]
struct Emitters {
    prims: Vec<u32>,
    areas: Vec<f32>,
    choice: Option<warp::Discrete>,
}

/// The full shading record at a surface hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    pub p: Vec3A,
    /// Conservative bound on the absolute error of `p`.
    pub p_err: Vec3A,
    /// Geometric normal as wound (decides the emitting side).
    pub ng: Vec3A,
    /// Shading normal: the geometric normal turned to face `wo` (walls are two-sided).
    pub n: Vec3A,
    /// Unit direction towards where the ray came from.
    pub wo: Vec3A,
    pub prim: u32,
    pub material: Material,
}

impl SurfaceInteraction {
    /// Radiance emitted towards `wo`: one-sided, along the geometric normal.
    #[inline]
    #[must_use]
    pub fn emitted(&self) -> Vec3A {
        if self.ng.dot(self.wo) > 0.0 { self.material.emission } else { Vec3A::ZERO }
    }

    /// A ray leaving the surface in direction `dir`, origin offset by the error bound.
    #[inline]
    #[must_use]
    pub fn spawn_ray(&self, dir: Vec3A) -> Ray {
        Ray::new(offset_ray_origin(self.p, self.p_err, self.ng, dir), dir)
    }
}

/// One sample of a point on an emitter, for next event estimation.
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample {
    pub p: Vec3A,
    pub p_err: Vec3A,
    pub ng: Vec3A,
    pub emission: Vec3A,
    /// Density of `p` with respect to area, over all emitters.
    pub pdf_area: f32,
}

impl Scene {
    /// Builds a scene from triangles already validated (finite, non-degenerate, material ids in
    /// range). `warnings` carries what the loader found.
    pub(crate) fn from_parts(
        name: String,
        path: PathBuf,
        camera: Camera,
        triangles: Vec<[Vec3A; 3]>,
        triangle_material: Vec<u32>,
        materials: Vec<Material>,
        mut warnings: Vec<String>,
    ) -> Self {
        let normals: Vec<Vec3A> = triangles.iter().map(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize()).collect();
        let mut emitters = Emitters::default();
        let mut power = Vec::new();
        for (i, t) in triangles.iter().enumerate() {
            let m = &materials[triangle_material[i] as usize];
            if m.is_emitter() {
                let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
                emitters.prims.push(i as u32);
                emitters.areas.push(area);
                power.push(PI * area * luminance(m.emission).max(1e-6 * m.emission.max_element()));
            }
        }
        emitters.choice = warp::Discrete::new(&power);
        if emitters.choice.is_none() {
            warnings.push("the scene has no emitter: the image will be black".into());
        }
        Self { name, path, camera, triangles, normals, triangle_material, materials, emitters, warnings }
    }

    /// A scene from raw triangles with one material, for procedural geometry (benchmarks,
    /// tests). Degenerate triangles are dropped.
    #[must_use]
    pub fn from_triangles(name: &str, camera: Camera, triangles: Vec<[Vec3A; 3]>, material: Material) -> Self {
        let triangles: Vec<[Vec3A; 3]> = triangles
            .into_iter()
            .filter(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero() != Vec3A::ZERO)
            .collect();
        let n = triangles.len();
        Self::from_parts(name.into(), PathBuf::new(), camera, triangles, vec![0; n], vec![material], Vec::new())
    }

    /// A hash of everything that decides the image: triangles, materials, camera and
    /// resolution (FNV-1a over their bits). Reference images are cached under it.
    #[must_use]
    pub fn content_hash(&self) -> u64 {
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        let mut eat = |x: u32| {
            for b in x.to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        };
        for t in &self.triangles {
            t.iter().flat_map(|v| v.to_array()).for_each(|x| eat(x.to_bits()));
        }
        self.triangle_material.iter().for_each(|&m| eat(m));
        for m in &self.materials {
            m.diffuse.to_array().into_iter().chain(m.emission.to_array()).for_each(|x| eat(x.to_bits()));
        }
        let c = &self.camera;
        for x in [c.width, c.height] {
            eat(x);
        }
        for v in [c.ray(glam::Vec2::ZERO).dir, c.ray(glam::Vec2::new(c.width as f32, c.height as f32)).dir, c.eye] {
            v.to_array().into_iter().for_each(|x| eat(x.to_bits()));
        }
        h
    }

    /// Replaces the image resolution, keeping the camera's view.
    pub fn set_resolution(&mut self, width: u32, height: u32) -> crate::Result<()> {
        load::check_resolution(width, height).map_err(|m| crate::Error::InvalidOption(m.to_string()))?;
        self.camera = self.camera.with_resolution(width, height);
        Ok(())
    }

    #[inline]
    #[must_use]
    pub fn material_of(&self, prim: u32) -> &Material {
        &self.materials[self.triangle_material[prim as usize] as usize]
    }

    #[must_use]
    pub fn has_emitters(&self) -> bool {
        self.emitters.choice.is_some()
    }

    /// Total emitted power `Σ π · area · Le` (RGB).
    #[must_use]
    pub fn emitted_power(&self) -> Vec3A {
        self.emitters
            .prims
            .iter()
            .zip(&self.emitters.areas)
            .map(|(&p, &a)| self.material_of(p).emission * (PI * a))
            .sum()
    }

    /// The shading record for `hit` along `ray`.
    #[inline]
    #[must_use]
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        let v = &self.triangles[hit.prim as usize];
        let b = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let p = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
        let ng = self.normals[hit.prim as usize];
        let wo = -ray.dir;
        let n = if ng.dot(wo) >= 0.0 { ng } else { -ng };
        SurfaceInteraction {
            p,
            p_err: barycentric_error(b, v),
            ng,
            n,
            wo,
            prim: hit.prim,
            material: *self.material_of(hit.prim),
        }
    }

    /// Picks an emitter triangle by power with `u_pick` and a uniform point on it with `u_point`.
    #[inline]
    #[must_use]
    pub fn sample_emitter(&self, u_pick: f32, u_point: Vec2) -> Option<EmitterSample> {
        let choice = self.emitters.choice.as_ref()?;
        let (i, pmf) = choice.sample(u_pick);
        let prim = self.emitters.prims[i];
        let v = &self.triangles[prim as usize];
        let b = warp::uniform_triangle(u_point);
        Some(EmitterSample {
            p: v[0] * b[0] + v[1] * b[1] + v[2] * b[2],
            p_err: barycentric_error(b, v),
            ng: self.normals[prim as usize],
            emission: self.material_of(prim).emission,
            pdf_area: pmf / self.emitters.areas[i],
        })
    }
}

//! Scenes: triangles with their materials and textures, the lights ([`LightSet`]), a pinhole
//! camera with its pixel filter, and the full shading record built once from a backend's
//! preliminary [`Hit`]; descriptions, their importers and the build from them below.
// The library's entry points: every public item documented (`cargo doc`).
#![warn(missing_docs)]
mod build;
mod camera;
pub mod description;
pub mod filter;
pub mod import;
#[cfg(test)]
mod light_tests;
pub mod limits;
mod materials;
mod media;
pub mod mesh;

pub use camera::Camera;
pub use description::RenderDescription;
pub use mesh::{obj_triangles, ply_triangles};

use crate::geometry::{Frame, Hit, Ray, Vec2, Vec3A, barycentric_error, luminance, offset_ray_origin};
use crate::light::{AreaLights, LightSet, Lights};
use crate::material::Bsdf;
use crate::material::microfacet::Microfacet;
use crate::texture::Texture;
use std::path::PathBuf;

/// A surface's material: how it scatters ([`Bsdf`]) and what it emits (`emission`, one-sided
/// into the hemisphere of its triangle's geometric normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// How it scatters.
    pub bsdf: Bsdf,
    /// Radiance emitted from its front side.
    pub emission: Vec3A,
    /// Opaque materials scatter on both sides (the TOML default, Mitsuba's `twosided`) or only
    /// on the side the geometric normal points to (Mitsuba's default: black from behind).
    /// Materials that transmit always see both sides, the normal marking the outside.
    pub two_sided: bool,
    /// Emit on both sides of the surface (pbrt's `twosided` area light), not only along the
    /// geometric normal.
    pub two_sided_emission: bool,
    /// Textures (indices into [`Scene::textures`]) that replace parameters of `bsdf` at each
    /// hit.
    pub textures: TextureSlots,
}

/// The textures a material reads at each hit, as indices into [`Scene::textures`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TextureSlots {
    /// The reflectance: a diffuse surface's, a plastic's base, a conductor's `specular` factor.
    pub reflectance: Option<u16>,
    /// The GGX `alpha` of a conductor or a dielectric that is not thin (its luminance,
    /// clamped to `[MIN_ALPHA, 1]`: a textured surface stays rough everywhere).
    pub roughness: Option<u16>,
}

impl TextureSlots {
    /// Whether any slot reads a texture.
    #[inline]
    #[must_use]
    pub fn any(&self) -> bool {
        self.reflectance.is_some() || self.roughness.is_some()
    }
}

/// What a mesh's vertices carry besides positions, per triangle (parallel to
/// [`Scene::triangles`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attributes {
    /// Shading normals at the three corners (unit), interpolated across the triangle; all
    /// zero for a triangle without. Empty when no triangle has them.
    pub normals: Vec<[Vec3A; 3]>,
    /// Texture coordinates at the three corners. Empty when no triangle has them; a triangle
    /// without gets `(0,0), (1,0), (0,1)`, so that `(u, v)` are its barycentric coordinates of
    /// corners 1 and 2, as in Mitsuba 3.
    pub uvs: Vec<[Vec2; 3]>,
}

impl Attributes {
    /// Texture coordinates of a triangle without any.
    pub const BARYCENTRIC_UV: [Vec2; 3] = [Vec2::ZERO, Vec2::X, Vec2::Y];
}

impl Material {
    /// A two-sided Lambertian reflector of `reflectance` that emits `emission`.
    #[must_use]
    pub fn diffuse(reflectance: Vec3A, emission: Vec3A) -> Self {
        Self {
            bsdf: Bsdf::Diffuse { reflectance },
            emission,
            two_sided: true,
            two_sided_emission: false,
            textures: TextureSlots { reflectance: None, roughness: None },
        }
    }

    /// Whether it emits.
    #[inline]
    #[must_use]
    pub fn is_emitter(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// The reflectance of a Lambertian material, `None` for any other.
    #[inline]
    #[must_use]
    pub fn lambertian(&self) -> Option<Vec3A> {
        match self.bsdf {
            Bsdf::Diffuse { reflectance } => Some(reflectance),
            _ => None,
        }
    }

    /// A stand-in for the share of light the surface scatters (for Russian roulette and the
    /// photon guide's radiance estimates; never a weight): see [`Bsdf::albedo`].
    #[inline]
    #[must_use]
    pub fn albedo(&self) -> Vec3A {
        self.bsdf.albedo()
    }
}

/// A renderable scene. Triangles are stored flat, in load order; `prim` indices from backends
/// refer to this order.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The name shown in summaries (the scene file's folder).
    pub name: String,
    /// The scene file this came from.
    pub path: PathBuf,
    /// The camera.
    pub camera: Camera,
    /// Vertices of each triangle, in world space.
    pub triangles: Vec<[Vec3A; 3]>,
    /// Unit geometric normal `normalize((v1−v0)×(v2−v0))` per triangle.
    pub normals: Vec<Vec3A>,
    /// Index into `materials` of each triangle.
    pub triangle_material: Vec<u32>,
    /// The materials.
    pub materials: Vec<Material>,
    /// Shading normals and texture coordinates of the meshes that have them.
    pub attributes: Attributes,
    /// The textures materials read ([`Material::textures`]).
    pub textures: Vec<Texture>,
    /// Per texture, a map of texture coordinates applied before it is read (Mitsuba's
    /// `to_uv`); empty when no texture has one.
    pub texture_uv: Vec<Option<glam::Affine2>>,
    /// Every light (emitting triangles, point, spot and distant lights, the environment) and
    /// the choice between them.
    pub lights: LightSet,
    /// A sphere around everything (centre, radius): environment photons start on a disc of it.
    pub bounds: (Vec3A, f32),
    /// Non-fatal findings while loading (no emitter, degenerate triangles skipped).
    pub warnings: Vec<String>,
    /// Files the scene was read from (the scene file, its meshes): no output may replace them.
    pub sources: Vec<PathBuf>,
    /// The scene's own render defaults (sample count, path depth), below the command line's.
    pub render: RenderDescription,
    /// Participating media (empty in most scenes).
    pub media: Vec<crate::medium::Medium>,
    /// The media on the two sides of each material's surfaces, parallel to `materials`
    /// (shorter where the rest separate nothing).
    pub material_media: Vec<crate::medium::MediumInterface>,
    /// The medium the camera sits in.
    pub camera_medium: Option<u16>,
}

/// The full shading record at a surface hit.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    /// The hit point.
    pub p: Vec3A,
    /// Conservative bound on the absolute error of `p`.
    pub p_err: Vec3A,
    /// Geometric normal as wound (decides the emitting side).
    pub ng: Vec3A,
    /// The geometric normal turned to face `wo`: the side light is gathered on (photon
    /// lookups, guide cells, NEE's choice of emitter).
    pub n: Vec3A,
    /// The shading normal (interpolated from the mesh's vertex normals), on the side of `n`;
    /// `n` itself where the mesh has none, or where `wo` lies below it or it below the
    /// surface (the usual fix-up: the geometric normal never lets a direction leak through).
    pub ns: Vec3A,
    /// Whether `ns` differs from `n`: directions are then checked against both
    /// ([`SurfaceInteraction::consistent`]).
    pub shaded: bool,
    /// Unit direction towards where the ray came from.
    pub wo: Vec3A,
    /// The triangle hit.
    pub prim: u32,
    /// The material with its textures read at this hit.
    pub material: Material,
}

impl SurfaceInteraction {
    /// Radiance emitted towards `wo`: along the geometric normal (both ways for a two-sided
    /// emitter).
    #[inline]
    #[must_use]
    pub fn emitted(&self) -> Vec3A {
        if self.ng.dot(self.wo) > 0.0 || self.material.two_sided_emission {
            self.material.emission
        } else {
            Vec3A::ZERO
        }
    }

    /// The normal of the BSDF's local frame: the shading normal `ns` for an opaque material
    /// (seen from behind, a one-sided one is black: [`Scene::interaction`]); for one that
    /// transmits, `ns` turned to the side of the geometric normal (`wo` below it: seen from
    /// inside).
    #[inline]
    #[must_use]
    pub fn bsdf_normal(&self) -> Vec3A {
        if self.material.bsdf.transmits() && self.ng.dot(self.wo) < 0.0 { -self.ns } else { self.ns }
    }

    /// The BSDF's local frame at this hit.
    #[inline]
    #[must_use]
    pub fn bsdf_frame(&self) -> Frame {
        Frame::from_normal(self.bsdf_normal())
    }

    /// The frame around `n` (photon lookups and guides work in it), given the BSDF's frame:
    /// the same frame unless the material transmits or the normal is shaded.
    #[inline]
    #[must_use]
    pub fn gather_frame(&self, bsdf_frame: &Frame) -> Frame {
        if self.material.bsdf.transmits() || self.shaded { Frame::from_normal(self.n) } else { *bsdf_frame }
    }

    /// Whether world direction `dir`, of local height `local_z` in the BSDF's frame, leaves on
    /// the side the BSDF means: reflected directions above the surface, refracted ones below
    /// it, by the geometric normal. Only shading normals can make them disagree; a direction
    /// that does scatters nothing (its BSDF value is taken as 0 by every strategy alike, so
    /// the estimators stay unbiased for that BSDF).
    #[inline]
    #[must_use]
    pub fn consistent(&self, dir: Vec3A, local_z: f32) -> bool {
        if !self.shaded {
            return true;
        }
        if self.material.bsdf.transmits() {
            // The BSDF's frame is on the geometric normal's side.
            (dir.dot(self.ng) > 0.0) == (local_z > 0.0)
        } else {
            dir.dot(self.n) > 0.0
        }
    }

    /// For a Lambertian surface sampled around the geometric normal (`cos = dir·n > 0`): the
    /// factor `cosθs / cos` that turns its weight into the one of the shading normal (0 below
    /// it; 1 without shading normals).
    #[inline]
    #[must_use]
    pub fn shading_ratio(&self, dir: Vec3A, cos: f32) -> f32 {
        if self.shaded { (self.ns.dot(dir) / cos).max(0.0) } else { 1.0 }
    }

    /// A ray leaving the surface in direction `dir`, origin offset by the error bound.
    #[inline]
    #[must_use]
    pub fn spawn_ray(&self, dir: Vec3A) -> Ray {
        Ray::new(offset_ray_origin(self.p, self.p_err, self.ng, dir), dir)
    }
}

/// A scene's surfaces as the loader validated them (finite, non-degenerate, material ids in
/// range): triangles, each one's material, the materials.
pub(crate) struct Surfaces {
    pub triangles: Vec<[Vec3A; 3]>,
    pub triangle_material: Vec<u32>,
    pub materials: Vec<Material>,
}

impl Scene {
    /// Builds a scene from its surfaces and other lights. `warnings` carries what the loader
    /// found.
    pub(crate) fn from_parts(
        name: String,
        path: PathBuf,
        camera: Camera,
        surfaces: Surfaces,
        lights: Lights,
        mut warnings: Vec<String>,
    ) -> Self {
        let Surfaces { triangles, triangle_material, materials } = surfaces;
        let normals: Vec<Vec3A> = triangles.iter().map(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize()).collect();
        let area = AreaLights::new(&triangles, &normals, |i| {
            let m = &materials[triangle_material[i] as usize];
            m.is_emitter().then_some((m.emission, m.two_sided_emission))
        });
        // The bounding sphere of the geometry and the point lights.
        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for p in triangles.iter().flatten().chain(lights.points.iter().map(|l| &l.position)) {
            (lo, hi) = (lo.min(*p), hi.max(*p));
        }
        let bounds = if lo.cmple(hi).all() {
            ((lo + hi) * 0.5, ((hi - lo) * 0.5).length().max(1e-3))
        } else {
            (Vec3A::ZERO, 1.0)
        };
        let lights = LightSet::new(area, lights, bounds);
        if !lights.has_emitters() {
            warnings.push("the scene has no emitter: the image will be black".into());
        }
        let sources = vec![path.clone()];
        Self {
            name,
            path,
            camera,
            triangles,
            normals,
            triangle_material,
            materials,
            attributes: Attributes::default(),
            textures: Vec::new(),
            texture_uv: Vec::new(),
            lights,
            bounds,
            warnings,
            sources,
            render: RenderDescription::default(),
            media: Vec::new(),
            material_media: Vec::new(),
            camera_medium: None,
        }
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
        Self::from_parts(
            name.into(),
            PathBuf::new(),
            camera,
            Surfaces { triangles, triangle_material: vec![0; n], materials: vec![material] },
            Lights::default(),
            Vec::new(),
        )
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
        // Attributes and textures only where a scene has them (older hashes stay valid).
        for n in &self.attributes.normals {
            n.iter().flat_map(|v| v.to_array()).for_each(|x| eat(x.to_bits()));
        }
        for t in &self.attributes.uvs {
            t.iter().flat_map(|v| v.to_array()).for_each(|x| eat(x.to_bits()));
        }
        for t in &self.textures {
            let (kind, values): (String, &[Vec3A]) = match t {
                Texture::Constant(c) => ("constant".into(), std::slice::from_ref(c)),
                Texture::Checkerboard { a, b, scale } => (format!("checkerboard {a} {b} {scale}"), &[] as &[Vec3A]),
                Texture::Bitmap(b) => (format!("bitmap {}x{} {:?} {:?}", b.width, b.height, b.wrap, b.filter), &[]),
            };
            kind.bytes().for_each(|b| eat(u32::from(b)));
            if let Texture::Bitmap(b) = t {
                // Megapixels of texels: a digest of fixed chunks hashed in parallel (byte by
                // byte they took half of a textured scene's load).
                let d = texel_digest(&b.texels);
                eat(d as u32);
                eat((d >> 32) as u32);
            } else {
                values.iter().flat_map(|v| v.to_array()).for_each(|x| eat(x.to_bits()));
            }
        }
        for m in self.texture_uv.iter().flatten() {
            m.to_cols_array().iter().for_each(|x| eat(x.to_bits()));
        }
        for m in &self.materials {
            // Two-sided Lambertian materials hash as they always have (cached references
            // stay valid); any other by its full description.
            match m.lambertian() {
                Some(rho) if m.two_sided => rho.to_array().into_iter().for_each(|x| eat(x.to_bits())),
                _ => format!("{:?}/{}", m.bsdf, m.two_sided).bytes().for_each(|b| eat(u32::from(b))),
            }
            if m.textures.any() {
                format!("{:?}", m.textures).bytes().for_each(|b| eat(u32::from(b)));
            }
            m.emission.to_array().into_iter().for_each(|x| eat(x.to_bits()));
            if m.two_sided_emission {
                eat(2);
            }
        }
        // A depth limit (the scene's, or the command line's over it) only where there is one
        // (older hashes stay valid): it changes every pixel's light.
        if let Some(d) = self.render.max_depth {
            format!("max_depth {d}").bytes().for_each(|b| eat(u32::from(b)));
        }
        // Media only where a scene has them (older hashes stay valid).
        if self.volumetric() {
            format!("media {:?} {:?} {:?}", self.media, self.material_media, self.camera_medium)
                .bytes()
                .for_each(|b| eat(u32::from(b)));
        }
        let c = &self.camera;
        for x in [c.width, c.height] {
            eat(x);
        }
        // A filter other than the one-pixel box (older hashes stay valid).
        if c.filter.shape != filter::FilterShape::PIXEL {
            format!("{:?}", c.filter.shape).bytes().for_each(|b| eat(u32::from(b)));
        }
        for v in [c.ray(glam::Vec2::ZERO).dir, c.ray(glam::Vec2::new(c.width as f32, c.height as f32)).dir, c.eye] {
            v.to_array().into_iter().for_each(|x| eat(x.to_bits()));
        }
        h
    }

    /// Replaces the image resolution, keeping the camera's view.
    pub fn set_resolution(&mut self, width: u32, height: u32) -> crate::Result<()> {
        limits::check_resolution(width, height).map_err(|m| crate::Error::InvalidOption(m.to_string()))?;
        self.camera = self.camera.with_resolution(width, height);
        Ok(())
    }

    /// The material of triangle `prim`.
    #[inline]
    #[must_use]
    pub fn material_of(&self, prim: u32) -> &Material {
        &self.materials[self.triangle_material[prim as usize] as usize]
    }

    /// Whether light paths must track participating media: the scene has media, or surfaces
    /// that bound them (which paths cross without scattering).
    #[must_use]
    pub fn volumetric(&self) -> bool {
        !self.media.is_empty() || self.materials.iter().any(|m| m.bsdf.is_interface())
    }

    /// The media on the two sides of triangle `prim`.
    #[inline]
    #[must_use]
    pub fn medium_interface(&self, prim: u32) -> crate::medium::MediumInterface {
        self.material_media.get(self.triangle_material[prim as usize] as usize).copied().unwrap_or_default()
    }

    /// Whether every material is Lambertian and nothing lies beyond the scene (no
    /// environment): the paper's kind of scene, where only NEE needs to count light past the
    /// first hit.
    #[must_use]
    pub fn lambertian_only(&self) -> bool {
        self.lights.environment.is_none() && self.materials.iter().all(|m| m.lambertian().is_some())
    }

    /// The shading record for `hit` along `ray`.
    #[inline]
    #[must_use]
    pub fn interaction(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        self.interaction_inline(ray, hit)
    }

    /// [`Self::interaction`], always inlined: for the path tracer's tightest loop, where the
    /// call and the record's trip through memory cost more than the work.
    #[inline(always)]
    #[must_use]
    pub(crate) fn interaction_inline(&self, ray: &Ray, hit: &Hit) -> SurfaceInteraction {
        let v = &self.triangles[hit.prim as usize];
        let b = [1.0 - hit.u - hit.v, hit.u, hit.v];
        let p = v[0] * b[0] + v[1] * b[1] + v[2] * b[2];
        let ng = self.normals[hit.prim as usize];
        let wo = -ray.dir;
        let front = ng.dot(wo) >= 0.0;
        let n = if front { ng } else { -ng };
        let mut material = *self.material_of(hit.prim);
        if material.textures.any() {
            self.read_textures(&mut material, hit.prim as usize, b);
        }
        if !front && !material.two_sided && !material.bsdf.transmits() {
            // A one-sided surface seen from behind scatters nothing (Mitsuba 3).
            material.bsdf = Bsdf::Diffuse { reflectance: Vec3A::ZERO };
        }
        let (mut ns, mut shaded) = (n, false);
        if let Some(corners) = self.attributes.normals.get(hit.prim as usize)
            && corners[0] != Vec3A::ZERO
        {
            let s = (corners[0] * b[0] + corners[1] * b[1] + corners[2] * b[2]).normalize_or_zero();
            let s = if front { s } else { -s };
            if s.dot(wo) > 0.0 && s.dot(n) > 0.0 {
                (ns, shaded) = (s, true);
            }
        }
        SurfaceInteraction { p, p_err: barycentric_error(b, v), ng, n, ns, shaded, wo, prim: hit.prim, material }
    }

    /// Texture `i` at texture coordinates `uv` (mapped by its `texture_uv`, if any).
    #[inline]
    fn texture(&self, i: u16, uv: Vec2) -> Vec3A {
        let i = usize::from(i);
        match self.texture_uv.get(i).copied().flatten() {
            Some(m) => self.textures[i].eval(m.transform_point2(uv)),
            None => self.textures[i].eval(uv),
        }
    }

    /// Replaces the parameters of `material` its textures drive by their values at
    /// barycentric coordinates `b` of triangle `prim`.
    fn read_textures(&self, material: &mut Material, prim: usize, b: [f32; 3]) {
        let t = self.attributes.uvs.get(prim).unwrap_or(&Attributes::BARYCENTRIC_UV);
        let uv = t[0] * b[0] + t[1] * b[1] + t[2] * b[2];
        let slots = material.textures;
        let reflectance = slots.reflectance.map(|i| self.texture(i, uv).clamp(Vec3A::ZERO, Vec3A::ONE));
        let alpha = slots.roughness.map(|i| {
            let alpha = luminance(self.texture(i, uv)).clamp(Microfacet::MIN_ALPHA, 1.0);
            if alpha.is_nan() { 1.0 } else { alpha }
        });
        material.bsdf.set_textured(reflectance, alpha);
    }
}

/// A 64-bit digest of texels: FNV-1a over 64-bit words (two channels each) of every chunk of
/// 65,536 texels, in parallel, then of the chunks' digests in order: the same value whatever
/// the thread count.
fn texel_digest(texels: &crate::texture::Texels) -> u64 {
    use rayon::prelude::*;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    const CHUNK: usize = 1 << 16;
    fn fnv(words: impl Iterator<Item = u64>) -> u64 {
        words.fold(0xcbf2_9ce4_8422_2325u64, |h, w| (h ^ w).wrapping_mul(PRIME))
    }
    let n = texels.len();
    let chunks: Vec<u64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            fnv(texels.values_in(c * CHUNK..((c + 1) * CHUNK).min(n)).flat_map(|v| {
                let [r, g, b] = v.to_array().map(f32::to_bits);
                [u64::from(r) | u64::from(g) << 32, u64::from(b)]
            }))
        })
        .collect();
    fnv(chunks.into_iter())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A bitmap's digest depends on its values, not on how its texels are stored.
    #[test]
    fn texel_digest_is_of_values() {
        use crate::texture::Texels;
        let n = (1 << 16) + 77;
        let codes: Vec<[u8; 3]> = (0..n).map(|k| [k as u8, (k >> 8) as u8, (k * 31) as u8]).collect();
        let table: [f32; 256] = std::array::from_fn(|v| v as f32 / 255.0);
        let decoded = codes.iter().map(|c| Vec3A::from_array(c.map(|v| table[v as usize]))).collect();
        let (coded, linear) = (Texels::Coded { codes, table: Box::new([table; 3]) }, Texels::Linear(decoded));
        assert_eq!(texel_digest(&coded), texel_digest(&linear));
        let mut other = linear.clone();
        other.map_channels(|v| v * 0.5);
        assert_ne!(texel_digest(&other), texel_digest(&linear));
    }

    /// A texture's `uv_transform` maps coordinates before the lookup (Mitsuba's `to_uv`): a
    /// checkerboard shifted by half a period swaps its colours.
    #[test]
    fn texture_coordinates_are_mapped() {
        let text = |map: &str| {
            format!(
                "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\nwidth = 4\nheight = 4\n\
                 [textures.c]\ntype = \"checkerboard\"\ncolor0 = [1.0, 1.0, 1.0]\ncolor1 = [0.0, 0.0, 0.0]\n{map}\n\
                 [materials.m]\ndiffuse_texture = \"c\"\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n"
            )
        };
        let plain = Scene::parse(&text(""), std::path::Path::new("t.toml")).unwrap();
        let shifted =
            Scene::parse(&text("uv_transform = [[1.0, 0.0, 0.5], [0.0, 1.0, 0.0]]"), std::path::Path::new("t.toml"))
                .unwrap();
        let uv = Vec2::new(0.25, 0.25);
        assert_eq!(plain.texture(0, uv), Vec3A::ONE);
        assert_eq!(shifted.texture(0, uv), Vec3A::ZERO);
        assert!(plain.texture_uv.is_empty());
        assert_ne!(plain.content_hash(), shifted.content_hash());
    }
}

//! The TOML scene file, as serde reads it. Unknown keys are rejected by name.
use serde::Deserialize;
use std::collections::BTreeMap;

/// A TOML scene file (`docs/scene-format.md`), as read.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDescription {
    /// The camera.
    pub camera: CameraDescription,
    /// Materials by name. They override MTL materials of the same name and can be assigned to
    /// a whole mesh with `material = "name"`.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDescription>,
    /// Textures by name, for materials' `*_texture` keys.
    #[serde(default)]
    pub textures: BTreeMap<String, TextureDescription>,
    /// Participating media by name, for materials' `interior_medium` and `exterior_medium`
    /// and the camera's `medium`.
    #[serde(default)]
    pub media: BTreeMap<String, MediumDescription>,
    /// Meshes read from OBJ or PLY files (`[[mesh]]`).
    #[serde(default, rename = "mesh")]
    pub meshes: Vec<MeshDescription>,
    /// Canonical shapes (`[[shape]]`).
    #[serde(default, rename = "shape")]
    pub shapes: Vec<ShapeDescription>,
    /// Point, spot and distant lights (`[[light]]`).
    #[serde(default, rename = "light")]
    pub lights: Vec<LightDescription>,
    /// Light from infinitely far away.
    pub environment: Option<EnvironmentDescription>,
    /// What the scene asks of a render: the command line's flags win.
    pub render: Option<RenderDescription>,
    /// Triangle meshes given inline by an imported scene (pbrt's `trianglemesh`); not part of
    /// the TOML format.
    #[serde(skip)]
    pub inline_meshes: Vec<InlineMesh>,
    /// Where an imported scene's textures and mesh files were named (`texture NAME`, `mesh
    /// FILE` → file and line), so that a file that cannot be read is reported there; not part
    /// of the TOML format.
    #[serde(skip)]
    pub origins: std::collections::HashMap<String, (std::path::PathBuf, u32)>,
}

/// A triangle mesh written out in an imported scene file, already placed in the world.
#[derive(Debug, Clone, Default)]
pub struct InlineMesh {
    /// Where it was written (`file:line`), for errors.
    pub origin: String,
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Three per triangle.
    pub indices: Vec<u32>,
    /// Per vertex, when given.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Texture coordinates per vertex, when given.
    pub uvs: Option<Vec<[f32; 2]>>,
    /// The material's name.
    pub material: String,
    /// Reverse every triangle's winding.
    pub reverse_winding: bool,
}

/// A scene's defaults for rendering it (Mitsuba's `sampler` and `integrator`).
#[derive(Debug, Deserialize, Clone, Copy, Default)]
#[serde(deny_unknown_fields)]
pub struct RenderDescription {
    /// Samples per pixel when `--spp` is not given.
    pub spp: Option<u32>,
    /// The longest path counted, in segments (1: emitters seen directly; 2: direct light),
    /// as Mitsuba's `max_depth`; absent: unbounded. `--max-depth` overrides it.
    pub max_depth: Option<u32>,
}

/// A light that is not a surface.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    /// Light from a point, in every direction.
    Point,
    /// Light from a point, in a cone.
    Spot,
    /// Parallel light from one direction.
    Distant,
}

/// A point light, or a spot light (`direction`, `cutoff` and `beam` in degrees: Mitsuba 3's
/// profile, defaults 20° and ¾ of the cutoff). `intensity` is power per steradian.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightDescription {
    /// Point, spot or distant.
    #[serde(rename = "type")]
    pub kind: LightKind,
    /// Point and spot lights.
    pub position: Option<[f32; 3]>,
    /// Point and spot lights: power per steradian.
    pub intensity: Option<[f32; 3]>,
    /// Spot lights: the axis; distant lights: the direction the light travels in.
    pub direction: Option<[f32; 3]>,
    /// Distant lights: the irradiance on a surface facing the light.
    pub irradiance: Option<[f32; 3]>,
    /// Spot lights: the cone's half-angle in degrees (default 20).
    pub cutoff: Option<f32>,
    /// Spot lights: where the falloff begins, in degrees (default ¾ of `cutoff`).
    pub beam: Option<f32>,
}

impl LightDescription {
    /// A point light (importers).
    #[must_use]
    pub fn point(position: [f32; 3], intensity: [f32; 3]) -> Self {
        Self::with(LightKind::Point, Some(position), Some(intensity), None, None)
    }

    /// A spot light along `direction`, `cutoff` and `beam` in degrees (importers).
    #[must_use]
    pub fn spot(position: [f32; 3], intensity: [f32; 3], direction: [f32; 3], cutoff: f32, beam: f32) -> Self {
        Self {
            cutoff: Some(cutoff),
            beam: Some(beam),
            ..Self::with(LightKind::Spot, Some(position), Some(intensity), Some(direction), None)
        }
    }

    /// A distant light travelling along `direction` (importers).
    #[must_use]
    pub fn distant(direction: [f32; 3], irradiance: [f32; 3]) -> Self {
        Self::with(LightKind::Distant, None, None, Some(direction), Some(irradiance))
    }

    fn with(
        kind: LightKind,
        position: Option<[f32; 3]>,
        intensity: Option<[f32; 3]>,
        direction: Option<[f32; 3]>,
        irradiance: Option<[f32; 3]>,
    ) -> Self {
        Self { kind, position, intensity, direction, irradiance, cutoff: None, beam: None }
    }
}

/// Light from infinitely far away: a constant `radiance`, or an equirectangular `map` (EXR
/// linear or PNG sRGB, relative to the scene file; +y up) times `scale`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDescription {
    /// Constant radiance.
    pub radiance: Option<[f32; 3]>,
    /// Or an image of it (relative to the scene file).
    pub map: Option<String>,
    /// A factor on either (default 1).
    pub scale: Option<f32>,
    /// How the map's image covers the sphere: `equirectangular` (the default, as above) or
    /// `equal_area` (pbrt-v4's octahedral equal-area square, +z up).
    pub layout: Option<MapLayout>,
    /// A rotation of the map into the world (row-major 4×4; its linear part is used).
    pub matrix: Option<[[f32; 4]; 4]>,
    /// How radiance is read from an equirectangular map: `nearest` (the default: constant
    /// over each texel's band of the sphere) or `mitsuba` (Mitsuba 3's `envmap`: bilinear
    /// between texels placed from the zenith row to the nadir row).
    pub lookup: Option<EnvLookupDescription>,
}

impl EnvironmentDescription {
    /// A constant environment of `radiance`.
    #[must_use]
    pub fn constant(radiance: [f32; 3]) -> Self {
        Self { radiance: Some(radiance), map: None, scale: None, layout: None, matrix: None, lookup: None }
    }
}

/// How an environment map is read (see [`crate::light::envmap::Lookup`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum EnvLookupDescription {
    /// The texel the direction falls in.
    Nearest,
    /// As Mitsuba 3 interpolates it.
    Mitsuba,
}

/// How an environment map's image covers the sphere.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum MapLayout {
    /// Longitude across, latitude down.
    Equirectangular,
    /// pbrt-v4's square equal-area octahedral map.
    EqualArea,
}

/// A pinhole camera.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDescription {
    /// Where the camera is.
    pub eye: [f32; 3],
    /// The point it looks at.
    pub look_at: [f32; 3],
    /// Which way is up (default +y).
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov_y: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Render only this window of the `width`×`height` film: `[x, y, width, height]` in
    /// pixels from the top left (Mitsuba's `crop_offset_x`, … ).
    pub crop: Option<[u32; 4]>,
    /// Mirror the image left–right (a camera whose transform mirrors, as some exported
    /// Mitsuba scenes have).
    #[serde(default)]
    pub mirror: bool,
    /// The pixel reconstruction filter (default: the one-pixel box).
    pub filter: Option<PixelFilterDescription>,
    /// The participating medium the camera sits in (a name from `[media]`; default none).
    pub medium: Option<String>,
}

/// A pixel reconstruction filter (see [`crate::scene::filter`]): `box` (`radius` ½),
/// `gaussian` (`stddev` 0.5, `radius` 4·`stddev`: Mitsuba 3's default filter) or `tent`
/// (`radius` 1); `radius` per axis, in pixels.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PixelFilterDescription {
    /// The filter's shape.
    #[serde(rename = "type")]
    pub kind: PixelFilterKind,
    /// Gaussian: the standard deviation in pixels.
    pub stddev: Option<f32>,
    /// Radius per axis, in pixels.
    pub radius: Option<[f32; 2]>,
}

/// The kinds of pixel filter.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum PixelFilterKind {
    /// Constant.
    Box,
    /// A truncated Gaussian.
    Gaussian,
    /// Linear falloff.
    Tent,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// The scattering model of a material (see [`crate::material::Bsdf`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum MaterialKind {
    /// Lambertian.
    #[default]
    Diffuse,
    /// A metal.
    Conductor,
    /// Glass: reflection and refraction.
    Dielectric,
    /// A thin sheet of glass (no refraction offset).
    ThinDielectric,
    /// A diffuse base under a dielectric coat.
    Plastic,
    /// No surface at all: the boundary of a participating medium (pbrt-v4's `interface`,
    /// Mitsuba 3's `null`). Light passes straight through.
    Interface,
}

/// A homogeneous participating medium (see [`crate::medium::Medium`]): coefficients per unit
/// length of the scene, multiplied by `scale`.
#[derive(Debug, Deserialize, Clone, Default, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MediumDescription {
    /// Absorption coefficient per channel.
    #[serde(default)]
    pub sigma_a: [f32; 3],
    /// Scattering coefficient per channel.
    #[serde(default)]
    pub sigma_s: [f32; 3],
    /// A factor on both coefficients (default 1).
    pub scale: Option<f32>,
    /// The Henyey–Greenstein phase function's asymmetry in `(-1, 1)` (default 0, isotropic).
    pub g: Option<f32>,
}

/// A material: a scattering model (`type`, diffuse by default) with its parameters, and
/// emission, one-sided along the geometric normal. Keys that do not apply to the type are
/// rejected by name.
#[derive(Debug, Deserialize, Clone, Default)]
#[serde(deny_unknown_fields)]
pub struct MaterialDescription {
    /// The scattering model (default diffuse).
    #[serde(default, rename = "type")]
    pub kind: MaterialKind,
    /// Diffuse reflectance (diffuse, plastic).
    #[serde(default)]
    pub diffuse: [f32; 3],
    /// Emitted radiance, one-sided along the geometric normal.
    #[serde(default)]
    pub emission: [f32; 3],
    /// Conductor: a named metal (Mitsuba's names, e.g. "Au"), or `eta` and `k` per channel.
    pub metal: Option<String>,
    /// Conductor: the index of refraction per channel.
    pub eta: Option<[f32; 3]>,
    /// Conductor: the absorption coefficient per channel.
    pub k: Option<[f32; 3]>,
    /// Conductor: a tint on the reflectance (Mitsuba's `specular_reflectance`).
    pub specular: Option<[f32; 3]>,
    /// Dielectric, thin dielectric, plastic: interior and exterior index of refraction.
    pub ior: Option<f32>,
    /// The exterior's index of refraction (default 1).
    pub exterior_ior: Option<f32>,
    /// Conductor, dielectric, plastic: microfacet roughness `α` (0 or absent: smooth).
    pub roughness: Option<f32>,
    /// Conductor, dielectric, plastic: the microfacets' distribution, `"ggx"` (default) or
    /// `"beckmann"`.
    pub distribution: Option<DistributionDescription>,
    /// Conductor, dielectric, plastic: how the microfacets' masking and shadowing combine,
    /// `"correlated"` (height-correlated, pbrt-v4's; default) or `"separable"` (Mitsuba 3's).
    pub masking: Option<MaskingDescription>,
    /// Plastic: Mitsuba's `nonlinear` inter-reflection of the base.
    pub nonlinear: Option<bool>,
    /// Opaque materials: scatter on both sides (default) or only on the normal's.
    pub two_sided: Option<bool>,
    /// Emit on both sides (default: only along the geometric normal).
    #[serde(default)]
    pub two_sided_emission: bool,
    /// A texture (a name from `[textures]`) for the diffuse reflectance (diffuse, plastic),
    /// in place of `diffuse`.
    pub diffuse_texture: Option<String>,
    /// A texture for a conductor's `specular` tint.
    pub specular_texture: Option<String>,
    /// A texture for the roughness `α` (conductor, dielectric): its luminance.
    pub roughness_texture: Option<String>,
    /// The medium (a name from `[media]`) behind the surface, against its normal: surfaces
    /// that name media decide which medium a ray crossing or leaving them is in.
    pub interior_medium: Option<String>,
    /// The medium in front of the surface, along its normal.
    pub exterior_medium: Option<String>,
}

/// A microfacet distribution (see [`crate::material::microfacet::Distribution`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum DistributionDescription {
    /// Trowbridge–Reitz (GGX).
    Ggx,
    /// Beckmann.
    Beckmann,
}

/// How microfacet masking and shadowing combine (see [`crate::material::microfacet::Masking`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum MaskingDescription {
    /// Height-correlated Smith masking–shadowing.
    Correlated,
    /// Masking times shadowing.
    Separable,
}

/// The kinds of texture (see [`crate::texture::Texture`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum TextureKind {
    /// An image file.
    Bitmap,
    /// Two colours in squares.
    Checkerboard,
}

/// What a bitmap holds beyond `[0, 1]²`.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum WrapDescription {
    /// The image tiles the plane.
    Repeat,
    /// Every tile mirrors its neighbours.
    Mirror,
    /// The edge texels extend for ever.
    Clamp,
}

/// How a bitmap is read between texel centres.
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum FilterDescription {
    /// Interpolated between the four nearest texels.
    Bilinear,
    /// The texel the point falls in.
    Nearest,
}

/// A texture: a `bitmap` (`file`: PNG decoded from sRGB unless `raw`, or EXR linear;
/// `wrap` repeat/mirror/clamp, `filter` bilinear/nearest) or a `checkerboard` (`color0` at
/// the origin, `color1`, `scale` squares across `u` and `v` in `[0, 1)`).
#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct TextureDescription {
    /// Bitmap or checkerboard.
    #[serde(rename = "type")]
    pub kind: TextureKind,
    /// Bitmaps: the image file, relative to the scene file.
    pub file: Option<String>,
    /// Bitmaps: what lies beyond `[0, 1]²` (default repeat).
    pub wrap: Option<WrapDescription>,
    /// Bitmaps: how texels are interpolated (default bilinear).
    pub filter: Option<FilterDescription>,
    /// Bitmaps: the values as stored, not decoded from sRGB (data such as roughness).
    pub raw: Option<bool>,
    /// Checkerboards: the colour at the origin.
    pub color0: Option<[f32; 3]>,
    /// Checkerboards: the other colour.
    pub color1: Option<[f32; 3]>,
    /// Checkerboards: squares across `u` and `v`.
    pub scale: Option<[f32; 2]>,
    /// Bitmaps: `v = 0` is the image's top row (Mitsuba's convention), not its bottom.
    pub v_from_top: Option<bool>,
    /// Map texture coordinates before reading: `u' = m[0]·(u, v, 1)`, `v' = m[1]·(u, v, 1)`
    /// (Mitsuba's `to_uv`).
    pub uv_transform: Option<[[f32; 3]; 2]>,
    /// Multiplies the texture's values per channel (pbrt's `scale` textures and imagemaps'
    /// `scale`).
    pub factor: Option<[f32; 3]>,
    /// Reads `1 − value` (after `factor`), at least 0 (pbrt's `invert`).
    pub invert: Option<bool>,
}

impl TextureDescription {
    /// A texture of one colour (a checkerboard of two equal colours: importers' fallback).
    #[must_use]
    pub fn constant(c: [f32; 3]) -> Self {
        Self { scale: None, ..Self::checkerboard(c, c, [1.0; 2]) }
    }

    /// A checkerboard of `color0` (at the origin) and `color1`, `scale` squares across `u` and
    /// `v`.
    #[must_use]
    pub fn checkerboard(color0: [f32; 3], color1: [f32; 3], scale: [f32; 2]) -> Self {
        Self {
            kind: TextureKind::Checkerboard,
            file: None,
            wrap: None,
            filter: None,
            raw: None,
            color0: Some(color0),
            color1: Some(color1),
            scale: Some(scale),
            v_from_top: None,
            uv_transform: None,
            factor: None,
            invert: None,
        }
    }
}

/// A mesh read from a file (`[[mesh]]`).
#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct MeshDescription {
    /// OBJ file, relative to the scene file's folder.
    pub obj: Option<String>,
    /// Or a PLY file (ASCII or binary; needs `material`).
    pub ply: Option<String>,
    /// Assign this material to every face of the mesh (overrides the OBJ's `usemtl`).
    pub material: Option<String>,
    /// Reverse every triangle's winding, flipping geometric normals and emitting sides.
    #[serde(default)]
    pub reverse_winding: bool,
    /// Place the mesh by this affine map (row-major 4×4, last row 0 0 0 1).
    pub matrix: Option<[[f32; 4]; 4]>,
    /// Give triangles without vertex normals smooth ones: at each vertex (corners sharing
    /// position and texture coordinates) the mean of its faces' normals weighted by their
    /// angles there, as Mitsuba 3 computes for meshes without normals.
    #[serde(default)]
    pub smooth_normals: bool,
    /// Drop the mesh's vertex normals: flat triangles (Mitsuba's `face_normals`).
    #[serde(default)]
    pub face_normals: bool,
    /// Replace the mesh's texture coordinates `v` by `1 − v` (Mitsuba's `flip_tex_coords`).
    #[serde(default)]
    pub flip_v: bool,
}

/// The canonical shapes (see [`crate::scene::mesh::shapes`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    /// The square `[−1, 1]²` in the plane z = 0, facing +z.
    Rectangle,
    /// The unit disk in the plane z = 0, facing +z.
    Disk,
    /// The cube `[−1, 1]³`.
    Cube,
    /// A sphere (`center`, `radius`).
    Sphere,
}

/// A rotation by `angle` degrees about `axis` (counter-clockwise looking down the axis).
#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(deny_unknown_fields)]
pub struct RotateDescription {
    /// The axis.
    pub axis: [f32; 3],
    /// Degrees, counter-clockwise looking down the axis.
    pub angle: f32,
}

/// A shape placed in the scene: the canonical shape, then `scale`, `rotate` and `translate`
/// in that order, or a whole `matrix` (row-major 4×4, last row 0 0 0 1).
#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
pub struct ShapeDescription {
    /// Which canonical shape.
    #[serde(rename = "type")]
    pub kind: ShapeKind,
    /// The shape's material (a name from `[materials]`).
    pub material: String,
    /// Sphere only: centre and radius (default the origin and 1), before the transform.
    pub center: Option<[f32; 3]>,
    /// Sphere only: radius.
    pub radius: Option<f32>,
    /// Disk only: segments of the rim.
    pub segments: Option<u32>,
    /// Sphere only: subdivisions of the icosahedron.
    pub subdivisions: Option<u32>,
    /// Scale per axis.
    pub scale: Option<[f32; 3]>,
    /// Then a rotation.
    pub rotate: Option<RotateDescription>,
    /// Then a translation.
    pub translate: Option<[f32; 3]>,
    /// Or the whole placement as a matrix.
    pub matrix: Option<[[f32; 4]; 4]>,
    /// Reverse every triangle's winding, flipping geometric normals and emitting sides.
    #[serde(default)]
    pub reverse_winding: bool,
}

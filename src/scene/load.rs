//! Loading a scene: the TOML file, its OBJ/MTL meshes, and every check that turns bad input
//! into an error naming the file (and line, where the parser knows it).
use super::description::{
    DistributionDescription, LightKind, MapLayout, MaskingDescription, MaterialDescription, SceneDescription,
    ShapeDescription, ShapeKind,
};
use super::filter::{FilterShape, PixelFilter};
use super::import::{Format, ImportOptions};
use super::{Attributes, Camera, Lights, Material, Scene, TextureSlots};
use crate::geometry::{Vec2, Vec3A};
use crate::io::{read_bounded, read_text};
use crate::light::envmap::Environment;
use crate::light::point::PointLight;
use crate::material::microfacet::{Distribution, Masking, Microfacet};
use crate::material::{Bsdf, conductors};
use crate::texture::Texture;
use crate::texture::{Bitmap, Filter, Wrap};
use crate::{Error, Result};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest accepted image side, in pixels.
pub const MAX_RESOLUTION: u32 = 16384;
/// Largest scene file (TOML) read.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// Largest OBJ or MTL file read.
pub const MAX_MESH_BYTES: u64 = 2 << 30;
/// Most triangles a scene may hold: about 500 bytes each at the peak of loading and the BVH
/// build (81,920 triangles took 41 MB), so 2^25 need about 17 GB of this machine's 24 GiB.
pub const MAX_TRIANGLES: usize = 1 << 25;
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

/// A scene argument is a scene file or a folder holding `scene.toml` (or else `scene.xml`,
/// or `scene.pbrt`).
#[must_use]
pub fn resolve_scene_path(path: &Path) -> PathBuf {
    if !path.is_dir() {
        return path.to_path_buf();
    }
    let toml = path.join("scene.toml");
    if toml.exists() {
        return toml;
    }
    ["scene.xml", "scene.pbrt"].iter().map(|f| path.join(f)).find(|p| p.exists()).unwrap_or(toml)
}

impl Scene {
    /// Loads a scene file (or a folder holding `scene.toml`).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
        Scene::load_with(path, &ImportOptions::default())
    }

    /// Loads a scene file in any format we read (by its extension: `.xml` is Mitsuba 3,
    /// anything else our TOML), or a folder holding `scene.toml`.
    pub fn load_with(path: impl AsRef<Path>, options: &ImportOptions) -> Result<Scene> {
        let path = resolve_scene_path(path.as_ref());
        let text = read_text(&path, MAX_SCENE_BYTES, "scene file")?;
        match Format::of(&path) {
            Format::Toml => Scene::parse(&text, &path),
            Format::Mitsuba => Scene::parse_mitsuba(&text, &path, options),
            Format::Pbrt => Scene::parse_pbrt(&text, &path, options),
        }
    }

    /// A pbrt-v4 scene from the text of its file (see [`super::import::pbrt`]).
    pub fn parse_pbrt(text: &str, path: &Path, options: &ImportOptions) -> Result<Scene> {
        let imported = super::import::pbrt::import(path, text, options)?;
        Scene::imported(path, imported.description, imported.warnings, imported.sources)
    }

    /// A Mitsuba 3 scene from the text of its file (see [`super::import::mitsuba`]).
    pub fn parse_mitsuba(text: &str, path: &Path, options: &ImportOptions) -> Result<Scene> {
        let imported = super::import::mitsuba::import(path, text, options)?;
        Scene::imported(path, imported.description, imported.warnings, imported.sources)
    }

    /// A scene from an importer's description, its warnings first and its files as sources.
    fn imported(path: &Path, d: SceneDescription, mut warnings: Vec<String>, files: Vec<PathBuf>) -> Result<Scene> {
        let mut scene = build(path, d)?;
        warnings.append(&mut scene.warnings);
        scene.warnings = warnings;
        for file in files.into_iter().rev() {
            if !scene.sources.contains(&file) {
                scene.sources.insert(0, file);
            }
        }
        Ok(scene)
    }

    /// A scene from the text of its file; `path` names it in errors and locates its meshes.
    pub fn parse(text: &str, path: &Path) -> Result<Scene> {
        let path = path.to_path_buf();
        let description: SceneDescription = toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            let message = e.message().trim().replace('\n', " ");
            Error::SceneSyntax {
                path: path.clone(),
                message: match line {
                    Some(l) => format!("line {l}: {message}"),
                    None => message,
                },
            }
        })?;
        build(&path, description)
    }
}

/// Fuzzing and tests: loads OBJ text `obj` (its `mtllib` files read as `mtl`) as a scene
/// mesh would be; returns the triangle count.
#[doc(hidden)]
pub fn obj_triangles(obj: &str, mtl: &str) -> Result<usize> {
    let mut meshes = Meshes::default();
    let loader = |_: &Path| parse_mtl(mtl);
    obj_into(Path::new("fuzz.obj"), obj, &loader, &RefCell::new(None), None, false, &mut meshes)?;
    Ok(meshes.geometry.triangles.len())
}

/// Fuzzing and tests: loads PLY bytes as a scene mesh would be; returns the triangle count.
#[doc(hidden)]
pub fn ply_triangles(bytes: &[u8]) -> Result<usize> {
    let mut geometry = Geometry::default();
    ply_into(Path::new("fuzz.ply"), bytes, 0, false, &mut geometry)?;
    Ok(geometry.triangles.len())
}

fn invalid(path: &Path, message: impl Into<String>) -> Error {
    Error::InvalidScene { path: path.to_path_buf(), message: message.into() }
}

fn vec3(a: [f32; 3]) -> Vec3A {
    Vec3A::from_array(a)
}

fn material_from(
    path: &Path,
    name: &str,
    d: &MaterialDescription,
    texture_ids: &HashMap<String, u16>,
    mean_of: impl Fn(u16) -> Vec3A,
) -> Result<Material> {
    let err = |m: String| invalid(path, format!("material `{name}`: {m}"));
    let (diffuse, emission) = (vec3(d.diffuse), vec3(d.emission));
    if !diffuse.is_finite() || diffuse.min_element() < 0.0 || diffuse.max_element() > 1.0 {
        return Err(err(format!("diffuse reflectance must lie in [0, 1], got {:?}", d.diffuse)));
    }
    if !emission.is_finite() || emission.min_element() < 0.0 {
        return Err(err(format!("emission must be finite and non-negative, got {:?}", d.emission)));
    }
    // Samples are squared for the variance (kept in f32): beyond this a sample's square
    // overflows, and the image's error estimates become infinite.
    if emission.max_element() > MAX_EMISSION {
        return Err(err(format!("emission must be at most {MAX_EMISSION:e} per channel, got {:?}", d.emission)));
    }
    let bsdf = bsdf_from(d).map_err(err)?;
    if bsdf.transmits() && d.two_sided.is_some() {
        return Err(err("`two_sided` is for opaque materials (glass always has two sides)".into()));
    }
    if d.two_sided_emission && emission == Vec3A::ZERO {
        return Err(err("`two_sided_emission` needs an `emission`".into()));
    }
    let textures = texture_slots(d, &bsdf, texture_ids).map_err(err)?;
    // A textured plastic chooses its mirror by the texture's mean reflectance.
    let bsdf = match (bsdf, textures.reflectance) {
        (Bsdf::Plastic { eta, nonlinear, coat, .. }, Some(t)) => {
            Bsdf::plastic_with(mean_of(t), eta, coat.map_or(Microfacet::ggx(0.0), |c| c.mf), nonlinear)
        }
        (bsdf, _) => bsdf,
    };
    Ok(Material {
        bsdf,
        emission,
        two_sided: d.two_sided.unwrap_or(true),
        two_sided_emission: d.two_sided_emission,
        textures,
    })
}

/// The textures a material description names, checked against its type.
fn texture_slots(
    d: &MaterialDescription,
    bsdf: &Bsdf,
    texture_ids: &HashMap<String, u16>,
) -> std::result::Result<TextureSlots, String> {
    let find = |key: &str, name: &Option<String>, applies: bool| -> std::result::Result<Option<u16>, String> {
        let Some(name) = name else { return Ok(None) };
        if !applies {
            return Err(format!("`{key}` does not apply to type \"{}\"", format!("{:?}", d.kind).to_lowercase()));
        }
        texture_ids.get(name).copied().map(Some).ok_or_else(|| format!("`{key}`: unknown texture `{name}`"))
    };
    let diffuse =
        find("diffuse_texture", &d.diffuse_texture, matches!(bsdf, Bsdf::Diffuse { .. } | Bsdf::Plastic { .. }))?;
    let specular = find("specular_texture", &d.specular_texture, matches!(bsdf, Bsdf::Conductor { .. }))?;
    let roughness = find(
        "roughness_texture",
        &d.roughness_texture,
        matches!(bsdf, Bsdf::Conductor { .. } | Bsdf::Dielectric { thin: false, .. }),
    )?;
    Ok(TextureSlots { reflectance: diffuse.or(specular), roughness })
}

/// A scene's textures, their indices by name, the files they were read from, and their maps
/// of texture coordinates (empty when none has one).
type Textures = (Vec<Texture>, HashMap<String, u16>, Vec<PathBuf>, Vec<Option<glam::Affine2>>);

/// The `[textures]` of a scene file, their indices by name, and the files they read.
fn textures_from(path: &Path, d: &SceneDescription) -> Result<Textures> {
    use super::description::{FilterDescription, TextureKind, WrapDescription};
    let (mut textures, mut ids, mut sources, mut maps) = (Vec::new(), HashMap::new(), Vec::new(), Vec::new());
    if d.textures.len() > usize::from(u16::MAX) {
        return Err(invalid(path, format!("more than {} textures", u16::MAX)));
    }
    // Image files are decoded first, in parallel (a scene may hold dozens of megapixels of
    // JPEG and PNG), each (file, raw) once; errors are reported below in the textures' order.
    let folder = path.parent().unwrap_or(Path::new("."));
    let files: Vec<(PathBuf, bool)> = {
        let mut seen = std::collections::BTreeSet::new();
        d.textures
            .values()
            .filter(|t| t.kind == TextureKind::Bitmap)
            .filter_map(|t| t.file.as_ref().map(|f| (folder.join(f), t.raw.unwrap_or(false))))
            .filter(|k| seen.insert(k.clone()))
            .collect()
    };
    let mut uses: HashMap<(PathBuf, bool), usize> = HashMap::new();
    let distinct: HashMap<String, &super::description::TextureDescription> =
        d.textures.values().map(|t| (format!("{t:?}"), t)).collect();
    for t in distinct.values().filter(|t| t.kind == TextureKind::Bitmap) {
        if let Some(f) = &t.file {
            *uses.entry((folder.join(f), t.raw.unwrap_or(false))).or_default() += 1;
        }
    }
    let mut reused: HashMap<(PathBuf, bool), Bitmap> = HashMap::new();
    let mut decoded: HashMap<(PathBuf, bool), Result<Bitmap>> = {
        use rayon::prelude::*;
        files
            .into_par_iter()
            .map(|(file, raw)| {
                let bitmap = Bitmap::load(&file, Wrap::Repeat, Filter::Bilinear, raw);
                ((file, raw), bitmap)
            })
            .collect()
    };
    // Textures described alike are one texture (importers name one per use of a file).
    let mut alike: HashMap<String, u16> = HashMap::new();
    for (name, t) in &d.textures {
        let description = format!("{t:?}");
        if let Some(&id) = alike.get(&description) {
            ids.insert(name.clone(), id);
            continue;
        }
        alike.insert(description, textures.len() as u16);
        let err = |m: String| invalid(path, format!("texture `{name}`: {m}"));
        let colour = |key: &str, v: Option<[f32; 3]>, default: f32| {
            let v = v.unwrap_or([default; 3]);
            if v.iter().all(|x| x.is_finite() && *x >= 0.0) {
                Ok(vec3(v))
            } else {
                Err(err(format!("`{key}` must be finite and non-negative, got {v:?}")))
            }
        };
        let texture = match t.kind {
            TextureKind::Checkerboard => {
                if t.file.is_some()
                    || t.wrap.is_some()
                    || t.filter.is_some()
                    || t.raw.is_some()
                    || t.v_from_top.is_some()
                {
                    return Err(err("`file`, `wrap`, `filter`, `raw` and `v_from_top` are for bitmaps".into()));
                }
                let scale = t.scale.unwrap_or([2.0; 2]);
                if !scale.iter().all(|x| x.is_finite() && *x > 0.0 && *x <= 1e6) {
                    return Err(err(format!("`scale` must lie in (0, 1e6], got {scale:?}")));
                }
                // Mitsuba 3's defaults: 0.4 and 0.2.
                Texture::Checkerboard {
                    a: colour("color0", t.color0, 0.4)?,
                    b: colour("color1", t.color1, 0.2)?,
                    scale: Vec2::from_array(scale),
                }
            }
            TextureKind::Bitmap => {
                if t.color0.is_some() || t.color1.is_some() || t.scale.is_some() {
                    return Err(err("`color0`, `color1` and `scale` are for checkerboards".into()));
                }
                let Some(file) = &t.file else {
                    return Err(err("a bitmap needs `file`".into()));
                };
                let file = folder.join(file);
                let wrap = match t.wrap {
                    None | Some(WrapDescription::Repeat) => Wrap::Repeat,
                    Some(WrapDescription::Mirror) => Wrap::Mirror,
                    Some(WrapDescription::Clamp) => Wrap::Clamp,
                };
                let filter = match t.filter {
                    None | Some(FilterDescription::Bilinear) => Filter::Bilinear,
                    Some(FilterDescription::Nearest) => Filter::Nearest,
                };
                let key = (file.clone(), t.raw.unwrap_or(false));
                let bitmap = match decoded.remove(&key) {
                    Some(loaded) => {
                        let b = loaded?;
                        if uses.get(&key).is_some_and(|&n| n > 1) {
                            reused.insert(key, b.clone());
                        }
                        b
                    }
                    None => match reused.get(&key) {
                        Some(b) => b.clone(),
                        None => Bitmap::load(&file, wrap, filter, key.1)?,
                    },
                };
                let mut bitmap = Bitmap { wrap, filter, ..bitmap };
                if t.v_from_top == Some(true) {
                    bitmap.flip_rows();
                }
                if bitmap.texels.iter().any(|t| !t.is_finite() || t.min_element() < 0.0) {
                    return Err(Error::Image {
                        path: file,
                        message: "a texture must be finite and non-negative".into(),
                    });
                }
                sources.push(file);
                Texture::Bitmap(bitmap)
            }
        };
        let texture = match (t.factor, t.invert) {
            (None, None | Some(false)) => texture,
            (factor, invert) => {
                let f = colour("factor", factor, 1.0)?;
                let invert = invert.unwrap_or(false);
                let apply = |v: Vec3A| if invert { (Vec3A::ONE - f * v).max(Vec3A::ZERO) } else { f * v };
                match texture {
                    Texture::Bitmap(mut b) => {
                        b.texels.iter_mut().for_each(|t| *t = apply(*t));
                        Texture::Bitmap(b)
                    }
                    Texture::Checkerboard { a, b, scale } => Texture::Checkerboard { a: apply(a), b: apply(b), scale },
                    Texture::Constant(c) => Texture::Constant(apply(c)),
                }
            }
        };
        let map = match t.uv_transform {
            None => None,
            Some(m) if m.iter().flatten().all(|x| x.is_finite()) => {
                Some(glam::Affine2::from_cols_array(&[m[0][0], m[1][0], m[0][1], m[1][1], m[0][2], m[1][2]]))
            }
            Some(m) => return Err(err(format!("`uv_transform` must be finite, got {m:?}"))),
        };
        maps.push(map);
        ids.insert(name.clone(), textures.len() as u16);
        textures.push(texture);
    }
    if maps.iter().all(Option::is_none) {
        maps.clear();
    }
    Ok((textures, ids, sources, maps))
}

/// A filter description's shape, checked.
fn filter_shape(f: &super::description::PixelFilterDescription) -> std::result::Result<FilterShape, String> {
    use super::description::PixelFilterKind as K;
    if f.stddev.is_some() && f.kind != K::Gaussian {
        return Err("`stddev` is for the gaussian filter".into());
    }
    let stddev = f.stddev.unwrap_or(0.5);
    let radius = f.radius.unwrap_or(match f.kind {
        K::Box => [0.5; 2],
        K::Gaussian => [4.0 * stddev; 2],
        K::Tent => [1.0; 2],
    });
    let shape = match f.kind {
        K::Box => FilterShape::Box { radius },
        K::Gaussian => FilterShape::Gaussian { stddev, radius },
        K::Tent => FilterShape::Tent { radius },
    };
    if shape.is_valid() {
        Ok(shape)
    } else {
        Err(format!("radius and stddev must lie in (0, 16] pixels, got {radius:?} and {stddev}"))
    }
}

/// The scattering model a material description asks for; keys that do not apply to its type
/// are errors.
fn bsdf_from(d: &MaterialDescription) -> std::result::Result<Bsdf, String> {
    use crate::scene::description::MaterialKind as K;
    let kind = format!("{:?}", d.kind).to_lowercase();
    let allowed: &[&str] = match d.kind {
        K::Diffuse => &["diffuse"],
        K::Conductor => &["metal", "eta", "k", "specular", "roughness", "distribution", "masking"],
        K::Dielectric => &["ior", "exterior_ior", "roughness", "distribution", "masking"],
        K::ThinDielectric => &["ior", "exterior_ior"],
        K::Plastic => &["diffuse", "ior", "exterior_ior", "nonlinear", "roughness", "distribution", "masking"],
    };
    let given = [
        ("diffuse", d.diffuse != [0.0; 3] && d.kind != K::Diffuse),
        ("metal", d.metal.is_some()),
        ("eta", d.eta.is_some()),
        ("k", d.k.is_some()),
        ("specular", d.specular.is_some()),
        ("ior", d.ior.is_some()),
        ("exterior_ior", d.exterior_ior.is_some()),
        ("roughness", d.roughness.is_some()),
        ("distribution", d.distribution.is_some()),
        ("masking", d.masking.is_some()),
        ("nonlinear", d.nonlinear.is_some()),
    ];
    if let Some((key, _)) = given.iter().find(|(key, set)| *set && !allowed.contains(key)) {
        return Err(format!("`{key}` does not apply to type \"{kind}\""));
    }
    let alpha = d.roughness.unwrap_or(0.0);
    if !(alpha.is_finite() && (0.0..=1.0).contains(&alpha)) {
        return Err(format!("roughness must lie in [0, 1], got {alpha}"));
    }
    let distribution = match d.distribution {
        None | Some(DistributionDescription::Ggx) => Distribution::Ggx,
        Some(DistributionDescription::Beckmann) => Distribution::Beckmann,
    };
    let masking = match d.masking {
        None | Some(MaskingDescription::Correlated) => Masking::Correlated,
        Some(MaskingDescription::Separable) => Masking::Separable,
    };
    // A roughness texture sets α per hit: the material is rough whatever `roughness` says.
    let alpha = if d.roughness_texture.is_some() { alpha.max(Microfacet::MIN_ALPHA) } else { alpha };
    let rough = Microfacet::new(distribution, masking, alpha);
    // Defaults: glass 1.5; plastic 1.49 (Mitsuba's polypropylene); outside, vacuum. A
    // dielectric is an interface between two media, so its relative index may lie below 1
    // (ice seen from water, as pbrt-v4 and Mitsuba 3 allow); a plastic's coat is denser than
    // the air above it.
    let eta = |default: f32, interface: bool| -> std::result::Result<f32, String> {
        let (int, ext) = (d.ior.unwrap_or(default), d.exterior_ior.unwrap_or(1.0));
        let eta = int / ext;
        let finite = int.is_finite() && ext.is_finite() && eta.is_finite() && eta > 0.0;
        if interface {
            if !(finite && int > 0.0 && ext > 0.0 && (1e-2..=1e2).contains(&eta)) {
                return Err(format!(
                    "indices of refraction must be positive and finite, within a factor of 100 of each other, got {int} and {ext}"
                ));
            }
        } else if !(finite && int >= 1.0 && ext >= 1.0) {
            return Err(format!(
                "a plastic's indices of refraction must be finite and at least 1, got {int} and {ext}"
            ));
        }
        if (eta - 1.0).abs() < 1e-4 {
            return Err("interior and exterior index of refraction must differ".into());
        }
        Ok(eta)
    };
    let triple = |what: &str, v: [f32; 3], max: f32| {
        let ok = v.iter().all(|x| x.is_finite() && *x >= 0.0 && *x <= max);
        if ok { Ok(vec3(v)) } else { Err(format!("{what} must lie in [0, {max}] per channel, got {v:?}")) }
    };
    Ok(match d.kind {
        K::Diffuse => Bsdf::Diffuse { reflectance: vec3(d.diffuse) },
        K::Conductor => {
            let (eta, k) = match (&d.metal, d.eta, d.k) {
                (Some(m), None, None) => conductors::lookup(m)
                    .ok_or_else(|| format!("unknown metal `{m}` (known: {})", conductors::names().join(", ")))?,
                (None, Some(eta), Some(k)) => (triple("eta", eta, 1e3)?, triple("k", k, 1e3)?),
                (None, None, None) => conductors::lookup("none").expect("the mirror is in the table"),
                _ => return Err("give either `metal` or both `eta` and `k`".into()),
            };
            let specular = triple("specular", d.specular.unwrap_or([1.0; 3]), 1.0)?;
            match Bsdf::conductor(eta, k, rough) {
                Bsdf::Conductor { eta, k, roughness, .. } => Bsdf::Conductor { eta, k, specular, roughness },
                other => other,
            }
        }
        K::Dielectric => Bsdf::dielectric(eta(1.5, true)?, rough),
        K::ThinDielectric => Bsdf::Dielectric { eta: eta(1.5, true)?, roughness: None, thin: true },
        K::Plastic => Bsdf::plastic_with(vec3(d.diffuse), eta(1.49, false)?, rough, d.nonlinear.unwrap_or(false)),
    })
}

fn build(path: &Path, d: SceneDescription) -> Result<Scene> {
    let c = &d.camera;
    check_resolution(c.width, c.height).map_err(|m| invalid(path, format!("camera: {m}")))?;
    if !(c.fov_y > 0.0 && c.fov_y < 180.0) {
        return Err(invalid(path, format!("camera: fov_y must lie in (0, 180) degrees, got {}", c.fov_y)));
    }
    if ![c.eye, c.look_at, c.up].iter().flatten().all(|x| x.is_finite()) {
        return Err(invalid(path, "camera: eye, look_at and up must be finite"));
    }
    let mut camera = Camera::new(vec3(c.eye), vec3(c.look_at), vec3(c.up), c.fov_y, c.width, c.height)
        .ok_or_else(|| invalid(path, "camera: eye equals look_at, or up is parallel to the view direction"))?;
    if let Some(f) = c.filter {
        camera.filter = PixelFilter::new(filter_shape(&f).map_err(|m| invalid(path, format!("camera: filter: {m}")))?);
    }
    if c.mirror {
        camera = camera.mirrored();
    }
    if let Some(window) = c.crop {
        camera = camera.cropped(window).ok_or_else(|| {
            invalid(
                path,
                format!("camera: crop {window:?} must be a non-empty window inside the {}x{} film", c.width, c.height),
            )
        })?;
    }

    let (textures, texture_ids, texture_sources, texture_uv) = textures_from(path, &d)?;
    let mut meshes = Meshes::default();
    for (name, m) in &d.materials {
        meshes.by_name.insert(name.clone(), meshes.materials.len() as u32);
        meshes.materials.push(material_from(path, name, m, &texture_ids, |t| textures[usize::from(t)].mean())?);
    }

    let folder = path.parent().unwrap_or(Path::new("."));
    let mut sources = Vec::new();
    // A file placed more than once (instancing) is read once: its triangles as read, before
    // any placement, are kept and copied.
    type MeshKey = (PathBuf, bool, Option<String>, bool);
    let key = |m: &super::description::MeshDescription| -> MeshKey {
        (
            folder.join(m.obj.as_ref().or(m.ply.as_ref()).map_or("", String::as_str)),
            m.ply.is_some(),
            m.material.clone(),
            m.reverse_winding,
        )
    };
    let mut uses: HashMap<MeshKey, usize> = HashMap::new();
    for mesh in &d.meshes {
        *uses.entry(key(mesh)).or_default() += 1;
    }
    let mut read_before: HashMap<MeshKey, Geometry> = HashMap::new();
    for mesh in &d.meshes {
        let (file, is_ply) = match (&mesh.obj, &mesh.ply) {
            (Some(f), None) => (f, false),
            (None, Some(f)) => (f, true),
            _ => return Err(invalid(path, "a [[mesh]] names one file: `obj = \"...\"` or `ply = \"...\"`")),
        };
        if file.is_empty() {
            return Err(invalid(path, "a [[mesh]] has an empty file path"));
        }
        let mesh_path = folder.join(file);
        let start = meshes.geometry.triangles.len();
        let mesh_key = key(mesh);
        if let Some(raw) = read_before.get(&mesh_key) {
            append_geometry(&mut meshes.geometry, raw).map_err(|e| invalid(path, format!("mesh `{file}`: {e}")))?;
        } else {
            sources.push(mesh_path.clone());
            read_mesh(path, mesh, file, &mesh_path, is_ply, &mut meshes)?;
            if uses.get(&mesh_key).is_some_and(|&n| n > 1) {
                read_before.insert(mesh_key, copy_geometry(&meshes.geometry, start));
            }
        }
        if let Some(m) = mesh.matrix {
            transform_since(&mut meshes.geometry, start, m)
                .map_err(|e| invalid(path, format!("mesh `{file}`: {e}")))?;
        }
        if mesh.face_normals && mesh.smooth_normals {
            return Err(invalid(
                path,
                format!("mesh `{file}`: `face_normals` and `smooth_normals` exclude each other"),
            ));
        }
        if mesh.face_normals {
            let normals = &mut meshes.geometry.attributes.normals;
            for c in normals.iter_mut().skip(start) {
                *c = [Vec3A::ZERO; 3];
            }
        }
        if mesh.smooth_normals {
            smooth_normals_since(&mut meshes.geometry, start);
        }
        if mesh.flip_v {
            let uvs = &mut meshes.geometry.attributes.uvs;
            for c in uvs.iter_mut().skip(start).filter(|c| **c != Attributes::BARYCENTRIC_UV) {
                for uv in c {
                    uv.y = 1.0 - uv.y;
                }
            }
        }
    }
    for (k, shape) in d.shapes.iter().enumerate() {
        add_shape(path, k, shape, &mut meshes)?;
    }
    for mesh in &d.inline_meshes {
        add_inline_mesh(path, mesh, &mut meshes)?;
    }
    let Meshes { materials, geometry: Geometry { triangles, triangle_material, attributes, findings }, .. } = meshes;
    if triangles.is_empty() {
        return Err(invalid(path, "the scene has no (non-degenerate) triangles"));
    }
    let mut warnings = Vec::new();
    if findings.degenerate > 0 {
        warnings.push(format!("skipped {} degenerate (zero-area) triangle(s)", findings.degenerate));
    }
    if findings.short_faces > 0 {
        warnings.push(format!(
            "skipped {} point(s), line(s) and face(s) with fewer than 3 vertices (not surfaces)",
            findings.short_faces
        ));
    }
    if findings.non_simple > 0 {
        warnings.push(format!(
            "{} polygon(s) are not simple (self-intersecting or degenerate): fan-triangulated",
            findings.non_simple
        ));
    }
    let name = path
        .parent()
        .and_then(|p| p.file_name())
        .map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned());
    let (lights, light_sources) = lights_from(path, &d)?;
    let mut scene =
        Scene::from_parts(name, path.to_path_buf(), camera, triangles, triangle_material, materials, lights, warnings);
    scene.attributes = attributes;
    scene.textures = textures;
    scene.texture_uv = texture_uv;
    if let Some(r) = d.render {
        if r.spp == Some(0) {
            return Err(invalid(path, "render: spp must be at least 1"));
        }
        scene.render = r;
    }
    scene.sources.extend(texture_sources);
    scene.sources.extend(sources);
    scene.sources.extend(light_sources);
    Ok(scene)
}

/// The point and spot lights and the environment of a scene file, and the files they read.
fn lights_from(path: &Path, d: &SceneDescription) -> Result<(Lights, Vec<PathBuf>)> {
    let mut lights = Lights::default();
    let mut sources = Vec::new();
    for (k, l) in d.lights.iter().enumerate() {
        let err = |e: Error| match e {
            Error::InvalidOption(m) => invalid(path, format!("light {}: {m}", k + 1)),
            other => other,
        };
        let need = |key: &str, v: Option<[f32; 3]>| {
            v.map(vec3).ok_or_else(|| invalid(path, format!("light {}: a {:?} light needs `{key}`", k + 1, l.kind)))
        };
        let forbid = |keys: &[(&str, bool)]| match keys.iter().find(|(_, given)| *given) {
            Some((key, _)) => Err(invalid(path, format!("light {}: `{key}` is not for {:?} lights", k + 1, l.kind))),
            None => Ok(()),
        };
        match l.kind {
            LightKind::Point => {
                forbid(&[
                    ("direction", l.direction.is_some()),
                    ("cutoff", l.cutoff.is_some()),
                    ("beam", l.beam.is_some()),
                    ("irradiance", l.irradiance.is_some()),
                ])?;
                let light = PointLight::point(need("position", l.position)?, need("intensity", l.intensity)?);
                lights.points.push(light.map_err(err)?);
            }
            LightKind::Spot => {
                forbid(&[("irradiance", l.irradiance.is_some())])?;
                let (position, intensity) = (need("position", l.position)?, need("intensity", l.intensity)?);
                let direction = need("direction", l.direction)?;
                let light = PointLight::spot(position, direction, intensity, l.cutoff.unwrap_or(20.0), l.beam);
                lights.points.push(light.map_err(err)?);
            }
            LightKind::Distant => {
                forbid(&[
                    ("position", l.position.is_some()),
                    ("intensity", l.intensity.is_some()),
                    ("cutoff", l.cutoff.is_some()),
                    ("beam", l.beam.is_some()),
                ])?;
                let (direction, irradiance) = (need("direction", l.direction)?, need("irradiance", l.irradiance)?);
                if irradiance.max_element() > MAX_EMISSION {
                    return Err(invalid(path, format!("light {}: irradiance must be at most {MAX_EMISSION:e}", k + 1)));
                }
                lights.distant.push(crate::light::DistantLight::new(direction, irradiance).map_err(err)?);
            }
        }
    }
    if let Some(e) = &d.environment {
        let scale = e.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(invalid(path, format!("environment: scale must be finite and non-negative, got {scale}")));
        }
        let env = match (&e.radiance, &e.map) {
            (Some(r), None) => {
                let r = vec3(*r) * scale;
                if !r.is_finite() || r.min_element() < 0.0 || r.max_element() > MAX_EMISSION {
                    return Err(invalid(
                        path,
                        format!("environment: radiance must lie in [0, {MAX_EMISSION:e}], got {r}"),
                    ));
                }
                Environment::constant(r)
            }
            (None, Some(file)) => {
                let file = path.parent().unwrap_or(Path::new(".")).join(file);
                let bitmap = Bitmap::load(&file, Wrap::Repeat, Filter::Nearest, false)?;
                let (w, h, texels) = bitmap.into_texels();
                if texels.iter().any(|t| !t.is_finite() || t.min_element() < 0.0) {
                    return Err(Error::Image {
                        path: file,
                        message: "an environment map must be finite and non-negative".into(),
                    });
                }
                sources.push(file.clone());
                let layout = e.layout.unwrap_or(MapLayout::Equirectangular);
                let rotation = match e.matrix {
                    None => None,
                    Some(m) => {
                        let (linear, _) = affine(m).map_err(|m| invalid(path, format!("environment: {m}")))?;
                        let r = glam::Mat3A::from_cols(
                            linear.x_axis.normalize_or_zero(),
                            linear.y_axis.normalize_or_zero(),
                            linear.z_axis.normalize_or_zero(),
                        );
                        // A mirror image too (pbrt's hair-curl turns its sky by a matrix of
                        // determinant −1): directions keep their solid angle either way.
                        let orthogonal =
                            (r.transpose() * r - glam::Mat3A::IDENTITY).to_cols_array().iter().all(|x| x.abs() < 1e-3);
                        if !orthogonal {
                            return Err(invalid(path, "environment: `matrix` must be a rotation or a reflection"));
                        }
                        Some(r)
                    }
                };
                let mitsuba = e.lookup == Some(super::description::EnvLookupDescription::Mitsuba);
                if mitsuba && layout != MapLayout::Equirectangular {
                    return Err(invalid(path, "environment: the mitsuba lookup is for equirectangular maps"));
                }
                // Read as Mitsuba reads it, the map is turned at each lookup; otherwise it is
                // resampled into our layout once.
                let (w, h, texels) = if mitsuba || (layout == MapLayout::Equirectangular && rotation.is_none()) {
                    (w, h, texels)
                } else {
                    equirectangular_from(layout, rotation.unwrap_or(glam::Mat3A::IDENTITY), w, h, &texels)
                };
                let env = Environment::from_texels(w, h, texels.into_iter().map(|t| t * scale).collect()).map_err(
                    |e| match e {
                        Error::InvalidOption(m) => Error::Image { path: file.clone(), message: m },
                        other => other,
                    },
                )?;
                if mitsuba { env.mitsuba(rotation) } else { env }
            }
            _ => return Err(invalid(path, "environment: give either `radiance` or `map`")),
        };
        lights.environment = Some(env);
    }
    Ok((lights, sources))
}

/// A row-major 4×4 `matrix` as `(linear part, translation)`: finite, affine.
fn affine(m: [[f32; 4]; 4]) -> Result<(glam::Mat3A, Vec3A), String> {
    if !m.iter().flatten().all(|x| x.is_finite()) {
        return Err("`matrix` must be finite".into());
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!("`matrix`'s last row must be [0, 0, 0, 1] (an affine map), got {:?}", m[3]));
    }
    let linear = glam::Mat3A::from_cols(
        Vec3A::new(m[0][0], m[1][0], m[2][0]),
        Vec3A::new(m[0][1], m[1][1], m[2][1]),
        Vec3A::new(m[0][2], m[1][2], m[2][2]),
    );
    Ok((linear, Vec3A::new(m[0][3], m[1][3], m[2][3])))
}

/// Moves the triangles from `start` on (a mesh just loaded) by the affine map `m`: corners,
/// and shading normals by the inverse transpose; a mirroring map swaps two corners so that
/// the outside stays outside. Triangles the map makes degenerate are an error (the map
/// flattens the mesh).
fn transform_since(g: &mut Geometry, start: usize, m: [[f32; 4]; 4]) -> Result<(), String> {
    let (linear, translate) = affine(m)?;
    let det = linear.determinant();
    if !(det.is_finite() && det.abs() > 1e-30) {
        return Err("the `matrix` flattens the mesh (its determinant is zero)".into());
    }
    let normal_map = linear.inverse().transpose();
    let flip = det < 0.0;
    for i in start..g.triangles.len() {
        let t = g.triangles[i].map(|p| linear * p + translate);
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        if !(t.iter().all(|p| p.is_finite()) && n.normalize().is_finite()) {
            return Err("the `matrix` makes a triangle degenerate or infinite".into());
        }
        g.triangles[i] = t;
        if let Some(c) = g.attributes.normals.get_mut(i).filter(|c| c[0] != Vec3A::ZERO) {
            *c = c.map(|v| (normal_map * v).normalize_or_zero());
            if c.contains(&Vec3A::ZERO) {
                *c = [Vec3A::ZERO; 3];
            }
        }
        if flip {
            g.triangles[i].swap(1, 2);
            if let Some(c) = g.attributes.normals.get_mut(i) {
                c.swap(1, 2);
            }
            if let Some(c) = g.attributes.uvs.get_mut(i) {
                c.swap(1, 2);
            }
        }
    }
    Ok(())
}

/// Smooth vertex normals for the triangles from `start` on that have none: corners with the
/// same position and texture coordinates are one vertex, whose normal is the sum of its
/// triangles' unit normals each weighted by the triangle's angle at it (Mitsuba 3's rule for
/// meshes without normals), normalised. A vertex whose sum vanishes leaves its triangles flat.
fn smooth_normals_since(g: &mut Geometry, start: usize) {
    let end = g.triangles.len();
    let has_normals = |g: &Geometry, i: usize| g.attributes.normals.get(i).is_some_and(|c| c[0] != Vec3A::ZERO);
    let key = |g: &Geometry, i: usize, k: usize| {
        let p = g.triangles[i][k];
        let uv = g.attributes.uvs.get(i).map_or(Vec2::ZERO, |t| t[k]);
        [p.x.to_bits(), p.y.to_bits(), p.z.to_bits(), uv.x.to_bits(), uv.y.to_bits()]
    };
    let mut sums: HashMap<[u32; 5], Vec3A> = HashMap::new();
    for i in (start..end).filter(|&i| !has_normals(g, i)) {
        let t = g.triangles[i];
        let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
        for k in 0..3 {
            let (a, b) = ((t[(k + 1) % 3] - t[k]).normalize_or_zero(), (t[(k + 2) % 3] - t[k]).normalize_or_zero());
            let angle = a.dot(b).clamp(-1.0, 1.0).acos();
            *sums.entry(key(g, i, k)).or_insert(Vec3A::ZERO) += n * angle;
        }
    }
    if sums.is_empty() {
        return;
    }
    let smooth: Vec<(usize, [Vec3A; 3])> = (start..end)
        .filter(|&i| !has_normals(g, i))
        .map(|i| (i, [0, 1, 2].map(|k| sums[&key(g, i, k)].normalize_or_zero())))
        .filter(|(_, c)| !c.contains(&Vec3A::ZERO))
        .collect();
    g.attributes.normals.resize(end, [Vec3A::ZERO; 3]);
    for (i, c) in smooth {
        g.attributes.normals[i] = c;
    }
}

/// Adds an imported scene's inline triangle mesh (positions already in the world).
fn add_inline_mesh(path: &Path, m: &super::description::InlineMesh, meshes: &mut Meshes) -> Result<()> {
    let err = |message: String| invalid(path, format!("{}: {message}", m.origin));
    let material = *meshes.by_name.get(&m.material).ok_or_else(|| err(format!("unknown material `{}`", m.material)))?;
    let n = m.positions.len();
    if !m.indices.len().is_multiple_of(3) {
        return Err(err(format!("{} indices are not whole triangles", m.indices.len())));
    }
    if let Some(&i) = m.indices.iter().find(|&&i| i as usize >= n) {
        return Err(err(format!("vertex index {i} out of range ({n} vertices)")));
    }
    for (what, len) in [("normals", m.normals.as_ref().map(Vec::len)), ("uv", m.uvs.as_ref().map(Vec::len))] {
        if len.is_some_and(|l| l != n) {
            return Err(err(format!("{} {what} for {n} vertices", len.unwrap_or(0))));
        }
    }
    for t in m.indices.chunks_exact(3) {
        let idx = [t[0] as usize, t[1] as usize, t[2] as usize];
        let mut tri = idx.map(|i| vec3(m.positions[i]));
        let mut corners = Corners {
            normals: m.normals.as_ref().map(|v| idx.map(|i| vec3(v[i]))),
            uvs: m.uvs.as_ref().map(|v| idx.map(|i| Vec2::from_array(v[i]))),
        };
        if m.reverse_winding {
            tri.swap(1, 2);
            corners.swap();
            corners.normals = corners.normals.map(|c| c.map(|v| -v));
        }
        push_triangle(&mut meshes.geometry, tri, corners, material).map_err(err)?;
    }
    Ok(())
}

/// An environment map resampled (bilinearly) into our layout, equirectangular with +y up,
/// from `layout` turned into the world by `rotation`: a square `N`×`N` equal-area map becomes
/// `2N`×`N`, an equirectangular one keeps its size.
fn equirectangular_from(
    layout: MapLayout,
    rotation: glam::Mat3A,
    w: usize,
    h: usize,
    texels: &[Vec3A],
) -> (usize, usize, Vec<Vec3A>) {
    use std::f32::consts::{PI, TAU};
    let (out_w, out_h) = match layout {
        MapLayout::EqualArea => (2 * h, h),
        MapLayout::Equirectangular => (w, h),
    };
    let texel = |x: i64, y: i64, wrap_x: bool| -> Vec3A {
        let x = if wrap_x { x.rem_euclid(w as i64) } else { x.clamp(0, w as i64 - 1) };
        texels[y.clamp(0, h as i64 - 1) as usize * w + x as usize]
    };
    let lookup = |u: f32, v: f32, wrap_x: bool| -> Vec3A {
        let (x, y) = (u * w as f32 - 0.5, v * h as f32 - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let top = texel(x0, y0, wrap_x) * (1.0 - fx) + texel(x0 + 1, y0, wrap_x) * fx;
        let bottom = texel(x0, y0 + 1, wrap_x) * (1.0 - fx) + texel(x0 + 1, y0 + 1, wrap_x) * fx;
        top * (1.0 - fy) + bottom * fy
    };
    let inverse = rotation.transpose();
    let mut out = Vec::with_capacity(out_w * out_h);
    for j in 0..out_h {
        for i in 0..out_w {
            let (phi, theta) = (TAU * (i as f32 + 0.5) / out_w as f32, PI * (j as f32 + 0.5) / out_h as f32);
            let d = Vec3A::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos());
            let m = inverse * d;
            out.push(match layout {
                MapLayout::Equirectangular => {
                    let u = m.x.atan2(-m.z) / TAU;
                    lookup(u.rem_euclid(1.0), m.y.clamp(-1.0, 1.0).acos() / PI, true)
                }
                MapLayout::EqualArea => {
                    let uv = crate::geometry::warp::equal_area_sphere_to_square(m);
                    lookup(uv.x, uv.y, false)
                }
            });
        }
    }
    (out_w, out_h, out)
}

/// The affine map of a shape's placement: `(linear part, translation)`.
fn shape_transform(s: &ShapeDescription) -> Result<(glam::Mat3A, Vec3A), String> {
    if let Some(m) = s.matrix {
        if s.scale.is_some() || s.rotate.is_some() || s.translate.is_some() {
            return Err("give either `matrix` or `scale`/`rotate`/`translate`, not both".into());
        }
        return affine(m);
    }
    let scale = vec3(s.scale.unwrap_or([1.0; 3]));
    let translate = vec3(s.translate.unwrap_or([0.0; 3]));
    if !(scale.is_finite() && translate.is_finite()) {
        return Err("`scale` and `translate` must be finite".into());
    }
    let rotation = match s.rotate {
        None => glam::Mat3A::IDENTITY,
        Some(r) => {
            let axis = vec3(r.axis)
                .try_normalize()
                .filter(|_| r.angle.is_finite())
                .ok_or_else(|| format!("`rotate` needs a finite angle and a non-zero axis, got {r:?}"))?;
            glam::Mat3A::from_axis_angle(axis.into(), r.angle.to_radians())
        }
    };
    Ok((rotation * glam::Mat3A::from_diagonal(scale.into()), translate))
}

/// The texture coordinates (and for a sphere the normals) of triangle `t` of a canonical
/// shape, as Mitsuba 3 gives them: the rectangle `((x+1)/2, (y+1)/2)` (each cube face alike, in
/// its own two axes); the disk `(r, φ/2π)`; the sphere `(φ/2π, θ/π)` about its centre (`θ`
/// from +z), with its radial normals for smooth shading. Triangles across the seam `φ = 0`
/// take `u` beyond 1, and a corner at a pole the mean `u` of the other two, so that no
/// triangle spans the whole texture.
fn shape_corners(kind: ShapeKind, t: &[Vec3A; 3], centre: Vec3A, radius: f32) -> Corners {
    let angle = |p: Vec3A| {
        let phi = p.y.atan2(p.x);
        if phi < 0.0 { phi + std::f32::consts::TAU } else { phi }
    };
    let fix_seam = |mut uv: [Vec2; 3], pole: [bool; 3]| {
        let off_pole = || (0..3).filter(|&k| !pole[k]);
        let (lo, hi) =
            off_pole().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), k| (a.min(uv[k].x), b.max(uv[k].x)));
        if hi - lo > 0.5 {
            for k in off_pole() {
                if uv[k].x < 0.5 {
                    uv[k].x += 1.0;
                }
            }
        }
        let (sum, count) = off_pole().fold((0.0f32, 0u32), |(s, n), k| (s + uv[k].x, n + 1));
        if count > 0 {
            for k in (0..3).filter(|&k| pole[k]) {
                uv[k].x = sum / count as f32;
            }
        }
        uv
    };
    match kind {
        ShapeKind::Rectangle => Corners { normals: None, uvs: Some(t.map(|p| Vec2::new(p.x + 1.0, p.y + 1.0) * 0.5)) },
        ShapeKind::Cube => {
            // The face's axis is the one all three corners share.
            let axis = (0..3).find(|&a| t[0][a] == t[1][a] && t[1][a] == t[2][a]).unwrap_or(2);
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            Corners { normals: None, uvs: Some(t.map(|p| Vec2::new(p[u] + 1.0, p[v] + 1.0) * 0.5)) }
        }
        ShapeKind::Disk => {
            let centre_corner = t.map(|p| p.truncate().length() < 1e-6);
            let uv = t.map(|p| Vec2::new(p.truncate().length(), angle(p) / std::f32::consts::TAU));
            // The disk's polar `u` is `r`: its seam is in `v`.
            let swapped = fix_seam(uv.map(|c| Vec2::new(c.y, c.x)), centre_corner);
            Corners { normals: None, uvs: Some(swapped.map(|c| Vec2::new(c.y, c.x))) }
        }
        ShapeKind::Sphere => {
            let d = t.map(|p| ((p - centre) / radius).normalize_or_zero());
            let pole = d.map(|n| n.x == 0.0 && n.y == 0.0);
            let uv = d.map(|n| {
                Vec2::new(angle(n) / std::f32::consts::TAU, n.z.clamp(-1.0, 1.0).acos() / std::f32::consts::PI)
            });
            Corners { normals: Some(d), uvs: Some(fix_seam(uv, pole)) }
        }
    }
}

/// Adds the triangles of the `k`-th `[[shape]]`.
fn add_shape(path: &Path, k: usize, s: &ShapeDescription, meshes: &mut Meshes) -> Result<()> {
    let err = |m: String| invalid(path, format!("shape {} ({:?}): {m}", k + 1, s.kind));
    let material = *meshes.by_name.get(&s.material).ok_or_else(|| err(format!("unknown material `{}`", s.material)))?;
    let sphere = s.kind == ShapeKind::Sphere;
    if !sphere && (s.center.is_some() || s.radius.is_some() || s.subdivisions.is_some()) {
        return Err(err("`center`, `radius` and `subdivisions` are for spheres".into()));
    }
    if s.kind != ShapeKind::Disk && s.segments.is_some() {
        return Err(err("`segments` is for disks".into()));
    }
    let (centre, radius) = (vec3(s.center.unwrap_or([0.0; 3])), s.radius.unwrap_or(1.0));
    let local = match s.kind {
        ShapeKind::Rectangle => super::shapes::rectangle(),
        ShapeKind::Cube => super::shapes::cube(),
        ShapeKind::Disk => {
            let n = s.segments.unwrap_or(super::shapes::DISK_SEGMENTS);
            if !(3..=1 << 20).contains(&n) {
                return Err(err(format!("`segments` must lie in 3..=2^20, got {n}")));
            }
            super::shapes::disk(n)
        }
        ShapeKind::Sphere => {
            let (c, r) = (vec3(s.center.unwrap_or([0.0; 3])), s.radius.unwrap_or(1.0));
            let n = s.subdivisions.unwrap_or(super::shapes::SPHERE_SUBDIVISIONS);
            if !(c.is_finite() && r.is_finite() && r > 0.0) {
                return Err(err(format!("a sphere needs a finite centre and a positive radius, got {c} and {r}")));
            }
            if n > super::shapes::MAX_SPHERE_SUBDIVISIONS {
                return Err(err(format!(
                    "`subdivisions` must be at most {}, got {n}",
                    super::shapes::MAX_SPHERE_SUBDIVISIONS
                )));
            }
            super::shapes::sphere(c, r, n)
        }
    };
    let (linear, translate) = shape_transform(s).map_err(err)?;
    let det = linear.determinant();
    if !(det.is_finite() && det.abs() > 1e-30) {
        return Err(err("the transform flattens the shape (its determinant is zero)".into()));
    }
    // A mirroring transform turns the winding inside out: flip it back (then as asked).
    let flip = (det < 0.0) != s.reverse_winding;
    // Normals map by the inverse transpose (outward stays outward), and turn with the winding
    // when it is reversed on request.
    let normal_map = linear.inverse().transpose() * if s.reverse_winding { -1.0 } else { 1.0 };
    for t in local {
        let mut corners = shape_corners(s.kind, &t, centre, radius);
        let mut t = t.map(|p| linear * p + translate);
        corners.normals = corners.normals.map(|c| c.map(|n| normal_map * n));
        if flip {
            t.swap(1, 2);
            corners.swap();
        }
        push_triangle(&mut meshes.geometry, t, corners, material).map_err(err)?;
    }
    Ok(())
}

/// What a triangle's corners carry besides positions.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Corners {
    pub normals: Option<[Vec3A; 3]>,
    pub uvs: Option<[Vec2; 3]>,
}

impl Corners {
    /// Swaps corners 1 and 2 (with a triangle's winding).
    fn swap(&mut self) {
        if let Some(n) = &mut self.normals {
            n.swap(1, 2);
        }
        if let Some(uv) = &mut self.uvs {
            uv.swap(1, 2);
        }
    }
}

/// Adds triangle `t` of `material` with its corners' attributes, unless it is degenerate or
/// not finite (counted in `findings`, reported as a warning); an error past
/// [`MAX_TRIANGLES`]. Vertex normals that are not finite and non-zero are dropped; where they
/// are kept they decide the outside, as in pbrt-v4: a triangle wound against them is turned.
fn push_triangle(g: &mut Geometry, mut t: [Vec3A; 3], mut corners: Corners, material: u32) -> Result<(), String> {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if !t.iter().all(|p| p.is_finite()) || n.length_squared() == 0.0 || !n.normalize().is_finite() {
        g.findings.degenerate += 1;
        return Ok(());
    }
    if g.triangles.len() >= MAX_TRIANGLES {
        return Err(format!("more than {MAX_TRIANGLES} triangles in the scene"));
    }
    corners.normals = corners.normals.and_then(|c| {
        let unit = c.map(|v| v.normalize_or_zero());
        unit.iter().all(|v| *v != Vec3A::ZERO).then_some(unit)
    });
    if corners.uvs.is_some_and(|uv| !uv.iter().all(|v| v.is_finite())) {
        corners.uvs = None;
    }
    if let Some(c) = corners.normals
        && (c[0] + c[1] + c[2]).dot(n) < 0.0
    {
        t.swap(1, 2);
        corners.swap();
    }
    let i = g.triangles.len();
    let attributes = &mut g.attributes;
    match corners.normals {
        Some(c) => {
            attributes.normals.resize(i, [Vec3A::ZERO; 3]);
            attributes.normals.push(c);
        }
        None if !attributes.normals.is_empty() => attributes.normals.push([Vec3A::ZERO; 3]),
        None => {}
    }
    match corners.uvs {
        Some(c) => {
            attributes.uvs.resize(i, Attributes::BARYCENTRIC_UV);
            attributes.uvs.push(c);
        }
        None if !attributes.uvs.is_empty() => attributes.uvs.push(Attributes::BARYCENTRIC_UV),
        None => {}
    }
    g.triangles.push(t);
    g.triangle_material.push(material);
    Ok(())
}

/// One polygon face's corners, filled by a mesh loader for [`push_face`]: positions, and
/// normals and texture coordinates (each empty when the face has none). Reused across faces.
#[derive(Default)]
struct Face {
    positions: Vec<Vec3A>,
    normals: Vec<Vec3A>,
    uvs: Vec<Vec2>,
    ears: Vec<[usize; 3]>,
}

impl Face {
    fn clear(&mut self) {
        self.positions.clear();
        self.normals.clear();
        self.uvs.clear();
    }
}

/// Triangulates `face` (ear clipping; a polygon that is not simple is fanned and counted) and
/// adds its triangles of `material`; `reverse` turns their winding and normals.
fn push_face(g: &mut Geometry, face: &mut Face, material: u32, reverse: bool) -> Result<(), String> {
    face.ears.clear();
    if !crate::geometry::polygon::triangulate(&face.positions, &mut face.ears) {
        g.findings.non_simple += 1;
    }
    let flip = if reverse { -1.0 } else { 1.0 };
    for e in &face.ears {
        let mut t = e.map(|k| face.positions[k]);
        let mut corners = Corners {
            normals: (!face.normals.is_empty()).then(|| e.map(|k| face.normals[k] * flip)),
            uvs: (!face.uvs.is_empty()).then(|| e.map(|k| face.uvs[k])),
        };
        if reverse {
            t.swap(1, 2);
            corners.swap();
        }
        push_triangle(g, t, corners, material)?;
    }
    Ok(())
}

/// Reads a `[[mesh]]`'s file into `meshes` (before its placement).
fn read_mesh(
    path: &Path,
    mesh: &super::description::MeshDescription,
    file: &str,
    mesh_path: &Path,
    is_ply: bool,
    meshes: &mut Meshes,
) -> Result<()> {
    let override_id = match &mesh.material {
        Some(name) => Some(
            *meshes
                .by_name
                .get(name)
                .ok_or_else(|| invalid(path, format!("mesh `{file}`: unknown material `{name}`")))?,
        ),
        None => None,
    };
    if is_ply {
        let material = override_id.ok_or_else(|| {
            invalid(path, format!("mesh `{file}`: a PLY mesh needs `material = \"...\"` (PLY has no materials)"))
        })?;
        load_ply(mesh_path, material, mesh.reverse_winding, &mut meshes.geometry)
    } else {
        load_obj(mesh_path, override_id, mesh.reverse_winding, meshes)
    }
}

/// The triangles of `g` from `start` on, with their attributes (findings not copied).
fn copy_geometry(g: &Geometry, start: usize) -> Geometry {
    let mut copy = Geometry::default();
    copy.triangles.extend_from_slice(&g.triangles[start..]);
    copy.triangle_material.extend_from_slice(&g.triangle_material[start..]);
    if !g.attributes.normals.is_empty() {
        copy.attributes.normals.extend_from_slice(g.attributes.normals.get(start..).unwrap_or_default());
    }
    if !g.attributes.uvs.is_empty() {
        copy.attributes.uvs.extend_from_slice(g.attributes.uvs.get(start..).unwrap_or_default());
    }
    copy
}

/// Appends `src`'s triangles to `g`, keeping each attribute list empty or one entry per
/// triangle; an error past [`MAX_TRIANGLES`].
fn append_geometry(g: &mut Geometry, src: &Geometry) -> std::result::Result<(), String> {
    let (start, n) = (g.triangles.len(), src.triangles.len());
    if start + n > MAX_TRIANGLES {
        return Err(format!("more than {MAX_TRIANGLES} triangles in the scene"));
    }
    g.triangles.extend_from_slice(&src.triangles);
    g.triangle_material.extend_from_slice(&src.triangle_material);
    let a = &mut g.attributes;
    if !src.attributes.normals.is_empty() || !a.normals.is_empty() {
        a.normals.resize(start, [Vec3A::ZERO; 3]);
        if src.attributes.normals.is_empty() {
            a.normals.resize(start + n, [Vec3A::ZERO; 3]);
        } else {
            a.normals.extend_from_slice(&src.attributes.normals);
            a.normals.resize(start + n, [Vec3A::ZERO; 3]);
        }
    }
    if !src.attributes.uvs.is_empty() || !a.uvs.is_empty() {
        a.uvs.resize(start, Attributes::BARYCENTRIC_UV);
        if src.attributes.uvs.is_empty() {
            a.uvs.resize(start + n, Attributes::BARYCENTRIC_UV);
        } else {
            a.uvs.extend_from_slice(&src.attributes.uvs);
            a.uvs.resize(start + n, Attributes::BARYCENTRIC_UV);
        }
    }
    Ok(())
}

/// The triangles added so far, with their materials and attributes.
#[derive(Default)]
pub(crate) struct Geometry {
    pub triangles: Vec<[Vec3A; 3]>,
    pub triangle_material: Vec<u32>,
    pub attributes: Attributes,
    findings: MeshFindings,
}

/// What a mesh had that the scene skips or repairs (reported as warnings).
#[derive(Debug, Default)]
struct MeshFindings {
    degenerate: usize,
    short_faces: usize,
    non_simple: usize,
}

/// Parses MTL text with tobj, after checking what tobj 4.0.5 would panic on: a colour line
/// (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three numbers (found by fuzzing).
fn parse_mtl(text: &str) -> tobj::MTLLoadResult {
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke")) && words.count() < 3 {
            return Err(tobj::LoadError::MaterialParseError);
        }
    }
    tobj::load_mtl_buf(&mut text.as_bytes())
}

/// The scene's materials (by name too) and the triangles its meshes added so far.
#[derive(Default)]
struct Meshes {
    materials: Vec<Material>,
    by_name: HashMap<String, u32>,
    geometry: Geometry,
}

/// Adds the triangles of the PLY file `ply_path`, all of `material` (polygons triangulated as
/// OBJ faces are; vertex normals and texture coordinates kept where every vertex has them).
fn load_ply(ply_path: &Path, material: u32, reverse: bool, geometry: &mut Geometry) -> Result<()> {
    let mut bytes = read_bounded(ply_path, MAX_MESH_BYTES, "mesh (PLY) file")?;
    if ply_path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz")) {
        bytes = gunzip(ply_path, &bytes)?;
    }
    ply_into(ply_path, &bytes, material, reverse, geometry)
}

/// A gzip file's contents (pbrt's `.ply.gz`), at most [`MAX_MESH_BYTES`] of them.
fn gunzip(path: &Path, bytes: &[u8]) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes)
        .take(MAX_MESH_BYTES + 1)
        .read_to_end(&mut out)
        .map_err(|e| Error::Mesh { path: path.to_path_buf(), message: format!("not a valid gzip file ({e})") })?;
    if out.len() as u64 > MAX_MESH_BYTES {
        return Err(Error::Mesh {
            path: path.to_path_buf(),
            message: format!("decompresses to more than {MAX_MESH_BYTES} bytes"),
        });
    }
    Ok(out)
}

/// Adds the triangles of PLY bytes `bytes` (named `ply_path` in errors).
fn ply_into(ply_path: &Path, bytes: &[u8], material: u32, reverse: bool, geometry: &mut Geometry) -> Result<()> {
    let mesh_err = |message: String| Error::Mesh { path: ply_path.to_path_buf(), message };
    let mesh = super::ply::parse(bytes).map_err(|m| mesh_err(format!("not a valid PLY file ({m})")))?;
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(mesh_err(format!("vertex {} has a non-finite coordinate", i + 1)));
    }
    let n = mesh.positions.len();
    let mut scratch = Face::default();
    for (f, face) in mesh.faces.iter().enumerate() {
        if let Some(&i) = face.iter().find(|&&i| i < 0 || i as usize >= n) {
            return Err(mesh_err(format!("face {}: vertex index {i} out of range ({n} vertices)", f + 1)));
        }
        if face.len() < 3 {
            geometry.findings.short_faces += 1;
            continue;
        }
        if face.len() > MAX_POLYGON_VERTICES {
            return Err(mesh_err(format!(
                "face {} has {} vertices (at most {MAX_POLYGON_VERTICES})",
                f + 1,
                face.len()
            )));
        }
        scratch.clear();
        scratch.positions.extend(face.iter().map(|&i| mesh.positions[i as usize]));
        if let Some(ns) = &mesh.normals {
            scratch.normals.extend(face.iter().map(|&i| ns[i as usize]));
        }
        if let Some(uvs) = &mesh.uvs {
            scratch.uvs.extend(face.iter().map(|&i| uvs[i as usize]));
        }
        push_face(geometry, &mut scratch, material, reverse).map_err(mesh_err)?;
    }
    if mesh.faces.is_empty() {
        return Err(mesh_err("no faces".into()));
    }
    Ok(())
}

/// Adds the triangles of the OBJ file `obj_path` (its `mtllib` files read beside it).
fn load_obj(obj_path: &Path, override_id: Option<u32>, reverse: bool, meshes: &mut Meshes) -> Result<()> {
    if obj_path.as_os_str().is_empty() || obj_path.file_name().is_none() {
        return Err(Error::Mesh {
            path: obj_path.to_path_buf(),
            message: "the mesh path is empty or names a folder".into(),
        });
    }
    let text = read_text(obj_path, MAX_MESH_BYTES, "mesh (OBJ) file")?;
    let folder = obj_path.parent().unwrap_or(Path::new("."));
    // tobj only learns that a library failed; why goes here.
    let mtl_note = RefCell::new(None);
    let loader = |name: &Path| {
        let path = folder.join(name);
        match read_text(&path, MAX_MESH_BYTES, "material library (MTL)") {
            Ok(t) => parse_mtl(&t),
            Err(e) => {
                *mtl_note.borrow_mut() = Some(e.to_string());
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    obj_into(obj_path, &text, &loader, &mtl_note, override_id, reverse, meshes)
}

/// Adds the triangles of OBJ text `text` (named `obj_path` in errors; `mtllib` files come
/// from `mtl_loader`, which may leave in `mtl_note` why one could not be loaded).
fn obj_into(
    obj_path: &Path,
    text: &str,
    mtl_loader: &dyn Fn(&Path) -> tobj::MTLLoadResult,
    mtl_note: &RefCell<Option<String>>,
    override_id: Option<u32>,
    reverse: bool,
    meshes: &mut Meshes,
) -> Result<()> {
    let Meshes { materials, by_name, geometry } = meshes;
    let mesh_err = |message: String| Error::Mesh { path: obj_path.to_path_buf(), message };
    // Polygons are kept whole (tobj would fan them, wrong for concave ones) and points and
    // lines kept too, so that nothing is dropped without a word.
    let options =
        tobj::LoadOptions { triangulate: false, ignore_points: false, ignore_lines: false, ..Default::default() };
    let (models, mtl) = tobj::load_obj_buf(&mut text.as_bytes(), &options, mtl_loader)
        .map_err(|e| mesh_err(format!("not a valid OBJ file ({e})")))?;
    // MTL materials: a name the scene file defines wins; otherwise Kd/Ke from the MTL.
    let mut mtl_ids = Vec::new();
    match mtl {
        Ok(list) => {
            for m in list {
                let id = match by_name.get(&m.name) {
                    Some(&id) => id,
                    None => {
                        let d = MaterialDescription {
                            diffuse: m.diffuse.unwrap_or([0.0; 3]),
                            emission: m.emissive.unwrap_or([0.0; 3]),
                            ..MaterialDescription::default()
                        };
                        let id = materials.len() as u32;
                        materials.push(material_from(obj_path, &m.name, &d, &HashMap::new(), |_| Vec3A::ZERO)?);
                        by_name.insert(m.name.clone(), id);
                        id
                    }
                };
                mtl_ids.push(id);
            }
        }
        Err(e) if override_id.is_none() => {
            let why = mtl_note.take().unwrap_or_else(|| e.to_string());
            return Err(mesh_err(format!(
                "its material library could not be loaded ({why}); add one or give the mesh `material = \"...\"`"
            )));
        }
        Err(_) => {}
    }
    let mut faces = 0usize;
    let mut scratch = Face::default();
    for model in &models {
        let m = &model.mesh;
        if m.indices.is_empty() {
            // Vertices without faces (or not an OBJ at all): nothing to draw, nothing to check.
            continue;
        }
        if let Some(i) = m.positions.iter().position(|x| !x.is_finite()) {
            return Err(mesh_err(format!("object `{}`: vertex {} has a non-finite coordinate", model.name, i / 3 + 1)));
        }
        let n_vertices = m.positions.len() / 3;
        if let Some(&i) = m.indices.iter().find(|&&i| i as usize >= n_vertices) {
            return Err(mesh_err(format!(
                "object `{}`: vertex index {} out of range ({n_vertices} vertices)",
                model.name,
                i + 1
            )));
        }
        let material = match (override_id, m.material_id) {
            (Some(id), _) => id,
            (None, Some(i)) if i < mtl_ids.len() => mtl_ids[i],
            _ => {
                return Err(mesh_err(format!(
                    "object `{}` has no material (use usemtl, or `material = \"...\"` in the scene)",
                    model.name
                )));
            }
        };
        let vertex = |i: u32| {
            let i = i as usize * 3;
            Vec3A::new(m.positions[i], m.positions[i + 1], m.positions[i + 2])
        };
        // Normals and texture coordinates where every corner has one (tobj lists them beside
        // the positions); an index out of range is an error like a vertex's.
        let has_normals = !m.normal_indices.is_empty() && m.normal_indices.len() == m.indices.len();
        let has_uvs = !m.texcoord_indices.is_empty() && m.texcoord_indices.len() == m.indices.len();
        for (has, ids, len, what) in [
            (has_normals, &m.normal_indices, m.normals.len() / 3, "normal"),
            (has_uvs, &m.texcoord_indices, m.texcoords.len() / 2, "texture coordinate"),
        ] {
            if let Some(&i) = ids.iter().take(if has { ids.len() } else { 0 }).find(|&&i| i as usize >= len) {
                return Err(mesh_err(format!("object `{}`: {what} index {} out of range ({len})", model.name, i + 1)));
            }
        }
        let normal = |i: u32| {
            let i = i as usize * 3;
            Vec3A::new(m.normals[i], m.normals[i + 1], m.normals[i + 2])
        };
        let texcoord = |i: u32| {
            let i = i as usize * 2;
            Vec2::new(m.texcoords[i], m.texcoords[i + 1])
        };
        // Face sizes: empty means all triangles.
        let arities: Box<dyn Iterator<Item = usize>> = if m.face_arities.is_empty() {
            Box::new(std::iter::repeat_n(3, m.indices.len() / 3))
        } else {
            Box::new(m.face_arities.iter().map(|&a| a as usize))
        };
        let mut start = 0usize;
        for (face, arity) in arities.enumerate() {
            let Some(ids) = m.indices.get(start..start + arity) else {
                return Err(mesh_err(format!("object `{}`: face {} is truncated", model.name, face + 1)));
            };
            start += arity;
            faces += 1;
            if arity < 3 {
                geometry.findings.short_faces += 1;
                continue;
            }
            if arity > MAX_POLYGON_VERTICES {
                return Err(mesh_err(format!(
                    "object `{}`: face {} has {arity} vertices (at most {MAX_POLYGON_VERTICES})",
                    model.name,
                    face + 1
                )));
            }
            let face_range = start - arity..start;
            scratch.clear();
            scratch.positions.extend(ids.iter().map(|&i| vertex(i)));
            if has_normals {
                scratch.normals.extend(m.normal_indices[face_range.clone()].iter().map(|&i| normal(i)));
            }
            if has_uvs {
                scratch.uvs.extend(m.texcoord_indices[face_range].iter().map(|&i| texcoord(i)));
            }
            push_face(geometry, &mut scratch, material, reverse).map_err(mesh_err)?;
        }
    }
    if faces == 0 {
        return Err(mesh_err("no faces: an OBJ file lists faces as `f` lines".into()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Hit, Ray};

    /// A folder of its own under the temporary directory, holding `files`.
    fn folder(name: &str, files: &[(&str, &str)]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("zvidpt-load-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (file, text) in files {
            std::fs::write(dir.join(file), text).unwrap();
        }
        dir
    }

    const HEAD: &str =
        "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\nwidth = 8\nheight = 8\n\n";

    /// The interaction of a ray towards `target` from `from` with triangle `prim` (the
    /// barycentric coordinates worked out here).
    fn hit(scene: &Scene, prim: u32, from: Vec3A, target: Vec3A) -> crate::scene::SurfaceInteraction {
        let t = scene.triangles[prim as usize];
        let (e1, e2, d) = (t[1] - t[0], t[2] - t[0], target - t[0]);
        let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
        let (d1, d2) = (d.dot(e1), d.dot(e2));
        let den = d11 * d22 - d12 * d12;
        let (u, v) = ((d22 * d1 - d12 * d2) / den, (d11 * d2 - d12 * d1) / den);
        let ray = Ray::new(from, (target - from).normalize());
        scene.interaction(&ray, &Hit { t: (target - from).length(), u, v, prim })
    }

    /// An OBJ quad in z = 0 with vertex normals leaning outwards (±x) and texture
    /// coordinates; a checkerboard of 2×2 squares on it.
    const QUAD: &str = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
        vn -0.6 0 0.8\nvn 0.6 0 0.8\n\
        vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
        f 1/1/1 2/2/2 3/3/2 4/4/1\n";

    /// A dielectric is an interface: its relative index may be below 1 (pbrt's `AirIce`); a
    /// plastic's may not, and no index may be zero, negative or infinite.
    #[test]
    fn dielectric_interfaces_below_one() {
        let material = |m: &str| {
            let text = format!("{HEAD}[materials.m]\n{m}\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n");
            Scene::parse(&text, Path::new("f/scene.toml")).map(|s| s.materials[0].bsdf).map_err(|e| e.to_string())
        };
        let ice = material("type = \"dielectric\"\nior = 0.763").unwrap();
        assert!(matches!(ice, Bsdf::Dielectric { eta, .. } if eta == 0.763), "{ice:?}");
        let water_ice = material("type = \"dielectric\"\nior = 1.31\nexterior_ior = 1.33").unwrap();
        assert!(matches!(water_ice, Bsdf::Dielectric { eta, .. } if (eta - 1.31 / 1.33).abs() < 1e-6));
        for bad in ["ior = 0.0", "ior = -1.5", "ior = 1e-3", "exterior_ior = 0.0"] {
            let e = material(&format!("type = \"dielectric\"\n{bad}")).unwrap_err();
            assert!(e.contains("positive and finite"), "{bad}: {e}");
        }
        let e = material("type = \"plastic\"\nior = 0.9").unwrap_err();
        assert!(e.contains("plastic"), "{e}");
        // pbrt-v4's glass of water: a named dielectric of eta 0.763.
        let pbrt = "Camera \"perspective\"\nWorldBegin\nMakeNamedMaterial \"AirIce\" \"string type\" \"dielectric\" \"float eta\" 0.763\n\
            NamedMaterial \"AirIce\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n";
        let options = crate::scene::import::ImportOptions::default();
        let scene = Scene::parse_pbrt(pbrt, Path::new("f/scene.pbrt"), &options).unwrap();
        assert!(scene.materials.iter().any(|m| matches!(m.bsdf, Bsdf::Dielectric { eta, .. } if eta == 0.763)));
    }

    /// `[camera] filter`: defaults per type, and its mistakes.
    #[test]
    fn camera_filters() {
        let scene = |filter: &str| {
            let text = format!(
                "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\nwidth = 8\nheight = 8\n\
                 filter = {filter}\n\n[materials.m]\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n"
            );
            Scene::parse(&text, Path::new("f/scene.toml")).map(|s| s.camera.filter.shape).map_err(|e| e.to_string())
        };
        assert_eq!(scene("{ type = \"gaussian\" }"), Ok(FilterShape::Gaussian { stddev: 0.5, radius: [2.0; 2] }));
        assert_eq!(
            scene("{ type = \"gaussian\", stddev = 0.25 }"),
            Ok(FilterShape::Gaussian { stddev: 0.25, radius: [1.0; 2] })
        );
        assert_eq!(scene("{ type = \"tent\", radius = [2.0, 1.0] }"), Ok(FilterShape::Tent { radius: [2.0, 1.0] }));
        assert_eq!(scene("{ type = \"box\" }"), Ok(FilterShape::PIXEL));
        for (filter, want) in [
            ("{ type = \"tent\", stddev = 1.0 }", "`stddev` is for the gaussian filter"),
            ("{ type = \"box\", radius = [0.0, 1.0] }", "must lie in (0, 16]"),
            ("{ type = \"gaussian\", stddev = 100.0 }", "must lie in (0, 16]"),
            ("{ type = \"mitchell\" }", "unknown variant"),
        ] {
            let e = scene(filter).unwrap_err();
            assert!(e.contains(want), "{filter}: {e}");
        }
    }

    /// `factor` multiplies a texture's values, `invert` then takes `1 − value` (at least 0).
    #[test]
    fn textures_described_alike_are_one() {
        let text = format!(
            "{HEAD}[textures.a]\ntype = \"checkerboard\"\n\n[textures.b]\ntype = \"checkerboard\"\n\n\
             [textures.c]\ntype = \"checkerboard\"\ncolor0 = [1.0, 0.0, 0.0]\n\n\
             [materials.m]\ndiffuse_texture = \"a\"\n\n[materials.n]\ndiffuse_texture = \"b\"\n\n\
             [materials.o]\ndiffuse_texture = \"c\"\n\n\
             [[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"n\"\n\n\
             [[shape]]\ntype = \"rectangle\"\nmaterial = \"o\"\n"
        );
        let scene = Scene::parse(&text, Path::new("f/scene.toml")).unwrap();
        assert_eq!(scene.textures.len(), 2, "a and b are one texture, c another");
    }

    #[test]
    fn texture_factor_and_invert() {
        let text = format!(
            "{HEAD}[textures.c]\ntype = \"checkerboard\"\ncolor0 = [0.5, 0.5, 0.5]\ncolor1 = [1.0, 1.0, 1.0]\n\
             factor = [0.5, 1.0, 4.0]\ninvert = true\n\n[textures.d]\ntype = \"checkerboard\"\nfactor = [2.0, 2.0, 2.0]\n\n\
             [materials.m]\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n"
        );
        let scene = Scene::parse(&text, Path::new("f/scene.toml")).unwrap();
        let Texture::Checkerboard { a, b, .. } = scene.textures[0] else { panic!() };
        assert_eq!((a, b), (Vec3A::new(0.75, 0.5, 0.0), Vec3A::new(0.5, 0.0, 0.0)));
        let Texture::Checkerboard { a, b, .. } = scene.textures[1] else { panic!() };
        assert_eq!((a, b), (Vec3A::splat(0.8), Vec3A::splat(0.4)), "Mitsuba's defaults doubled");
        let bad = text.replace("factor = [2.0, 2.0, 2.0]", "factor = [-1.0, 2.0, 2.0]");
        assert!(Scene::parse(&bad, Path::new("f/scene.toml")).unwrap_err().to_string().contains("`factor`"));
    }

    /// A file placed more than once is read once and copied: the same triangles, normals and
    /// texture coordinates as two files of the same text, before and after meshes without
    /// attributes.
    #[test]
    fn a_mesh_placed_twice_is_copied_alike() {
        const BARE: &str = "v 0 0 2\nv 1 0 2\nv 0 1 2\nf 1 2 3\n";
        let mesh = |file: &str, m: &str| format!("[[mesh]]\nobj = \"{file}\"\nmaterial = \"m\"\nmatrix = {m}\n");
        let (a, b) = (
            "[[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
            "[[-2.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.5], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]",
        );
        let scene = |second: &str| {
            let text = format!(
                "{HEAD}[materials.m]\n\n{}{}{}{}",
                mesh("bare.obj", a),
                mesh("quad.obj", a),
                mesh("bare.obj", b),
                mesh(second, b)
            );
            let dir = folder(
                &format!("twice-{}", second.len()),
                &[("quad.obj", QUAD), ("copy.obj", QUAD), ("bare.obj", BARE), ("scene.toml", &text)],
            );
            Scene::load(&dir).unwrap()
        };
        let (twice, apart) = (scene("quad.obj"), scene("copy.obj"));
        assert_eq!(twice.triangles.len(), 2 + 2 * 2);
        assert_eq!(twice.triangles, apart.triangles);
        assert_eq!(twice.attributes.normals, apart.attributes.normals);
        assert_eq!(twice.attributes.uvs, apart.attributes.uvs);
        assert_eq!(twice.attributes.normals.len(), twice.triangles.len());
        assert_eq!(twice.triangles[4][0].x, -2.0 * twice.triangles[1][0].x + 1.0, "placed by its own matrix");
    }

    #[test]
    fn obj_normals_and_texture_coordinates_reach_the_interaction() {
        let scene_text = format!(
            "{HEAD}[textures.checks]\ntype = \"checkerboard\"\ncolor0 = [0.9, 0.1, 0.1]\ncolor1 = [0.1, 0.1, 0.9]\n\
             scale = [2.0, 2.0]\n\n[materials.m]\ndiffuse_texture = \"checks\"\nemission = [1.0, 1.0, 1.0]\n\n\
             [[mesh]]\nobj = \"quad.obj\"\nmaterial = \"m\"\n"
        );
        let dir = folder("quad", &[("quad.obj", QUAD), ("scene.toml", &scene_text)]);
        let scene = Scene::load(&dir).unwrap();
        assert_eq!(scene.attributes.normals.len(), 2);
        assert_eq!(scene.attributes.uvs.len(), 2);
        let eye = Vec3A::new(0.0, 0.0, 3.0);
        // At x = ±0.5 the interpolated normal leans a quarter of the way to its corners'.
        let holds = |prim: usize, p: Vec3A| {
            let t = scene.triangles[prim];
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(p - t[k]).dot(n) >= 0.0)
        };
        for (x, y) in [(-0.5f32, -0.6f32), (0.5, -0.6), (-0.5, 0.6), (0.5, 0.6)] {
            let target = Vec3A::new(x, y, 0.0);
            let prim = (0..2).find(|&i| holds(i, target)).expect("a triangle holds the point");
            let si = hit(&scene, prim as u32, eye, target);
            assert!(si.shaded);
            let want = Vec3A::new(0.6 * x, 0.0, 0.8).normalize();
            assert!((si.ns - want).length() < 1e-5, "at x {x}: ns {} want {want}", si.ns);
            // uv = ((x+1)/2, (y+1)/2): with 2×2 squares, colour0 where both halves agree.
            let u = Vec2::new((x + 1.0) / 2.0, (y + 1.0) / 2.0);
            let want = if (u.x < 0.5) == (u.y < 0.5) { Vec3A::new(0.9, 0.1, 0.1) } else { Vec3A::new(0.1, 0.1, 0.9) };
            assert_eq!(si.material.lambertian(), Some(want), "at {target}");
        }
        // Seen from behind: the shading normal turns with the geometric one.
        let prim = (0..2).find(|&i| holds(i, Vec3A::new(0.5, -0.6, 0.0))).unwrap() as u32;
        let si = hit(&scene, prim, Vec3A::new(0.0, 0.0, -3.0), Vec3A::new(0.5, -0.6, 0.0));
        assert!(si.shaded && si.ns.z < 0.0 && si.ns.dot(si.n) > 0.0);
        // Seen from a grazing angle beneath the shading normal: the geometric normal is used.
        let si = hit(&scene, prim, Vec3A::new(-40.0, -0.6, 1.0), Vec3A::new(0.5, -0.6, 0.0));
        assert!(!si.shaded && si.ns == si.n, "{:?}", si.ns);
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn vertex_normals_decide_the_outside() {
        // Wound to face −z, but its normals say +z: turned (pbrt-v4's rule), so it emits
        // towards +z.
        let obj = "v -1 -1 0\nv -1 1 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";
        let text =
            format!("{HEAD}[materials.m]\nemission = [1.0, 1.0, 1.0]\n\n[[mesh]]\nobj = \"t.obj\"\nmaterial = \"m\"\n");
        let dir = folder("outside", &[("t.obj", obj), ("scene.toml", &text)]);
        let scene = Scene::load(&dir).unwrap();
        assert_eq!(scene.normals[0], Vec3A::Z);
        // And with `reverse_winding`, normals and winding both turn.
        let text = text.replace("material = \"m\"", "material = \"m\"\nreverse_winding = true");
        std::fs::write(dir.join("scene.toml"), text).unwrap();
        let scene = Scene::load(&dir).unwrap();
        assert_eq!(scene.normals[0], Vec3A::NEG_Z);
        assert_eq!(scene.attributes.normals[0][0], Vec3A::NEG_Z);
        std::fs::remove_dir_all(dir).ok();
    }

    #[test]
    fn spheres_are_smooth_and_mapped_like_mitsubas() {
        let text = format!(
            "{HEAD}[materials.m]\ndiffuse = [0.5, 0.5, 0.5]\n\n[[shape]]\ntype = \"sphere\"\nmaterial = \"m\"\n\
             center = [0.2, 0.1, -0.3]\nradius = 0.5\nsubdivisions = 3\nrotate = {{ axis = [1.0, 0.0, 0.0], angle = 90.0 }}\n"
        );
        let scene = Scene::parse(&text, Path::new("sphere/scene.toml")).unwrap();
        let rotation = glam::Mat3A::from_axis_angle(glam::Vec3::X, 90f32.to_radians());
        let centre = rotation * Vec3A::new(0.2, 0.1, -0.3);
        for (i, t) in scene.triangles.iter().enumerate() {
            for (p, n) in t.iter().zip(scene.attributes.normals[i]) {
                assert!((n - (*p - centre).normalize()).length() < 1e-5);
            }
            let u = scene.attributes.uvs[i].map(|c| c.x);
            let span =
                u.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) - u.iter().fold(f32::INFINITY, |a, &b| a.min(b));
            assert!(span < 0.3, "triangle {i} spans u {u:?}");
        }
        // At a triangle's centroid, uv is (φ/2π, θ/π) of the direction in the sphere's own
        // frame, within the tessellation's error (u modulo 1 across the seam).
        for (i, t) in scene.triangles.iter().enumerate().step_by(37) {
            let c = (t[0] + t[1] + t[2]) / 3.0;
            let uv = scene.attributes.uvs[i].iter().fold(Vec2::ZERO, |a, &b| a + b) / 3.0;
            let local = rotation.transpose() * (c - centre).normalize();
            let phi = local.y.atan2(local.x).rem_euclid(std::f32::consts::TAU);
            let theta = local.z.acos();
            let du = (uv.x - phi / std::f32::consts::TAU).rem_euclid(1.0);
            let du = du.min(1.0 - du);
            // Near the poles u is ill-defined (the pole corner takes the others' mean).
            let polar = theta.sin() < 0.3;
            assert!((polar || du < 0.02) && (uv.y - theta / std::f32::consts::PI).abs() < 0.02, "triangle {i}: {uv}");
        }
        // Rectangles: (x+1)/2, (y+1)/2.
        let text = format!("{HEAD}[materials.m]\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n");
        let scene = Scene::parse(&text, Path::new("rect/scene.toml")).unwrap();
        for (t, uv) in scene.triangles.iter().zip(&scene.attributes.uvs) {
            for k in 0..3 {
                assert_eq!(uv[k], Vec2::new(t[k].x + 1.0, t[k].y + 1.0) * 0.5);
            }
        }
        assert!(scene.attributes.normals.is_empty());
    }

    #[test]
    fn texture_keys_are_checked() {
        let with = |materials: &str| {
            let text = format!(
                "{HEAD}[textures.c]\ntype = \"checkerboard\"\n\n{materials}\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n"
            );
            Scene::parse(&text, Path::new("t/scene.toml")).map(|_| ()).map_err(|e| e.to_string())
        };
        assert!(with("[materials.m]\ndiffuse_texture = \"c\"").is_ok());
        assert!(
            with("[materials.m]\ntype = \"conductor\"\nroughness_texture = \"c\"\nspecular_texture = \"c\"").is_ok()
        );
        let cases = [
            ("[materials.m]\ndiffuse_texture = \"nope\"", "unknown texture `nope`"),
            ("[materials.m]\nroughness_texture = \"c\"", "`roughness_texture` does not apply to type \"diffuse\""),
            ("[materials.m]\ntype = \"thindielectric\"\nroughness_texture = \"c\"", "does not apply"),
            ("[materials.m]\ntype = \"conductor\"\ndiffuse_texture = \"c\"", "does not apply"),
            ("[materials.m]\n[textures.b]\ntype = \"bitmap\"", "a bitmap needs `file`"),
            ("[materials.m]\n[textures.b]\ntype = \"checkerboard\"\nfile = \"x.png\"", "are for bitmaps"),
            ("[materials.m]\n[textures.b]\ntype = \"checkerboard\"\nscale = [0.0, 1.0]", "`scale` must lie"),
            ("[materials.m]\n[textures.b]\ntype = \"bitmap\"\nfile = \"missing.png\"", "missing.png"),
        ];
        for (materials, want) in cases {
            let e = with(materials).unwrap_err();
            assert!(e.contains(want), "{materials}: {e}");
        }
    }

    /// `distribution` and `masking` choose the microfacets; they apply where `roughness` does,
    /// and a roughness texture keeps them.
    #[test]
    fn microfacet_keys() {
        use crate::material::microfacet::{Distribution, Masking};
        let parse = |m: &str| toml::from_str::<MaterialDescription>(m).map_err(|e| e.to_string());
        let rough = |m: &str| match bsdf_from(&parse(m).unwrap()) {
            Ok(Bsdf::Conductor { roughness, .. } | Bsdf::Dielectric { roughness, .. }) => roughness,
            Ok(Bsdf::Plastic { coat, .. }) => coat.map(|c| c.mf),
            other => panic!("{m}: {other:?}"),
        };
        let r = rough("type = \"conductor\"\nroughness = 0.3\ndistribution = \"beckmann\"\nmasking = \"separable\"");
        assert_eq!(
            r.map(|r| (r.alpha, r.distribution, r.masking)),
            Some((0.3, Distribution::Beckmann, Masking::Separable))
        );
        let r = rough("type = \"dielectric\"\nroughness = 0.3");
        assert_eq!(r.map(|r| (r.distribution, r.masking)), Some((Distribution::Ggx, Masking::Correlated)));
        let r = rough("type = \"plastic\"\nroughness = 0.2\ndistribution = \"beckmann\"");
        assert_eq!(r.map(|r| r.distribution), Some(Distribution::Beckmann));
        let r = rough("type = \"conductor\"\nroughness_texture = \"t\"\ndistribution = \"beckmann\"");
        assert_eq!(r.map(|r| r.distribution), Some(Distribution::Beckmann), "rough through its texture");
        let e = bsdf_from(&parse("distribution = \"beckmann\"").unwrap()).unwrap_err();
        assert!(e.contains("`distribution` does not apply to type \"diffuse\""), "{e}");
        let e = bsdf_from(&parse("type = \"thindielectric\"\nmasking = \"separable\"").unwrap()).unwrap_err();
        assert!(e.contains("`masking` does not apply"), "{e}");
        assert!(parse("type = \"conductor\"\ndistribution = \"phong\"").unwrap_err().contains("unknown variant"));
    }
}

#[cfg(test)]
mod ply_tests {
    use super::*;

    /// The OBJ quad of the tests above as a binary PLY (normals, texture coordinates, one
    /// quad face): the same triangles and attributes, and `reverse_winding` turns both alike.
    #[test]
    fn a_ply_mesh_loads_like_the_same_obj() {
        let dir = std::env::temp_dir().join(format!("zvidpt-load-ply-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let obj = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn -0.6 0 0.8\nvn 0.6 0 0.8\n\
                   vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1/1 2/2/2 3/3/2 4/4/1\n";
        let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n\
            property float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
            property float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for v in [
            [-1.0f32, -1.0, 0.0, -0.6, 0.0, 0.8, 0.0, 0.0],
            [1.0, -1.0, 0.0, 0.6, 0.0, 0.8, 1.0, 0.0],
            [1.0, 1.0, 0.0, 0.6, 0.0, 0.8, 1.0, 1.0],
            [-1.0, 1.0, 0.0, -0.6, 0.0, 0.8, 0.0, 1.0],
        ] {
            v.iter().for_each(|c| ply.extend(c.to_le_bytes()));
        }
        ply.push(4);
        [0i32, 1, 2, 3].iter().for_each(|i| ply.extend(i.to_le_bytes()));
        std::fs::write(dir.join("q.obj"), obj).unwrap();
        std::fs::write(dir.join("q.ply"), &ply).unwrap();
        let head = "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\nwidth = 8\nheight = 8\n\n\
                    [materials.m]\ndiffuse = [0.5, 0.5, 0.5]\n\n[[mesh]]\nmaterial = \"m\"\n";
        for reverse in [false, true] {
            let load = |file: &str| {
                let text = format!("{head}{file}\nreverse_winding = {reverse}\n");
                Scene::parse(&text, &dir.join("scene.toml")).unwrap()
            };
            let (a, b) = (load("obj = \"q.obj\""), load("ply = \"q.ply\""));
            assert_eq!(a.triangles, b.triangles);
            assert_eq!(a.attributes, b.attributes);
            assert_eq!(a.normals, b.normals);
            assert!(b.sources.contains(&dir.join("q.ply")));
        }
        // A PLY mesh needs a material; an index out of range is an error naming the face.
        let e = Scene::parse(&head.replace("material = \"m\"\n", "ply = \"q.ply\"\n"), &dir.join("scene.toml"));
        assert!(e.unwrap_err().to_string().contains("needs `material"));
        let last = ply.len() - 4;
        ply[last..].copy_from_slice(&9i32.to_le_bytes());
        std::fs::write(dir.join("bad.ply"), &ply).unwrap();
        let e = Scene::parse(&format!("{head}ply = \"bad.ply\"\n"), &dir.join("scene.toml")).unwrap_err().to_string();
        assert!(e.contains("bad.ply") && e.contains("face 1: vertex index 9 out of range"), "{e}");
        std::fs::remove_dir_all(dir).ok();
    }
}

#[cfg(test)]
mod environment_tests {
    use super::*;

    /// A map turned by a mirror image (determinant −1, as pbrt's hair-curl turns its sky)
    /// is read mirrored; a shear is refused.
    #[test]
    fn environments_may_be_mirrored_not_sheared() {
        let dir = std::env::temp_dir().join(format!("zvidpt-env-mirror-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // 4 × 2 PFM (rows from the bottom), bright only in its first column (φ near 0: +x).
        let mut pfm = b"PF\n4 2\n-1\n".to_vec();
        for _row in 0..2 {
            for i in 0..4 {
                let v: f32 = if i == 0 { 1.0 } else { 0.0 };
                for _ in 0..3 {
                    pfm.extend(v.to_le_bytes());
                }
            }
        }
        std::fs::write(dir.join("sky.pfm"), pfm).unwrap();
        let scene = |matrix: &str| {
            let text = format!(
                "{}[environment]\nmap = \"sky.pfm\"\nlookup = \"mitsuba\"\nmatrix = {matrix}\n\n\
                 [materials.m]\n\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n",
                "[camera]\neye = [0.0, 0.0, 3.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 40.0\nwidth = 8\nheight = 8\n\n"
            );
            Scene::parse(&text, &dir.join("scene.toml"))
        };
        let identity = "[[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]";
        let mirror = "[[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]";
        let shear = "[[1.0, 0.5, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]";
        let plain = scene(identity).unwrap();
        let mirrored = scene(mirror).unwrap();
        let (e, m) = (plain.lights.environment.as_ref().unwrap(), mirrored.lights.environment.as_ref().unwrap());
        // Mirroring z swaps a direction with its mirror image.
        let mut lit = 0;
        for k in 0..64 {
            let phi = std::f32::consts::TAU * (k as f32 + 0.5) / 64.0;
            let d = Vec3A::new(phi.cos(), 0.3, phi.sin()).normalize();
            let mirror_d = Vec3A::new(d.x, d.y, -d.z);
            assert_eq!(m.eval(d), e.eval(mirror_d), "{d}");
            lit += usize::from(e.eval(d).x > 0.0);
            assert!(m.eval(d) != e.eval(d) || e.eval(d) == e.eval(mirror_d));
        }
        assert!(lit > 0 && lit < 64, "the map is bright in some directions only ({lit} of 64)");
        assert!(scene(shear).unwrap_err().to_string().contains("rotation or a reflection"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An equal-area map bright only around its centre (pbrt's +z) lands, resampled, around
    /// our +z (the middle of the equirectangular image); turned by a rotation taking +z to +y,
    /// at the top row.
    #[test]
    fn equal_area_maps_are_resampled_where_they_point() {
        let n = 32;
        let texels: Vec<Vec3A> = (0..n * n)
            .map(|k| {
                let (i, j) = ((k % n) as f32 + 0.5, (k / n) as f32 + 0.5);
                let near_centre = (i / n as f32 - 0.5).abs() + (j / n as f32 - 0.5).abs() < 0.1;
                if near_centre { Vec3A::ONE } else { Vec3A::ZERO }
            })
            .collect();
        let (w, h, out) = equirectangular_from(MapLayout::EqualArea, glam::Mat3A::IDENTITY, n, n, &texels);
        assert_eq!((w, h), (2 * n, n));
        assert_eq!(out[(h / 2) * w + w / 2], Vec3A::ONE, "+z: u = 1/2, v = 1/2");
        assert_eq!(out[w / 2], Vec3A::ZERO, "+y is dark");
        let z_to_y = glam::Mat3A::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        assert!((z_to_y * Vec3A::Z - Vec3A::Y).length() < 1e-6);
        let (_, _, turned) = equirectangular_from(MapLayout::EqualArea, z_to_y, n, n, &texels);
        assert_eq!(turned[w / 2], Vec3A::ONE, "now at the top row");
        assert_eq!(turned[(h / 2) * w + w / 2], Vec3A::ZERO);
    }
}

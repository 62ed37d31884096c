//! Building a scene from its description (written by the TOML reader and both importers):
//! materials, textures, lights and meshes, with every check that turns bad input into an
//! error naming the file (and line, where the parser knows it); and the entry points that
//! load a scene file in any format we read.
use super::description::{LightKind, MapLayout, SceneDescription};
use super::filter::{FilterShape, PixelFilter};
use super::import::{Format, ImportOptions};
use super::{Attributes, Camera, Scene, Surfaces};
use crate::geometry::{Vec2, Vec3A};
use crate::io::read_text;
use crate::light::Lights;
use crate::light::envmap::Environment;
use crate::light::point::PointLight;
use crate::texture::Texture;
use crate::texture::{Bitmap, Filter, Wrap};
use crate::{Error, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::limits::*;
use super::materials::*;
use super::mesh::*;

/// The files a scene folder is looked into for, in order: ours, Mitsuba 3's and pbrt-v4's
/// names, then the layout of Bitterli's collection (`pbrt/scene-v4.pbrt`).
pub const SCENE_FILES: [&str; 4] = ["scene.toml", "scene.xml", "scene.pbrt", "pbrt/scene-v4.pbrt"];

/// A scene argument is a scene file or a folder holding one of [`SCENE_FILES`] (the first
/// found; `scene.toml`, to be reported missing, where none is).
#[must_use]
pub fn resolve_scene_path(path: &Path) -> PathBuf {
    if !path.is_dir() {
        return path.to_path_buf();
    }
    SCENE_FILES.iter().map(|f| path.join(f)).find(|p| p.exists()).unwrap_or_else(|| path.join(SCENE_FILES[0]))
}

impl Scene {
    /// Loads a scene file (or a folder holding `scene.toml`).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
        Scene::load_with(path, &ImportOptions::default())
    }

    /// Loads a scene file in any format we read (by its extension: `.xml` is Mitsuba 3,
    /// anything else our TOML), or a folder holding `scene.toml`.
    pub fn load_with(path: impl AsRef<Path>, options: &ImportOptions) -> Result<Scene> {
        let given = path.as_ref();
        let path = resolve_scene_path(given);
        if given.is_dir() && !path.exists() {
            return Err(Error::InvalidScene {
                path: given.to_path_buf(),
                message: format!("a folder without a scene file (looked for {})", SCENE_FILES.join(", ")),
            });
        }
        let text = read_text(&path, MAX_SCENE_BYTES, "scene file")?;
        match Format::of(&path) {
            Format::Toml => Scene::parse(&text, &path),
            Format::Mitsuba => Scene::parse_mitsuba(&text, &path, options),
            Format::Pbrt => Scene::parse_pbrt(&text, &path, options),
        }
    }

    /// A pbrt-v4 scene from the text of its file (the subset read: `docs/import.md`).
    pub fn parse_pbrt(text: &str, path: &Path, options: &ImportOptions) -> Result<Scene> {
        let imported = super::import::pbrt::import(path, text, options)?;
        Scene::imported(path, imported.description, imported.warnings, imported.sources)
    }

    /// A Mitsuba 3 scene from the text of its file (the subset read: `docs/import.md`).
    pub fn parse_mitsuba(text: &str, path: &Path, options: &ImportOptions) -> Result<Scene> {
        let imported = super::import::mitsuba::import(path, text, options)?;
        Scene::imported(path, imported.description, imported.warnings, imported.sources)
    }

    /// A scene from an importer's description, its warnings first and its files as sources.
    fn imported(path: &Path, d: SceneDescription, mut warnings: Vec<String>, files: Vec<PathBuf>) -> Result<Scene> {
        let mut scene = build(path, d)?;
        warnings.append(&mut scene.warnings);
        scene.warnings = warnings;
        // The importer's files first (each once, at its last mention), then the scene's own.
        let mut seen: std::collections::HashSet<PathBuf> = scene.sources.iter().cloned().collect();
        let mut front: Vec<PathBuf> = files.into_iter().rev().filter(|f| seen.insert(f.clone())).collect();
        front.reverse();
        front.append(&mut scene.sources);
        scene.sources = front;
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

/// A scene's textures, their indices by name, the files they were read from, and their maps
/// of texture coordinates (empty when none has one).
type Textures = (Vec<Texture>, HashMap<String, u16>, Vec<PathBuf>, Vec<Option<glam::Affine2>>);

/// An error reading a file that a texture or mesh names (`key` in the description's origins;
/// `what` the texture, or empty: the error names the file), reported where the scene file
/// names it: an imported scene's file and line, or the TOML file. Other errors pass as they
/// are.
fn located(path: &Path, d: &SceneDescription, key: &str, what: &str, e: Error) -> Error {
    if !matches!(e, Error::Io { .. } | Error::Image { .. } | Error::Mesh { .. }) {
        return e;
    }
    let what = if what.is_empty() { String::new() } else { format!("{what}: ") };
    at_origin(d, key, invalid(path, format!("{what}{e}")))
}

/// An error in the material or light `key` names in the description's origins (`material
/// NAME`, `light K`), moved to the imported file and line that declared it; unchanged for a
/// TOML scene, whose errors name the item.
fn at_origin(d: &SceneDescription, key: &str, e: Error) -> Error {
    match (e, d.origins.get(key)) {
        (Error::InvalidScene { message, .. }, Some((file, line))) => {
            Error::InvalidScene { path: file.clone(), message: format!("line {line}: {message}") }
        }
        (e, _) => e,
    }
}

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
                let here = |e: Error| located(path, d, &format!("texture {name}"), &format!("texture `{name}`"), e);
                let bitmap = match decoded.remove(&key) {
                    Some(loaded) => {
                        let b = loaded.map_err(here)?;
                        if uses.get(&key).is_some_and(|&n| n > 1) {
                            reused.insert(key, b.clone());
                        }
                        b
                    }
                    None => match reused.get(&key) {
                        Some(b) => b.clone(),
                        None => Bitmap::load(&file, wrap, filter, key.1).map_err(here)?,
                    },
                };
                let mut bitmap = Bitmap { wrap, filter, ..bitmap };
                if t.v_from_top == Some(true) {
                    bitmap.flip_rows();
                }
                if !bitmap.texels.all_finite_non_negative() {
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
                        b.texels.map_channels(apply);
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

    let folder = path.parent().unwrap_or(Path::new("."));
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
    // Image and mesh files are read and parsed in parallel, each once (a scene may hold
    // hundreds of meshes beside dozens of megapixels of texture); their triangles are added
    // in the scene's order below, and any error is reported there, in that order.
    let to_parse: Vec<MeshKey> = {
        let mut seen = std::collections::HashSet::new();
        let valid = |m: &&super::description::MeshDescription| {
            m.obj.as_ref().xor(m.ply.as_ref()).is_some_and(|f| !f.is_empty())
        };
        d.meshes.iter().filter(valid).map(key).filter(|k| seen.insert(k.clone())).collect()
    };
    let (textures, mut parsed) = rayon::join(
        || textures_from(path, &d),
        || {
            use rayon::prelude::*;
            to_parse
                .into_par_iter()
                .map(|k| {
                    let file = parse_mesh_file(&k.0, k.1);
                    (k, file)
                })
                .collect::<HashMap<_, _>>()
        },
    );
    let (textures, texture_ids, texture_sources, texture_uv) = textures?;
    let mut meshes = Meshes::default();
    // A texture's mean is a pass over all its texels: computed once, when a material asks.
    let means: Vec<std::cell::OnceCell<Vec3A>> = textures.iter().map(|_| std::cell::OnceCell::new()).collect();
    let mean_of = |t: u16| *means[usize::from(t)].get_or_init(|| textures[usize::from(t)].mean());
    let media = super::media::Media::from_description(path, &d)?;
    let mut material_media = Vec::new();
    for (name, m) in &d.materials {
        meshes.by_name.insert(name.clone(), meshes.materials.len() as u32);
        let material = material_from(path, name, m, &texture_ids, mean_of);
        meshes.materials.push(material.map_err(|e| at_origin(&d, &format!("material {name}"), e))?);
        material_media.push(media.interface_of(path, name, m)?);
    }
    let camera_medium = media.id(path, "camera", d.camera.medium.as_ref())?;

    let mut sources = Vec::new();
    let mut read_before: HashMap<MeshKey, Geometry> = HashMap::new();
    for mesh in &d.meshes {
        let file = match (&mesh.obj, &mesh.ply) {
            (Some(f), None) | (None, Some(f)) => f,
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
            let file_parsed =
                parsed.remove(&mesh_key).ok_or_else(|| invalid(path, format!("mesh `{file}`: not read")))?;
            if let Ok(ParsedMesh::Obj(obj)) = &file_parsed {
                sources.extend(obj.mtl_files.iter().cloned());
            }
            read_mesh(path, mesh, file, &mesh_path, file_parsed, &mut meshes)
                .map_err(|e| located(path, &d, &format!("mesh {file}"), "", e))?;
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
    // Every shape's and inline mesh's triangles against the cap before any is tessellated
    // (410 of pbrt's spheres, 81,920 triangles each, took 4 GB and 8 s before the cap
    // refused the 411th).
    let planned = meshes.geometry.triangles.len()
        + d.shapes.iter().map(shape_triangles).sum::<usize>()
        + d.inline_meshes.iter().map(|m| m.indices.len() / 3).sum::<usize>();
    if planned > MAX_TRIANGLES {
        return Err(invalid(
            path,
            format!("the scene's shapes and meshes make {planned} triangles, more than {MAX_TRIANGLES}"),
        ));
    }
    // And against the memory left: an allocation that fails aborts the process.
    let to_build = (planned - meshes.geometry.triangles.len()) as u64 * BYTES_PER_TRIANGLE;
    if let Some(free) = crate::io::memory_short_of(to_build) {
        return Err(invalid(
            path,
            format!(
                "the scene's shapes make {} triangles, about {} while loading, and {} of memory is available",
                planned - meshes.geometry.triangles.len(),
                crate::io::human_bytes(to_build),
                crate::io::human_bytes(free)
            ),
        ));
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
    // The scene file's folder; in Bitterli's layout (`NAME/pbrt/scene-v4.pbrt`) the one above.
    fn folder_of(p: &Path) -> Option<&Path> {
        p.parent().filter(|f| !f.as_os_str().is_empty())
    }
    let mut named = folder_of(path);
    if named.and_then(Path::file_name).is_some_and(|n| n == "pbrt")
        && path.file_name().is_some_and(|n| n == "scene-v4.pbrt")
        && let Some(above) = named.and_then(folder_of)
    {
        named = Some(above);
    }
    let name =
        named.and_then(|p| p.file_name()).map_or_else(|| "scene".to_string(), |n| n.to_string_lossy().into_owned());
    let (lights, light_sources) = lights_from(path, &d)?;
    let surfaces = Surfaces { triangles, triangle_material, materials };
    let mut scene = Scene::from_parts(name, path.to_path_buf(), camera, surfaces, lights, warnings);
    scene.attributes = attributes;
    scene.textures = textures;
    scene.texture_uv = texture_uv;
    if material_media.iter().any(|m| *m != crate::medium::MediumInterface::default()) {
        scene.material_media = material_media;
    }
    scene.media = media.media;
    scene.camera_medium = camera_medium;
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

/// One rule for every light's strength (as for emitting materials): finite, non-negative and
/// at most [`MAX_EMISSION`] per channel, beyond which a sample's square overflows.
fn check_strength(path: &Path, what: &str, v: Vec3A) -> Result<()> {
    if v.is_finite() && v.min_element() >= 0.0 && v.max_element() <= MAX_EMISSION {
        Ok(())
    } else {
        Err(invalid(path, format!("{what} must lie in [0, {MAX_EMISSION:e}] per channel, got {v}")))
    }
}

/// Light `k` of the description (a point, spot or distant light), added to `lights`.
fn light_from(path: &Path, k: usize, l: &super::description::LightDescription, lights: &mut Lights) -> Result<()> {
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
            let intensity = need("intensity", l.intensity)?;
            check_strength(path, &format!("light {}: intensity", k + 1), intensity)?;
            let light = PointLight::point(need("position", l.position)?, intensity);
            lights.points.push(light.map_err(err)?);
        }
        LightKind::Spot => {
            forbid(&[("irradiance", l.irradiance.is_some())])?;
            let (position, intensity) = (need("position", l.position)?, need("intensity", l.intensity)?);
            check_strength(path, &format!("light {}: intensity", k + 1), intensity)?;
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
            check_strength(path, &format!("light {}: irradiance", k + 1), irradiance)?;
            lights.distant.push(crate::light::DistantLight::new(direction, irradiance).map_err(err)?);
        }
    }
    Ok(())
}

/// The point and spot lights and the environment of a scene file, and the files they read.
fn lights_from(path: &Path, d: &SceneDescription) -> Result<(Lights, Vec<PathBuf>)> {
    let mut lights = Lights::default();
    let mut sources = Vec::new();
    for (k, l) in d.lights.iter().enumerate() {
        light_from(path, k, l, &mut lights).map_err(|e| at_origin(d, &format!("light {}", k + 1), e))?;
    }
    if let Some(e) = &d.environment {
        let scale = e.scale.unwrap_or(1.0);
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(invalid(path, format!("environment: scale must be finite and non-negative, got {scale}")));
        }
        let env = match (&e.radiance, &e.map) {
            (Some(r), None) => {
                let r = vec3(*r) * scale;
                check_strength(path, "environment: radiance (times scale)", r)?;
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
                let brightest = texels.iter().fold(Vec3A::ZERO, |m, t| m.max(*t)) * scale;
                check_strength(path, "environment: the map's brightest texel (times scale)", brightest)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Hit, Ray};
    use crate::material::Bsdf;
    use crate::scene::description::MaterialDescription;

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

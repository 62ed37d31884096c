//! Loading a scene: the TOML file, its OBJ/MTL meshes, and every check that turns bad input
//! into an error naming the file (and line, where the parser knows it).
use super::description::{LightKind, MaterialDescription, SceneDescription, ShapeDescription, ShapeKind};
use super::{Camera, Lights, Material, Scene};
use crate::geometry::Vec3A;
use crate::light::envmap::Environment;
use crate::light::point::PointLight;
use crate::material::texture::{Bitmap, Filter, Wrap};
use crate::material::{Bsdf, conductors};
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

/// Reads a whole file after checking that it is a regular file (a FIFO or device would hang
/// or never end) of at most `limit` bytes. `what` names it in the error.
pub(crate) fn read_bounded(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>> {
    use std::io::Read as _;
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::io(path, std::io::Error::other(format!("not a regular file (a {what} must be one)"))));
    }
    let too_big = |size: u64| {
        Error::io(path, std::io::Error::other(format!("{size} bytes: larger than the {limit}-byte limit for a {what}")))
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    std::fs::File::open(path)
        .and_then(|f| f.take(limit + 1).read_to_end(&mut bytes))
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_big(bytes.len() as u64));
    }
    Ok(bytes)
}

/// Reads a text file with [`read_bounded`]; a byte sequence that is not UTF-8 is reported
/// with its line.
pub(crate) fn read_text(path: &Path, limit: u64, what: &str) -> Result<String> {
    let bytes = read_bounded(path, limit, what)?;
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        let line = e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count() + 1;
        Error::io(path, std::io::Error::other(format!("line {line}: not UTF-8 text: is this a {what}?")))
    })
}

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

/// A scene argument is a scene file or a folder holding `scene.toml`.
#[must_use]
pub fn resolve_scene_path(path: &Path) -> PathBuf {
    if path.is_dir() { path.join("scene.toml") } else { path.to_path_buf() }
}

impl Scene {
    /// Loads a scene file (or a folder holding `scene.toml`).
    pub fn load(path: impl AsRef<Path>) -> Result<Scene> {
        let path = resolve_scene_path(path.as_ref());
        let text = read_text(&path, MAX_SCENE_BYTES, "scene file")?;
        Scene::parse(&text, &path)
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
    Ok(meshes.triangles.len())
}

fn invalid(path: &Path, message: impl Into<String>) -> Error {
    Error::InvalidScene { path: path.to_path_buf(), message: message.into() }
}

fn vec3(a: [f32; 3]) -> Vec3A {
    Vec3A::from_array(a)
}

fn material_from(path: &Path, name: &str, d: &MaterialDescription) -> Result<Material> {
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
    Ok(Material { bsdf, emission, two_sided: d.two_sided.unwrap_or(true), two_sided_emission: d.two_sided_emission })
}

/// The scattering model a material description asks for; keys that do not apply to its type
/// are errors.
fn bsdf_from(d: &MaterialDescription) -> std::result::Result<Bsdf, String> {
    use crate::scene::description::MaterialKind as K;
    let kind = format!("{:?}", d.kind).to_lowercase();
    let allowed: &[&str] = match d.kind {
        K::Diffuse => &["diffuse"],
        K::Conductor => &["metal", "eta", "k", "specular", "roughness"],
        K::Dielectric => &["ior", "exterior_ior", "roughness"],
        K::ThinDielectric => &["ior", "exterior_ior"],
        K::Plastic => &["diffuse", "ior", "exterior_ior", "nonlinear"],
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
        ("nonlinear", d.nonlinear.is_some()),
    ];
    if let Some((key, _)) = given.iter().find(|(key, set)| *set && !allowed.contains(key)) {
        return Err(format!("`{key}` does not apply to type \"{kind}\""));
    }
    let alpha = d.roughness.unwrap_or(0.0);
    if !(alpha.is_finite() && (0.0..=1.0).contains(&alpha)) {
        return Err(format!("roughness must lie in [0, 1], got {alpha}"));
    }
    // Defaults: glass 1.5; plastic 1.49 (Mitsuba's polypropylene); outside, vacuum.
    let eta = |default: f32| -> std::result::Result<f32, String> {
        let (int, ext) = (d.ior.unwrap_or(default), d.exterior_ior.unwrap_or(1.0));
        let eta = int / ext;
        if !(int.is_finite() && ext.is_finite() && int >= 1.0 && ext >= 1.0 && eta.is_finite()) {
            return Err(format!("indices of refraction must be finite and at least 1, got {int} and {ext}"));
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
            match Bsdf::conductor(eta, k, alpha) {
                Bsdf::Conductor { eta, k, roughness, .. } => Bsdf::Conductor { eta, k, specular, roughness },
                other => other,
            }
        }
        K::Dielectric => Bsdf::dielectric(eta(1.5)?, alpha),
        K::ThinDielectric => Bsdf::Dielectric { eta: eta(1.5)?, roughness: None, thin: true },
        K::Plastic => Bsdf::plastic(vec3(d.diffuse), eta(1.49)?, d.nonlinear.unwrap_or(false)),
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
    let camera = Camera::new(vec3(c.eye), vec3(c.look_at), vec3(c.up), c.fov_y, c.width, c.height)
        .ok_or_else(|| invalid(path, "camera: eye equals look_at, or up is parallel to the view direction"))?;

    let mut meshes = Meshes::default();
    for (name, m) in &d.materials {
        meshes.by_name.insert(name.clone(), meshes.materials.len() as u32);
        meshes.materials.push(material_from(path, name, m)?);
    }

    let folder = path.parent().unwrap_or(Path::new("."));
    let mut sources = Vec::new();
    for mesh in &d.meshes {
        if mesh.obj.is_empty() {
            return Err(invalid(path, "a [[mesh]] has an empty `obj` path"));
        }
        let obj_path = folder.join(&mesh.obj);
        sources.push(obj_path.clone());
        let override_id = match &mesh.material {
            Some(name) => Some(
                *meshes
                    .by_name
                    .get(name)
                    .ok_or_else(|| invalid(path, format!("mesh `{}`: unknown material `{name}`", mesh.obj)))?,
            ),
            None => None,
        };
        load_obj(&obj_path, override_id, mesh.reverse_winding, &mut meshes)?;
    }
    for (k, shape) in d.shapes.iter().enumerate() {
        add_shape(path, k, shape, &mut meshes)?;
    }
    let Meshes { materials, triangles, triangle_material, findings, .. } = meshes;
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
        let (position, intensity) = (vec3(l.position), vec3(l.intensity));
        let light = match l.kind {
            LightKind::Point => {
                if l.direction.is_some() || l.cutoff.is_some() || l.beam.is_some() {
                    return Err(invalid(
                        path,
                        format!("light {}: `direction`, `cutoff` and `beam` are for spot lights", k + 1),
                    ));
                }
                PointLight::point(position, intensity)
            }
            LightKind::Spot => {
                let direction = l
                    .direction
                    .ok_or_else(|| invalid(path, format!("light {}: a spot light needs `direction`", k + 1)))?;
                PointLight::spot(position, vec3(direction), intensity, l.cutoff.unwrap_or(20.0), l.beam)
            }
        }
        .map_err(err)?;
        lights.points.push(light);
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
                let bitmap = Bitmap::load(&file, Wrap::Repeat, Filter::Nearest)?;
                let (w, h, texels) = bitmap.into_texels();
                if texels.iter().any(|t| !t.is_finite() || t.min_element() < 0.0) {
                    return Err(Error::Image {
                        path: file,
                        message: "an environment map must be finite and non-negative".into(),
                    });
                }
                sources.push(file.clone());
                Environment::from_texels(w, h, texels.into_iter().map(|t| t * scale).collect()).map_err(
                    |e| match e {
                        Error::InvalidOption(m) => Error::Image { path: file.clone(), message: m },
                        other => other,
                    },
                )?
            }
            _ => return Err(invalid(path, "environment: give either `radiance` or `map`")),
        };
        lights.environment = Some(env);
    }
    Ok((lights, sources))
}

/// The affine map of a shape's placement: `(linear part, translation)`.
fn shape_transform(s: &ShapeDescription) -> Result<(glam::Mat3A, Vec3A), String> {
    if let Some(m) = s.matrix {
        if s.scale.is_some() || s.rotate.is_some() || s.translate.is_some() {
            return Err("give either `matrix` or `scale`/`rotate`/`translate`, not both".into());
        }
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
        return Ok((linear, Vec3A::new(m[0][3], m[1][3], m[2][3])));
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
    for t in local {
        let mut t = t.map(|p| linear * p + translate);
        if flip {
            t.swap(1, 2);
        }
        let Meshes { triangles, triangle_material, findings, .. } = &mut *meshes;
        push_triangle(triangles, triangle_material, findings, t, material).map_err(err)?;
    }
    Ok(())
}

/// Adds triangle `t` of `material`, unless it is degenerate or not finite (counted in
/// `findings`, reported as a warning); an error past [`MAX_TRIANGLES`].
fn push_triangle(
    triangles: &mut Vec<[Vec3A; 3]>,
    triangle_material: &mut Vec<u32>,
    findings: &mut MeshFindings,
    t: [Vec3A; 3],
    material: u32,
) -> Result<(), String> {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    if !t.iter().all(|p| p.is_finite()) || n.length_squared() == 0.0 || !n.normalize().is_finite() {
        findings.degenerate += 1;
        return Ok(());
    }
    if triangles.len() >= MAX_TRIANGLES {
        return Err(format!("more than {MAX_TRIANGLES} triangles in the scene"));
    }
    triangles.push(t);
    triangle_material.push(material);
    Ok(())
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
    triangles: Vec<[Vec3A; 3]>,
    triangle_material: Vec<u32>,
    findings: MeshFindings,
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
    let Meshes { materials, by_name, triangles, triangle_material, findings } = meshes;
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
                        materials.push(material_from(obj_path, &m.name, &d)?);
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
    let mut polygon = Vec::new();
    let mut ears = Vec::new();
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
                findings.short_faces += 1;
                continue;
            }
            if arity > MAX_POLYGON_VERTICES {
                return Err(mesh_err(format!(
                    "object `{}`: face {} has {arity} vertices (at most {MAX_POLYGON_VERTICES})",
                    model.name,
                    face + 1
                )));
            }
            polygon.clear();
            polygon.extend(ids.iter().map(|&i| vertex(i)));
            ears.clear();
            if !crate::geometry::polygon::triangulate(&polygon, &mut ears) {
                findings.non_simple += 1;
            }
            for e in &ears {
                let mut t = [polygon[e[0]], polygon[e[1]], polygon[e[2]]];
                if reverse {
                    t.swap(1, 2);
                }
                push_triangle(triangles, triangle_material, findings, t, material).map_err(mesh_err)?;
            }
        }
    }
    if faces == 0 {
        return Err(mesh_err("no faces: an OBJ file lists faces as `f` lines".into()));
    }
    Ok(())
}

//! Meshes: OBJ/MTL and PLY files, inline meshes and canonical shapes turned into the scene's
//! triangle soup (with normals, texture coordinates and materials), transformed and checked
//! against the limits.
pub mod curves;
pub mod ply;
pub mod shapes;

use super::description::{MaterialDescription, ShapeDescription, ShapeKind};
use super::{Attributes, Material};
use crate::geometry::{Vec2, Vec3A};
use crate::io::{read_bounded, read_text};
use crate::{Error, Result};
use std::cell::RefCell;
use std::collections::HashMap;
use std::path::Path;

use super::limits::*;
use super::materials::material_from;

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

pub(super) fn invalid(path: &Path, message: impl Into<String>) -> Error {
    Error::InvalidScene { path: path.to_path_buf(), message: message.into() }
}

pub(super) fn vec3(a: [f32; 3]) -> Vec3A {
    Vec3A::from_array(a)
}

/// A row-major 4×4 `matrix` as `(linear part, translation)`: finite, affine.
pub(super) fn affine(m: [[f32; 4]; 4]) -> Result<(glam::Mat3A, Vec3A), String> {
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
pub(super) fn transform_since(g: &mut Geometry, start: usize, m: [[f32; 4]; 4]) -> Result<(), String> {
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
pub(super) fn smooth_normals_since(g: &mut Geometry, start: usize) {
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
pub(super) fn add_inline_mesh(path: &Path, m: &super::description::InlineMesh, meshes: &mut Meshes) -> Result<()> {
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

/// The affine map of a shape's placement: `(linear part, translation)`.
pub(super) fn shape_transform(s: &ShapeDescription) -> Result<(glam::Mat3A, Vec3A), String> {
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
pub(super) fn shape_corners(kind: ShapeKind, t: &[Vec3A; 3], centre: Vec3A, radius: f32) -> Corners {
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
/// The triangles shape `s` tessellates into (at most: degenerate ones are dropped).
pub(super) fn shape_triangles(s: &ShapeDescription) -> usize {
    match s.kind {
        ShapeKind::Rectangle => 2,
        ShapeKind::Cube => 12,
        ShapeKind::Disk => s.segments.unwrap_or(shapes::DISK_SEGMENTS).min(1 << 20) as usize,
        ShapeKind::Sphere => {
            20usize << (2 * s.subdivisions.unwrap_or(shapes::SPHERE_SUBDIVISIONS).min(shapes::MAX_SPHERE_SUBDIVISIONS))
        }
    }
}

pub(super) fn add_shape(path: &Path, k: usize, s: &ShapeDescription, meshes: &mut Meshes) -> Result<()> {
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
    // The triangle cap before tessellating.
    if meshes.geometry.triangles.len() + shape_triangles(s) > MAX_TRIANGLES {
        return Err(err(format!("more than {MAX_TRIANGLES} triangles in the scene")));
    }
    let local = match s.kind {
        ShapeKind::Rectangle => shapes::rectangle(),
        ShapeKind::Cube => shapes::cube(),
        ShapeKind::Disk => {
            let n = s.segments.unwrap_or(shapes::DISK_SEGMENTS);
            if !(3..=1 << 20).contains(&n) {
                return Err(err(format!("`segments` must lie in 3..=2^20, got {n}")));
            }
            shapes::disk(n)
        }
        ShapeKind::Sphere => {
            let (c, r) = (vec3(s.center.unwrap_or([0.0; 3])), s.radius.unwrap_or(1.0));
            let n = s.subdivisions.unwrap_or(shapes::SPHERE_SUBDIVISIONS);
            if !(c.is_finite() && r.is_finite() && r > 0.0) {
                return Err(err(format!("a sphere needs a finite centre and a positive radius, got {c} and {r}")));
            }
            if n > shapes::MAX_SPHERE_SUBDIVISIONS {
                return Err(err(format!(
                    "`subdivisions` must be at most {}, got {n}",
                    shapes::MAX_SPHERE_SUBDIVISIONS
                )));
            }
            shapes::sphere(c, r, n)
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
pub(super) fn push_triangle(
    g: &mut Geometry,
    mut t: [Vec3A; 3],
    mut corners: Corners,
    material: u32,
) -> Result<(), String> {
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
pub(super) struct Face {
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
pub(super) fn push_face(g: &mut Geometry, face: &mut Face, material: u32, reverse: bool) -> Result<(), String> {
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

/// A mesh file read and parsed but not yet turned into triangles: the costly part of
/// reading a mesh, which needs nothing of the scene and so runs in parallel over the files
/// (see [`parse_mesh_file`]); [`read_mesh`] then adds it in the scene's order.
pub(super) enum ParsedMesh {
    Obj(ParsedObj),
    Ply(ply::PlyMesh),
}

/// What tobj made of an OBJ file: its models, its material libraries, and why a library
/// could not be read.
pub(super) struct ParsedObj {
    models: Vec<tobj::Model>,
    mtl: Result<Vec<tobj::Material>, tobj::LoadError>,
    mtl_note: Option<String>,
    /// The material libraries it read (inputs no output may replace).
    pub(crate) mtl_files: Vec<std::path::PathBuf>,
}

/// Refuses a mesh file of `bytes` bytes (decompressed) whose triangles would need more than
/// the memory left: at [`BYTES_PER_TRIANGLE`] each, about `per_byte` times its size (a binary
/// PLY holds a triangle in about 30 bytes, an OBJ in about 35 of text; counted low, so that
/// only a file that cannot fit is refused).
fn check_mesh_memory(mesh_path: &Path, bytes: usize, per_byte: u64) -> Result<()> {
    let need = bytes as u64 * per_byte;
    match crate::io::memory_short_of(need) {
        Some(free) => Err(Error::Mesh {
            path: mesh_path.to_path_buf(),
            message: format!(
                "a mesh file of {} needs about {} while loading, and {} of memory is available",
                crate::io::human_bytes(bytes as u64),
                crate::io::human_bytes(need),
                crate::io::human_bytes(free)
            ),
        }),
        _ => Ok(()),
    }
}

/// Reads and parses the mesh file `mesh_path` (PLY when `is_ply`, else OBJ with its `mtllib`
/// files beside it).
pub(super) fn parse_mesh_file(mesh_path: &Path, is_ply: bool) -> Result<ParsedMesh> {
    if is_ply {
        let mut bytes = read_bounded(mesh_path, MAX_MESH_BYTES, "mesh (PLY) file")?;
        if mesh_path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz")) {
            bytes = gunzip(mesh_path, &bytes)?;
        }
        check_mesh_memory(mesh_path, bytes.len(), 12)?;
        return parse_ply(mesh_path, &bytes).map(ParsedMesh::Ply);
    }
    if mesh_path.as_os_str().is_empty() || mesh_path.file_name().is_none() {
        return Err(Error::Mesh {
            path: mesh_path.to_path_buf(),
            message: "the mesh path is empty or names a folder".into(),
        });
    }
    let text = read_text(mesh_path, MAX_MESH_BYTES, "mesh (OBJ) file")?;
    check_mesh_memory(mesh_path, text.len(), 8)?;
    let folder = mesh_path.parent().unwrap_or(Path::new("."));
    // tobj only learns that a library failed; why goes here.
    let mtl_note = RefCell::new(None);
    let mtl_files = RefCell::new(Vec::new());
    let loader = |name: &Path| {
        let path = folder.join(name);
        mtl_files.borrow_mut().push(path.clone());
        match read_text(&path, MAX_MESH_BYTES, "material library (MTL)") {
            Ok(t) => parse_mtl(&t),
            Err(e) => {
                *mtl_note.borrow_mut() = Some(e.to_string());
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    let mut obj = parse_obj(mesh_path, &text, &loader, &mtl_note)?;
    obj.mtl_files = mtl_files.take();
    Ok(ParsedMesh::Obj(obj))
}

/// Adds a `[[mesh]]`'s file, as [`parse_mesh_file`] read it, to `meshes` (before its
/// placement). The scene's own checks come first, then the file's errors.
pub(super) fn read_mesh(
    path: &Path,
    mesh: &super::description::MeshDescription,
    file: &str,
    mesh_path: &Path,
    parsed: Result<ParsedMesh>,
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
    let needs_material =
        || invalid(path, format!("mesh `{file}`: a PLY mesh needs `material = \"...\"` (PLY has no materials)"));
    // The scene's mistake is reported before the file's.
    if mesh.ply.is_some() && override_id.is_none() {
        return Err(needs_material());
    }
    match parsed? {
        ParsedMesh::Ply(ply) => {
            let material = override_id.ok_or_else(needs_material)?;
            ply_mesh_into(mesh_path, &ply, material, mesh.reverse_winding, &mut meshes.geometry)
        }
        ParsedMesh::Obj(obj) => obj_models_into(mesh_path, obj, override_id, mesh.reverse_winding, meshes),
    }
}

/// The triangles of `g` from `start` on, with their attributes (findings not copied).
pub(super) fn copy_geometry(g: &Geometry, start: usize) -> Geometry {
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
pub(super) fn append_geometry(g: &mut Geometry, src: &Geometry) -> std::result::Result<(), String> {
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
    pub(crate) findings: MeshFindings,
}

/// What a mesh had that the scene skips or repairs (reported as warnings).
#[derive(Debug, Default)]
pub(crate) struct MeshFindings {
    pub(crate) degenerate: usize,
    pub(crate) short_faces: usize,
    pub(crate) non_simple: usize,
}

/// Parses MTL text with tobj, after checking what tobj 4.0.5 would panic on: a colour line
/// (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three numbers (found by fuzzing).
pub(super) fn parse_mtl(text: &str) -> tobj::MTLLoadResult {
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
pub(super) struct Meshes {
    pub(crate) materials: Vec<Material>,
    pub(crate) by_name: HashMap<String, u32>,
    pub(crate) geometry: Geometry,
}

/// A gzip file's contents (pbrt's `.ply.gz`), at most [`MAX_MESH_BYTES`] of them.
pub(super) fn gunzip(path: &Path, bytes: &[u8]) -> Result<Vec<u8>> {
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
pub(super) fn ply_into(
    ply_path: &Path,
    bytes: &[u8],
    material: u32,
    reverse: bool,
    geometry: &mut Geometry,
) -> Result<()> {
    ply_mesh_into(ply_path, &parse_ply(ply_path, bytes)?, material, reverse, geometry)
}

/// PLY bytes `bytes` (named `ply_path` in errors) parsed.
fn parse_ply(ply_path: &Path, bytes: &[u8]) -> Result<ply::PlyMesh> {
    ply::parse(bytes)
        .map_err(|m| Error::Mesh { path: ply_path.to_path_buf(), message: format!("not a valid PLY file ({m})") })
}

/// Adds the triangles of the parsed PLY file `mesh` (named `ply_path` in errors), all of
/// `material` (polygons triangulated as OBJ faces are; vertex normals and texture coordinates
/// kept where every vertex has them).
fn ply_mesh_into(
    ply_path: &Path,
    mesh: &ply::PlyMesh,
    material: u32,
    reverse: bool,
    geometry: &mut Geometry,
) -> Result<()> {
    let mesh_err = |message: String| Error::Mesh { path: ply_path.to_path_buf(), message };
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

/// Adds the triangles of OBJ text `text` (named `obj_path` in errors; `mtllib` files come
/// from `mtl_loader`, which may leave in `mtl_note` why one could not be loaded).
pub(super) fn obj_into(
    obj_path: &Path,
    text: &str,
    mtl_loader: &dyn Fn(&Path) -> tobj::MTLLoadResult,
    mtl_note: &RefCell<Option<String>>,
    override_id: Option<u32>,
    reverse: bool,
    meshes: &mut Meshes,
) -> Result<()> {
    obj_models_into(obj_path, parse_obj(obj_path, text, mtl_loader, mtl_note)?, override_id, reverse, meshes)
}

/// OBJ text `text` parsed (named `obj_path` in errors; `mtllib` files come from
/// `mtl_loader`, which may leave in `mtl_note` why one could not be loaded).
fn parse_obj(
    obj_path: &Path,
    text: &str,
    mtl_loader: &dyn Fn(&Path) -> tobj::MTLLoadResult,
    mtl_note: &RefCell<Option<String>>,
) -> Result<ParsedObj> {
    // Polygons are kept whole (tobj would fan them, wrong for concave ones) and points and
    // lines kept too, so that nothing is dropped without a word.
    let options =
        tobj::LoadOptions { triangulate: false, ignore_points: false, ignore_lines: false, ..Default::default() };
    let (models, mtl) = tobj::load_obj_buf(&mut text.as_bytes(), &options, mtl_loader)
        .map_err(|e| Error::Mesh { path: obj_path.to_path_buf(), message: format!("not a valid OBJ file ({e})") })?;
    Ok(ParsedObj { models, mtl, mtl_note: mtl_note.take(), mtl_files: Vec::new() })
}

/// Adds the triangles of the parsed OBJ file `obj` (named `obj_path` in errors).
fn obj_models_into(
    obj_path: &Path,
    obj: ParsedObj,
    override_id: Option<u32>,
    reverse: bool,
    meshes: &mut Meshes,
) -> Result<()> {
    let Meshes { materials, by_name, geometry } = meshes;
    let mesh_err = |message: String| Error::Mesh { path: obj_path.to_path_buf(), message };
    let ParsedObj { models, mtl, mut mtl_note, .. } = obj;
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
mod ply_tests {
    use crate::scene::Scene;

    /// The OBJ quad of the build tests as a binary PLY (normals, texture coordinates, one
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

//! The TOML scene file, as serde reads it. Unknown keys are rejected by name.
use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDescription {
    pub camera: CameraDescription,
    /// Materials by name. They override MTL materials of the same name and can be assigned to
    /// a whole mesh with `material = "name"`.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDescription>,
    #[serde(default, rename = "mesh")]
    pub meshes: Vec<MeshDescription>,
    #[serde(default, rename = "shape")]
    pub shapes: Vec<ShapeDescription>,
}

/// A pinhole camera.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDescription {
    pub eye: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees.
    pub fov_y: f32,
    pub width: u32,
    pub height: u32,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// A two-sided diffuse reflector that may also emit, one-sided, along its geometric normal.
#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(deny_unknown_fields)]
pub struct MaterialDescription {
    #[serde(default)]
    pub diffuse: [f32; 3],
    #[serde(default)]
    pub emission: [f32; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshDescription {
    /// OBJ file, relative to the scene file's folder.
    pub obj: String,
    /// Assign this material to every face of the mesh (overrides the OBJ's `usemtl`).
    pub material: Option<String>,
    /// Reverse every triangle's winding, flipping geometric normals and emitting sides.
    #[serde(default)]
    pub reverse_winding: bool,
}

/// The canonical shapes (see [`crate::scene::shapes`]).
#[derive(Debug, Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    Rectangle,
    Disk,
    Cube,
    Sphere,
}

/// A rotation by `angle` degrees about `axis` (counter-clockwise looking down the axis).
#[derive(Debug, Deserialize, Clone, Copy)]
#[serde(deny_unknown_fields)]
pub struct RotateDescription {
    pub axis: [f32; 3],
    pub angle: f32,
}

/// A shape placed in the scene: the canonical shape, then `scale`, `rotate` and `translate`
/// in that order, or a whole `matrix` (row-major 4×4, last row 0 0 0 1).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeDescription {
    #[serde(rename = "type")]
    pub kind: ShapeKind,
    /// The shape's material (a name from `[materials]`).
    pub material: String,
    /// Sphere only: centre and radius (default the origin and 1), before the transform.
    pub center: Option<[f32; 3]>,
    pub radius: Option<f32>,
    /// Disk only: segments of the rim.
    pub segments: Option<u32>,
    /// Sphere only: subdivisions of the icosahedron.
    pub subdivisions: Option<u32>,
    pub scale: Option<[f32; 3]>,
    pub rotate: Option<RotateDescription>,
    pub translate: Option<[f32; 3]>,
    pub matrix: Option<[[f32; 4]; 4]>,
    /// Reverse every triangle's winding, flipping geometric normals and emitting sides.
    #[serde(default)]
    pub reverse_winding: bool,
}

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

//! `zvidpt render --aov`: the EXR gains albedo, normal, depth and spp layers under the names
//! tev and Open Image Denoise's tools expect, with sensible values: the back wall's albedo is
//! its reflectance, its normal faces the camera, its depth is the camera's distance to it.
use exr::prelude::*;
use std::process::Command;

fn channels(path: &std::path::Path) -> Vec<(String, Vec<f32>)> {
    let image = read_all_flat_layers_from_file(path).unwrap();
    image.layer_data[0]
        .channel_data
        .list
        .iter()
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect()
}

#[test]
fn aov_layers_are_present_and_sensible() {
    let dir = std::env::temp_dir().join(format!("zvidpt-aov-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("a.exr");
    let scene = format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"));
    let o = Command::new(env!("CARGO_BIN_EXE_zvidpt"))
        .args(["render", &scene, "-o", out.to_str().unwrap(), "--integrator", "path", "--resolution", "32x24"])
        .args(["--spp", "3", "--no-png", "-q", "--aov", "albedo,normal,depth,spp,variance"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ch = channels(&out);
    let get =
        |name: &str| ch.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).unwrap_or_else(|| panic!("no {name}"));
    for name in [
        "R",
        "G",
        "B",
        "variance.R",
        "albedo.R",
        "albedo.G",
        "albedo.B",
        "normal.X",
        "normal.Y",
        "normal.Z",
        "Z",
        "spp",
    ] {
        assert_eq!(get(name).len(), 32 * 24, "{name}");
    }
    // The centre pixel sees the back wall (white, Kd 0.73; z = -1, facing +z; camera at z 3.4).
    let centre = 12 * 32 + 16;
    for c in ["albedo.R", "albedo.G", "albedo.B"] {
        assert!((get(c)[centre] - 0.73).abs() < 1e-5, "{c} {}", get(c)[centre]);
    }
    let n = [get("normal.X")[centre], get("normal.Y")[centre], get("normal.Z")[centre]];
    assert!(n[0].abs() < 1e-5 && n[1].abs() < 1e-5 && (n[2] - 1.0).abs() < 1e-5, "{n:?}");
    let z = get("Z")[centre];
    assert!((4.4..4.45).contains(&z), "depth {z}");
    // The left wall (red, Kd 0.63 0.065 0.05) at the left edge, middle row; its normal is +x.
    let left = 12 * 32 + 6;
    assert!((get("albedo.R")[left] - 0.63).abs() < 1e-5 && (get("albedo.G")[left] - 0.065).abs() < 1e-5);
    assert!((get("normal.X")[left] - 1.0).abs() < 1e-5);
    assert!(get("spp").iter().all(|&s| s == 3.0));
    // Without --aov only the colour and variance layers are written.
    let plain = dir.join("b.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_zvidpt"))
        .args(["render", &scene, "-o", plain.to_str().unwrap(), "--integrator", "path", "--resolution", "8x6"])
        .args(["--spp", "1", "--no-png", "-q"])
        .output()
        .unwrap();
    assert!(o.status.success());
    assert_eq!(channels(&plain).len(), 6);
    let _ = std::fs::remove_dir_all(&dir);
}

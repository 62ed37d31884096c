//! pbrt-v4 import: a scene loads as the same scene written in our TOML (geometry, materials,
//! textures, lights, camera rays, render defaults), and renders as that TOML scene does.
mod common;
use common::cli::{scratch, text, zvidpt};
use std::path::{Path, PathBuf};
use zvidpt::film::read_exr;
use zvidpt::geometry::{Vec2, Vec3A};
use zvidpt::integrator::PathTracer;
use zvidpt::scene::{Material, Scene};

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/pbrt")
}

type Triangle = ([Vec3A; 3], Option<[Vec3A; 3]>, Option<[Vec2; 3]>, Material);

/// Every triangle with its attributes and material, in a canonical order (by centroid): the
/// importer adds shapes in another order than the TOML loader.
fn triangles(s: &Scene) -> Vec<Triangle> {
    let mut out: Vec<Triangle> = (0..s.triangles.len())
        .map(|i| {
            let normals = s.attributes.normals.get(i).copied().filter(|c| c[0] != Vec3A::ZERO);
            (s.triangles[i], normals, s.attributes.uvs.get(i).copied(), *s.material_of(i as u32))
        })
        .collect();
    let key = |t: &Triangle| {
        let c = (t.0[0] + t.0[1] + t.0[2]) * 1e4 / 3.0;
        (c.x.round() as i64, c.y.round() as i64, c.z.round() as i64)
    };
    out.sort_by_key(key);
    out
}

fn close(a: Vec3A, b: Vec3A, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn pbrt_loads_as_its_toml_twin() {
    let pbrt = Scene::load(dir().join("box.pbrt")).unwrap();
    let toml = Scene::load(dir().join("box.toml")).unwrap();
    let (a, b) = (triangles(&pbrt), triangles(&toml));
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
        for k in 0..3 {
            assert!(close(x.0[k], y.0[k], 2e-6), "triangle {i} corner {k}: {} vs {}", x.0[k], y.0[k]);
        }
        match (x.1, y.1) {
            (None, None) => {}
            (Some(p), Some(q)) => assert!((0..3).all(|k| close(p[k], q[k], 1e-5)), "triangle {i}'s normals"),
            _ => panic!("triangle {i}: normals on one side only"),
        }
        let uv = |u: Option<[Vec2; 3]>| u.unwrap_or(zvidpt::scene::Attributes::BARYCENTRIC_UV);
        assert!((0..3).all(|k| (uv(x.2)[k] - uv(y.2)[k]).abs().max_element() < 1e-6), "triangle {i}'s uv");
        assert_eq!(x.3, y.3, "triangle {i}'s material");
    }
    assert_eq!(pbrt.textures, toml.textures);
    assert_eq!(pbrt.lights.points.len(), 2);
    assert_eq!(format!("{:?}", pbrt.lights.points), format!("{:?}", toml.lights.points));
    for (u, v) in [(0.0, 0.0), (32.0, 24.0), (63.5, 0.5), (10.0, 47.0)] {
        let (p, q) = (pbrt.camera.ray(Vec2::new(u, v)), toml.camera.ray(Vec2::new(u, v)));
        assert!(close(p.origin, q.origin, 1e-6) && close(p.dir, q.dir, 1e-6), "ray {u},{v}: {p:?} vs {q:?}");
    }
    assert_eq!((pbrt.render.spp, pbrt.render.max_depth), (Some(64), Some(101)));
    // The coated diffuse approximated by a plastic is the only warning.
    assert_eq!(pbrt.warnings.len(), 1, "{:?}", pbrt.warnings);
    assert!(pbrt.warnings[0].contains("box.pbrt:") && pbrt.warnings[0].contains("coateddiffuse"));
}

/// The same pixels, within their noise: a per-block z-test between the two renders (the
/// scenes are one scene; a mis-read parameter moves blocks by many standard errors).
#[test]
fn pbrt_renders_as_its_toml_twin() {
    let pbrt = Scene::load(dir().join("box.pbrt")).unwrap();
    let toml = Scene::load(dir().join("box.toml")).unwrap();
    let a = common::render_bvh(&pbrt, &mut PathTracer::default(), 256, 1);
    let b = common::render_bvh(&toml, &mut PathTracer::default(), 256, 2);
    let (z, tests) = common::max_block_z_both(&a, &b, 8);
    assert_eq!(tests, 144);
    assert!(z < 4.5, "largest block |z| {z:.2}");
}

/// pbrt's own camera convention: without the `Scale -1 1 1`, the image is mirrored.
#[test]
fn a_left_handed_camera_mirrors() {
    let text = std::fs::read_to_string(dir().join("box.pbrt")).unwrap().replace("Scale -1 1 1", "");
    let mirrored = Scene::parse_pbrt(&text, &dir().join("box.pbrt"), &Default::default()).unwrap();
    let plain = Scene::load(dir().join("box.pbrt")).unwrap();
    let (p, q) = (mirrored.camera.ray(Vec2::new(10.0, 20.0)), plain.camera.ray(Vec2::new(54.0, 20.0)));
    assert!(close(p.dir, q.dir, 1e-6), "{:?} vs {:?}", p.dir, q.dir);
}

#[test]
fn command_line() {
    let d = scratch("pbrt", "cli");
    let out = d.join("box.exr");
    let o = zvidpt(&[
        "render",
        dir().join("box.pbrt").to_str().unwrap(),
        "--integrator",
        "path",
        "--resolution",
        "32x24",
        "-o",
        out.to_str().unwrap(),
        "--no-png",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let (image, _) = read_exr(&out).unwrap();
    assert_eq!((image.width, image.height, image.spp), (32, 24, 64));

    let bad = d.join("bad.pbrt");
    std::fs::write(&bad, "WorldBegin\nShape \"sphere\"\n  \"float radius\" [ one ]\n").unwrap();
    let o = zvidpt(&["render", bad.to_str().unwrap(), "-o", d.join("bad.exr").to_str().unwrap()]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error:") && stderr.contains("bad.pbrt") && stderr.contains("line 3"), "{stderr}");

    let odd = d.join("odd.pbrt");
    std::fs::write(&odd, "WorldBegin\nShape \"sphere\"\nShape \"curve\" \"point3 P\" [0 0 0]\n").unwrap();
    let o = zvidpt(&["render", odd.to_str().unwrap(), "--strict", "-o", d.join("odd.exr").to_str().unwrap()]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("line 3") && stderr.contains("curve") && stderr.contains("--strict"), "{stderr}");
}

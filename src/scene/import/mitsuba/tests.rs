//! The Mitsuba importer's unit tests: reading, translation and the errors of each stage.
use super::*;
use crate::scene::description::LightKind;

fn read(body: &str, defines: &[(&str, &str)], strict: bool) -> Result<Imported> {
    let text = format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n");
    let options =
        ImportOptions { defines: defines.iter().map(|(a, b)| ((*a).to_string(), (*b).to_string())).collect(), strict };
    import(Path::new("/nowhere/scene.xml"), &text, &options)
}

fn ok(body: &str) -> SceneDescription {
    read(body, &[], true).unwrap().description
}

fn message(r: Result<Imported>) -> String {
    match r {
        Err(e) => e.to_string(),
        Ok(_) => panic!("expected an error"),
    }
}

const SHAPE: &str = "<shape type=\"rectangle\"/>";

#[test]
fn defaults_and_defines_substitute() {
    let body = "<default name=\"r\" value=\"0.25\"/>
        <shape type=\"sphere\"><float name=\"radius\" value=\"$r\"/></shape>
        <shape type=\"sphere\"><float name=\"radius\" value=\"${r}5\"/></shape>";
    let d = ok(body);
    assert_eq!(d.shapes[0].radius, Some(0.25));
    assert_eq!(d.shapes[1].radius, Some(0.255));
    let d = read(body, &[("r", "2")], true).unwrap().description;
    assert_eq!(d.shapes[0].radius, Some(2.0), "-D wins over <default>");
    let e = message(read("<shape type=\"sphere\">\n<float name=\"radius\" value=\"$missing\"/></shape>", &[], false));
    assert!(e.contains("line 3") && e.contains("$missing"), "{e}");
}

#[test]
fn transforms_compose_in_order() {
    let d = ok("<shape type=\"rectangle\"><transform name=\"to_world\">
            <scale value=\"2\"/><translate x=\"1\"/><rotate z=\"1\" angle=\"90\"/>
        </transform></shape>");
    // x ↦ 2x, then +1 along x, then a quarter turn about z: (1, 0, 0) ↦ (3, 0, 0) ↦ (0, 3, 0).
    let m = d.shapes[0].matrix.unwrap();
    let p = [1.0f32, 0.0, 0.0, 1.0];
    let q: Vec<f32> = (0..3).map(|r| (0..4).map(|c| m[r][c] * p[c]).sum()).collect();
    assert!((q[0] - 0.0).abs() < 1e-6 && (q[1] - 3.0).abs() < 1e-6 && q[2].abs() < 1e-6, "{q:?}");
    let d = ok("<shape type=\"rectangle\"><transform name=\"to_world\">
            <matrix value=\"1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1\"/></transform></shape>");
    assert_eq!(d.shapes[0].matrix.unwrap()[1], [0.0, 1.0, 0.0, 6.0]);
}

/// Mitsuba's `fov` is across `fov_axis` (x by default); ours is vertical.
#[test]
fn field_of_view_axes() {
    let fov_y = |axis: &str, w: u32, h: u32| {
        let d = ok(&format!(
            "{SHAPE}<sensor type=\"perspective\"><float name=\"fov\" value=\"60\"/>
             <string name=\"fov_axis\" value=\"{axis}\"/>
             <film type=\"hdrfilm\"><integer name=\"width\" value=\"{w}\"/><integer name=\"height\" value=\"{h}\"/></film>
             </sensor>"
        ));
        f64::from(d.camera.fov_y)
    };
    let t = 30f64.to_radians().tan();
    let deg = |x: f64| (2.0 * x.atan()).to_degrees();
    assert!((fov_y("x", 400, 200) - deg(t / 2.0)).abs() < 1e-4);
    assert!((fov_y("y", 400, 200) - 60.0).abs() < 1e-4);
    assert!((fov_y("diagonal", 400, 300) - deg(t * 300.0 / 500.0)).abs() < 1e-4);
    assert!((fov_y("smaller", 400, 200) - 60.0).abs() < 1e-4);
    assert!((fov_y("smaller", 200, 400) - deg(t * 2.0)).abs() < 1e-4);
    assert!((fov_y("larger", 400, 200) - deg(t / 2.0)).abs() < 1e-4);
    let d = ok(SHAPE);
    assert_eq!((d.camera.width, d.camera.height), (768, 576), "Mitsuba's default film");
    // The default 50 mm lens: 46.8° across the 43.3 mm diagonal.
    let diagonal = (36f64.hypot(24.0) / 100.0).atan();
    let want = (2.0 * (diagonal.tan() * 576.0 / 768f64.hypot(576.0)).atan()).to_degrees();
    assert!((f64::from(d.camera.fov_y) - want).abs() < 1e-4, "{} vs {want}", d.camera.fov_y);
}

/// `lookat` gives our camera as it is; a mirroring `to_world` sets `mirror`; a crop window.
#[test]
fn camera_frame_mirror_and_crop() {
    let sensor = |extra: &str| {
        ok(&format!(
            "{SHAPE}<sensor type=\"perspective\"><transform name=\"to_world\">{extra}
             <lookat origin=\"1, 2, 3\" target=\"1, 2, 0\" up=\"0, 1, 0\"/></transform>
             <film type=\"hdrfilm\"><integer name=\"crop_offset_x\" value=\"10\"/>
             <integer name=\"crop_width\" value=\"20\"/></film></sensor>"
        ))
        .camera
    };
    let c = sensor("");
    assert_eq!(c.eye, [1.0, 2.0, 3.0]);
    assert!((c.look_at[2] - 2.0).abs() < 1e-6 && c.up == [0.0, 1.0, 0.0] && !c.mirror);
    assert_eq!(c.crop, Some([10, 0, 20, 576]));
    assert!(sensor("<scale x=\"-1\"/>").mirror);
}

/// `to_uv` of a bitmap, and of a checkerboard beyond a scale, becomes `uv_transform`.
#[test]
fn texture_coordinate_maps() {
    let d = ok("<shape type=\"rectangle\"><bsdf type=\"diffuse\"><texture type=\"bitmap\" name=\"reflectance\">
            <string name=\"filename\" value=\"t.png\"/>
            <transform name=\"to_uv\"><scale x=\"2\" y=\"3\"/><translate x=\"0.5\"/></transform></texture></bsdf></shape>
        <shape type=\"rectangle\"><bsdf type=\"diffuse\"><texture type=\"checkerboard\" name=\"reflectance\">
            <transform name=\"to_uv\"><rotate z=\"1\" angle=\"90\"/></transform></texture></bsdf></shape>");
    let t: Vec<&TextureDescription> = d.textures.values().collect();
    assert_eq!(t[0].uv_transform, Some([[2.0, 0.0, 0.5], [0.0, 3.0, 0.0]]));
    let r = t[1].uv_transform.unwrap();
    assert!((r[0][1] + 1.0).abs() < 1e-6 && (r[1][0] - 1.0).abs() < 1e-6, "{r:?}");
    assert_eq!(t[1].scale, Some([2.0, 2.0]));
}

/// An instance is its shapegroup's shapes placed by its `to_world` after their own: the
/// same triangles (to f32 rounding) as the shapes written out in place, mirrored
/// instances included; the group alone renders nothing.
#[test]
fn shapegroups_and_instances() {
    let shapes = "<shape type=\"rectangle\"><transform name=\"to_world\"><translate z=\"1\"/></transform></shape>
        <shape type=\"sphere\"><float name=\"radius\" value=\"0.25\"/><bsdf type=\"conductor\"/></shape>";
    let placements = ["<translate x=\"5\"/>", "<rotate y=\"1\" angle=\"30\"/>", "<scale x=\"-1\"/>"];
    let instanced: String = std::iter::once(format!("<shape type=\"shapegroup\" id=\"g\">{shapes}</shape>"))
        .chain(placements.iter().map(|p| {
            format!("<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\">{p}</transform></shape>")
        }))
        .collect();
    let placed = |p: &str| {
        // The same shapes with the placement after their own transform.
        shapes
            .replace("<translate z=\"1\"/></transform>", &format!("<translate z=\"1\"/>{p}</transform>"))
            .replace("<bsdf", &format!("<transform name=\"to_world\">{p}</transform><bsdf"))
    };
    let direct: String = placements.iter().map(|p| placed(p)).collect();
    let triangles = |body: &str| {
        let text = format!("<scene version=\"3.0.0\">{body}</scene>");
        let scene =
            crate::scene::Scene::parse_mitsuba(&text, Path::new("/nowhere/s.xml"), &ImportOptions::default()).unwrap();
        let mut t: Vec<[f32; 9]> =
            scene.triangles.iter().map(|t| t.map(|p| p.to_array()).concat().try_into().unwrap()).collect();
        t.sort_by(|a, b| {
            a.iter().zip(b).map(|(x, y)| x.total_cmp(y)).find(|o| o.is_ne()).unwrap_or(std::cmp::Ordering::Equal)
        });
        (t, scene.materials.len())
    };
    let ((a, _), (b, _)) = (triangles(&instanced), triangles(&direct));
    assert_eq!(a.len(), b.len());
    assert!(a.len() > 3 * (2 + 1000), "{}", a.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(x.iter().zip(y).all(|(p, q)| (p - q).abs() <= 1e-5), "{x:?} vs {y:?}");
    }
    let d = ok(&format!("<shape type=\"shapegroup\" id=\"g\">{shapes}</shape><shape type=\"cube\"/>"));
    assert_eq!(d.shapes.len(), 1, "a group is not rendered by itself");
    for (body, want) in [
        ("<shape type=\"instance\"><ref id=\"nope\"/></shape>", "no object in the scene has that id"),
        ("<bsdf type=\"diffuse\" id=\"b\"/><shape type=\"instance\"><ref id=\"b\"/></shape>", "not a shapegroup"),
        ("<shape type=\"instance\"/>", "holds one shapegroup"),
        ("<shape type=\"shapegroup\" id=\"g\"><shape type=\"shapegroup\"/></shape>", "inside a shapegroup"),
    ] {
        let e = message(read(body, &[], false));
        assert!(e.contains(want), "{body}: {e}");
    }
    let r = read(
        "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"><emitter type=\"area\"/></shape></shape>
         <shape type=\"instance\"><ref id=\"g\"/></shape>",
        &[],
        false,
    )
    .unwrap();
    assert!(r.warnings.iter().any(|w| w.contains("does not instance emitters")), "{:?}", r.warnings);
    assert!(r.description.materials.values().all(|m| m.emission == [0.0; 3]));
}

/// BSDFs we approximate: normal maps, bump maps and masks by their nested BSDF, a blend
/// by its heavier BSDF, principled by a rough plastic, conductor or dielectric; each with
/// a warning.
#[test]
fn wrapped_and_approximated_bsdfs() {
    let material = |bsdf: &str| {
        let r = read(&format!("<shape type=\"cube\">{bsdf}</shape>"), &[], false).unwrap();
        (r.description.materials.values().next().unwrap().clone(), r.warnings)
    };
    let (m, w) = material(
        "<bsdf type=\"normalmap\"><texture name=\"normalmap\" type=\"bitmap\"><string name=\"filename\" value=\"n.png\"/></texture>
         <bsdf type=\"roughplastic\"><rgb name=\"diffuse_reflectance\" value=\"0.1, 0.2, 0.3\"/></bsdf></bsdf>",
    );
    assert_eq!((m.kind, m.diffuse), (MaterialKind::Plastic, [0.1, 0.2, 0.3]));
    assert!(w.len() == 1 && w[0].contains("normal perturbation"), "{w:?}");
    let (m, w) =
        material("<bsdf type=\"mask\"><float name=\"opacity\" value=\"0.5\"/><bsdf type=\"conductor\"/></bsdf>");
    assert!(m.kind == MaterialKind::Conductor && w[0].contains("opacity"), "{w:?}");
    let (m, _) = material(
        "<bsdf type=\"blendbsdf\"><float name=\"weight\" value=\"0.8\"/><bsdf type=\"diffuse\"/><bsdf type=\"dielectric\"/></bsdf>",
    );
    assert_eq!(m.kind, MaterialKind::Dielectric, "the heavier one");
    let (m, w) = material(
        "<bsdf type=\"principled\"><rgb name=\"base_color\" value=\"0.8, 0.1, 0.1\"/><float name=\"roughness\" value=\"0.4\"/></bsdf>",
    );
    assert_eq!(
        (m.kind, m.diffuse, m.roughness.map(|a| (a * 100.0).round())),
        (MaterialKind::Plastic, [0.8, 0.1, 0.1], Some(16.0))
    );
    assert!(w[0].contains("principled"), "{w:?}");
    let (m, _) = material("<bsdf type=\"principled\"><float name=\"metallic\" value=\"1\"/></bsdf>");
    assert_eq!((m.kind, m.metal.as_deref(), m.specular), (MaterialKind::Conductor, Some("none"), Some([0.5; 3])));
    let e = message(read("<shape type=\"cube\"><bsdf type=\"bumpmap\"/></shape>", &[], false));
    assert!(e.contains("needs one nested BSDF"), "{e}");
}

/// The film's `rfilter`, Mitsuba's default Gaussian without one.
#[test]
fn reconstruction_filters() {
    let filter = |film: &str| {
        let r = read(
            &format!(
                "<sensor type=\"perspective\"><film type=\"hdrfilm\">{film}</film></sensor><shape type=\"cube\"/>"
            ),
            &[],
            false,
        )
        .unwrap();
        (r.description.camera.filter.unwrap(), r.warnings)
    };
    let gaussian = PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: None };
    assert_eq!(filter("").0, gaussian);
    assert_eq!(ok("<shape type=\"cube\"/>").camera.filter, Some(gaussian), "the default sensor's film");
    assert_eq!(filter("<rfilter type=\"box\"/>").0.kind, PixelFilterKind::Box);
    let (f, _) = filter("<rfilter type=\"gaussian\"><float name=\"stddev\" value=\"0.25\"/></rfilter>");
    assert_eq!(f.stddev, Some(0.25));
    let (f, _) = filter("<rfilter type=\"tent\"><float name=\"radius\" value=\"2\"/></rfilter>");
    assert_eq!((f.kind, f.radius), (PixelFilterKind::Tent, Some([2.0; 2])));
    let (f, warnings) = filter("<rfilter type=\"mitchell\"/>");
    assert!(f == gaussian && warnings[0].contains("mitchell"), "{warnings:?}");
}

#[test]
fn materials_and_their_defaults() {
    let d = ok("<bsdf type=\"roughconductor\" id=\"m\"><string name=\"material\" value=\"Cu\"/>
            <string name=\"distribution\" value=\"ggx\"/></bsdf>
        <shape type=\"cube\"><ref id=\"m\"/></shape>
        <shape type=\"cube\"><bsdf type=\"dielectric\"><string name=\"int_ior\" value=\"water\"/></bsdf></shape>
        <shape type=\"cube\"><bsdf type=\"twosided\"><bsdf type=\"plastic\"/></bsdf></shape>
        <shape type=\"cube\"/>");
    let m: Vec<&MaterialDescription> = d.shapes.iter().map(|s| &d.materials[&s.material]).collect();
    assert_eq!((m[0].kind, m[0].metal.as_deref(), m[0].roughness), (MaterialKind::Conductor, Some("Cu"), Some(0.1)));
    assert_eq!(
        (m[0].distribution, m[0].masking),
        (Some(DistributionDescription::Ggx), Some(MaskingDescription::Separable))
    );
    let d2 =
        ok("<shape type=\"cube\"><bsdf type=\"roughdielectric\"><float name=\"alpha\" value=\"0.3\"/></bsdf></shape>");
    let rough = d2.materials.values().next().unwrap();
    assert_eq!(
        (rough.roughness, rough.distribution),
        (Some(0.3), Some(DistributionDescription::Beckmann)),
        "Mitsuba's default"
    );
    assert_eq!(m[0].two_sided, Some(false), "Mitsuba's surfaces are one-sided");
    assert_eq!((m[1].kind, m[1].ior, m[1].exterior_ior), (MaterialKind::Dielectric, Some(1.333), Some(1.000_277)));
    assert_eq!((m[2].kind, m[2].ior, m[2].two_sided), (MaterialKind::Plastic, Some(1.49), Some(true)));
    assert_eq!((m[2].diffuse, m[3].diffuse), ([0.5; 3], [0.5; 3]));
    // A checkerboard read as one value swaps its colours, as Mitsuba's `eval_1` does.
    let d3 = ok("<shape type=\"cube\"><bsdf type=\"roughconductor\"><texture type=\"checkerboard\" name=\"alpha\">
            <rgb name=\"color0\" value=\"0.05\"/><rgb name=\"color1\" value=\"0.5\"/></texture></bsdf></shape>");
    let m = d3.materials.values().next().unwrap();
    let t = &d3.textures[m.roughness_texture.as_ref().unwrap()];
    assert_eq!((t.color0, t.color1), (Some([0.5; 3]), Some([0.05; 3])));
    // An emitter without a BSDF reflects nothing, as in Mitsuba 3.
    let lamp = ok("<shape type=\"rectangle\"><emitter type=\"area\"/></shape>");
    let m = lamp.materials.values().next().unwrap();
    assert_eq!((m.diffuse, m.emission), ([0.0; 3], [1.0; 3]));
    let e = message(read("<shape type=\"cube\"><ref id=\"nope\"/></shape>", &[], false));
    assert!(e.contains("nope") && e.contains("line 2"), "{e}");
}

/// Outside the subset: one warning naming element, file and line, and the fallback; an
/// error with `strict`.
#[test]
fn unsupported_warns_or_fails() {
    let body = "<shape type=\"cube\">\n<bsdf type=\"hair\"/></shape>";
    let r = read(body, &[], false).unwrap();
    assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
    assert!(r.warnings[0].starts_with("/nowhere/scene.xml:3:") && r.warnings[0].contains("grey diffuse"));
    let r = read("<shape type=\"cube\"><bsdf type=\"roughplastic\"><string name=\"distribution\" value=\"phong\"/></bsdf></shape>", &[], false).unwrap();
    assert!(r.warnings[0].contains("phong") && r.warnings[0].contains("beckmann used"), "{:?}", r.warnings);
    let e = message(read(body, &[], true));
    assert!(e.contains("line 3") && e.contains("hair") && e.contains("--strict"), "{e}");
    let r = read("<shape type=\"serialized\"/><emitter type=\"projector\"/>", &[], false).unwrap();
    assert_eq!(r.warnings.len(), 2);
}

#[test]
fn malformed_files_are_one_error() {
    for (body, want) in [
        ("<shape type=\"cube\">", "line"),
        ("<float name=\"x\" value=\"1e999\"/>", "not finite"),
        ("<rgb name=\"x\" value=\"1, 2\"/>", "1 or 3 numbers"),
        ("<shape type=\"cube\"><transform name=\"to_world\"><rotate angle=\"3\"/></transform></shape>", "axis"),
        ("<shape type=\"cube\"><transform name=\"to_world\"><matrix value=\"1 2 3\"/></transform></shape>", "16"),
        ("<boolean name=\"b\" value=\"yes\"/>", "true nor false"),
        ("<sensor type=\"orthographic\"/>", "perspective"),
        (
            "<sensor type=\"perspective\"><sampler type=\"independent\"><integer name=\"sample_count\" value=\"5000000000\"/></sampler></sensor>",
            "1..=4294967295",
        ),
    ] {
        let e = message(read(body, &[], false));
        assert!(e.contains(want), "{body}: {e}");
    }
    let deep = "<bsdf type=\"diffuse\">".repeat(100) + &"</bsdf>".repeat(100);
    assert!(message(read(&deep, &[], false)).contains("nest"));
}

#[test]
fn references_resolve_after_the_whole_scene_is_read() {
    // Mitsuba's own cbox-rgb.xml: shapes in one include name BSDFs of another and an area
    // emitter defined after both.
    let dir = std::env::temp_dir().join(format!("zvidpt-mitsuba-forward-{}", std::process::id()));
    // Files named in an included file are found from the main file's folder, as
    // Mitsuba's file resolver finds them (cbox's fragments/shapes.xml names meshes/…).
    std::fs::create_dir_all(dir.join("fragments")).unwrap();
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::write(dir.join("meshes/tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let scene = |body: &str| format!("<scene version=\"3.0.0\">{body}</scene>");
    let mesh = "<string name=\"filename\" value=\"meshes/tri.obj\"/>";
    let shapes = format!("<shape type=\"obj\">{mesh}<ref id=\"white\"/><ref id=\"area-emitter\"/></shape>");
    std::fs::write(dir.join("fragments/shapes.xml"), scene(&shapes)).unwrap();
    let white = "<bsdf type=\"diffuse\" id=\"white\"><rgb name=\"reflectance\" value=\"0.2, 0.4, 0.6\"/></bsdf>";
    std::fs::write(dir.join("fragments/bsdfs.xml"), scene(white)).unwrap();
    let main = scene(
        "<include filename=\"fragments/shapes.xml\"/><include filename=\"fragments/bsdfs.xml\"/>\
         <emitter type=\"area\" id=\"area-emitter\"><rgb name=\"radiance\" value=\"3, 2, 1\"/></emitter>",
    );
    let r = import(&dir.join("main.xml"), &main, &ImportOptions { defines: Vec::new(), strict: true }).unwrap();
    let d = r.description;
    assert_eq!(d.meshes.len(), 1);
    assert_eq!(d.meshes[0].obj.as_deref().map(Path::new), Some(dir.join("meshes/tri.obj").as_path()));
    let m = &d.materials[d.meshes[0].material.as_ref().unwrap()];
    assert_eq!(m.diffuse, [0.2, 0.4, 0.6]);
    assert_eq!(m.emission, [3.0, 2.0, 1.0]);
    // An instance before its shapegroup; a nested object's id; an id given twice.
    let d = ok("<shape type=\"instance\"><ref id=\"g\"/></shape>\
         <shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\"><bsdf type=\"conductor\" id=\"metal\"/></shape></shape>\
         <shape type=\"cube\"><ref id=\"metal\"/></shape>");
    assert_eq!(d.shapes.len(), 2, "the instance's sphere and the cube; the group itself is not rendered");
    let e = message(read("<bsdf type=\"diffuse\" id=\"a\"/><bsdf type=\"conductor\" id=\"a\"/>", &[], false));
    assert!(e.contains("given twice") && e.contains("line"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn includes_and_their_cycles() {
    let dir = std::env::temp_dir().join(format!("zvidpt-mitsuba-include-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::write(dir.join("sub/part.xml"), "<scene version=\"3.0.0\"><shape type=\"sphere\"/></scene>").unwrap();
    std::fs::write(dir.join("loop.xml"), "<scene version=\"3.0.0\"><include filename=\"loop.xml\"/></scene>").unwrap();
    let main = dir.join("main.xml");
    let text = "<scene version=\"3.0.0\"><include filename=\"sub/part.xml\"/></scene>";
    let r = import(&main, text, &ImportOptions::default()).unwrap();
    assert_eq!(r.description.shapes.len(), 1);
    assert!(r.sources.contains(&dir.join("sub/part.xml")));
    let text = "<scene version=\"3.0.0\"><include filename=\"loop.xml\"/></scene>";
    let e = message(import(&main, text, &ImportOptions::default()));
    assert!(e.contains("deeper"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn emitters_and_render_settings() {
    let d = ok("<shape type=\"rectangle\"><emitter type=\"area\"><rgb name=\"radiance\" value=\"3\"/></emitter></shape>
        <emitter type=\"point\"><point name=\"position\" value=\"1, 2, 3\"/><rgb name=\"intensity\" value=\"5\"/></emitter>
        <emitter type=\"spot\"><transform name=\"to_world\"><lookat origin=\"0, 4, 0\" target=\"0, 0, 0\" up=\"0, 0, 1\"/></transform>
            <float name=\"cutoff_angle\" value=\"30\"/></emitter>
        <emitter type=\"constant\"><spectrum name=\"radiance\" value=\"0.5\"/></emitter>
        <emitter type=\"directional\"><vector name=\"direction\" value=\"0, -2, 0\"/><rgb name=\"irradiance\" value=\"2\"/></emitter>
        <integrator type=\"path\"><integer name=\"max_depth\" value=\"4\"/></integrator>
        <sensor type=\"perspective\"><sampler type=\"independent\"><integer name=\"sample_count\" value=\"9\"/></sampler></sensor>");
    assert_eq!(d.materials[&d.shapes[0].material].emission, [3.0; 3]);
    assert_eq!((d.lights[0].position, d.lights[0].intensity), (Some([1.0, 2.0, 3.0]), Some([5.0; 3])));
    let spot = &d.lights[1];
    assert_eq!(
        (spot.kind, spot.position, spot.cutoff, spot.beam),
        (LightKind::Spot, Some([0.0, 4.0, 0.0]), Some(30.0), Some(22.5))
    );
    assert!((spot.direction.unwrap()[1] + 1.0).abs() < 1e-6);
    assert_eq!(d.environment.as_ref().unwrap().radiance, Some([0.5; 3]));
    let sun = &d.lights[2];
    assert_eq!((sun.kind, sun.direction, sun.irradiance), (LightKind::Distant, Some([0.0, -2.0, 0.0]), Some([2.0; 3])));
    let r = d.render.unwrap();
    assert_eq!((r.spp, r.max_depth), (Some(9), Some(4)));
}

/// Media: a nested medium in the sensor, a shared one by reference (translated once), the
/// `null` boundary; a heterogeneous medium is warned about and leaves vacuum.
#[test]
fn media_nest_and_are_shared() {
    let body = "<medium type=\"homogeneous\" id=\"m\"><float name=\"sigma_t\" value=\"2\"/></medium>
        <sensor type=\"perspective\"><medium type=\"homogeneous\"><rgb name=\"albedo\" value=\"0.5, 0.5, 0.5\"/></medium></sensor>
        <shape type=\"sphere\"><bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>
        <shape type=\"cube\"><ref name=\"exterior\" id=\"m\"/></shape>";
    let d = ok(body);
    assert_eq!(d.media.len(), 2, "the shared medium once, the sensor's own");
    let shared = d.materials.values().filter_map(|m| m.interior_medium.clone().or(m.exterior_medium.clone()));
    let names: std::collections::BTreeSet<String> = shared.collect();
    assert_eq!(names.len(), 1);
    let m = &d.media[names.first().unwrap()];
    // Mitsuba's default albedo 0.75: σs = 0.75·σt, σa = 0.25·σt.
    assert_eq!((m.sigma_s, m.sigma_a), ([1.5; 3], [0.5; 3]));
    let camera = d.camera.medium.as_ref().expect("the sensor's medium");
    assert_eq!((d.media[camera].sigma_s, d.media[camera].sigma_a), ([0.5; 3], [0.5; 3]));
    assert!(d.materials.values().any(|m| m.kind == MaterialKind::Interface));
    let grid = "<shape type=\"cube\"><medium type=\"heterogeneous\" name=\"interior\"/></shape>";
    let r = read(grid, &[], false).unwrap();
    assert!(r.description.media.is_empty() && r.description.materials.values().all(|m| m.interior_medium.is_none()));
    assert!(r.warnings.iter().any(|w| w.contains("heterogeneous")), "{:?}", r.warnings);
}

/// Defaults that name defaults cannot expand without bound: 40 levels of doubling are refused
/// once a value would pass 16 MiB (they hung, growing towards terabytes).
#[test]
fn defaults_cannot_expand_without_bound() {
    let mut body = String::from("<default name=\"a0\" value=\"xxxxxxxxxxxxxxxx\"/>\n");
    for i in 1..40 {
        body.push_str(&format!("<default name=\"a{i}\" value=\"$a{}$a{}\"/>\n", i - 1, i - 1));
    }
    body.push_str("<shape type=\"sphere\"><float name=\"radius\" value=\"$a39\"/></shape>");
    assert!(message(read(&body, &[], true)).contains("longer than"));
}

//! pbrt-v4 scenes, read into the same description a TOML scene file gives.
//!
//! A tokenizer of our own (`tokens.rs`: the `pbrt4` crate panics on `Import` and does not load
//! PLY), then the directives in order, each group in its own file: `state.rs` pbrt's graphics
//! state (the current transform with named coordinate systems, `AttributeBegin`/`End`,
//! `ReverseOrientation`, the current material and area light), `options.rs` camera, film,
//! sampler, integrator and pixel filter, `materials.rs` materials and textures, `lights.rs`,
//! `shapes.rs` shapes, curves, objects and instances; this file holds the parser's state,
//! includes and the dispatch. Each shape gets the material it was declared with (made emitting
//! by the area light in force). Files named in the scene are relative to the main scene
//! file's folder, as in pbrt.
//!
//! Outside the subset: one warning naming the directive, its file and line, and the fallback
//! (`strict`: an error).
use super::super::description::{MaterialDescription, PixelFilterDescription, PixelFilterKind, SceneDescription};
use super::{At, ImportOptions, Imported, Includes, Mark, Prototype, empty_description, syntax, unsupported};
use crate::error::Result;
use glam::DMat4;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use tokens::{Cursor, Params, Token, describe, tokenize};

mod lights;
mod materials;
mod media;
mod options;
mod shapes;
mod state;
mod tokens;

use state::State;

/// A colour-valued parameter: a constant, or a texture's name.
enum Colour {
    Constant([f32; 3]),
    Texture(String),
}

struct Parser<'o> {
    options: &'o ImportOptions,
    /// The main scene file's folder: every file is relative to it.
    folder: PathBuf,
    warnings: Vec<String>,
    /// The include guard, with every file read (the scene's sources).
    includes: Includes,
    state: State,
    /// Saved states of the open `AttributeBegin`s, with where each began.
    stack: Vec<(State, At)>,
    named_frames: HashMap<String, DMat4>,
    /// Named materials' names in the description (`MakeNamedMaterial` → `named:NAME`).
    named_materials: HashMap<String, String>,
    /// Textures by name: float and spectrum textures share pbrt's namespace per class.
    textures: HashMap<(bool, String), String>,
    out: SceneDescription,
    count: usize,
    /// (material, area light) → the emitting material made for them.
    emitting: HashMap<String, String>,
    camera_seen: bool,
    /// Past `WorldBegin`.
    in_world: bool,
    film: (i64, i64, Option<[f64; 4]>),
    camera: Option<(DMat4, f64, At)>,
    /// Objects (`ObjectBegin`) by name, and the one being defined with where it began.
    objects: HashMap<String, Prototype>,
    defining: Option<(String, Mark, At)>,
    /// `ObjectInstance`s: the object's name and the transform then.
    instances: Vec<(String, DMat4, At)>,
    /// The pixel filter (pbrt-v4's default: a Gaussian of σ 0.5, radius 1.5).
    filter: PixelFilterDescription,
    /// Curves tessellated so far, one mesh per material (a hair file holds thousands of
    /// one-curve directives), with where the first was written; and whether flat curves
    /// were warned about.
    curves: Vec<(String, crate::scene::mesh::curves::CurveMesh, String)>,
    warned_flat_curves: bool,
    /// Media by pbrt name: the description's name, or `None` where vacuum stands in.
    media: HashMap<String, Option<String>>,
    /// The medium the camera was declared in (the outside of the `MediumInterface` then).
    camera_medium: Option<String>,
    /// (material, inside, outside) → the material made for shapes between those media.
    bounding: HashMap<(String, [Option<String>; 2]), String>,
}

/// Reads the pbrt-v4 scene at `path` (text `text`).
pub(crate) fn import(path: &Path, text: &str, options: &ImportOptions) -> Result<Imported> {
    let folder = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let folder = std::path::absolute(&folder).unwrap_or(folder);
    let mut out = empty_description();
    // pbrt's default material: diffuse, reflectance 0.5.
    out.materials.insert("default".into(), MaterialDescription { diffuse: [0.5; 3], ..MaterialDescription::default() });
    let mut p = Parser {
        options,
        folder,
        warnings: Vec::new(),
        includes: Includes::new(path),
        state: State {
            ctm: DMat4::IDENTITY,
            reverse: false,
            material: "default".into(),
            area_light: None,
            media: [None, None],
        },
        stack: Vec::new(),
        named_frames: HashMap::new(),
        named_materials: HashMap::new(),
        textures: HashMap::new(),
        out,
        count: 0,
        emitting: HashMap::new(),
        camera_seen: false,
        in_world: false,
        film: (1280, 720, None),
        camera: None,
        objects: HashMap::new(),
        defining: None,
        instances: Vec::new(),
        filter: PixelFilterDescription { kind: PixelFilterKind::Gaussian, stddev: Some(0.5), radius: Some([1.5; 2]) },
        curves: Vec::new(),
        warned_flat_curves: false,
        media: HashMap::new(),
        camera_medium: None,
        bounding: HashMap::new(),
    };
    p.file(path, text)?;
    p.finish()?;
    Ok(Imported { description: p.out, warnings: p.warnings, sources: p.includes.files })
}

impl Parser<'_> {
    fn unsupported(&mut self, at: &At, message: String) -> Result<()> {
        unsupported(self.options.strict, &mut self.warnings, at, message)
    }

    fn check_unused(&mut self, what: &str, params: &Params, at: &At) -> Result<()> {
        let unused = params.unused();
        if unused.is_empty() {
            return Ok(());
        }
        self.unsupported(at, format!("{what}: {} not supported: ignored", unused.join(", ")))
    }

    fn fresh(&mut self, prefix: &str) -> String {
        self.count += 1;
        format!("{prefix}{}", self.count)
    }

    fn resolve(&self, name: &str) -> PathBuf {
        self.folder.join(name)
    }

    fn file(&mut self, path: &Path, text: &str) -> Result<()> {
        let file = Rc::new(path.to_path_buf());
        let tokens = tokenize(text, &file)?;
        let mut c = Cursor { tokens: &tokens, i: 0, file };
        while let Some(t) = c.next() {
            let at = At { file: c.file.clone(), line: c.tokens[c.i - 1].1 };
            let Token::Word(directive) = t else {
                return Err(syntax(&at, format!("expected a directive, found {}", describe(Some(&t)))));
            };
            self.directive(&directive, &mut c, &at)?;
        }
        Ok(())
    }

    fn directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<()> {
        let known = self.state_directive(d, c, at)?
            || self.include_directive(d, c, at)?
            || self.option_directive(d, c, at)?
            || self.material_directive(d, c, at)?
            || self.light_directive(d, c, at)?
            || self.shape_directive(d, c, at)?
            || self.object_directive(d, c, at)?
            || self.medium_directive(d, c, at)?
            || self.unsupported_directive(d, c, at)?;
        if known { Ok(()) } else { Err(syntax(at, format!("unknown directive {d}"))) }
    }

    /// `Include` and `Import`: the named file read in place.
    fn include_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "Include" | "Import" => {
                let name = c.text(d)?;
                let path = self.resolve(&name);
                let text = self.includes.enter(&name, &path, at)?;
                self.file(&path, &text)?;
                self.includes.leave();
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Default attributes: warned about and skipped.
    fn unsupported_directive(&mut self, d: &str, c: &mut Cursor, at: &At) -> Result<bool> {
        match d {
            "Attribute" => {
                let _ = c.text(d)?;
                let _ = c.params()?;
                self.unsupported(at, "Attribute: default parameters are not supported: ignored".into())?;
            }
            _ => return Ok(false),
        }
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::description::{LightKind, MaterialKind};
    use glam::Vec3A;

    fn read(text: &str, strict: bool) -> Result<Imported> {
        import(Path::new("/nowhere/scene.pbrt"), text, &ImportOptions { defines: Vec::new(), strict })
    }

    fn ok(text: &str) -> SceneDescription {
        read(text, true).unwrap().description
    }

    fn message(r: Result<Imported>) -> String {
        match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("expected an error"),
        }
    }

    #[test]
    fn tokens_comments_and_strings() {
        let file = Rc::new(PathBuf::from("x.pbrt"));
        let t =
            tokenize("Shape \"sphere\" # a comment \"ignored\"\n \"float radius\" [ 2.5e0 ] true\n", &file).unwrap();
        let kinds: Vec<&Token> = t.iter().map(|(t, _)| t).collect();
        assert_eq!(
            kinds,
            [
                &Token::Word("Shape".into()),
                &Token::Text("sphere".into()),
                &Token::Text("float radius".into()),
                &Token::Open,
                &Token::Number(2.5),
                &Token::Close,
                &Token::Word("true".into())
            ]
        );
        assert_eq!(t[2].1, 2, "lines are counted");
        assert!(message_of(tokenize("\"open", &file)).contains("unterminated"));
        assert!(message_of(tokenize("1e999", &file)).contains("not finite"));
    }

    fn message_of<T>(r: Result<T>) -> String {
        match r {
            Err(e) => e.to_string(),
            Ok(_) => panic!("expected an error"),
        }
    }

    /// Transforms compose as pbrt's do (each new one applied first to points), and
    /// AttributeBegin/End restore them; named coordinate systems.
    /// Instances are their object's shapes placed by the instance's transform after the
    /// definition's: the same triangles (to f32 rounding) as the shapes written out in place,
    /// mirrored instances included; an instance may come before its definition.
    #[test]
    fn objects_and_instances() {
        let object = "Translate 0 0 1
                Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]
                Shape \"trianglemesh\" \"point3 P\" [0 0 0 0 1 0 1 0 0] \"normal N\" [0 0 1 0 0 1 0 0 1]
                Shape \"sphere\" \"float radius\" 0.25";
        let placements = ["Translate 5 0 0", "Rotate 30 0 1 0", "Scale -1 1 1"];
        let instanced = format!(
            "WorldBegin
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd
            ObjectBegin \"thing\" {object} ObjectEnd
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd
            AttributeBegin {} ObjectInstance \"thing\" AttributeEnd",
            placements[0], placements[1], placements[2]
        );
        let direct: String = std::iter::once("WorldBegin".to_string())
            .chain(placements.iter().map(|p| format!("AttributeBegin {p} {object} AttributeEnd")))
            .collect::<Vec<_>>()
            .join("\n");
        let triangles = |text: &str| {
            let scene =
                crate::scene::Scene::parse_pbrt(text, Path::new("/nowhere/s.pbrt"), &ImportOptions::default()).unwrap();
            let mut t: Vec<([f32; 9], [f32; 3])> = scene
                .triangles
                .iter()
                .enumerate()
                .map(|(i, t)| {
                    let n = scene.attributes.normals.get(i).map_or([0.0; 3], |c| c[0].to_array());
                    (t.map(|p| p.to_array()).concat().try_into().unwrap(), n)
                })
                .collect();
            t.sort_by(|a, b| {
                a.0.iter()
                    .zip(&b.0)
                    .map(|(x, y)| x.total_cmp(y))
                    .find(|o| o.is_ne())
                    .unwrap_or(std::cmp::Ordering::Equal)
            });
            t
        };
        let (a, b) = (triangles(&instanced), triangles(&direct));
        assert_eq!(a.len(), b.len());
        assert!(a.len() > 3 * 2 + 3 * 1000, "the spheres too: {}", a.len());
        for (x, y) in a.iter().zip(&b) {
            let far = x.0.iter().zip(&y.0).chain(x.1.iter().zip(&y.1)).any(|(p, q)| (p - q).abs() > 1e-5);
            assert!(!far, "{x:?} vs {y:?}");
        }
        // Without instances, an object's shapes are not in the scene.
        let d = ok("WorldBegin ObjectBegin \"a\" Shape \"sphere\" ObjectEnd Shape \"disk\"");
        assert_eq!(d.shapes.len(), 1);
        // Mistakes.
        for (text, want) in [
            ("WorldBegin ObjectBegin \"a\" ObjectBegin \"b\"", "inside the definition of \"a\""),
            ("WorldBegin ObjectEnd", "ObjectEnd without an ObjectBegin"),
            ("WorldBegin ObjectBegin \"a\" Shape \"sphere\"", "without an ObjectEnd"),
            ("WorldBegin ObjectBegin \"a\" ObjectInstance \"a\" ObjectEnd", "inside an object's definition"),
            ("WorldBegin Shape \"sphere\" ObjectInstance \"nope\"", "no such object"),
        ] {
            assert!(message(read(text, true)).contains(want), "{text}: {}", message(read(text, true)));
        }
        // Area lights in an object do not emit (as in pbrt-v4), with a warning.
        let r = read(
            "WorldBegin ObjectBegin \"lamp\" AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] Shape \"sphere\" ObjectEnd
             ObjectInstance \"lamp\"",
            false,
        )
        .unwrap();
        assert!(r.warnings.iter().any(|w| w.contains("instances do not emit")), "{:?}", r.warnings);
        assert!(r.description.materials.values().all(|m| m.emission == [0.0; 3]));
    }

    #[test]
    fn transforms_and_attributes() {
        let d = ok("WorldBegin
            AttributeBegin Translate 1 0 0 Scale 2 2 2 Shape \"sphere\" AttributeEnd
            Shape \"sphere\"
            Translate 0 5 0 CoordinateSystem \"up\" Identity CoordSysTransform \"up\" Shape \"sphere\"
            Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  7 8 9 1 ] Shape \"sphere\"");
        let m: Vec<[[f32; 4]; 4]> = d.shapes.iter().map(|s| s.matrix.unwrap()).collect();
        assert_eq!((m[0][0][0], m[0][0][3]), (2.0, 1.0), "x ↦ 2x + 1");
        assert_eq!(m[1][0], [1.0, 0.0, 0.0, 0.0], "restored");
        assert_eq!(m[2][1][3], 5.0);
        assert_eq!((m[3][0][3], m[3][1][3], m[3][2][3]), (7.0, 8.0, 9.0), "Transform's numbers are columns");
        assert!(message(read("AttributeEnd", false)).contains("without a matching begin"));
    }

    #[test]
    fn camera_film_sampler_integrator() {
        let d = ok("LookAt 0 0 5  0 0 0  0 1 0
            Camera \"perspective\" \"float fov\" 60
            Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" 400 \"float cropwindow\" [ 0.25 0.75 0 0.5 ]
            Sampler \"halton\" \"integer pixelsamples\" 32
            Integrator \"volpath\" \"integer maxdepth\" 3
            WorldBegin");
        let c = &d.camera;
        assert_eq!((c.width, c.height, c.eye), (200, 400, [0.0, 0.0, 5.0]));
        // 60° across the shorter side (the width): tan(fov_y/2) = tan 30° · 400/200.
        let want = (2.0 * (30f64.to_radians().tan() * 2.0).atan()).to_degrees();
        assert!((f64::from(c.fov_y) - want).abs() < 1e-4, "{} vs {want}", c.fov_y);
        assert!(c.mirror, "pbrt's LookAt leaves a left-handed image");
        assert_eq!(c.crop, Some([50, 0, 100, 200]));
        let r = d.render.unwrap();
        assert_eq!((r.spp, r.max_depth), (Some(32), Some(4)));
        let d = ok("WorldBegin");
        assert_eq!((d.camera.width, d.camera.height, d.camera.fov_y), (1280, 720, 90.0), "pbrt's defaults");
    }

    /// Materials we approximate: mix by its likelier material, coatedconductor by its
    /// conductor, diffusetransmission by its reflection; each with a warning.
    #[test]
    fn approximated_materials() {
        let r = read(
            "WorldBegin
            MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]
            MakeNamedMaterial \"b\" \"string type\" \"dielectric\"
            MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [\"a\" \"b\"] \"float amount\" 0.25
            NamedMaterial \"m\" Shape \"sphere\"
            Material \"coatedconductor\" \"spectrum conductor.eta\" \"metal-Au-eta\" \"spectrum conductor.k\" \"metal-Au-k\"
                \"float conductor.roughness\" 0.04 \"float interface.roughness\" 0
            Shape \"sphere\"
            Material \"diffusetransmission\" \"rgb reflectance\" [0.4 0.4 0.4] \"rgb transmittance\" [0.5 0.5 0.5]
            Shape \"sphere\"",
            false,
        )
        .unwrap();
        let d = &r.description;
        let m = |i: usize| &d.materials[&d.shapes[i].material];
        assert_eq!((m(0).kind, m(0).diffuse), (MaterialKind::Diffuse, [0.1, 0.2, 0.3]), "amount 0.25: the first");
        assert_eq!(
            (m(1).kind, m(1).metal.as_deref(), m(1).roughness),
            (MaterialKind::Conductor, Some("Au"), Some(0.2))
        );
        assert_eq!((m(2).kind, m(2).diffuse), (MaterialKind::Diffuse, [0.4; 3]));
        assert_eq!(r.warnings.len(), 3, "{:?}", r.warnings);
        let e = message(read("WorldBegin Material \"mix\" \"string materials\" [\"x\" \"y\"]", false));
        assert!(e.contains("no named material \"x\""), "{e}");
    }

    #[test]
    fn pixel_filters() {
        let filter = |f: &str| ok(&format!("{f} WorldBegin Shape \"sphere\"")).camera.filter.unwrap();
        let gaussian = |s: f32, r: f32| PixelFilterDescription {
            kind: PixelFilterKind::Gaussian,
            stddev: Some(s),
            radius: Some([r; 2]),
        };
        assert_eq!(filter(""), gaussian(0.5, 1.5), "pbrt-v4's default");
        assert_eq!(
            filter("PixelFilter \"gaussian\" \"float sigma\" 0.25 \"float xradius\" 1 \"float yradius\" 1"),
            gaussian(0.25, 1.0)
        );
        let f = filter("PixelFilter \"box\"");
        assert_eq!((f.kind, f.radius), (PixelFilterKind::Box, Some([0.5; 2])));
        let f = filter("PixelFilter \"triangle\" \"float yradius\" 1");
        assert_eq!((f.kind, f.radius), (PixelFilterKind::Tent, Some([2.0, 1.0])));
        let r = read("PixelFilter \"mitchell\" \"float B\" 0.3 WorldBegin Shape \"sphere\"", false).unwrap();
        assert_eq!(r.description.camera.filter, Some(gaussian(0.5, 1.5)));
        assert!(r.warnings[0].contains("mitchell"), "{:?}", r.warnings);
    }

    #[test]
    fn scaled_and_inverted_textures() {
        let d = ok("WorldBegin
            Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"a.png\" \"float scale\" 0.5 \"bool invert\" true
            Texture \"plain\" \"spectrum\" \"imagemap\" \"string filename\" \"b.png\"
            Texture \"dim\" \"spectrum\" \"scale\" \"texture tex\" \"plain\" \"rgb scale\" [0.25 0.5 1]
            Texture \"dimmer\" \"spectrum\" \"scale\" \"float tex\" 0.5 \"texture scale\" \"dim\"
            Texture \"grey\" \"spectrum\" \"scale\" \"rgb tex\" [0.2 0.4 0.6] \"float scale\" 0.5
            Texture \"r\" \"float\" \"imagemap\" \"string filename\" \"r.png\"
            Texture \"r2\" \"float\" \"scale\" \"texture tex\" \"r\" \"float scale\" 2");
        let t = |file: &str, factor: Option<[f32; 3]>| {
            d.textures.values().any(|t| t.file.as_deref().is_some_and(|f| f.ends_with(file)) && t.factor == factor)
        };
        assert!(d.textures.values().any(|t| t.factor == Some([0.5; 3]) && t.invert == Some(true)));
        assert!(t("b.png", None) && t("b.png", Some([0.25, 0.5, 1.0])) && t("b.png", Some([0.125, 0.25, 0.5])));
        assert!(t("r.png", Some([2.0; 3])), "a float texture scaled");
        assert!(d.textures.values().any(|t| t.color0 == Some([0.1, 0.2, 0.3])), "constants fold");
        let e = message(read("WorldBegin Texture \"s\" \"float\" \"scale\" \"texture tex\" \"nope\"", false));
        assert!(e.contains("no such texture \"nope\""), "{e}");
    }

    /// Curves become triangles (one mesh per material however many directives), placed by
    /// the transform with their width scaled; hair is a diffuse colour from its melanin.
    #[test]
    fn curves_and_hair() {
        let r = read(
            "WorldBegin
            MakeNamedMaterial \"h\" \"string type\" \"hair\" \"float eumelanin\" 0.2
            NamedMaterial \"h\"
            Translate 0 0 5
            Scale 2 2 2
            Shape \"curve\" \"string type\" \"cylinder\" \"string basis\" \"bspline\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3 0 0 4] \"float width\" 0.1
            Shape \"curve\" \"point3 P\" [1 0 0 1 0 1 1 0 2 1 0 3] \"float width0\" 0.1 \"float width1\" 0
            Material \"diffuse\"
            Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [2 0 0 2 0 1 2 0 2 2 0 3] \"normal N\" [1 0 0 1 0 0]",
            false,
        )
        .unwrap();
        let d = &r.description;
        assert_eq!(d.inline_meshes.len(), 2, "one mesh per material");
        let hair = &d.inline_meshes[0];
        assert!(!hair.indices.is_empty() && hair.indices.len().is_multiple_of(3));
        for p in &hair.positions {
            // Placed: z from 5 to 13, x near 0 (first curve) or 2 (second), radius ≤ 0.1.
            assert!(p[2] >= 4.9 && p[2] <= 13.1, "{p:?}");
            assert!(p[0].abs() <= 0.11 || (p[0] - 2.0).abs() <= 0.11, "{p:?}");
        }
        let colour = d.materials[&hair.material].diffuse;
        // Eumelanin 0.2: σa = 0.2 × (0.419, 0.697, 1.37); at βn 0.3, c = exp(−√σa · 5.888).
        for (c, eu) in colour.iter().zip([0.419f64, 0.697, 1.37]) {
            let want = (-(0.2 * eu).sqrt() * 5.888_29).exp() as f32;
            assert!((c - want).abs() < 1e-4, "{colour:?}");
        }
        assert!(r.warnings.iter().any(|w| w.contains("hair")) && r.warnings.iter().any(|w| w.contains("flat curves")));
        assert_eq!(r.warnings.iter().filter(|w| w.contains("flat curves")).count(), 1);
        for (body, want) in [
            ("Shape \"curve\" \"string basis\" \"catmull\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "basis"),
            ("Shape \"curve\" \"point3 P\" [0 0 0 0 0 1 0 0 2]", "control points"),
            ("Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "normal"),
            ("Shape \"curve\" \"integer degree\" 5 \"point3 P\" [0 0 0 0 0 1 0 0 2 0 0 3]", "degree"),
        ] {
            let e = message(read(&format!("WorldBegin {body}"), false));
            assert!(e.contains(want), "{body}: {e}");
        }
    }

    #[test]
    fn materials_textures_and_area_lights() {
        let d = ok("WorldBegin
            Texture \"t\" \"float\" \"imagemap\" \"string filename\" \"r.png\"
            MakeNamedMaterial \"m\" \"string type\" \"conductor\" \"spectrum eta\" \"metal-Ag-eta\" \"spectrum k\" \"metal-Ag-k\"
                \"texture roughness\" \"t\" \"bool remaproughness\" false
            NamedMaterial \"m\"
            Shape \"sphere\"
            AttributeBegin
              AreaLightSource \"diffuse\" \"rgb L\" [ 1 2 3 ] \"float scale\" 2 \"bool twosided\" true
              Material \"dielectric\" \"spectrum eta\" \"glass-BK7\" \"float roughness\" 0.01
              Shape \"disk\"
            AttributeEnd
            Shape \"disk\"");
        let m = |i: usize| &d.materials[&d.shapes[i].material];
        assert_eq!((m(0).kind, m(0).metal.as_deref()), (MaterialKind::Conductor, Some("Ag")));
        assert!(m(0).roughness_texture.is_some());
        assert_eq!((m(1).kind, m(1).ior, m(1).roughness), (MaterialKind::Dielectric, Some(1.5168), Some(0.1)));
        assert_eq!((m(1).emission, m(1).two_sided_emission), ([2.0, 4.0, 6.0], true));
        assert_eq!(m(2).emission, [0.0; 3], "the area light ends with its attribute block");
        assert!(d.textures.values().next().unwrap().file.as_deref().unwrap().ends_with("r.png"));
    }

    #[test]
    fn lights() {
        let d = ok("WorldBegin
            Translate 0 1 0
            LightSource \"point\" \"rgb I\" [ 1 2 3 ] \"float scale\" 2
            LightSource \"spot\" \"point3 from\" [ 0 0 0 ] \"point3 to\" [ 0 -1 0 ] \"float coneangle\" 40 \"float conedelta\" 10
            LightSource \"distant\" \"point3 from\" [ 0 1 0 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]
            LightSource \"infinite\" \"spectrum L\" [ 400 1 700 1 ]");
        let l = &d.lights;
        assert_eq!(
            (l[0].kind, l[0].position, l[0].intensity),
            (LightKind::Point, Some([0.0, 1.0, 0.0]), Some([2.0, 4.0, 6.0]))
        );
        assert_eq!(
            (l[1].kind, l[1].direction, l[1].cutoff, l[1].beam),
            (LightKind::Spot, Some([0.0, -1.0, 0.0]), Some(40.0), Some(30.0))
        );
        assert_eq!(
            (l[2].kind, l[2].direction, l[2].irradiance),
            (LightKind::Distant, Some([0.0, -1.0, 0.0]), Some([3.0; 3]))
        );
        // A light's spectrum is normalised to luminance 1.
        let env = d.environment.unwrap().radiance.unwrap();
        let y = 0.2126 * env[0] + 0.7152 * env[1] + 0.0722 * env[2];
        assert!((y - 1.0).abs() < 1e-4, "{env:?}");
    }

    #[test]
    fn unsupported_warns_or_fails() {
        let text = "WorldBegin\nShape \"sphere\" \"float zmax\" 0.5\nLightSource \"goniometric\" \"rgb I\" [1 1 1]\nMaterial \"measured\"\nShape \"cylinder\"\n";
        let r = read(text, false).unwrap();
        assert_eq!(r.warnings.len(), 4, "{:?}", r.warnings);
        assert!(r.warnings[0].starts_with("/nowhere/scene.pbrt:2:") && r.warnings[0].contains("partial"));
        assert!(r.warnings[1].contains("goniometric") && r.warnings[2].contains("grey diffuse"));
        let e = message(read(text, true));
        assert!(e.contains("line 2") && e.contains("--strict"), "{e}");
        let r = read("WorldBegin Shape \"sphere\" \"float radius\" 2 \"float nonsense\" 3", false).unwrap();
        assert!(r.warnings[0].contains("nonsense"), "{:?}", r.warnings);
    }

    #[test]
    fn malformed_files_are_one_error() {
        for (text, want) in [
            ("Translate 1 2", "expected a number"),
            ("Bogus 1", "unknown directive"),
            ("WorldBegin Shape \"sphere\" \"float radius\" [ 1 ", "expected a value"),
            ("WorldBegin Shape \"sphere\" \"floaty radius\" 1", "unknown parameter type"),
            (
                "WorldBegin Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 5]",
                "out of range",
            ),
            ("WorldBegin NamedMaterial \"nope\"", "no such material"),
            ("Rotate 10 0 0 0", "axis"),
            ("WorldBegin Camera \"perspective\"", "after WorldBegin"),
            ("WorldBegin Film \"rgb\"", "after WorldBegin"),
            ("WorldBegin WorldBegin", "second WorldBegin"),
            ("Sampler \"independent\" \"integer pixelsamples\" 5000000000", "1..=4294967295"),
            ("WorldBegin AttributeBegin Shape \"sphere\"", "not closed"),
            ("Camera \"orthographic\"", "perspective"),
        ] {
            let e = message(read(text, false));
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    /// pbrt-v4's equal-area map: the poles at the centre and the corners, the equator on the
    /// diamond, and every direction inside the square.
    #[test]
    fn equal_area_square() {
        use crate::geometry::warp::equal_area_sphere_to_square as f;
        assert!((f(Vec3A::Z) - glam::Vec2::splat(0.5)).length() < 1e-6);
        let south = f(-Vec3A::Z);
        assert!([south.x, south.y].iter().all(|c| *c == 0.0 || *c == 1.0), "the south pole at a corner: {south}");
        assert!((f(Vec3A::X) - glam::Vec2::new(1.0, 0.5)).length() < 1e-6);
        for k in 0..100 {
            let d = Vec3A::new((k as f32 * 0.7).sin(), (k as f32 * 1.3).cos(), (k as f32 * 0.37).sin()).normalize();
            let uv = f(d);
            assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
        }
    }

    /// Media: a homogeneous medium's coefficients (times `scale`), the camera in the outside
    /// medium of the `MediumInterface` in force, shapes between different media given a
    /// material that names them, `interface` surfaces, and media we do not render (a grid)
    /// warned about and left as vacuum.
    #[test]
    fn media_and_their_boundaries() {
        let text = "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.1 0.2 0.3] \
                    \"rgb sigma_s\" [1 2 3] \"float scale\" 2 \"float g\" 0.5\n\
                    MediumInterface \"\" \"fog\"\nCamera \"perspective\"\nWorldBegin\n\
                    AttributeBegin MediumInterface \"fog\" \"\" Material \"interface\"\n\
                    Shape \"sphere\" \"float radius\" 1 AttributeEnd\n\
                    Shape \"sphere\" \"float radius\" 3\n";
        let d = ok(text);
        let fog = &d.media["medium:fog"];
        assert_eq!(
            (fog.sigma_a, fog.sigma_s, fog.scale, fog.g),
            ([0.1, 0.2, 0.3], [1.0, 2.0, 3.0], Some(2.0), Some(0.5))
        );
        assert_eq!(d.camera.medium.as_deref(), Some("medium:fog"));
        let bounding: Vec<_> = d.materials.values().filter(|m| m.interior_medium.is_some()).collect();
        assert_eq!(bounding.len(), 1);
        assert_eq!((bounding[0].kind, bounding[0].exterior_medium.as_deref()), (MaterialKind::Interface, None));
        // The outer sphere, after the block: the interface set before the camera holds again.
        let outer: Vec<_> = d.materials.values().filter(|m| m.exterior_medium.is_some()).collect();
        assert_eq!((outer.len(), outer[0].kind, outer[0].interior_medium.as_deref()), (1, MaterialKind::Diffuse, None));
        let grid = "MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"float density\" [1]\n\
                    WorldBegin MediumInterface \"smoke\" \"\" Shape \"sphere\"\n";
        let r = read(grid, false).unwrap();
        assert!(r.description.media.is_empty());
        assert!(r.warnings.iter().any(|w| w.contains("uniformgrid") && w.contains("vacuum")), "{:?}", r.warnings);
        assert!(message(read(grid, true)).contains("uniformgrid"));
    }
}

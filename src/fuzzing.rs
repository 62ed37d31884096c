//! Entry points of the fuzz targets (`fuzz/`, run with `cargo fuzz run -s none TARGET`) and
//! of the test that replays their corpora (`tests/fuzz_corpus.rs`). Each takes raw bytes and
//! must return — an error is a fine answer — without panicking, hanging or allocating
//! without bound.
use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// The folder whose `scene.toml` the scene target parses as (it holds a small mesh, so mesh
/// references resolve).
#[must_use]
pub fn scene_folder() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/scene")
}

/// Scene files: TOML, the schema and every validation.
pub fn scene_toml(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Scene::parse(text, &scene_folder().join("scene.toml"));
    }
}

/// Mitsuba 3 scene files: the XML reader, the translation and the scene it builds (as
/// `scene.xml` beside the TOML target's files, so that meshes and includes resolve).
pub fn mitsuba(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let options = crate::scene::import::ImportOptions::default();
        let _ = Scene::parse_mitsuba(text, &scene_folder().join("scene.xml"), &options);
    }
}

/// pbrt-v4 scene files: the tokenizer, the directives and the scene they build (as
/// `scene.pbrt` beside the TOML target's files).
pub fn pbrt(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let options = crate::scene::import::ImportOptions::default();
        let _ = Scene::parse_pbrt(text, &scene_folder().join("scene.pbrt"), &options);
    }
}

/// OBJ meshes: the bytes up to the first NUL are the OBJ, the rest its MTL library.
pub fn obj(data: &[u8]) {
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    if let (Ok(obj), Ok(mtl)) = (std::str::from_utf8(obj), std::str::from_utf8(mtl)) {
        let _ = crate::scene::obj_triangles(obj, mtl);
    }
}

/// PLY meshes (ASCII or binary), parsed and triangulated.
pub fn ply(data: &[u8]) {
    let _ = crate::scene::mesh::ply_triangles(data);
}

/// Texture and environment images in the formats decoded from memory (PFM, Radiance HDR,
/// TGA, JPEG): the first byte picks the format, the rest is the file.
pub fn image(data: &[u8]) {
    use crate::texture::ImageFormat;
    let Some((&pick, bytes)) = data.split_first() else { return };
    let format = [ImageFormat::Pfm, ImageFormat::Hdr, ImageFormat::Tga, ImageFormat::Jpeg][usize::from(pick % 4)];
    let _ = crate::texture::decode(bytes, format, pick & 4 != 0);
}

/// EXR input of `diff`, `info`, `converge` and `reference`.
pub fn exr(data: &[u8]) {
    let _ = crate::film::read_exr_from(std::io::Cursor::new(data), Path::new("fuzz.exr"));
}

/// EXR metadata text (any UTF-8: scene paths, labels, flags) written and read back: it must
/// come back as it was, never panic. The input is `key NUL value`.
pub fn exr_metadata(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let (key, value) = text.split_once('\0').unwrap_or(("k", &text));
    // (`spp` is the encoder's own key.)
    let key = if key.is_empty() || key == "spp" { "k" } else { key };
    let image = crate::film::Image { width: 1, height: 1, pixels: vec![[0.0; 3]], variance: None, spp: 1 };
    let mut meta = crate::film::Metadata::default();
    meta.push(key, value);
    let mut bytes = std::io::Cursor::new(Vec::new());
    if crate::film::write_exr_to(&mut bytes, Path::new("fuzz.exr"), &image, &meta).is_err() {
        return;
    }
    let (_, read) = crate::film::read_exr_from(std::io::Cursor::new(bytes.into_inner()), Path::new("fuzz.exr"))
        .expect("an EXR we wrote reads back");
    assert_eq!(read.get(key), Some(value), "metadata text changed on the way");
}

/// The command line: arguments separated by NUL bytes, parsed and validated (no render).
pub fn cli(data: &[u8]) {
    let args = std::iter::once("zvidpt".into())
        .chain(data.split(|&b| b == 0).map(|a| std::ffi::OsString::from(String::from_utf8_lossy(a).into_owned())));
    if let Ok(cli) = crate::cli::parse_from(args) {
        let _ = crate::cli::validate(&cli);
    }
}

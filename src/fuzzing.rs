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

/// Batch job files and the Slurm scripts written for them: the job file parsed (defaults,
/// jobs, matrices, output templates), and for every job that may be scripted, its task and
/// merge scripts. Whatever the fields hold, each script must have exactly the lines it is
/// built from outside quotes and comments (a newline that ended a comment or a quoted word
/// would start a command of the job's own text).
pub fn slurm_script(data: &[u8]) {
    let _ = slurm_scripts_checked(data);
}

/// [`slurm_script`], returning how many scripts it checked.
fn slurm_scripts_checked(data: &[u8]) -> usize {
    use crate::batch::slurm::{SlurmOptions, Split, check_scriptable, scripts, split_of};
    let mut checked = 0;
    let Ok(text) = std::str::from_utf8(data) else { return checked };
    let base = scene_folder();
    let Ok(jobs) = crate::batch::parse(text, &base.join("jobs.toml"), &base) else { return checked };
    let options = SlurmOptions {
        tasks: 3,
        cpus_per_task: 1,
        sbatch_args: Vec::new(),
        exe: "/opt/zvidpt's bin/zvidpt".into(),
        workdir: ".".into(),
    };
    for job in jobs.iter().take(64) {
        if check_scriptable(job, &options).is_err() {
            continue;
        }
        let Ok(split) = split_of(job, options.tasks) else { continue };
        let (task, merge) = scripts(job, &split, &options);
        let task_lines = if split == Split::Whole { 4 } else { 7 };
        for (script, lines) in std::iter::once((task, task_lines)).chain(merge.map(|m| (m, 6))) {
            assert_eq!(shell_lines(&script), lines, "a job field made a line of its own:\n{script}");
            checked += 1;
        }
    }
    checked
}

/// Newlines of a `sh` script outside single and double quotes, backslash escapes and
/// comments' text: the script's lines as the shell reads them.
fn shell_lines(script: &str) -> usize {
    let (mut lines, mut single, mut double, mut escaped, mut comment) = (0, false, false, false, false);
    let mut previous = '\n';
    for c in script.chars() {
        if comment {
            if c == '\n' {
                comment = false;
                lines += 1;
            }
        } else if escaped {
            escaped = false;
        } else if single {
            single = c != '\'';
        } else {
            match c {
                '\\' => escaped = true,
                '"' => double = !double,
                '\'' if !double => single = true,
                '#' if !double && previous.is_whitespace() => comment = true,
                '\n' if !double => lines += 1,
                _ => {}
            }
        }
        previous = c;
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The script check counts the shell's lines: quoted newlines, escapes and comments'
    /// text do not start lines; a newline outside them does.
    #[test]
    fn shell_lines_follow_the_shell() {
        assert_eq!(shell_lines("a 'x\ny' \"p\nq\" b\n"), 1);
        assert_eq!(shell_lines("# it's a comment\nexec 'a'\\''b'\n"), 2);
        assert_eq!(shell_lines("x=a#b\ntouch y\n"), 2);
        assert_eq!(shell_lines("echo 'a'\ntouch y\n#'\n"), 3);
    }

    /// The seed corpus reaches the scripts (a job file the parser refused would test only
    /// the parser), and a field with a newline in it is kept inside its quotes.
    #[test]
    fn slurm_corpus_writes_scripts() {
        let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/slurm_script/fields.toml");
        let checked = slurm_scripts_checked(&std::fs::read(corpus).unwrap());
        assert!(checked >= 10, "{checked} scripts checked");
    }
}

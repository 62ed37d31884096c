//! Adversarial inputs (the hardening issue): outputs that must not be replaced, sizes a user or
//! a file controls, signals while writing, the parser's messages, and nonsense that used to
//! be accepted silently. Each test names the class it covers.
mod common;
use common::cli::Scratch;
use std::path::Path;
use std::process::{Command, Output, Stdio};

fn zvidpt_in(dir: Option<&Path>, args: &[&str]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_zvidpt"));
    c.args(args).env_remove("RUST_BACKTRACE");
    if let Some(d) = dir {
        c.current_dir(d);
    }
    c.output().expect("binary runs")
}

fn zvidpt(args: &[&str]) -> Output {
    zvidpt_in(None, args)
}

fn scratch(name: &str) -> Scratch {
    common::cli::scratch("hard", name)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const LIGHT: &str = "mtllib box.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const MTL: &str = "newmtl white\nKd 0.5 0.5 0.5\nKe 1 1 1\n";

fn camera(w: u32, h: u32) -> String {
    format!("[camera]\neye = [0.3, 0.3, 2.0]\nlook_at = [0.3, 0.3, 0.0]\nfov_y = 45.0\nwidth = {w}\nheight = {h}\n")
}

/// A scene folder with `scene.toml`, `box.obj` = `obj` and `box.mtl`.
fn scene(name: &str, obj: &str) -> Scratch {
    let d = scratch(name);
    std::fs::write(d.join("scene.toml"), format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8))).unwrap();
    std::fs::write(d.join("box.obj"), obj).unwrap();
    std::fs::write(d.join("box.mtl"), MTL).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Fails with exit 1 and one `error:` line containing `needle`.
fn fails_with(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.lines().count() == 1 && e.starts_with("error: ") && e.contains(needle), "`{needle}` not in:\n{e}");
}

fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

// Class 1: outputs never replace a link, a device, a read-only file, an input, or each other;
// several outputs are committed together; a closed or full stdout does not fail a finished
// render.

#[test]
fn an_exr_named_like_its_png_is_refused() {
    let d = scene("samepng", LIGHT);
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("out.png")), "--spp", "1", "-q"]);
    fails_with(&o, "same file");
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("x.exr")), "--png", s(&d.join("./x.exr")), "--spp", "1", "-q"]);
    fails_with(&o, "is both the EXR and the PNG");
    let o = zvidpt(&["reference", s(&d), "-o", s(&d.join("ref.png")), "--spp", "1", "-q"]);
    fails_with(&o, "same file");
    assert_eq!(files(&d), ["box.mtl", "box.obj", "scene.toml"]);
}

#[test]
fn links_devices_read_only_files_and_inputs_are_not_replaced() {
    let d = scene("links", LIGHT);
    let target = d.join("precious.txt");
    std::fs::write(&target, "keep").unwrap();
    let link = d.join("out.exr");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let o = zvidpt(&["render", s(&d), "-o", s(&link), "--no-png", "--spp", "1", "-q"]);
    fails_with(&o, "symbolic link");
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    let o = zvidpt(&["render", s(&d), "-o", "/dev/null", "--no-png", "--spp", "1", "-q"]);
    fails_with(&o, "not a regular file");
    let ro = d.join("ro.exr");
    std::fs::write(&ro, "keep").unwrap();
    let mut p = std::fs::metadata(&ro).unwrap().permissions();
    p.set_readonly(true);
    std::fs::set_permissions(&ro, p).unwrap();
    let o = zvidpt(&["render", s(&d), "-o", s(&ro), "--no-png", "--spp", "1", "-q"]);
    fails_with(&o, "read-only");
    // The scene's own files are inputs.
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("box.obj")), "--no-png", "--spp", "1", "-q"]);
    fails_with(&o, "input");
    // So is the material library the OBJ reads (loaded indirectly, through its `mtllib`).
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("box.mtl")), "--no-png", "--spp", "1", "-q"]);
    fails_with(&o, "input");
    // The PNG beside the EXR (a name the user did not type) replaces only a PNG.
    std::fs::write(d.join("img.png"), "not a png").unwrap();
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("img.exr")), "--spp", "1", "-q"]);
    fails_with(&o, "not a PNG");
    assert_eq!(std::fs::read_to_string(d.join("img.png")).unwrap(), "not a png");
    assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
    assert_eq!(std::fs::read_to_string(&ro).unwrap(), "keep");
    assert!(!files(&d).iter().any(|f| f.ends_with(".tmp") || f == "img.exr"), "{:?}", files(&d));
}

#[test]
fn diff_never_writes_over_its_inputs() {
    let d = scene("diffself", LIGHT);
    let a = d.join("a.exr");
    assert!(zvidpt(&["render", s(&d), "-o", s(&a), "--no-png", "--spp", "1", "-q"]).status.success());
    let before = std::fs::read(&a).unwrap();
    let o = zvidpt(&["diff", s(&a), s(&a), "--error-map", s(&d.join("./a.exr"))]);
    fails_with(&o, "would overwrite the image");
    assert_eq!(std::fs::read(&a).unwrap(), before);
}

#[test]
fn a_full_stdout_does_not_fail_a_written_render() {
    let d = scene("fullout", LIGHT);
    let out = d.join("out.exr");
    let o = Command::new(env!("CARGO_BIN_EXE_zvidpt"))
        .args(["render", s(&d), "-o", s(&out), "--spp", "1", "-q"])
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("summary could not be printed"), "{}", stderr(&o));
    assert!(out.is_file() && d.join("out.png").is_file());
}

// Class 2: sizes a user or a file controls are bounded before allocation.

#[test]
fn huge_counts_and_resolutions_are_refused() {
    let d = scene("huge", LIGHT);
    let out = d.join("o.exr");
    let base = ["render", s(&d), "-o", s(&out), "--spp", "1", "-q"];
    let with = |extra: &[&str]| zvidpt(&[&base[..], extra].concat());
    fails_with(&with(&["--integrator", "jensen", "--photons", "1000000000000"]), "--photons must lie in");
    fails_with(&with(&["--integrator", "jensen", "--photons", "0"]), "--photons must lie in");
    fails_with(&with(&["--integrator", "jensen", "--photons", "50", "--knn", "100"]), "--knn must lie in 1..=50");
    fails_with(&with(&["--resolution", "16384x16384"]), "pixels");
    fails_with(&with(&["--threads", "100000"]), "threads");
    assert_eq!(files(&d), ["box.mtl", "box.obj", "scene.toml"]);
}

/// An EXR whose header claims 10⁹ × 10⁹ pixels: refused from the header, no allocation.
#[test]
fn an_exr_claiming_a_huge_data_window_is_refused() {
    let d = scene("exrhuge", LIGHT);
    let a = d.join("a.exr");
    assert!(zvidpt(&["render", s(&d), "-o", s(&a), "--no-png", "--spp", "1", "-q"]).status.success());
    let mut bytes = std::fs::read(&a).unwrap();
    for name in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = bytes.windows(name.len()).position(|w| w == name).expect("attribute present") + name.len() + 4;
        bytes[at + 8..at + 12].copy_from_slice(&1_000_000_000i32.to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&1_000_000_000i32.to_le_bytes());
    }
    let huge = d.join("huge.exr");
    std::fs::write(&huge, bytes).unwrap();
    for cmd in [vec!["info", s(&huge)], vec!["diff", s(&huge), s(&a)], vec!["diff", s(&a), s(&huge)]] {
        let o = zvidpt(&cmd);
        assert_eq!(o.status.code(), Some(1), "{cmd:?}: {}", stderr(&o));
        assert!(stderr(&o).starts_with("error: ") && stderr(&o).lines().count() == 1, "{}", stderr(&o));
    }
}

#[test]
fn scene_and_mesh_files_must_be_regular_and_bounded() {
    let d = scene("fifo", LIGHT);
    let fifo = d.join("pipe.toml");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    fails_with(&zvidpt(&["render", s(&fifo), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "not a regular file");
    // A mesh that is a FIFO.
    let m = scratch("fifomesh");
    std::fs::write(m.join("scene.toml"), format!("{}[[mesh]]\nobj = \"pipe.obj\"\n", camera(8, 8))).unwrap();
    assert!(Command::new("mkfifo").arg(m.join("pipe.obj")).status().unwrap().success());
    fails_with(&zvidpt(&["render", s(&m), "-o", s(&m.join("o.exr")), "-q", "--spp", "1"]), "not a regular file");
    // A 17 MiB scene file (sparse).
    let big = d.join("big.toml");
    std::fs::File::create(&big).unwrap().set_len(17 << 20).unwrap();
    fails_with(&zvidpt(&["render", s(&big), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "limit");
}

/// Runs the binary with `args`, failing the test if it has not ended within 30 s (a hang).
fn zvidpt_within(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_zvidpt"))
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() > 30 {
            child.kill().unwrap();
            panic!("zvidpt {args:?} hangs");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Every image input that is a FIFO is refused at once (opening one for reading waits for a
/// writer, forever): textures, environment maps, `info`, `diff`, `converge --reference`,
/// `merge`'s parts.
#[test]
fn image_inputs_must_be_regular_files() {
    let d = scene("fifoimages", LIGHT);
    for f in ["tex.png", "env.exr", "ref.exr", "part.zvp"] {
        assert!(Command::new("mkfifo").arg(d.join(f)).status().unwrap().success());
    }
    let with = |extra: &str| {
        let t = d.join("t.toml");
        std::fs::write(&t, format!("{}[[mesh]]\nobj = \"box.obj\"\n{extra}", camera(8, 8))).unwrap();
        t
    };
    let textured =
        with("[textures.t]\ntype = \"bitmap\"\nfile = \"tex.png\"\n[materials.white]\ndiffuse_texture = \"t\"\n");
    fails_with(
        &zvidpt_within(&["render", s(&textured), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]),
        "not a regular file",
    );
    let lit = with("[environment]\nmap = \"env.exr\"\n");
    fails_with(
        &zvidpt_within(&["render", s(&lit), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]),
        "not a regular file",
    );
    let reference = d.join("ref.exr");
    fails_with(&zvidpt_within(&["info", s(&reference)]), "not a regular file");
    fails_with(&zvidpt_within(&["diff", s(&reference), s(&reference)]), "not a regular file");
    let study = ["converge", s(&d), "--reference", s(&reference), "--integrators", "path", "--spp", "1", "-o"];
    fails_with(&zvidpt_within(&[&study[..], &[s(&d.join("cv"))]].concat()), "not a regular file");
    fails_with(&zvidpt_within(&["merge", "-o", s(&d.join("m.exr")), s(&d.join("part.zvp"))]), "not a regular file");
}

/// A PNG whose header claims 20000 × 20000 pixels (a 77-byte file) is refused from its header,
/// before 1.6 GB are allocated for it.
#[test]
fn image_headers_are_bounded_before_allocation() {
    let d = scene("pngbomb", LIGHT);
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend_from_slice(kind);
        c.extend_from_slice(data);
        let mut crc = crc32fast::Hasher::new();
        crc.update(kind);
        crc.update(data);
        c.extend_from_slice(&crc.finalize().to_be_bytes());
        c
    };
    let mut ihdr = 20000u32.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&20000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]));
    png.extend(chunk(b"IEND", &[]));
    std::fs::write(d.join("bomb.png"), png).unwrap();
    let t = d.join("t.toml");
    let extra = "[textures.t]\ntype = \"bitmap\"\nfile = \"bomb.png\"\n[materials.white]\ndiffuse_texture = \"t\"\n";
    std::fs::write(&t, format!("{}[[mesh]]\nobj = \"box.obj\"\n{extra}", camera(8, 8))).unwrap();
    fails_with(&zvidpt_within(&["render", s(&t), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "20000x20000");
}

/// An error quoting a file name with a newline in it is still one line.
#[test]
fn errors_are_one_line_whatever_they_quote() {
    let d = scratch("newline");
    let o = zvidpt(&["render", s(&d.join("no\nsuch\rscene.toml")), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]);
    fails_with(&o, "no\\nsuch\\rscene.toml");
}

/// One rule for every light's strength, as for emitting materials: a point or spot light's
/// intensity, a distant light's irradiance and an environment's radiance above 1e12 are
/// refused (a point light of 1e30 rendered an image whose every sample's square overflowed).
#[test]
fn every_light_kind_has_one_strength_bound() {
    let d = scratch("strength");
    for (name, light) in [
        ("point", "[[light]]\ntype = \"point\"\nposition = [0.0, 0.5, 1.0]\nintensity = [1e30, 1.0, 1.0]\n"),
        (
            "spot",
            "[[light]]\ntype = \"spot\"\nposition = [0.0, 0.5, 1.0]\ndirection = [0.0, 0.0, -1.0]\nintensity = [1e30, 1.0, 1.0]\n",
        ),
        ("distant", "[[light]]\ntype = \"distant\"\ndirection = [0.0, 0.0, -1.0]\nirradiance = [1e30, 1.0, 1.0]\n"),
        ("sky", "[environment]\nradiance = [1.0, 1.0, 1.0]\nscale = 1e30\n"),
    ] {
        let f = d.join(format!("{name}.toml"));
        std::fs::write(&f, format!("{}[materials.m]\ndiffuse = [0.5, 0.5, 0.5]\n[[shape]]\ntype = \"rectangle\"\nmaterial = \"m\"\n{light}", camera(8, 8))).unwrap();
        fails_with(&zvidpt(&["render", s(&f), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "[0, 1e12]");
    }
}

/// A part of a render (`--samples`) written under an image's name is refused (it holds sums
/// for `merge`, not an image); a depth limit of 0 warns that the image is black.
#[test]
fn parts_are_not_images_and_depth_zero_warns() {
    let d = scene("partname", LIGHT);
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("p.exr")), "-q", "--spp", "4", "--samples", "0..2"]);
    fails_with(&o, ".zvp");
    assert!(!d.join("p.exr").exists());
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1", "--max-depth", "0"]);
    assert!(o.status.success() && stderr(&o).contains("the image is black"), "{}", stderr(&o));
}

/// Training samples (which the image holds) above the render's requested total are refused,
/// as are a noise target for a part and a nonsensical target.
#[test]
fn budgets_that_contradict_each_other_are_refused() {
    let d = scene("budgets", LIGHT);
    let out = d.join("o.exr");
    let o = zvidpt(&["render", s(&d), "-o", s(&out), "-q", "--spp", "8", "--train-spp", "31"]);
    fails_with(&o, "--train-spp 31 is more than --spp 8");
    let o = zvidpt(&[
        "render",
        s(&d),
        "-o",
        s(&d.join("p.zvp")),
        "-q",
        "--spp",
        "8",
        "--samples",
        "0..4",
        "--noise-target",
        "0.1",
    ]);
    fails_with(&o, "--noise-target with --samples");
    for bad in ["0", "-1", "nan", "inf"] {
        fails_with(&zvidpt(&["render", s(&d), "-o", s(&out), "-q", "--noise-target", bad]), "--noise-target must be");
    }
    assert!(!out.exists());
}

/// 500 spheres of 81,920 triangles each exceed the triangle cap: refused before any is
/// tessellated, within 1 GB of address space (tessellating up to the cap took 4 GB, and
/// under this limit aborted on a failed allocation).
#[test]
fn the_triangle_cap_is_checked_before_tessellating() {
    let d = scratch("spheres");
    let mut text = String::from(
        "[camera]\neye = [0.0, 0.0, 50.0]\nlook_at = [0.0, 0.0, 0.0]\nfov_y = 60.0\nwidth = 8\nheight = 8\n[materials.m]\nemission = [1.0, 1.0, 1.0]\n",
    );
    for i in 0..500 {
        text.push_str(&format!(
            "[[shape]]\ntype = \"sphere\"\nmaterial = \"m\"\ncenter = [{}.0, 0.0, 0.0]\nradius = 0.2\n",
            i - 250
        ));
    }
    std::fs::write(d.join("scene.toml"), text).unwrap();
    let script = format!(
        "ulimit -v 1000000; exec {} render {} -o {} -q --spp 1",
        env!("CARGO_BIN_EXE_zvidpt"),
        s(&d),
        s(&d.join("o.exr"))
    );
    let o = Command::new("sh").arg("-c").arg(script).env_remove("RUST_BACKTRACE").output().unwrap();
    fails_with(&o, "more than 33554432");
}

// Class 3: SIGINT or SIGTERM while an output is being written leaves no temporary file and
// exits 130 or 143.

#[test]
fn signals_while_writing_leave_no_temporary_file() {
    for (signal, code) in [("-INT", 130), ("-TERM", 143)] {
        let d = scene(&format!("signal{code}"), LIGHT);
        std::fs::write(d.join("scene.toml"), format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(3072, 3072))).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_zvidpt"))
            .args(["render", s(&d), "-o", s(&d.join("out.exr")), "--spp", "1", "-q", "--threads", "2"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait for the temporary EXR to appear, then interrupt.
        let start = std::time::Instant::now();
        let mut seen = false;
        while start.elapsed().as_secs() < 120 {
            // The staged EXR (non-empty; the writability probe at the start is empty).
            let staged = std::fs::read_dir(&d)
                .unwrap()
                .map(|e| e.unwrap())
                .any(|e| e.file_name().to_string_lossy().ends_with(".tmp") && e.metadata().is_ok_and(|m| m.len() > 0));
            if staged {
                seen = true;
                break;
            }
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        assert!(seen, "the render never wrote a temporary file (or finished first)");
        // The shell's builtin `kill` (/bin/kill is procps', not on every Debian).
        let sent = Command::new("sh").arg("-c").arg(format!("kill {signal} {}", child.id())).status().unwrap();
        assert!(sent.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "{signal}");
        let left = files(&d);
        assert!(!left.iter().any(|f| f.ends_with(".tmp") || f.ends_with(".bak")), "{left:?}");
        // Both images or neither: never an EXR without its PNG.
        assert_eq!(left.contains(&"out.exr".to_string()), left.contains(&"out.png".to_string()), "{left:?}");
    }
}

// Class 4: errors that help.

#[test]
fn argument_errors_keep_the_parsers_whole_message() {
    let o = zvidpt(&["diff"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("<IMAGE>") && stderr(&o).contains("Usage"), "{}", stderr(&o));
    let o = zvidpt(&["render", "--integrator", "pathh"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("possible values") || stderr(&o).contains("did you mean"), "{}", stderr(&o));
    // A negative number is a bad value, not an unknown argument.
    let o = zvidpt(&["render", "--seed", "-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("invalid value '-1'"), "{}", stderr(&o));
}

#[test]
fn mesh_errors_say_what_is_wrong() {
    let d = scene("garbage", "\u{1}\u{2}binary\u{ff}");
    std::fs::write(d.join("box.obj"), [0x00u8, 0xff, 0xfe, 0x80, b'\n']).unwrap();
    fails_with(&zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "not UTF-8 text");
    std::fs::write(d.join("box.obj"), "hello, this is not a mesh\n").unwrap();
    fails_with(&zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "no faces");
    std::fs::write(d.join("scene.toml"), format!("{}[[mesh]]\nobj = \"\"\n", camera(8, 8))).unwrap();
    fails_with(&zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "empty");
}

#[test]
fn info_escapes_attribute_text() {
    let d = scene("escape", LIGHT);
    let a = d.join("a.exr");
    assert!(zvidpt(&["render", s(&d), "-o", s(&a), "--no-png", "--spp", "1", "-q"]).status.success());
    // Overwrite the `zvidpt.integrator` text ("path") with an escape sequence of equal length.
    let mut bytes = std::fs::read(&a).unwrap();
    let key = b"zvidpt.integrator\0string\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
    bytes[at..at + 4].copy_from_slice(b"\x1b[2J");
    std::fs::write(&a, bytes).unwrap();
    let o = zvidpt(&["info", s(&a)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stdout(&o).contains('\u{1b}') && stdout(&o).contains("\\u{1b}[2J"), "{}", stdout(&o));
}

#[test]
fn converge_checks_its_output_folder_before_rendering() {
    let d = scene("convout", LIGHT);
    let file = d.join("taken");
    std::fs::write(&file, "x").unwrap();
    let o = zvidpt(&["converge", s(&d), "--reference", s(&d.join("missing.exr")), "-o", s(&file)]);
    fails_with(&o, "is not a folder");
    let out = d.join("c");
    let converge =
        |extra: &[&str]| zvidpt(&[&["converge", s(&d), "--reference", "r.exr", "-o", s(&out)], extra].concat());
    let o = converge(&["--seed", "18446744073709551615", "--runs", "2"]);
    fails_with(&o, "largest seed");
    let o = converge(&["--time-to-mse", "0.1", "--max-spp", "0"]);
    fails_with(&o, "--max-spp");
}

// Class 5: nonsense is no longer accepted silently.

#[test]
fn short_faces_are_counted_and_concave_polygons_keep_their_shape() {
    // An L-shaped emitter (area 3) as one concave polygon, plus a two-vertex "face".
    let obj =
        "mtllib box.mtl\nusemtl white\nv 0 0 0\nv 0 2 0\nv 1 2 0\nv 1 1 0\nv 2 1 0\nv 2 0 0\nf 6 5 4 3 2 1\nf 1 2\n";
    let d = scene("concave", obj);
    let scene = zvidpt::scene::Scene::load(&d).unwrap();
    let area: f32 = scene.triangles.iter().map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()).sum();
    assert!((area - 3.0).abs() < 1e-5, "area {area}");
    assert!(scene.warnings.iter().any(|w| w.contains("fewer than 3 vertices")), "{:?}", scene.warnings);
    let o = zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]);
    assert!(o.status.success() && stderr(&o).contains("fewer than 3 vertices"), "{}", stderr(&o));
}

#[test]
fn absurd_emission_and_nan_images_are_explained() {
    let d = scene("emission", LIGHT);
    std::fs::write(d.join("box.mtl"), "newmtl white\nKd 0.5 0.5 0.5\nKe 1e30 1 1\n").unwrap();
    fails_with(&zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "-q", "--spp", "1"]), "emission must be at most");
    // An image with a NaN pixel: diff and info say why their figures are NaN.
    let image = zvidpt::film::Image {
        width: 2,
        height: 1,
        pixels: vec![[f32::NAN, 0.0, 0.0], [1.0; 3]],
        variance: None,
        spp: 1,
    };
    let (nan, one) = (d.join("nan.exr"), d.join("one.exr"));
    zvidpt::film::write_exr(&nan, &image, &zvidpt::film::Metadata::default()).unwrap();
    zvidpt::film::write_exr(&one, &zvidpt::film::Image { pixels: vec![[1.0; 3]; 2], ..image }, &Default::default())
        .unwrap();
    let o = zvidpt(&["diff", s(&nan), s(&one)]);
    assert!(stderr(&o).contains("1 NaN or infinite"), "{}", stderr(&o));
    let o = zvidpt(&["info", s(&nan)]);
    assert!(stdout(&o).contains("1 pixel values are NaN or infinite"), "{}", stdout(&o));
}

#[test]
fn a_missing_relative_scene_is_not_found_elsewhere() {
    let d = scratch("relative");
    let o = zvidpt_in(Some(&d), &["render", "scenes/cornell-classic", "-o", "o.exr", "-q", "--spp", "1"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("scenes/cornell-classic"), "{}", stderr(&o));
    assert!(files(&d).is_empty());
}

/// A texture or mesh file that cannot be read is reported where the scene names it: the
/// pbrt-v4 or Mitsuba 3 file and line of its directive, the TOML file otherwise.
#[test]
fn missing_files_are_reported_where_the_scene_names_them() {
    let d = scratch("missing-files");
    let out = d.join("o.exr");
    let head = "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\nWorldBegin\n";
    let light = "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\nShape \"sphere\" \"float radius\" 0.2\nAttributeEnd\n";
    let texture = format!(
        "{head}Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"missing.png\"\nMaterial \"diffuse\" \"texture reflectance\" \"t\"\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n{light}"
    );
    std::fs::write(d.join("texture.pbrt"), texture).unwrap();
    fails_with(
        &zvidpt(&["render", s(&d.join("texture.pbrt")), "-o", s(&out), "-q", "--spp", "1"]),
        "texture.pbrt: line 4: texture",
    );
    std::fs::write(d.join("ply.pbrt"), format!("{head}{light}Shape \"plymesh\" \"string filename\" \"nope.ply\"\n"))
        .unwrap();
    fails_with(&zvidpt(&["render", s(&d.join("ply.pbrt")), "-o", s(&out), "-q", "--spp", "1"]), "ply.pbrt: line 8: ");
    let xml = "<scene version=\"3.0.0\">\n<sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"8\"/></film></sensor>\n<shape type=\"obj\">\n<string name=\"filename\" value=\"gone.obj\"/>\n</shape>\n</scene>\n";
    std::fs::write(d.join("scene.xml"), xml).unwrap();
    fails_with(&zvidpt(&["render", s(&d.join("scene.xml")), "-o", s(&out), "-q", "--spp", "1"]), "scene.xml: line 3: ");
    let toml = format!(
        "{}[textures.t]\ntype = \"bitmap\"\nfile = \"gone.png\"\n[materials.m]\ndiffuse_texture = \"t\"\n[[mesh]]\nobj = \"box.obj\"\nmaterial = \"m\"\n",
        camera(8, 8)
    );
    std::fs::write(d.join("scene.toml"), toml).unwrap();
    std::fs::write(d.join("box.obj"), LIGHT).unwrap();
    std::fs::write(d.join("box.mtl"), MTL).unwrap();
    fails_with(&zvidpt(&["render", s(&d), "-o", s(&out), "-q", "--spp", "1"]), "scene.toml: texture `t`: ");
    assert!(!out.exists());
}

/// An include that names no file, or one that cannot be read, is an error at the including
/// file's line (pbrt-v4 `Include`/`Import`, Mitsuba 3 `<include>`): it was ": No such file or
/// directory", without a file or line.
#[test]
fn includes_are_reported_where_the_scene_names_them() {
    let d = scratch("includes");
    let out = d.join("o.exr");
    let render = |file: &str| zvidpt(&["render", s(&d.join(file)), "-o", s(&out), "-q", "--spp", "1"]);
    std::fs::write(d.join("empty.pbrt"), "Camera \"perspective\"\nInclude \"\"\nWorldBegin\n").unwrap();
    fails_with(&render("empty.pbrt"), "empty.pbrt: line 2: the include names no file");
    std::fs::write(d.join("import.pbrt"), "Camera \"perspective\"\nWorldBegin\n\nImport \"gone.pbrt\"\n").unwrap();
    fails_with(&render("import.pbrt"), "import.pbrt: line 4: cannot include ");
    std::fs::write(d.join("empty.xml"), "<scene version=\"3.0.0\">\n<include filename=\"\"/>\n</scene>\n").unwrap();
    fails_with(&render("empty.xml"), "empty.xml: line 2: the include names no file");
    std::fs::write(d.join("gone.xml"), "<scene version=\"3.0.0\">\n\n<include filename=\"missing.xml\"/>\n</scene>\n")
        .unwrap();
    fails_with(&render("gone.xml"), "gone.xml: line 3: cannot include ");
    assert!(!out.exists());
}

/// `zvidpt render ARGS --spp 1 -q` under an address-space limit of 600,000 KiB (`ulimit -v`;
/// the arguments reach it as the shell's positional parameters, unquoted by nothing).
fn render_within_600_mb(args: &[&str]) -> Output {
    Command::new("sh")
        .args(["-c", "ulimit -v 600000 && exec \"$0\" render \"$@\" --spp 1 -q", env!("CARGO_BIN_EXE_zvidpt")])
        .args(args)
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap()
}

/// Under an address-space limit (`ulimit -v`) a render, a scene's shapes or a mesh file too
/// large for it are refused with one line before allocating, instead of aborting ("memory
/// allocation of … failed", exit 134).
#[test]
fn a_render_larger_than_the_memory_left_is_refused() {
    let d = scratch("memory");
    let out = d.join("o.exr");
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell-paper");
    fails_with(
        &render_within_600_mb(&[paper, "--resolution", "8000x8000", "-o", s(&out)]),
        "a 8000x8000 render needs about",
    );
    // And a scene whose shapes would not fit, before they are tessellated (101 spheres of
    // 81,920 triangles: 3.9 GiB).
    let spheres = "Shape \"sphere\" \"float radius\" 0.1\n".repeat(100);
    let many = format!(
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\"\nShape \"sphere\"\nAttributeEnd\n{spheres}"
    );
    std::fs::write(d.join("many.pbrt"), many).unwrap();
    fails_with(&render_within_600_mb(&[s(&d.join("many.pbrt")), "-o", s(&out)]), "many.pbrt: the scene's shapes make");
    // And a mesh file too large for it, from its size before it is parsed (a 1000×1000 grid:
    // 74 MB of OBJ, about 590 MiB counted at 8 bytes per byte).
    let mut obj = String::from("mtllib box.mtl\nusemtl white\n");
    for i in 0..1000 {
        for j in 0..1000 {
            obj.push_str(&format!("v {:.6} {:.6} 0.000000\n", f64::from(i) * 1e-3, f64::from(j) * 1e-3));
        }
    }
    for i in 0..999 {
        for j in 0..999 {
            let a = i * 1000 + j + 1;
            obj.push_str(&format!("f {a} {} {}\nf {} {} {}\n", a + 1, a + 1000, a + 1, a + 1001, a + 1000));
        }
    }
    let grid = scene("memory-mesh", &obj);
    fails_with(&render_within_600_mb(&[s(&grid), "-o", s(&out)]), "box.obj: a mesh file of");
    assert!(!out.exists());
}

/// A material or light of an imported scene that fails validation is reported at the line
/// that declared it (an area light's emission at its `AreaLightSource`, a light at its
/// `LightSource` or `<emitter>`, a Mitsuba shape's material at its `<shape>`): the message
/// named only the importer's own name for it (`material `emitter1``).
#[test]
fn imported_scene_validation_names_the_line() {
    let d = scratch("validation-lines");
    let out = d.join("o.exr");
    let render = |file: &str| zvidpt(&["render", s(&d.join(file)), "-o", s(&out), "-q", "--spp", "1"]);
    let head = "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\nWorldBegin\n\n";
    let area = "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1e13 1 1]\nShape \"sphere\" \"float radius\" 0.2\nAttributeEnd\n";
    std::fs::write(d.join("area.pbrt"), format!("{head}{area}")).unwrap();
    fails_with(&render("area.pbrt"), "area.pbrt: line 6: ");
    let point = "LightSource \"point\" \"rgb I\" [1e13 1 1]\nShape \"sphere\" \"float radius\" 0.2\n";
    std::fs::write(d.join("point.pbrt"), format!("{head}{point}")).unwrap();
    fails_with(&render("point.pbrt"), "point.pbrt: line 5: light 1: intensity");
    let film = "<sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"8\"/></film></sensor>\n";
    let xml = format!(
        "<scene version=\"3.0.0\">\n{film}\n<shape type=\"sphere\">\n<emitter type=\"area\"><rgb name=\"radiance\" value=\"1e13\"/></emitter>\n</shape>\n<emitter type=\"point\"><rgb name=\"intensity\" value=\"1e13\"/></emitter>\n</scene>\n"
    );
    std::fs::write(d.join("area.xml"), xml).unwrap();
    fails_with(&render("area.xml"), "area.xml: line 4: ");
    assert!(!out.exists());
}

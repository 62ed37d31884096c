//! The command line: a smoke test of `render`, `info` and `diff`, and every bad input the
//! foundation issue lists, each of which must print one `error:` line, exit non-zero and write
//! no output file.
mod common;
use common::cli::Scratch;
use std::path::Path;
use std::process::{Command, Output};

fn zvidpt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_zvidpt")).args(args).env_remove("RUST_BACKTRACE").output().expect("binary runs")
}

/// A fresh scratch folder per test, removed when it ends.
fn scratch(name: &str) -> Scratch {
    common::cli::scratch("cli", name)
}

fn repo(p: &str) -> String {
    format!("{}/{p}", env!("CARGO_MANIFEST_DIR"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const BOX: &str = "mtllib box.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const MTL: &str = "newmtl white\nKd 0.5 0.5 0.5\nKe 1 1 1\n";

fn camera(w: u32, h: u32) -> String {
    format!("[camera]\neye = [0.3, 0.3, 2.0]\nlook_at = [0.3, 0.3, 0.0]\nfov_y = 45.0\nwidth = {w}\nheight = {h}\n")
}

/// Writes a scene folder with `scene.toml` = `toml` and `box.obj` = `obj`.
fn scene_dir(name: &str, toml: &str, obj: &str) -> Scratch {
    let d = scratch(name);
    std::fs::write(d.join("scene.toml"), toml).unwrap();
    std::fs::write(d.join("box.obj"), obj).unwrap();
    std::fs::write(d.join("box.mtl"), MTL).unwrap();
    d
}

/// Runs a render that must fail: one `error:` line naming `needle`, exit ≠ 0, no files.
fn expect_error(dir: &Path, extra: &[&str], needle: &str) {
    let out_exr = dir.join("out.exr");
    let mut args = vec!["render", s(dir), "-o", s(&out_exr), "-q"];
    if !extra.contains(&"--spp") {
        args.extend(["--spp", "1"]);
    }
    args.extend_from_slice(extra);
    let out = zvidpt(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "succeeded: {args:?}");
    assert!(matches!(out.status.code(), Some(1 | 2)), "exit code for {args:?}: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    if out.status.code() == Some(2) {
        // A malformed command line: the parser's whole message (what, valid values, usage).
        assert!(lines[0].starts_with("error: "), "stderr for {args:?}:\n{stderr}");
        assert!(stderr.contains(needle), "`{needle}` not in: {stderr}");
    } else {
        assert!(lines.len() == 1 && lines[0].starts_with("error: "), "stderr for {args:?}:\n{stderr}");
        assert!(lines[0].contains(needle), "`{needle}` not in: {}", lines[0]);
    }
    let folder = if dir.is_dir() { dir } else { dir.parent().unwrap() };
    let leftovers: Vec<_> = std::fs::read_dir(folder)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".exr") || n.ends_with(".png") || n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "files written: {leftovers:?}");
}

#[test]
fn render_info_and_diff_smoke() {
    let d = scratch("smoke");
    let (a, b, map) = (d.join("a.exr"), d.join("b.exr"), d.join("err.png"));
    for (path, seed) in [(&a, "1"), (&b, "2")] {
        let out = zvidpt(&[
            "render",
            &repo("scenes/cornell-paper"),
            "-o",
            s(path),
            "--spp",
            "4",
            "--resolution",
            "64x48",
            "--seed",
            seed,
            "-q",
        ]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("64x48, 4 spp") && stdout.contains("samples/s") && stdout.contains("rays/s"),
            "{stdout}"
        );
    }
    assert!(a.with_extension("png").is_file() && b.with_extension("png").is_file());
    let info = zvidpt(&["info", s(&a)]);
    let text = String::from_utf8_lossy(&info.stdout);
    // `--backend auto` (the default) picks Embree when this build has it.
    let backend = if cfg!(feature = "embree") { "backend = embree" } else { "backend = bvh" };
    for key in ["integrator = zvidpt", backend, "spp = 4", "seed = 1", "seconds = ", "version = "] {
        assert!(text.contains(key), "{key} missing from info:\n{text}");
    }
    let diff = zvidpt(&["diff", s(&a), s(&b), "--error-map", s(&map)]);
    let text = String::from_utf8_lossy(&diff.stdout);
    assert!(diff.status.success() && text.starts_with("MSE ") && text.contains("relMSE"), "{text}");
    assert!(map.is_file());
    let same = zvidpt(&["diff", s(&a), s(&a)]);
    assert!(String::from_utf8_lossy(&same.stdout).starts_with("MSE 0.000000e0"));
    // Two references: their mean is the reference and their spread its noise. Measured against
    // a and b, a's error is all the references' noise: (a − b)²/4 each way, so nothing is left.
    let pair = zvidpt(&["diff", s(&a), s(&a), s(&b)]);
    let text = String::from_utf8_lossy(&pair.stdout);
    let value =
        |key: &str| -> f64 { text.split(key).nth(1).unwrap().split_whitespace().next().unwrap().parse().unwrap() };
    let (mse, noise, less) = (value("MSE "), value("reference noise "), value("MSE less it "));
    assert!(
        pair.status.success() && mse > 0.0 && (noise - mse).abs() < 1e-5 * mse && less.abs() < 1e-5 * mse,
        "{text}"
    );
    assert!(text.contains("from 2 independent references"), "{text}");
    // Error by bands of rows: one line each, shares adding up to 100%.
    let bands = zvidpt(&["diff", s(&a), s(&b), "--bands", "4"]);
    let text = String::from_utf8_lossy(&bands.stdout);
    let shares: f64 = text
        .lines()
        .filter_map(|l| l.split("share").nth(1))
        .map(|v| v.trim().trim_end_matches('%').trim().parse::<f64>().unwrap())
        .sum();
    assert!(bands.status.success() && text.lines().count() == 5 && (shares - 100.0).abs() < 0.5, "{text}");
    let zero = zvidpt(&["diff", s(&a), s(&b), "--bands", "0"]);
    assert!(!zero.status.success() && String::from_utf8_lossy(&zero.stderr).starts_with("error: "));
    // A reader that goes away (`| head`) ends the command quietly, not with a panic.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_zvidpt"))
        .args(["diff", s(&a), s(&b), "--bands", "8"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !stderr.contains("panicked"), "{stderr}");
    // Time budget: stops after whole passes.
    let out = zvidpt(&[
        "render",
        &repo("scenes/cornell-paper"),
        "-o",
        s(&a),
        "--time",
        "0.2",
        "--resolution",
        "32x24",
        "--no-png",
        "-q",
    ]);
    // (`zvidpt`, the default, reports its training samples in the image apart.)
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && stdout.contains(" spp"), "{stdout}");
}

#[test]
fn png_bytes_identical_across_threads_and_tiles() {
    let d = scratch("determinism");
    let mut pngs = Vec::new();
    for (i, (threads, tile)) in [("1", "32"), ("2", "32"), ("2", "5")].iter().enumerate() {
        let exr = d.join(format!("r{i}.exr"));
        let out = zvidpt(&[
            "render",
            &repo("scenes/cornell-paper"),
            "-o",
            s(&exr),
            "--spp",
            "3",
            "--resolution",
            "80x60",
            "--threads",
            threads,
            "--tile-size",
            tile,
            "-q",
        ]);
        assert!(out.status.success());
        pngs.push(std::fs::read(exr.with_extension("png")).unwrap());
    }
    assert!(pngs[0] == pngs[1] && pngs[1] == pngs[2]);
}

#[test]
fn missing_and_unreadable_scene() {
    let d = scratch("missing");
    expect_error(&d.join("nope"), &[], "nope");
    // A folder without scene.toml.
    expect_error(&d, &[], "scene.toml");
    // A folder in the layout of Bitterli's collection: its pbrt/scene-v4.pbrt, named by the
    // folder.
    let bit = scratch("bitterli-layout");
    std::fs::create_dir_all(bit.join("pbrt")).unwrap();
    let pbrt = "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\n\
        Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\nWorldBegin\n\
        AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\nShape \"sphere\" \"float radius\" 1\n";
    std::fs::write(bit.join("pbrt/scene-v4.pbrt"), pbrt).unwrap();
    let o = zvidpt(&["render", s(&bit), "-o", s(&bit.join("o.exr")), "--spp", "1", "-q", "--integrator", "path"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let name = bit.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(&format!("{name} 8x8")),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    // Not UTF-8 text.
    let bin = scratch("binary");
    std::fs::write(bin.join("scene.toml"), [0xff, 0xfe, 0x00, 0x80]).unwrap();
    expect_error(&bin, &[], "scene.toml");
}

#[test]
fn missing_obj() {
    let d = scene_dir("missing-obj", &format!("{}[[mesh]]\nobj = \"gone.obj\"\n", camera(8, 8)), BOX);
    expect_error(&d, &[], "gone.obj");
}

#[test]
fn malformed_toml_names_the_line() {
    let d = scene_dir("malformed", &format!("{}[[mesh]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
    expect_error(&d, &[], "line 7");
}

#[test]
fn unknown_key_is_named() {
    let d = scene_dir("unknown", &format!("{}colour = 3\n[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
    expect_error(&d, &[], "colour");
    let d = scene_dir("unknown2", &format!("{}[[mesh]]\nobj = \"box.obj\"\nflip = true\n", camera(8, 8)), BOX);
    expect_error(&d, &[], "flip");
}

#[test]
fn non_finite_vertex() {
    for (i, bad) in ["nan", "inf", "-inf"].iter().enumerate() {
        let obj = BOX.replace("v 1 0 0", &format!("v 1 {bad} 0"));
        let d = scene_dir(&format!("nan{i}"), &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), &obj);
        expect_error(&d, &[], "non-finite");
    }
}

#[test]
fn mesh_index_out_of_range() {
    let obj = BOX.replace("f 1 2 3", "f 1 2 9");
    let d = scene_dir("index", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), &obj);
    expect_error(&d, &[], "box.obj");
}

#[test]
fn bad_resolutions() {
    let mesh = "[[mesh]]\nobj = \"box.obj\"\n";
    expect_error(&scene_dir("zero-w", &format!("{}{mesh}", camera(0, 8)), BOX), &[], "at least 1");
    expect_error(&scene_dir("huge", &format!("{}{mesh}", camera(20000, 8)), BOX), &[], "16384");
    let ok = scene_dir("override", &format!("{}{mesh}", camera(8, 8)), BOX);
    expect_error(&ok, &["--resolution", "0x10"], "at least 1");
    expect_error(&ok, &["--resolution", "17000x10"], "16384");
}

#[test]
fn zero_spp_and_bad_numbers() {
    let d = scene_dir("spp", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
    expect_error(&d, &["--spp", "0"], "spp");
    expect_error(&d, &["--time", "-1"], "time");
    expect_error(&d, &["--threads", "0"], "threads");
    expect_error(&d, &["--spp", "many"], "many");
    expect_error(&d, &["--resolution", "12"], "WIDTHxHEIGHT");
    expect_error(&d, &["--integrator", "magic"], "magic");
    expect_error(&d, &["--light-sampling", "sideways"], "sideways");
    expect_error(&d, &["--guide-floor", "0"], "guide-floor");
    expect_error(&d, &["--q-kappa", "0"], "q-kappa");
    expect_error(&d, &["--q-max", "1"], "q-max");
}

#[test]
fn unwritable_output() {
    let d = scene_dir("unwritable", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
    let out = zvidpt(&["render", s(&d), "-o", s(&d.join("no/such/dir/out.exr")), "--spp", "1", "-q"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success()
            && stderr.lines().count() == 1
            && stderr.starts_with("error: ")
            && stderr.contains("no/such/dir"),
        "{stderr}"
    );
    // An output path that is a folder.
    let out = zvidpt(&["render", s(&d), "-o", s(&d), "--spp", "1", "-q"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).starts_with("error: "));
}

#[test]
fn no_emitter_warns_and_renders_black() {
    let mtl_dark = "newmtl white\nKd 0.5 0.5 0.5\n";
    let d = scene_dir("dark", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
    std::fs::write(d.join("box.mtl"), mtl_dark).unwrap();
    let exr = d.join("out.exr");
    let out = zvidpt(&["render", s(&d), "-o", s(&exr), "--spp", "2", "-q"]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("warning: the scene has no emitter"));
    let info = String::from_utf8_lossy(&zvidpt(&["info", s(&exr)]).stdout).into_owned();
    assert!(info.contains("mean RGB (0.00000, 0.00000, 0.00000)"), "{info}");
}

#[test]
fn degenerate_triangles_are_counted() {
    let obj = format!("{BOX}v 2 2 2\nf 4 4 4\nf 1 2 2\n");
    let d = scene_dir("degenerate", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), &obj);
    let out = zvidpt(&["render", s(&d), "-o", s(&d.join("o.exr")), "--spp", "1", "-q"]);
    assert!(out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("skipped 2 degenerate"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn unknown_material_and_backend_not_built() {
    let d = scene_dir("material", &format!("{}[[mesh]]\nobj = \"box.obj\"\nmaterial = \"gold\"\n", camera(8, 8)), BOX);
    expect_error(&d, &[], "gold");
    if !cfg!(feature = "embree") {
        let ok = scene_dir("backend", &format!("{}[[mesh]]\nobj = \"box.obj\"\n", camera(8, 8)), BOX);
        expect_error(&ok, &["--backend", "embree"], "embree");
    }
}

#[test]
fn diff_errors() {
    let d = scratch("diff");
    let out = zvidpt(&["diff", s(&d.join("a.exr")), s(&d.join("b.exr"))]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).starts_with("error: "));
    std::fs::write(d.join("junk.exr"), b"not an exr").unwrap();
    let out = zvidpt(&["diff", s(&d.join("junk.exr")), s(&d.join("junk.exr"))]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.starts_with("error: ") && stderr.lines().count() == 1, "{stderr}");
}

#[test]
fn reference_is_cached_and_converge_writes_csv() {
    let d = scratch("converge");
    let reference = d.join("ref.exr");
    let scene = repo("scenes/cornell-paper");
    let make = || zvidpt(&["reference", &scene, "--resolution", "32x24", "--spp", "8", "-o", s(&reference), "-q"]);
    let first = make();
    assert!(first.status.success(), "{}", String::from_utf8_lossy(&first.stderr));
    assert!(String::from_utf8_lossy(&make().stdout).contains("up to date"));
    let out = d.join("out");
    let run = zvidpt(&[
        "converge",
        &scene,
        "--resolution",
        "32x24",
        "--reference",
        s(&reference),
        "--spp",
        "1,2",
        "--runs",
        "2",
        "--integrators",
        "path,zvidpt-terminal",
        "-o",
        s(&out),
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let csv = std::fs::read_to_string(out.join("converge.csv")).unwrap();
    assert!(csv.starts_with("integrator,spp,runs,mse"));
    assert_eq!(csv.lines().count(), 1 + 2 * 2, "{csv}");
    assert_eq!(std::fs::read_to_string(out.join("runs.csv")).unwrap().lines().count(), 1 + 2 * 2 * 2);
    // Time to a target MSE (loose, so a few doublings reach it) and the equal-time image.
    let ttm = zvidpt(&[
        "converge",
        &scene,
        "--resolution",
        "32x24",
        "--reference",
        s(&reference),
        "--runs",
        "1",
        "--integrators",
        "path,jensen",
        "--time-to-mse",
        "1000",
        "--max-spp",
        "64",
        "--equal-time",
        "0.05",
        "-o",
        s(&out),
    ]);
    assert!(ttm.status.success(), "{}", String::from_utf8_lossy(&ttm.stderr));
    let csv = std::fs::read_to_string(out.join("time_to_mse.csv")).unwrap();
    assert!(csv.starts_with("integrator,seed,target_mse,seconds,spp,reached") && csv.lines().count() == 3, "{csv}");
    assert!(
        out.join("equal_time.png").is_file()
            && out.join("mse_vs_spp.png").is_file()
            && out.join("mse_vs_seconds.svg").is_file()
    );
    // A reference of another resolution is refused with one error line.
    let bad = zvidpt(&["converge", &scene, "--resolution", "16x12", "--reference", s(&reference), "-o", s(&out)]);
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(!bad.status.success() && stderr.lines().count() == 1 && stderr.contains("32x24"), "{stderr}");
}

/// Every folder of `scenes/` renders from a clean checkout: each file a scene names (meshes,
/// textures) is in the repository (a file kept out by `.gitignore` fails here).
#[test]
fn every_shipped_scene_renders() {
    let d = scratch("shipped");
    let mut count = 0;
    for entry in std::fs::read_dir(repo("scenes")).unwrap() {
        let scene = entry.unwrap().path();
        if !scene.is_dir() {
            continue;
        }
        let out_exr = d.join("out.exr");
        let o =
            zvidpt(&["render", s(&scene), "--resolution", "16x12", "--spp", "1", "-q", "--no-png", "-o", s(&out_exr)]);
        assert!(o.status.success(), "{}: {}", scene.display(), String::from_utf8_lossy(&o.stderr));
        count += 1;
    }
    assert!(count >= 9, "only {count} shipped scenes found");
}

/// `zvidpt denoise` never writes over its input, `render --denoise` is refused on a part;
/// where Open Image Denoise is installed, `render --denoise` adds the `denoised` layers and the
/// `-denoised` PNG and leaves the image itself as a render without it writes it.
#[test]
fn denoise_outputs_beside_the_noisy_image() {
    let d = scratch("denoise");
    let noisy = d.join("noisy.exr");
    let base = [
        "render",
        &repo("scenes/cornell-paper"),
        "--spp",
        "4",
        "--resolution",
        "32x24",
        "--seed",
        "1",
        "-q",
        "--aov",
        "albedo,normal",
    ];
    let out = zvidpt(&[&base[..], &["-o", s(&noisy)]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let before = std::fs::read(&noisy).unwrap();
    let out = zvidpt(&["denoise", s(&noisy), "-o", s(&noisy)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.lines().count() == 1 && err.contains("input"), "{err}");
    assert_eq!(std::fs::read(&noisy).unwrap(), before, "the noisy image was touched");
    let out = zvidpt(&[&base[..], &["--samples", "0..2", "--denoise", "-o", s(&d.join("p.zvp"))]].concat());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("--denoise"), "{err}");

    if zvidpt::denoise::Denoiser::load(Some(1)).is_err() {
        assert!(std::env::var_os("ZVIDPT_REQUIRE_OIDN").is_none(), "Open Image Denoise is required here");
        eprintln!("skipped the denoising half: Open Image Denoise is not installed");
        return;
    }
    let both = d.join("both.exr");
    let out = zvidpt(&[&base[..], &["--denoise", "-o", s(&both)]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("denoised in"));
    assert!(d.join("both-denoised.png").is_file() && d.join("both.png").is_file());
    let (image, meta, layers) =
        zvidpt::film::read_exr_with(&both, &["denoised.R", "denoised.G", "denoised.B"]).unwrap();
    assert!(layers.iter().all(Option::is_some) && meta.get("denoiser").is_some());
    let (plain, _) = zvidpt::film::read_exr(&noisy).unwrap();
    assert_eq!(image.pixels, plain.pixels, "--denoise changed the image itself");
    let out = zvidpt(&["denoise", s(&noisy), "-o", s(&d.join("d.exr"))]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("guided by albedo+normal"));
    let _ = std::fs::remove_dir_all(&d);
}

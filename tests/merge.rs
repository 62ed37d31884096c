//! `zvidpt render --samples A..B` and `zvidpt merge`: parts of a render, in any split, merge
//! into pixels (and variances) bit-identical to one render of all the samples, for the path
//! tracer and for the learned integrator (whose parts each recompute the same training); parts
//! that overlap, leave a gap or come from different renders are refused.
mod common;
use common::cli::*;
use zvidpt::film::read_exr;

/// Renders whole and in parts; returns the whole render's output.
fn split_and_merge(integrator: &str, spp: u32, ranges: &[(u32, u32)]) -> String {
    let dir = scratch("merge", &format!("{integrator}-{spp}"));
    let scene = format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"));
    let spp_s = spp.to_string();
    let common = ["--integrator", integrator, "--resolution", "40x30", "--seed", "5", "--spp", &spp_s, "-q"];
    let whole = dir.join("whole.exr");
    let o = zvidpt(&[&["render", &scene, "-o", s(&whole), "--no-png"][..], &common[..]].concat());
    assert!(o.status.success(), "{}", text(&o));
    let said = text(&o);
    let mut parts = Vec::new();
    // Parts render with different thread counts: the pixels must not care.
    for (i, (a, b)) in ranges.iter().enumerate() {
        let part = dir.join(format!("part{i}.zvp"));
        let range = format!("{a}..{b}");
        let threads = (1 + i % 2).to_string();
        let o = zvidpt(
            &[&["render", &scene, "-o", s(&part), "--samples", &range, "--threads", &threads][..], &common[..]]
                .concat(),
        );
        assert!(o.status.success(), "{}", text(&o));
        assert!(!dir.join(format!("part{i}.png")).exists(), "a part writes no PNG");
        parts.push(part);
    }
    // Merge in reverse order: the order of the parts does not matter.
    let merged = dir.join("merged.exr");
    let mut args = vec!["merge".to_string(), "-o".into(), s(&merged).into(), "--no-png".into()];
    args.extend(parts.iter().rev().map(|p| s(p).to_string()));
    let o = zvidpt(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", text(&o));
    let (a, meta) = read_exr(&whole).unwrap();
    let (b, merged_meta) = read_exr(&merged).unwrap();
    let bits = |img: &zvidpt::film::Image| -> Vec<u32> {
        img.pixels.iter().chain(img.variance.as_ref().unwrap()).flat_map(|p| p.map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&a), bits(&b), "{integrator}: merged pixels differ from one render");
    assert_eq!(a.spp, b.spp);
    for key in ["scene_hash", "integrator", "seed"] {
        assert_eq!(meta.get(key), merged_meta.get(key), "{key}");
    }
    assert_eq!(merged_meta.get("merged_parts"), Some(ranges.len().to_string().as_str()));
    said
}

#[test]
fn path_parts_merge_bit_identically() {
    split_and_merge("path", 10, &[(0, 3), (3, 4), (4, 10)]);
}

#[test]
fn learned_parts_merge_bit_identically() {
    split_and_merge("zvidpt", 8, &[(0, 5), (5, 8)]);
}

/// With 7 or more training samples per pixel, the learned integrator shares the render's
/// samples by the training's error: every part takes its pixels' share of its range, and
/// the counts add up as the whole render's.
#[test]
fn learned_parts_with_sample_rates_merge_bit_identically() {
    let said = split_and_merge("zvidpt", 16, &[(0, 3), (3, 11), (11, 16)]);
    assert!(said.contains("samples shared by the training's error"), "{said}");
}

#[test]
fn wrong_parts_are_refused() {
    let dir = scratch("merge", "refuse");
    let scene = format!("{}/scenes/cornell-paper", env!("CARGO_MANIFEST_DIR"));
    let part = |name: &str, range: &str, seed: &str| {
        let p = dir.join(name);
        let o = zvidpt(&[
            "render",
            &scene,
            "-o",
            s(&p),
            "--integrator",
            "path",
            "--resolution",
            "8x6",
            "--spp",
            "6",
            "--samples",
            range,
            "--seed",
            seed,
            "-q",
        ]);
        assert!(o.status.success(), "{}", text(&o));
        p
    };
    let (a, b, c, d) = (
        part("a.zvp", "0..3", "1"),
        part("b.zvp", "2..6", "1"),
        part("c.zvp", "4..6", "1"),
        part("d.zvp", "3..6", "2"),
    );
    // A damaged part (one flipped bit in its sums) is refused by its checksum.
    let e = part("e.zvp", "3..6", "1");
    let mut bytes = std::fs::read(&e).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x04;
    std::fs::write(&e, bytes).unwrap();
    let out = dir.join("m.exr");
    for (parts, expected) in [
        (vec![&a, &e], "checksum mismatch"),
        (vec![&a, &b], "in two parts"),
        (vec![&a, &c], "samples 3..4 are in no part"),
        (vec![&a], "samples 3..6 are in no part"),
        (vec![&a, &d], "parts of different renders (seed)"),
    ] {
        let mut args = vec!["merge", "-o", s(&out), "--no-png"];
        args.extend(parts.iter().map(|p| s(p)));
        let o = zvidpt(&args);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains(expected) && text(&o).starts_with("error: "), "{expected}: {}", text(&o));
        assert!(!out.exists());
    }
    // Bad ranges are refused before rendering.
    for (range, expected) in [("3..3", "holds no sample"), ("0..7", "within 0..6"), ("a..b", "invalid value 'a..b'")] {
        let o = zvidpt(&["render", &scene, "-o", s(&dir.join("x.zvp")), "--spp", "6", "--samples", range]);
        assert!(!o.status.success() && text(&o).contains(expected), "{range}: {}", text(&o));
    }
    let o = zvidpt(&["render", &scene, "-o", s(&dir.join("x.zvp")), "--samples", "0..2"]);
    assert!(text(&o).contains("needs --spp"), "{}", text(&o));
    // An EXR is not a part.
    let exr = dir.join("img.exr");
    assert!(
        zvidpt(&["render", &scene, "-o", s(&exr), "--resolution", "8x6", "--spp", "1", "--no-png", "-q"])
            .status
            .success()
    );
    let o = zvidpt(&["merge", "-o", s(&out), s(&exr)]);
    assert!(text(&o).contains("not a zvidpt partial render"), "{}", text(&o));
}

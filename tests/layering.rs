//! The library's modules form layers (docs/architecture.md): a module may use modules of lower
//! layers only, so there are no import cycles and each layer can be read, tested and replaced
//! without the ones above it. This test reads every `crate::` path in `src/` (outside comments
//! and unit tests) and fails when one points sideways or up.
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Lowest first. A module may use any module of a lower row, none of its own row or above.
const LAYERS: &[&[&str]] = &[
    &["error"],
    &["io", "stats", "color", "denoise"],
    &["sampler"],
    &["geometry"],
    &["film"],
    &["texture", "material", "medium", "light", "accel"],
    &["scene"],
    &["photon"],
    &["learned_guide"],
    &["integrator"],
    &["render"],
    &["plot", "batch"],
    &["converge"],
    &["cli"],
    &["fuzzing"],
];

/// Items of the crate root that every module may use (`lib.rs` re-exports and constants).
fn root_item(name: &str) -> Option<&'static str> {
    match name {
        "Error" | "Result" => Some("error"),
        "VERSION" => Some(""),
        _ => None,
    }
}

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|row| row.contains(&module))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The code of a file without comments and without its unit tests (a `tests.rs` file, or
/// everything from `#[cfg(test)]` followed by `mod tests`).
fn code_of(path: &Path, text: &str) -> String {
    if path.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    let mut code = String::new();
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let trimmed = line.trim_start();
        if trimmed == "#[cfg(test)]" && lines.peek().is_some_and(|l| l.trim_start().starts_with("mod tests")) {
            break;
        }
        let line = line.find("//").map_or(line, |i| &line[..i]);
        code.push_str(line);
        code.push('\n');
    }
    code
}

/// The first path segment of every `crate::` path in `code`, with the grouped form
/// `crate::{a::b, c}` read as `a` and `c`.
fn crate_paths(code: &str) -> Vec<String> {
    let ident = |s: &str| -> String { s.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect() };
    let mut out = Vec::new();
    for (i, _) in code.match_indices("crate::") {
        let before = code[..i].chars().next_back();
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue; // e.g. `zvidpt_crate::`
        }
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0;
            let mut start = true;
            for (j, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => break,
                    '}' => depth -= 1,
                    ',' if depth == 0 => start = true,
                    c if c.is_whitespace() => {}
                    _ if start && depth == 0 => {
                        out.push(ident(&group[j..]));
                        start = false;
                    }
                    _ => {}
                }
            }
        } else {
            out.push(ident(rest));
        }
    }
    out
}

#[test]
fn modules_use_only_lower_layers() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut violations = Vec::new();
    let mut unplaced = BTreeSet::new();
    for path in &files {
        let rel = path.strip_prefix(&src).unwrap();
        let first = rel.components().next().unwrap().as_os_str().to_string_lossy().into_owned();
        let module = first.trim_end_matches(".rs").to_string();
        if module == "lib" || module == "main" {
            continue;
        }
        let Some(own) = layer(&module) else {
            unplaced.insert(module);
            continue;
        };
        let text = std::fs::read_to_string(path).unwrap();
        for (n, line) in code_of(path, &text).lines().enumerate() {
            for target in crate_paths(line) {
                let target = root_item(&target).map_or(target.clone(), str::to_string);
                if target.is_empty() || target == module {
                    continue;
                }
                match layer(&target) {
                    Some(l) if l < own => {}
                    Some(_) => violations.push(format!("{}:{}: `{module}` uses `{target}`", rel.display(), n + 1)),
                    None => {
                        unplaced.insert(target);
                    }
                }
            }
        }
    }
    assert!(unplaced.is_empty(), "modules missing from LAYERS (place them in a layer): {unplaced:?}");
    assert!(violations.is_empty(), "a module uses one of its own layer or above:\n{}", violations.join("\n"));
}

#[test]
fn the_reader_sees_grouped_and_plain_paths_and_skips_comments_and_tests() {
    assert_eq!(crate_paths("use crate::{film::Image, scene::{A, B}, Result};"), ["film", "scene", "Result"]);
    assert_eq!(crate_paths("let x = crate::render::render(a);"), ["render"]);
    let code = code_of(
        Path::new("a.rs"),
        "use crate::geometry::Ray; // crate::cli\n/// [`crate::render`]\n#[cfg(test)]\nmod tests {\n use crate::cli;\n}\n",
    );
    assert_eq!(crate_paths(&code), ["geometry"]);
}

//! With the `embree` feature: generates Rust bindings for the *installed* Embree headers with
//! bindgen, and links the matching library. Embree 4 headers are used when present, Embree 3
//! otherwise; the `embree4` cfg tells `src/accel/embree.rs` which. Without the feature it does
//! nothing.
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    #[cfg(feature = "embree")]
    embree::generate();
}

#[cfg(feature = "embree")]
mod embree {
    use std::path::{Path, PathBuf};

    /// Include folders to look in: `$EMBREE_DIR/include` first, then the system's.
    fn include_dirs() -> Vec<PathBuf> {
        let mut dirs = Vec::new();
        if let Some(root) = std::env::var_os("EMBREE_DIR") {
            let root = PathBuf::from(root);
            dirs.push(root.join("include"));
            dirs.push(root);
        }
        dirs.extend(["/usr/include", "/usr/local/include"].map(PathBuf::from));
        dirs
    }

    pub fn generate() {
        let found = include_dirs().into_iter().find_map(|dir| {
            [("embree4", 4), ("embree3", 3)].into_iter().find_map(|(sub, version)| {
                let header = dir.join(sub).join("rtcore.h");
                header.is_file().then_some((dir.clone(), header, version))
            })
        });
        let Some((include, header, version)) = found else {
            panic!(
                "\n\nzvidpt: the `embree` feature needs Embree's headers and library.\n\
                 On Debian/Ubuntu: apt-get install libembree-dev libclang-dev\n\
                 Or set EMBREE_DIR to an Embree install (with include/embree4 or include/embree3 and lib/).\n\n"
            );
        };
        println!("cargo:rerun-if-changed={}", header.display());
        if let Some(root) = std::env::var_os("EMBREE_DIR") {
            let lib = Path::new(&root).join("lib");
            println!("cargo:rustc-link-search=native={}", lib.display());
        }
        println!("cargo:rustc-link-lib=embree{version}");
        if version == 4 {
            println!("cargo:rustc-cfg=embree4");
        }
        let bindings = bindgen::Builder::default()
            .header(header.to_string_lossy())
            .clang_arg(format!("-I{}", include.display()))
            .allowlist_function("rtc.*")
            .allowlist_type("RTC.*")
            .allowlist_var("RTC_.*")
            .default_enum_style(bindgen::EnumVariation::Consts)
            .derive_default(true)
            .layout_tests(false)
            .generate()
            .unwrap_or_else(|e| panic!("zvidpt: bindgen failed on {}: {e}", header.display()));
        let out = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("embree_bindings.rs");
        bindings.write_to_file(&out).unwrap_or_else(|e| panic!("zvidpt: cannot write {}: {e}", out.display()));
    }
}

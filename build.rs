//! Does nothing unless the `embree` feature is on (then it generates Embree bindings).
fn main() {
    println!("cargo:rerun-if-changed=build.rs");
}

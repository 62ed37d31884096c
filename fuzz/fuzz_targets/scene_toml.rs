//! Fuzz target: zvidpt::fuzzing::scene_toml (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::scene_toml(data));

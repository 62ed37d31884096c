//! Fuzz target: zvidpt::fuzzing::pbrt (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::pbrt(data));

//! Fuzz target: zvidpt::fuzzing::exr_metadata (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::exr_metadata(data));

//! Fuzz target: zvidpt::fuzzing::image (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::image(data));

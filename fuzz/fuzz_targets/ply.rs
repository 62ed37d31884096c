//! Fuzz target: zvidpt::fuzzing::ply (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::ply(data));

//! Fuzz target: zvidpt::fuzzing::cli (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::cli(data));

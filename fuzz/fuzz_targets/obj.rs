//! Fuzz target: zvidpt::fuzzing::obj (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::obj(data));

//! Fuzz target: zvidpt::fuzzing::mitsuba (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::mitsuba(data));

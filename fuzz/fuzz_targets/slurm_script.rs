//! Fuzz target: zvidpt::fuzzing::slurm_script (see src/fuzzing.rs).
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| zvidpt::fuzzing::slurm_script(data));

//! Fuzz target `exr_header`: see fuzz/checks.rs (`exr_header`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("exr_header", data));

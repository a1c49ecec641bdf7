//! Fuzz target `png_recipe`: see fuzz/checks.rs (`png_recipe`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("png_recipe", data));

//! Fuzz target `scene`: see fuzz/checks.rs (`scene`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("scene", data));

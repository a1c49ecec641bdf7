//! Fuzz target `part`: see fuzz/checks.rs (`part`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("part", data));

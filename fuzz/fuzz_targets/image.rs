//! Fuzz target `image`: see fuzz/checks.rs (`image`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("image", data));

//! Fuzz target `request`: see fuzz/checks.rs (`request`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("request", data));

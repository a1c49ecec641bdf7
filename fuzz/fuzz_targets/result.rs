//! Fuzz target `result`: see fuzz/checks.rs (`result`) for what it checks of each input.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| tessera_fuzz::run("result", data));

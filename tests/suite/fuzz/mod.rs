//! Hostile input in bulk: thousands of generated and mutated scene files, partial files, images with recipes,
//! command lines and requests to the live viewer. Nothing may panic, abort or hang, nothing may allocate what an input merely
//! claims, and every refusal names where it comes from (the binary's exit 2 with a message).
//!
//! Every case is generated from its own fixed seed, so a run is reproducible; a failing case
//! is printed with its name and input, and `TESSERA_FUZZ_CASE=scene:123` (or `part:…`, `image:…`,
//! `cli:…`, `request:…`) replays that one case alone. A run takes a fifth of each family's
//! base count; `TESSERA_FUZZ_SCALE=5` runs all of it, `=50` ten times as many.

mod command_lines;
mod corpus;
mod harness;
mod images;
mod parts;
#[cfg(feature = "preview")]
mod requests;
mod scenes;

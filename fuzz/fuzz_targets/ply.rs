//! cargo-fuzz target `ply`: the body is `sl_fuzz::ply` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::ply(data);
});

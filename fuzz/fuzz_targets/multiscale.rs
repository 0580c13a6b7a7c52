//! cargo-fuzz target `multiscale`: the body is `sl_fuzz::multiscale` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::multiscale(data);
});

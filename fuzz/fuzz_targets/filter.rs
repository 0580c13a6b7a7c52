//! cargo-fuzz target `filter`: the body is `sl_fuzz::filter` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::filter(data);
});

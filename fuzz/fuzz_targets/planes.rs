//! cargo-fuzz target `planes`: the body is `sl_fuzz::planes` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::planes(data);
});

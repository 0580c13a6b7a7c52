//! cargo-fuzz target `noise_stats`: the body is `sl_fuzz::noise_stats` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::noise_stats(data);
});

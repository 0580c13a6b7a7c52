//! cargo-fuzz target `depth_png`: the body is `sl_fuzz::depth_png` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::depth_png(data);
});

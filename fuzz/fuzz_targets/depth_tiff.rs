//! cargo-fuzz target `depth_tiff`: the body is `sl_fuzz::depth_tiff` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::depth_tiff(data);
});

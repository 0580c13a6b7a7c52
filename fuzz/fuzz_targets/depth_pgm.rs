//! cargo-fuzz target `depth_pgm`: the body is `sl_fuzz::depth_pgm` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::depth_pgm(data);
});

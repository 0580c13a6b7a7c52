//! cargo-fuzz target `tsdf`: the body is `sl_fuzz::tsdf` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::tsdf(data);
});

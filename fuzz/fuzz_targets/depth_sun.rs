//! cargo-fuzz target `depth_sun`: the body is `sl_fuzz::depth_sun` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::depth_sun(data);
});

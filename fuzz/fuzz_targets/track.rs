//! cargo-fuzz target `track`: the body is `sl_fuzz::track` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::track(data);
});

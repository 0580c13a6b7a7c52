//! cargo-fuzz target `motion`: the body is `sl_fuzz::motion` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::motion(data);
});

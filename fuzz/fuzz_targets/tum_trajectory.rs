//! cargo-fuzz target `tum_trajectory`: the body is `sl_fuzz::tum_trajectory` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::tum_trajectory(data);
});

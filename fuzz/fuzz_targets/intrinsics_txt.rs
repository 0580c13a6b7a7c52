//! cargo-fuzz target `intrinsics_txt`: the body is `sl_fuzz::intrinsics_txt` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::intrinsics_txt(data);
});

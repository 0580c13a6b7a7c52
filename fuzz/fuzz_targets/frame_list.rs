//! cargo-fuzz target `frame_list`: the body is `sl_fuzz::frame_list` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::frame_list(data);
});

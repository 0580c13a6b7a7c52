//! cargo-fuzz target `camera_json`: the body is `sl_fuzz::camera_json` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::camera_json(data);
});

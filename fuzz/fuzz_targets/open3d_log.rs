//! cargo-fuzz target `open3d_log`: the body is `sl_fuzz::open3d_log` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::open3d_log(data);
});

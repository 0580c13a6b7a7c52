//! cargo-fuzz target `tum_depth_list`: the body is `sl_fuzz::tum_depth_list` (replayed on
//! stable by `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::tum_depth_list(data);
});

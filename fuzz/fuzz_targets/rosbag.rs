//! cargo-fuzz target `rosbag`: the body is `sl_fuzz::rosbag` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::rosbag(data);
});

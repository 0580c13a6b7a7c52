//! cargo-fuzz target `tum_associations`: the body is `sl_fuzz::tum_associations` (replayed on stable by
//! `crates/sl-fuzz/tests/corpus.rs`).
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    sl_fuzz::tum_associations(data);
});

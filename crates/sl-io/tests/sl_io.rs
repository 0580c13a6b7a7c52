//! Integration tests of `sl-io`: file round trips, reference checks on the real frames under
//! `../shared/data` (skipped with a message when absent), and fuzz-style robustness tests.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

#[path = "sl_io/fuzz.rs"]
mod fuzz;
#[path = "sl_io/real_data.rs"]
mod real_data;
#[path = "sl_io/round_trip.rs"]
mod round_trip;

/// `../shared/data` relative to the workspace root, or `None` (after printing why) when absent.
pub fn data_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipping: ../shared/data not found (looked in {})",
            dir.display()
        );
        None
    }
}

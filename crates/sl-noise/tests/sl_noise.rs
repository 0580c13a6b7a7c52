//! Integration tests of `sl-noise`: real frames, simulate → analyze recovery, proptests.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod sl_noise {
    mod algorithm1;
    mod geometry;
    mod real_frames;
    mod recovery;
    mod weak_returns;
}

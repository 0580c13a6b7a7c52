//! Integration tests of `sl-filter`: the fast kernel against the slow reference, and the
//! geometric invariants of the filters on synthetic planes.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod sl_filter {
    pub mod common;
    mod dilated;
    mod invariants;
    mod real;
    mod reference;
}

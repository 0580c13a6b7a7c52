//! Integration tests of `sl-filter`: the fast kernel against the slow reference, and the
//! geometric invariants of the filters on synthetic planes.

mod sl_filter {
    pub mod common;
    mod invariants;
    mod reference;
}

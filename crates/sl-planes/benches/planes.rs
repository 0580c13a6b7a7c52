//! Plane extraction benchmark (filled in below).
fn main() {}

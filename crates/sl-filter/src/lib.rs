//! # sl-filter — depth-map smoothing that knows the structured-light noise model
//!
//! Placeholder docs, completed below.
#![deny(missing_docs)]

pub mod error;
pub mod eval;
pub mod fastexp;
pub mod filter;
pub mod kernel;
pub mod reference;
pub mod render;

pub use error::{FilterError, Result};
pub use filter::{
    BILATERAL_DEFAULT_DEPTH_M, DEFAULT_K_MULTIPLIER, DEFAULT_RADIUS_PX, DepthFilter, MAX_DEPTH_M, MAX_PIXELS, MAX_RADIUS_PX,
    MIN_DEPTH_M, Method, RangeKernel, default_k_per_m, default_sigma_s_px,
};
pub use kernel::Isa;

/// Number of threads the filters use when called outside a custom rayon pool.
pub fn current_threads() -> usize {
    rayon::current_num_threads()
}

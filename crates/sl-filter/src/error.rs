//! The error type of `sl-filter`.

/// Everything that can go wrong in `sl-filter`.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum FilterError {
    /// A filter parameter outside its supported range (radius, σ_s, σ_d, k, σ_D).
    #[error("invalid filter parameter: {0}")]
    InvalidParameter(String),
    /// A valid depth value the filter cannot represent (outside [[`crate::MIN_DEPTH_M`],
    /// [`crate::MAX_DEPTH_M`]]).
    #[error(
        "depth {value_m:e} m at pixel ({x}, {y}) is outside the supported range [{min_m:e}, {max_m}] m"
    )]
    DepthOutOfRange {
        /// The offending value, metres.
        value_m: f32,
        /// Pixel column.
        x: usize,
        /// Pixel row.
        y: usize,
        /// The supported minimum, metres.
        min_m: f32,
        /// The supported maximum, metres.
        max_m: f32,
    },
    /// The image is larger than the filter's memory budget, or its size does not match.
    #[error("image size: {0}")]
    ImageSize(String),
    /// An error from `sl-core` (e.g. mismatched intrinsics).
    #[error(transparent)]
    Core(#[from] sl_core::CoreError),
}

/// `Result` with [`FilterError`].
pub type Result<T> = std::result::Result<T, FilterError>;

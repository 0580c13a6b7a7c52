//! The error type of `sl-eval`.

/// Everything that can go wrong while scoring or rendering for an evaluation.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum EvalError {
    /// Two images that must have the same size do not.
    #[error("image size: {0}")]
    ImageSize(String),
    /// Two label images of different sizes (SegComp).
    #[error("size mismatch: expected {expected_width}x{expected_height}, got {width}x{height}")]
    SizeMismatch {
        /// Width of the reference image.
        expected_width: usize,
        /// Height of the reference image.
        expected_height: usize,
        /// Width of the compared image.
        width: usize,
        /// Height of the compared image.
        height: usize,
    },
    /// An argument outside its valid range (a tolerance, a mask length, a render size, a view
    /// direction).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// An error from `sl-core` (e.g. intrinsics that do not match the depth image).
    #[error(transparent)]
    Core(#[from] sl_core::CoreError),
}

/// `Result` with [`EvalError`].
pub type Result<T> = std::result::Result<T, EvalError>;

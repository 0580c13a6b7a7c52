//! The error type of `sl-planes`.

/// Everything that can go wrong in `sl-planes`.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum PlanesError {
    /// A configuration value outside its valid range.
    #[error("invalid configuration: {0}")]
    InvalidConfig(String),
    /// Image and camera (or two images) of different sizes.
    #[error(
        "size mismatch: image is {width}x{height}, expected {expected_width}x{expected_height}"
    )]
    SizeMismatch {
        /// Width that was expected.
        expected_width: usize,
        /// Height that was expected.
        expected_height: usize,
        /// Width that was found.
        width: usize,
        /// Height that was found.
        height: usize,
    },
    /// A plane that cannot be represented (e.g. through the camera centre, or a disparity
    /// function that is zero everywhere).
    #[error("degenerate plane: {0}")]
    DegeneratePlane(String),
    /// An error from `sl-core`.
    #[error(transparent)]
    Core(#[from] sl_core::CoreError),
}

/// `Result` with [`PlanesError`].
pub type Result<T> = std::result::Result<T, PlanesError>;

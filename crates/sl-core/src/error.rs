//! The error type of `sl-core`.

/// Everything that can go wrong in `sl-core`.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum CoreError {
    /// A camera preset name that is not in the table.
    #[error("unknown camera preset {0}")]
    UnknownPreset(String),
    /// Camera intrinsics that cannot describe a real camera.
    #[error("invalid intrinsics: {0}")]
    InvalidIntrinsics(String),
    /// A sensor model with a non-positive focal length, baseline or step count.
    #[error("invalid sensor model: {0}")]
    InvalidSensor(String),
    /// Image dimensions that do not match the buffer or the camera.
    #[error("size mismatch: expected {expected_width}x{expected_height}, got {width}x{height}")]
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
    /// A buffer whose length is not `width * height`.
    #[error("buffer of {len} values cannot hold a {width}x{height} image")]
    BufferLength {
        /// Buffer length.
        len: usize,
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
    /// A 4x4 matrix that is not a rigid transform.
    #[error("not a rigid transform: {0}")]
    NotRigid(String),
    /// A plane with a zero or non-finite normal or offset.
    #[error("degenerate plane: {0}")]
    DegeneratePlane(String),
    /// A mesh whose attributes or triangle indices do not match its vertices.
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
}

/// `Result` with [`CoreError`].
pub type Result<T> = std::result::Result<T, CoreError>;

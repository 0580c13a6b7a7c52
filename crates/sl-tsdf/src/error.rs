//! The error type of `sl-tsdf`.

/// Everything that can go wrong while fusing depth frames or extracting a mesh.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TsdfError {
    /// A parameter outside its valid range (non-positive voxel size, truncation, ...).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The depth image does not have the camera's size.
    #[error("depth image is {width}x{height} but the camera is {expected_width}x{expected_height}")]
    SizeMismatch {
        /// Camera width.
        expected_width: usize,
        /// Camera height.
        expected_height: usize,
        /// Depth image width.
        width: usize,
        /// Depth image height.
        height: usize,
    },
    /// Integrating the frame would need more memory than the configured budget. The volume is
    /// left unchanged (the frame is not integrated).
    #[error(
        "memory budget exceeded: {blocks} voxel blocks would need {needed_bytes} bytes, budget is {budget_bytes} bytes (raise the budget or the voxel size)"
    )]
    MemoryBudget {
        /// Number of blocks the volume would hold.
        blocks: usize,
        /// Bytes they would need.
        needed_bytes: usize,
        /// The configured budget.
        budget_bytes: usize,
    },
    /// Finding the blocks a frame touches listed more candidate blocks than the memory budget
    /// can hold (checked while they are listed, so the lists stay within the budget). The
    /// volume is left unchanged.
    #[error(
        "memory budget exceeded: the frame touches more than {max_candidates} candidate voxel blocks ({candidates} listed), more than the budget can hold (raise the budget or the voxel size)"
    )]
    CandidateBudget {
        /// Candidate blocks listed when integration stopped.
        candidates: usize,
        /// The most the budget allows.
        max_candidates: usize,
    },
    /// Extracting the mesh would need more memory than the budget allows.
    #[error(
        "memory budget exceeded: the mesh ({vertices} vertices, {triangles} triangles) and the volume would need {needed_bytes} bytes, budget is {budget_bytes} bytes"
    )]
    MeshBudget {
        /// Vertices of the mesh.
        vertices: usize,
        /// Triangles of the mesh.
        triangles: usize,
        /// Bytes the volume, the extraction tables and the mesh would need.
        needed_bytes: usize,
        /// The budget.
        budget_bytes: usize,
    },
    /// The allocator refused memory (reported instead of aborting).
    #[error("out of memory while allocating {0}")]
    OutOfMemory(&'static str),
    /// A pose or point too far from the origin for the block index (±2^20 blocks).
    #[error("geometry out of range: {0}")]
    OutOfRange(String),
    /// Reading or writing a file (PLY, PNG) failed.
    #[error(transparent)]
    Io(#[from] sl_io::IoError),
    /// An error from `sl-core`.
    #[error(transparent)]
    Core(#[from] sl_core::CoreError),
}

/// `Result` with [`TsdfError`].
pub type Result<T> = std::result::Result<T, TsdfError>;

//! The error type of `sl-io`: every variant names the file it is about.

use std::fmt;
use std::path::{Path, PathBuf};

/// Everything that can go wrong while reading or writing a file.
///
/// Every variant but [`IoError::InvalidConfig`] (a configuration checked before any file is
/// named) carries the path of the file, so the message alone tells the user which file is wrong
/// and why; text formats also give the 1-based line number.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// The operating system refused to open, read, write or rename the file.
    #[error("{}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a valid instance of its format (bad header, truncated data, ...).
    #[error("{}: {message}", .path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A text file has a malformed line.
    #[error("{}:{line}: {message}", .path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An image decoder rejected the file.
    #[error("{}: cannot decode image: {message}", .path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// The decoder's message.
        message: String,
    },
    /// The image decodes, but does not hold what the format requires (e.g. an RGB image where a
    /// 16-bit single-channel depth map is expected).
    #[error("{}: unsupported image: found {found}, expected {expected}", .path.display())]
    UnsupportedImage {
        /// The file.
        path: PathBuf,
        /// What the file holds, e.g. `"8-bit RGB"`.
        found: String,
        /// What was expected, e.g. `"16-bit single-channel"`.
        expected: String,
    },
    /// The file's size or declared size exceeds what we agree to allocate.
    #[error("{}: too large: {message}", .path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Which limit was exceeded.
        message: String,
    },
    /// The depth format could not be determined, or an option does not apply to it.
    #[error("{}: {message}", .path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A depth scale (integer units per metre) outside
    /// [`crate::depth::MIN_UNITS_PER_M`]`..=`[`crate::depth::MAX_UNITS_PER_M`] (zero, negative,
    /// not finite, or so extreme that no stored value would be a meaningful depth).
    #[error("{}: invalid depth scale {units_per_m:e} units per metre (valid: 1 to 1e6 units per metre)", .path.display())]
    InvalidScale {
        /// The file.
        path: PathBuf,
        /// The rejected scale.
        units_per_m: f64,
    },
    /// A depth value that the target encoding cannot store (it would wrap or vanish).
    #[error(
        "{}: depth {depth_m} m at pixel ({x}, {y}) cannot be stored in this encoding \
         (valid depths {min_depth_m} m to max depth {max_depth_m} m)",
        .path.display()
    )]
    DepthOutOfRange {
        /// The file being written.
        path: PathBuf,
        /// Pixel column.
        x: usize,
        /// Pixel row.
        y: usize,
        /// The offending depth.
        depth_m: f32,
        /// Smallest storable depth.
        min_depth_m: f64,
        /// Largest storable depth.
        max_depth_m: f64,
    },
    /// Data handed to a writer is inconsistent (mismatched lengths, out-of-range indices, ...).
    #[error("{}: invalid data: {message}", .path.display())]
    InvalidData {
        /// The file being written.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A value read from the file is rejected by `sl-core` (invalid intrinsics, non-rigid pose).
    #[error("{}{}: {source}", .path.display(), LineSuffix(*.line))]
    Core {
        /// The file.
        path: PathBuf,
        /// 1-based line number, when the file is text and the line is known.
        line: Option<usize>,
        /// The core error.
        #[source]
        source: sl_core::CoreError,
    },
    /// A JSON file that does not parse or lacks required keys.
    #[error("{}: invalid JSON: {source}", .path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The JSON error (it carries line and column).
        #[source]
        source: serde_json::Error,
    },
    /// An output name that must not be replaced: it exists and is not a regular file (a
    /// symbolic link, directory, device, FIFO or socket), see [`crate::atomic::check_output`].
    #[error("{}: refusing to write: {message}", .path.display())]
    UnsafeOutput {
        /// The output name.
        path: PathBuf,
        /// What the name refers to.
        message: String,
    },
    /// A configuration that no file could satisfy, found by its `validate()` before any file
    /// is named (e.g. [`crate::depth::ReadConfig::validate`]); the one variant without a path
    /// ([`IoError::path`] is empty).
    #[error("invalid configuration: {message}")]
    InvalidConfig {
        /// What is wrong.
        message: String,
    },
    /// A PLY file that ply-rs cannot parse, or PLY content that does not fit [`crate::ply::PlyData`].
    #[error("{}: invalid PLY: {message}", .path.display())]
    Ply {
        /// The file.
        path: PathBuf,
        /// What is wrong (includes ply-rs's line number where it gives one).
        message: String,
    },
}

/// Formats `:line` after a path when a line is known.
struct LineSuffix(Option<usize>);

impl fmt::Display for LineSuffix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(line) => write!(f, ":{line}"),
            None => Ok(()),
        }
    }
}

impl IoError {
    /// The file this error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::Malformed { path, .. }
            | Self::Parse { path, .. }
            | Self::Decode { path, .. }
            | Self::UnsupportedImage { path, .. }
            | Self::TooLarge { path, .. }
            | Self::Format { path, .. }
            | Self::InvalidScale { path, .. }
            | Self::DepthOutOfRange { path, .. }
            | Self::InvalidData { path, .. }
            | Self::Core { path, .. }
            | Self::Json { path, .. }
            | Self::UnsafeOutput { path, .. }
            | Self::Ply { path, .. } => path,
            Self::InvalidConfig { .. } => Path::new(""),
        }
    }

    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn malformed(path: &Path, message: impl Into<String>) -> Self {
        Self::Malformed {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn parse(path: &Path, line: usize, message: impl Into<String>) -> Self {
        Self::Parse {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    pub(crate) fn too_large(path: &Path, message: impl Into<String>) -> Self {
        Self::TooLarge {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn invalid_data(path: &Path, message: impl Into<String>) -> Self {
        Self::InvalidData {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn core(path: &Path, line: Option<usize>, source: sl_core::CoreError) -> Self {
        Self::Core {
            path: path.to_path_buf(),
            line,
            source,
        }
    }
}

/// `Result` with [`IoError`].
pub type Result<T> = std::result::Result<T, IoError>;

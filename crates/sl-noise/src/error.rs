//! The error type of `sl-noise`.

use sl_core::CoreError;

/// Everything that can go wrong in `sl-noise`.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum NoiseError {
    /// A depth map with too few distinct depth values for a resolution analysis.
    #[error("too few distinct depths{within}: found {found}, need at least {needed}")]
    TooFewDepths {
        /// Where they were counted: empty for the whole frame, else e.g. " in the far range".
        within: &'static str,
        /// Distinct depth values found.
        found: usize,
        /// Distinct depth values needed.
        needed: usize,
    },
    /// A parameter outside its valid range (non-positive step, NaN, …).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// Degenerate geometry: zero-length normal, non-orthogonal rectangle axes, non-positive radius.
    #[error("degenerate geometry: {0}")]
    DegenerateGeometry(String),
    /// A scene already holding the maximum of 65535 labelled surfaces.
    #[error("a scene holds at most {max} surfaces")]
    SceneFull {
        /// The maximum number of surfaces.
        max: usize,
    },
    /// A scene name that [`crate::sim::named_scene`] does not know.
    #[error("unknown scene {name:?}; known scenes: {known}")]
    UnknownScene {
        /// The requested name.
        name: String,
        /// The known names, comma-separated.
        known: String,
    },
    /// Work that would exceed a stated memory budget.
    #[error("{what}: {requested} exceeds the budget of {budget}")]
    TooLarge {
        /// What was refused.
        what: String,
        /// The requested amount.
        requested: usize,
        /// The budget.
        budget: usize,
    },
    /// An error from `sl-core` (bad intrinsics, sensor model, buffer sizes).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// `Result` with [`NoiseError`].
pub type Result<T> = std::result::Result<T, NoiseError>;

/// A number for a message: as Rust prints it for magnitudes from 1e-4 to below 1e6, in
/// scientific notation beyond them (a `1e300` printed by `{}` is a 301-digit decimal).
pub(crate) fn num(v: f64) -> String {
    let a = v.abs();
    if a.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

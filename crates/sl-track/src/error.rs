//! The error type of `sl-track`.

/// Everything that can go wrong in `sl-track`.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum TrackError {
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
    /// Too few matched planes or points to determine a motion.
    #[error("motion not determined: {0}")]
    MotionUndetermined(String),
    /// No motion hypothesis passed the check against the depth data, or two distinct ones
    /// passed about equally well: the motion is not determined (rather than guessed).
    #[error("motion not verified: {reason}")]
    MotionNotVerified {
        /// Why the check failed.
        reason: String,
        /// Inlier fraction of the best hypothesis (of the overlapping points).
        inlier_fraction: f64,
        /// Largest inlier fraction of an alternative that is rotated more than
        /// `distinct_deg` from the best (another hypothesis, or the best turned).
        alternative_inlier_fraction: f64,
    },
    /// A frame's timestamp is not finite or not after the previous frame's (`previous_s` is
    /// NaN when there was none).
    #[error("{}", timestamp_message(*previous_s, *timestamp_s))]
    TimestampOrder {
        /// The previous frame's timestamp, seconds.
        previous_s: f64,
        /// This frame's timestamp, seconds.
        timestamp_s: f64,
    },
    /// An error from plane extraction (`sl-planes`).
    #[error(transparent)]
    Planes(#[from] sl_planes::PlanesError),
    /// An error from the model (`sl-tsdf`), as its message (`TsdfError` is neither `Clone`
    /// nor `PartialEq`).
    #[error("model: {0}")]
    Tsdf(String),
    /// An error from `sl-core`.
    #[error(transparent)]
    Core(#[from] sl_core::CoreError),
}

impl From<sl_tsdf::TsdfError> for TrackError {
    fn from(e: sl_tsdf::TsdfError) -> Self {
        Self::Tsdf(e.to_string())
    }
}

/// `Result` with [`TrackError`].
pub type Result<T> = std::result::Result<T, TrackError>;

/// The message of [`TrackError::TimestampOrder`].
fn timestamp_message(previous_s: f64, timestamp_s: f64) -> String {
    let (t, p) = (stamp(timestamp_s), stamp(previous_s));
    if !timestamp_s.is_finite() {
        format!("timestamp {t} s is not a finite number of seconds")
    } else {
        format!("timestamp {t} s is not after the previous frame's {p} s")
    }
}

/// A timestamp as written (every digit of a clock's seconds), or in exponent form when it is
/// too large to be one (a 300-digit number helps nobody).
fn stamp(t: f64) -> String {
    if t.abs() < 1e15 {
        t.to_string()
    } else {
        sl_core::Compact(t).to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::timestamp_message;

    /// A clock's timestamp keeps its digits; an absurd one is short.
    #[test]
    fn timestamps_in_messages_are_readable() {
        let m = timestamp_message(1305031229.528784, 1305031229.5);
        assert!(
            m.contains("1305031229.5 s") && m.contains("1305031229.528784 s"),
            "{m}"
        );
        let m = timestamp_message(0.0, -1e300);
        assert!(m.contains("-1e300") && m.len() < 80, "{m}");
    }
}

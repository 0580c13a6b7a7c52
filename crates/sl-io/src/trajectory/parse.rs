//! Text input shared by the trajectory readers: reading a file within the [`Limits`], its data
//! lines, the numbers on them, and the frame limit.

use std::path::Path;

use crate::error::{IoError, Result};
use crate::limits::{BUDGET_OPTION, Limits};
use crate::text::read_text;

/// Reads a text input within `limits`.
pub(super) fn read_limited(path: &Path, limits: &Limits) -> Result<String> {
    read_text(path, limits.max_text_bytes, limits.max_text_lines)
}

/// Fails when a sequence has more than [`Limits::max_frames`] frames.
pub(crate) fn check_frames(path: &Path, n: usize, limits: &Limits) -> Result<()> {
    if n > limits.max_frames {
        return Err(IoError::too_large(
            path,
            format!(
                "more than {} frames, over the frame limit (raise it with {BUDGET_OPTION})",
                limits.max_frames
            ),
        ));
    }
    Ok(())
}

/// Non-empty, non-comment lines with their 1-based numbers.
pub(super) fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    crate::text::text_lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

pub(super) fn parse_f64(path: &Path, line: usize, tok: &str, what: &str) -> Result<f64> {
    let v: f64 = tok
        .parse()
        .map_err(|_| IoError::parse(path, line, format!("{what}: {tok:?} is not a number")))?;
    if !v.is_finite() {
        return Err(IoError::parse(
            path,
            line,
            format!("{what}: {tok:?} is not finite"),
        ));
    }
    Ok(v)
}

pub(super) fn parse_n<const N: usize>(
    path: &Path,
    line: usize,
    toks: &[&str],
    what: &str,
) -> Result<[f64; N]> {
    if toks.len() != N {
        return Err(IoError::parse(
            path,
            line,
            format!("expected {N} numbers ({what}), found {} fields", toks.len()),
        ));
    }
    let mut out = [0.0; N];
    for (o, t) in out.iter_mut().zip(toks) {
        *o = parse_f64(path, line, t, what)?;
    }
    Ok(out)
}

//! A strict, bounded reader for binary PNM files (`P5` grey, `P6` colour).
//!
//! The header is parsed from at most [`MAX_HEADER_BYTES`] bytes, the sizes are checked (at most
//! [`crate::limits::MAX_SIDE`] per side, the pixels within [`Limits::max_pixels`], the sample
//! data within [`Limits::max_decoded_bytes`]) *before* the sample buffer is allocated; the
//! samples are then read as they arrive (a pipe works too) and a short file is an error.

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{IoError, Result};
use crate::limits::{Limits, MAX_SIDE};

/// The longest header we accept (magic, sizes, maxval and comments).
pub(crate) const MAX_HEADER_BYTES: usize = 4096;

/// Binary PNM kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PnmKind {
    /// `P5`: one channel.
    Gray,
    /// `P6`: three channels.
    Rgb,
}

impl PnmKind {
    pub(crate) fn channels(self) -> usize {
        match self {
            Self::Gray => 1,
            Self::Rgb => 3,
        }
    }
}

/// A parsed PNM header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct PnmHeader {
    pub kind: PnmKind,
    pub width: usize,
    pub height: usize,
    pub maxval: u32,
    /// Offset of the first sample byte.
    pub data_offset: usize,
}

impl PnmHeader {
    /// Bytes per sample: 1 for maxval < 256, else 2.
    pub(crate) fn bytes_per_sample(&self) -> usize {
        if self.maxval < 256 { 1 } else { 2 }
    }

    /// Sample data length in bytes (checked; sides are at most 65536 so this cannot overflow
    /// on 64-bit, but stay checked for 32-bit targets).
    pub(crate) fn data_len(&self) -> Option<usize> {
        self.width
            .checked_mul(self.height)?
            .checked_mul(self.kind.channels())?
            .checked_mul(self.bytes_per_sample())
    }
}

/// Why a header prefix did not parse.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum HeaderError {
    /// The prefix ended before the header did.
    Incomplete,
    /// The header is invalid.
    Invalid(String),
}

fn is_ws(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
}

/// Parses a header from the start of `buf`.
pub(crate) fn parse_header(buf: &[u8]) -> std::result::Result<PnmHeader, HeaderError> {
    if buf.len() < 2 {
        return Err(HeaderError::Incomplete);
    }
    let kind = match &buf[..2] {
        b"P5" => PnmKind::Gray,
        b"P6" => PnmKind::Rgb,
        other => {
            return Err(HeaderError::Invalid(format!(
                "not a binary PGM/PPM file: magic {:?}, expected \"P5\" or \"P6\"",
                String::from_utf8_lossy(other)
            )));
        }
    };
    let mut pos = 2;
    let mut fields = [0u64; 3];
    for (i, name) in ["width", "height", "maxval"].iter().enumerate() {
        // At least one whitespace character (comments count as whitespace).
        let start = pos;
        loop {
            match buf.get(pos) {
                None => return Err(HeaderError::Incomplete),
                Some(&b) if is_ws(b) => pos += 1,
                Some(b'#') => {
                    while let Some(&b) = buf.get(pos) {
                        pos += 1;
                        if b == b'\n' || b == b'\r' {
                            break;
                        }
                    }
                    if pos >= buf.len() {
                        return Err(HeaderError::Incomplete);
                    }
                }
                Some(_) => break,
            }
        }
        if pos == start {
            return Err(HeaderError::Invalid(format!(
                "missing whitespace before {name}"
            )));
        }
        let digits_start = pos;
        let mut value: u64 = 0;
        while let Some(&b) = buf.get(pos) {
            if !b.is_ascii_digit() {
                break;
            }
            if pos - digits_start >= 9 {
                return Err(HeaderError::Invalid(format!("{name} has too many digits")));
            }
            value = value * 10 + u64::from(b - b'0');
            pos += 1;
        }
        if pos == digits_start {
            return match buf.get(pos) {
                None => Err(HeaderError::Incomplete),
                Some(&b) => Err(HeaderError::Invalid(format!(
                    "expected a decimal {name}, found byte 0x{b:02x}"
                ))),
            };
        }
        if pos >= buf.len() {
            return Err(HeaderError::Incomplete);
        }
        fields[i] = value;
    }
    // Exactly one whitespace character separates maxval from the data.
    match buf.get(pos) {
        None => return Err(HeaderError::Incomplete),
        Some(&b) if is_ws(b) => pos += 1,
        Some(&b) => {
            return Err(HeaderError::Invalid(format!(
                "expected whitespace after maxval, found byte 0x{b:02x}"
            )));
        }
    }
    let [w, h, maxval] = fields;
    for (name, v) in [("width", w), ("height", h)] {
        if v == 0 || v > MAX_SIDE as u64 {
            return Err(HeaderError::Invalid(format!(
                "{name} {v} must be in 1..={MAX_SIDE}"
            )));
        }
    }
    if maxval == 0 || maxval > 65535 {
        return Err(HeaderError::Invalid(format!(
            "maxval {maxval} must be in 1..=65535"
        )));
    }
    Ok(PnmHeader {
        kind,
        width: w as usize,
        height: h as usize,
        maxval: maxval as u32,
        data_offset: pos,
    })
}

/// Reads a binary PNM file: the header, then exactly the sample bytes it declares (trailing
/// bytes, which the format allows for further images, are ignored).
pub(crate) fn read_pnm(path: &Path, limits: &Limits) -> Result<(PnmHeader, Vec<u8>)> {
    let mut file = File::open(path).map_err(|e| IoError::io(path, e))?;
    let mut prefix = Vec::with_capacity(MAX_HEADER_BYTES);
    (&mut file)
        .take(MAX_HEADER_BYTES as u64)
        .read_to_end(&mut prefix)
        .map_err(|e| IoError::io(path, e))?;
    let header = match parse_header(&prefix) {
        Ok(h) => h,
        Err(HeaderError::Invalid(msg)) => return Err(IoError::malformed(path, msg)),
        Err(HeaderError::Incomplete) if prefix.len() >= MAX_HEADER_BYTES => {
            return Err(IoError::malformed(
                path,
                format!("PGM/PPM header longer than {MAX_HEADER_BYTES} bytes"),
            ));
        }
        Err(HeaderError::Incomplete) => {
            return Err(IoError::malformed(path, "truncated PGM/PPM header"));
        }
    };
    limits
        .check_pixels(header.width as u64, header.height as u64)
        .map_err(|m| IoError::too_large(path, m))?;
    let Some(data_len) = header.data_len() else {
        return Err(IoError::too_large(path, "image size overflows"));
    };
    if data_len as u64 > limits.max_decoded_bytes {
        return Err(IoError::too_large(
            path,
            format!(
                "{}x{} image needs {data_len} bytes, over the {}-byte decode limit",
                header.width, header.height, limits.max_decoded_bytes
            ),
        ));
    }
    // The samples: what followed the header in the prefix, then the rest as it arrives (no
    // seek, no metadata: a FIFO reads the same way), never more than the header declares.
    // A regular file's length tells a truncated file before the buffer is allocated; a pipe's
    // buffer grows as data arrives.
    let regular_len = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    let declared_end = header.data_offset as u64 + data_len as u64;
    let mut data = match regular_len {
        Some(len) if len < declared_end => Vec::new(),
        Some(_) => Vec::with_capacity(data_len),
        None => Vec::with_capacity(data_len.min(1 << 20)),
    };
    let head = prefix.get(header.data_offset..).unwrap_or(&[]);
    data.extend_from_slice(&head[..head.len().min(data_len)]);
    let missing = (data_len - data.len()) as u64;
    if regular_len.is_none_or(|len| len >= declared_end) {
        file.take(missing)
            .read_to_end(&mut data)
            .map_err(|e| IoError::io(path, e))?;
    } else {
        data.clear();
    }
    if data.len() < data_len {
        return Err(IoError::malformed(
            path,
            format!(
                "truncated data: the header declares {}x{}x{} samples of {} byte(s) = {data_len} bytes, \
                 the file holds {}",
                header.width,
                header.height,
                header.kind.channels(),
                header.bytes_per_sample(),
                regular_len.map_or(data.len() as u64, |l| l
                    .saturating_sub(header.data_offset as u64))
            ),
        ));
    }
    Ok((header, data))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_nyu_style_header() {
        let h = parse_header(b"P5 640 480 65535\n\xff\x07").unwrap();
        assert_eq!(
            h,
            PnmHeader {
                kind: PnmKind::Gray,
                width: 640,
                height: 480,
                maxval: 65535,
                data_offset: 17
            }
        );
        assert_eq!(h.data_len(), Some(640 * 480 * 2));
    }

    #[test]
    fn comments_are_whitespace() {
        let h = parse_header(b"P6\n# made by hand\n3 # w\n2\n255\nxyz").unwrap();
        assert_eq!(
            (h.kind, h.width, h.height, h.maxval),
            (PnmKind::Rgb, 3, 2, 255)
        );
        assert_eq!(h.bytes_per_sample(), 1);
        assert_eq!(h.data_len(), Some(18));
    }

    #[test]
    fn rejects_bad_headers() {
        for bad in [
            &b"P2 1 1 255\n"[..],
            b"P5 0 1 255\n",
            b"P5 65537 1 255\n",
            b"P5 1 1 65536\n",
            b"P5 1 1 0\n",
            b"P5 x 1 255\n",
            b"P51 1 255\n",
            b"P5 1 1 255x",
            b"P5 9999999999 1 255\n",
        ] {
            assert!(
                matches!(parse_header(bad), Err(HeaderError::Invalid(_))),
                "{:?}",
                String::from_utf8_lossy(bad)
            );
        }
        for short in [
            &b""[..],
            b"P5",
            b"P5 640",
            b"P5 640 480 65535",
            b"P5 # comment",
        ] {
            assert_eq!(parse_header(short), Err(HeaderError::Incomplete));
        }
    }
}

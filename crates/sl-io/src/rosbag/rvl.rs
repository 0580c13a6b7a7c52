//! RVL, the `compressedDepth` plugin's second codec (`"16UC1; compressedDepth rvl"`, ROS 1
//! Noetic and ROS 2 `image_transport_plugins`): A. D. Wilson's run-length / variable-length
//! coding of 16-bit depth (*Fast Lossless Depth Image Compression*, ISS 2017).
//!
//! After the plugin's 12-byte configuration header the message holds the image's width and
//! height (two little-endian `u32`) and then a stream of little-endian 32-bit words, each read
//! as eight 4-bit nibbles from its most significant end. A number is written in nibbles of 3
//! value bits, least significant first, the nibble's fourth bit set while more follow. The
//! pixels, in row order, alternate between a run of zeros and a run of non-zero values: the
//! length of each run, then each non-zero value as its zig-zag coded difference from the
//! previous non-zero value (`2d` for `d ≥ 0`, `−2d − 1` for `d < 0`; the first from 0).
//!
//! Written by hand (about 80 lines): no maintained crate decodes it. Nothing in the stream is
//! trusted: the size is checked against [`Limits`] before anything is allocated, a run longer
//! than the pixels left, a number of more than 11 nibbles or a stream that ends early is an
//! error (the plugin's own decoder writes past its buffer on the first and reads past the
//! message on the last).

use std::path::Path;

use sl_core::Image;

use crate::error::{IoError, Result};
use crate::limits::Limits;

/// Nibbles a number may take: 11 hold 33 bits, more than any run length or difference.
const MAX_NIBBLES: u32 = 11;

/// The 16-bit image of an RVL stream (`data`: what follows the configuration header).
pub(super) fn decode(path: &Path, data: &[u8], limits: &Limits) -> Result<Image<u16>> {
    let malformed = |what: String| IoError::malformed(path, format!("an RVL depth image: {what}"));
    let Some((size, stream)) = data.split_first_chunk::<8>() else {
        return Err(malformed(format!(
            "{} bytes, shorter than its 8-byte size",
            data.len()
        )));
    };
    let width = u32::from_le_bytes([size[0], size[1], size[2], size[3]]);
    let height = u32::from_le_bytes([size[4], size[5], size[6], size[7]]);
    if width == 0 || height == 0 {
        return Err(malformed(format!("size {width}x{height}")));
    }
    limits
        .check_pixels(u64::from(width), u64::from(height))
        .map_err(|m| IoError::too_large(path, m))?;
    let n = width as usize * height as usize;
    let mut px = vec![0u16; n];
    let mut nibbles = Nibbles::new(stream);
    let mut number = |what: &str, at: usize| {
        nibbles
            .number()
            .map_err(|e| malformed(format!("{e} in the {what} at pixel {at} of {n}")))
    };
    let (mut i, mut previous) = (0usize, 0u16);
    while i < n {
        let zeros = number("length of a run of zeros", i)?;
        i = run_end(i, zeros, n).map_err(&malformed)?;
        if i == n {
            // The encoder still writes the (empty) run of non-zero values that follows.
            break;
        }
        let values = number("length of a run of values", i)?;
        let end = run_end(i, values, n).map_err(&malformed)?;
        for p in &mut px[i..end] {
            let zigzag = number("value", i)?;
            // At most 33 bits (`MAX_NIBBLES`): exact as an `i64`.
            let delta = (zigzag >> 1) as i64 ^ -((zigzag & 1) as i64);
            // The plugin adds in `int` and stores the low 16 bits.
            previous = (i64::from(previous) + delta) as u16;
            *p = previous;
            i += 1;
        }
    }
    Image::from_vec(width as usize, height as usize, px).map_err(|e| IoError::core(path, None, e))
}

/// The pixel after a run of `len` starting at `i`, or why there is none.
fn run_end(i: usize, len: u64, n: usize) -> std::result::Result<usize, String> {
    match usize::try_from(len).ok().and_then(|l| i.checked_add(l)) {
        Some(end) if end <= n => Ok(end),
        _ => Err(format!(
            "a run of {len} pixels at pixel {i}, past the image's {n}"
        )),
    }
}

/// Reads the stream's nibbles, most significant first within each little-endian word.
struct Nibbles<'a> {
    words: std::slice::ChunksExact<'a, u8>,
    word: u32,
    left: u32,
}

impl<'a> Nibbles<'a> {
    fn new(stream: &'a [u8]) -> Self {
        Self {
            words: stream.chunks_exact(4),
            word: 0,
            left: 0,
        }
    }

    /// The next number (3 bits a nibble, least significant first, bit 3 = more follow).
    fn number(&mut self) -> std::result::Result<u64, String> {
        let mut value = 0u64;
        for k in 0..MAX_NIBBLES {
            if self.left == 0 {
                let w = self.words.next().ok_or("the stream ends")?;
                self.word = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
                self.left = 8;
            }
            let nibble = self.word >> 28;
            self.word <<= 4;
            self.left -= 1;
            value |= u64::from(nibble & 7) << (3 * k);
            if nibble & 8 == 0 {
                return Ok(value);
            }
        }
        Err(format!("a number longer than {MAX_NIBBLES} nibbles"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The test kit's encoder, written from the format's description.
    fn encode(width: u32, height: u32, px: &[u16]) -> Vec<u8> {
        let img = Image::from_vec(width as usize, height as usize, px.to_vec()).unwrap();
        sl_testkit::rosbag_writer::rvl_encode(&img)
    }

    fn path() -> &'static Path {
        Path::new("m.bag")
    }

    #[test]
    fn decodes_what_the_format_encodes() {
        let px: Vec<u16> = vec![
            0, 0, 1000, 1001, 999, 65535, 1, 0, 0, 0, 0, 0, 4000, 0, 0, 12, 12, 12, 0, 0, 0,
        ];
        let data = encode(7, 3, &px);
        let img = decode(path(), &data, &Limits::default()).unwrap();
        assert_eq!((img.width(), img.height()), (7, 3));
        assert_eq!(img.data(), &px[..]);
        // All zero; all non-zero; a single pixel.
        for px in [vec![0u16; 640 * 480], vec![777u16; 640 * 480]] {
            let img = decode(path(), &encode(640, 480, &px), &Limits::default()).unwrap();
            assert_eq!(img.data(), &px[..]);
        }
        let img = decode(path(), &encode(1, 1, &[9]), &Limits::default()).unwrap();
        assert_eq!(img.data(), &[9]);
    }

    #[test]
    fn a_large_frame_round_trips() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let px: Vec<u16> = (0..640 * 480)
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                if state.is_multiple_of(11) {
                    0
                } else {
                    (800 + (i % 640) + (state % 5) as usize) as u16
                }
            })
            .collect();
        let data = encode(640, 480, &px);
        assert!(data.len() < px.len() * 2);
        let img = decode(path(), &data, &Limits::default()).unwrap();
        assert_eq!(img.data(), &px[..]);
    }

    #[test]
    fn damaged_streams_are_errors() {
        let px = vec![0u16, 5, 6, 7, 0, 0, 9, 9];
        let good = encode(4, 2, &px);
        let err = |d: &[u8]| {
            decode(path(), d, &Limits::default())
                .unwrap_err()
                .to_string()
        };
        // Every cut: an error, never a panic (a cut inside the last word's padding may still
        // hold the whole image: then it decodes).
        for cut in 0..good.len() {
            if let Err(e) = decode(path(), &good[..cut], &Limits::default()) {
                assert!(e.to_string().contains("RVL"), "{e}");
            }
        }
        assert!(err(&good[..4]).contains("shorter than its 8-byte size"));
        assert!(err(&good[..8]).contains("the stream ends"));
        // A size of zero, and one beyond the limits (checked before allocating).
        let mut zero = good.clone();
        zero[..4].copy_from_slice(&0u32.to_le_bytes());
        assert!(err(&zero).contains("size 0x2"));
        let mut huge = good.clone();
        huge[..8].copy_from_slice(&[0xff; 8]);
        let e = decode(path(), &huge, &Limits::default()).unwrap_err();
        assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
        // A run longer than the image: the image is 4x2, the stream says 9 zeros.
        let mut long = 4u32.to_le_bytes().to_vec();
        long.extend_from_slice(&2u32.to_le_bytes());
        long.extend_from_slice(&0x9100_0000u32.to_le_bytes());
        assert!(err(&long).contains("past the image's 8"), "{}", err(&long));
        // A number that never ends.
        let mut endless = 4u32.to_le_bytes().to_vec();
        endless.extend_from_slice(&2u32.to_le_bytes());
        endless.extend_from_slice(&[0xff; 8]);
        assert!(err(&endless).contains("longer than 11 nibbles"));
    }

    /// Random streams behind a valid size, and random flips of a valid stream: an image or an
    /// error, never a panic.
    #[test]
    fn random_streams_decode_or_fail_cleanly() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let px: Vec<u16> = (0..40 * 30)
            .map(|i| if i % 9 < 3 { 0 } else { i as u16 })
            .collect();
        let good = encode(40, 30, &px);
        let mut decoded = 0;
        for round in 0..4000 {
            let data = if round % 2 == 0 {
                let mut d = 40u32.to_le_bytes().to_vec();
                d.extend_from_slice(&30u32.to_le_bytes());
                d.extend((0..next() % 600).map(|_| next() as u8));
                d
            } else {
                let mut d = good.clone();
                for _ in 0..1 + next() % 4 {
                    let at = (next() as usize) % d.len();
                    d[at] ^= 1 << (next() % 8);
                }
                d
            };
            if let Ok(img) = decode(path(), &data, &Limits::default()) {
                assert_eq!(img.data().len(), img.width() * img.height());
                decoded += 1;
            }
        }
        assert!(decoded > 0);
    }
}

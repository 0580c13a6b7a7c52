//! Resource limits: how much a reader may allocate, checked **before** it allocates.
//!
//! A [`Limits`] value (modelled on `image::Limits`) bounds every reader of this crate and the
//! commands of the `sldepth` CLI:
//!
//! | field | default | checked |
//! |---|---|---|
//! | [`Limits::max_memory_bytes`] | 4 GiB | the budget all the others derive from ([`Limits::for_memory`]) |
//! | [`Limits::max_pixels`] | 16 777 216 (4096²: VGA … 4K depth maps) | image and PGM headers before decoding, camera sizes at load |
//! | [`Limits::max_decoded_bytes`] | 128 MiB | the `image` decoder's own allocation cap |
//! | [`Limits::max_text_bytes`] | 64 MiB | text inputs, counted while streaming (pipes and FIFOs too) |
//! | [`Limits::max_text_lines`] | 1 048 576 | text inputs, counted while streaming |
//! | [`Limits::max_frames`] | 524 288 (4.8 h at 30 Hz) | trajectories, associations, frame lists |
//! | [`Limits::max_ply_elements`] | 33 554 432 | PLY element counts, from the header |
//! | [`Limits::tsdf_budget_bytes`] | 1.33 GiB | TSDF voxel blocks and candidate blocks |
//! | [`Limits::mesh_budget_bytes`] | 3 GiB | a TSDF volume and the mesh extracted from it |
//!
//! Each derived limit is the memory budget divided by a fixed per-item cost
//! ([`BYTES_PER_PIXEL`], [`BYTES_PER_TEXT_BYTE`], ...), so that one number — the CLI's
//! `--max-memory` — raises them all together, and a command on any input stays within the
//! budget (plus the constant cost of the program itself, see `docs/ARCHITECTURE.md`).

/// How a message names the memory budget's setting: the command line's option. Front-ends with
/// another name for it (the Python keyword) replace this one string in the messages.
pub const BUDGET_OPTION: &str = "--max-memory";

/// Largest accepted image side, pixels (`sl_core::Intrinsics::validate`'s bound).
pub const MAX_SIDE: usize = sl_core::intrinsics::MAX_SIDE_PX;

/// Largest decoded image of the default limits, bytes ([`Limits::max_decoded_bytes`]).
pub const MAX_DECODE_BYTES: u64 = DEFAULT_MAX_MEMORY_BYTES / BYTES_PER_DECODED_BYTE;

/// Largest text file of the default limits, bytes ([`Limits::max_text_bytes`]).
pub const MAX_TEXT_BYTES: u64 = DEFAULT_MAX_MEMORY_BYTES / BYTES_PER_TEXT_BYTE;

/// The default memory budget: 4 GiB.
pub const DEFAULT_MAX_MEMORY_BYTES: u64 = 4 << 30;

/// Smallest memory budget [`Limits::for_memory`] accepts: 16 MiB.
pub const MIN_MEMORY_BYTES: u64 = 16 << 20;

/// Budget bytes per image pixel: the most any command holds per pixel of its input (raw
/// values, metres, filtered copy, per-pixel tables of plane extraction and motion, output
/// encoding) stays below this.
pub const BYTES_PER_PIXEL: u64 = 256;

/// Budget bytes per byte the `image` decoder may allocate.
pub const BYTES_PER_DECODED_BYTE: u64 = 32;

/// Budget bytes per byte of a text input (the text, its parsed lines and their values).
pub const BYTES_PER_TEXT_BYTE: u64 = 64;

/// Budget bytes per line of a text input.
pub const BYTES_PER_TEXT_LINE: u64 = 4096;

/// Budget bytes per frame of a sequence (its path and pose, and the per-frame timings and
/// status): `sldepth track`, the heaviest holder, keeps about 0.5 KiB per frame (path, pose or
/// the reason it was lost, eight timings). 256 KiB until session 79 refused a 9-minute
/// recording at the default budget.
pub const BYTES_PER_FRAME: u64 = 8 << 10;

/// Budget bytes per PLY element (parsed record, copy into `PlyData`).
pub const BYTES_PER_PLY_ELEMENT: u64 = 128;

/// How much any reader or command may allocate. Build it with [`Limits::default`] or
/// [`Limits::for_memory`], then adjust fields if needed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Limits {
    /// The memory budget the other limits derive from, bytes.
    pub max_memory_bytes: u64,
    /// Most pixels of one image (width × height), checked from the header before decoding.
    pub max_pixels: u64,
    /// Most bytes the image decoder may allocate.
    pub max_decoded_bytes: u64,
    /// Most bytes of one text input (camera files, trajectories, frame lists), counted while
    /// reading.
    pub max_text_bytes: u64,
    /// Most lines of one text input, counted while reading.
    pub max_text_lines: u64,
    /// Most frames of a sequence (trajectory, associations, frame list).
    pub max_frames: usize,
    /// Most entries of all the elements of a PLY file together.
    pub max_ply_elements: u64,
    /// Memory of the TSDF volume and its candidate blocks during integration, bytes: 1/3 of the
    /// budget (4/9 of [`Limits::mesh_budget_bytes`]).
    pub tsdf_budget_bytes: usize,
    /// Memory of a TSDF volume and the mesh extracted from it together, bytes: 3/4 of the
    /// budget (the rest is for the program and the frames).
    pub mesh_budget_bytes: usize,
}

impl Default for Limits {
    /// [`Limits::for_memory`] of [`DEFAULT_MAX_MEMORY_BYTES`] (4 GiB).
    fn default() -> Self {
        Self::for_memory(DEFAULT_MAX_MEMORY_BYTES)
    }
}

impl Limits {
    /// The limits of a memory budget of `bytes` (at least [`MIN_MEMORY_BYTES`]; smaller values
    /// are raised to it): every limit is the budget divided by its per-item cost. A TSDF volume
    /// and its mesh get 3/4 of it together (the rest is for the frames being integrated and the
    /// program), the volume alone 1/3, so that a full volume can still be meshed: extracting a
    /// mesh takes up to about as much memory as its volume (TUM fr1/rpy-200 fused at 4 mm
    /// without a prefilter, 23 frames: 78 MB of blocks, a mesh of 0.91 M vertices and 1.71 M
    /// triangles, 46 MB; two simulated white-noise frames fused at 5 mm at the wrong poses,
    /// surfaces everywhere: 118 MB of blocks, 127 MB to mesh them), and 3/4 = 1/3 · (1 + 1.25)
    /// leaves room for a mesh of 1.25 times its volume.
    pub fn for_memory(bytes: u64) -> Self {
        let b = bytes.max(MIN_MEMORY_BYTES);
        let mesh = b - b / 4;
        Self {
            max_memory_bytes: b,
            max_pixels: b / BYTES_PER_PIXEL,
            max_decoded_bytes: b / BYTES_PER_DECODED_BYTE,
            max_text_bytes: b / BYTES_PER_TEXT_BYTE,
            max_text_lines: b / BYTES_PER_TEXT_LINE,
            max_frames: usize::try_from(b / BYTES_PER_FRAME).unwrap_or(usize::MAX),
            max_ply_elements: b / BYTES_PER_PLY_ELEMENT,
            tsdf_budget_bytes: usize::try_from(b / 3).unwrap_or(usize::MAX),
            mesh_budget_bytes: usize::try_from(mesh).unwrap_or(usize::MAX),
        }
    }

    /// Limits that never refuse anything (for trusted inputs and tests).
    pub fn unlimited() -> Self {
        Self {
            max_memory_bytes: u64::MAX,
            max_pixels: u64::MAX,
            max_decoded_bytes: u64::MAX,
            max_text_bytes: u64::MAX - 1,
            max_text_lines: u64::MAX,
            max_frames: usize::MAX,
            max_ply_elements: u64::MAX,
            tsdf_budget_bytes: usize::MAX,
            mesh_budget_bytes: usize::MAX,
        }
    }

    /// Checks an image size against [`Limits::max_pixels`] and [`MAX_SIDE`]; the message says
    /// which limit and how to raise it.
    pub fn check_pixels(&self, width: u64, height: u64) -> std::result::Result<(), String> {
        let pixels = width.saturating_mul(height);
        if width > MAX_SIDE as u64 || height > MAX_SIDE as u64 {
            return Err(format!(
                "{width}x{height} image: each side must be at most {MAX_SIDE} pixels"
            ));
        }
        if pixels > self.max_pixels {
            return Err(format!(
                "{width}x{height} image has {pixels} pixels, over the limit of {} pixels \
                 (memory budget {} bytes at {BYTES_PER_PIXEL} bytes per pixel; raise it with \
                 {BUDGET_OPTION})",
                self.max_pixels, self.max_memory_bytes
            ));
        }
        Ok(())
    }

    /// The `image` crate limits of these limits.
    pub(crate) fn image_limits(&self) -> image::Limits {
        let mut limits = image::Limits::default();
        let side = (MAX_SIDE as u64)
            .min(self.max_pixels)
            .min(u64::from(u32::MAX)) as u32;
        limits.max_image_width = Some(side);
        limits.max_image_height = Some(side);
        limits.max_alloc = Some(self.max_decoded_bytes);
        limits
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_cover_4k_and_refuse_bombs() {
        let l = Limits::default();
        assert!(l.check_pixels(640, 480).is_ok());
        assert!(l.check_pixels(3840, 2160).is_ok());
        assert!(l.check_pixels(4096, 4096).is_ok());
        assert!(l.check_pixels(16384, 16384).is_err());
        assert!(l.check_pixels(65537, 1).is_err());
        // An hour at 30 Hz.
        assert!(l.max_frames >= 108_000, "{}", l.max_frames);
        assert_eq!(l.max_decoded_bytes, MAX_DECODE_BYTES);
        assert_eq!(l.max_text_bytes, MAX_TEXT_BYTES);
    }

    #[test]
    fn limits_scale_with_the_budget() {
        let small = Limits::for_memory(64 << 20);
        let big = Limits::for_memory(64 << 30);
        assert!(small.max_pixels < Limits::default().max_pixels);
        assert!(big.max_pixels > Limits::default().max_pixels);
        assert_eq!(Limits::for_memory(0), Limits::for_memory(MIN_MEMORY_BYTES));
        assert!(Limits::unlimited().check_pixels(65536, 65536).is_ok());
    }
}

//! Resource limits applied to every decoder, so a malicious header cannot make us allocate
//! gigabytes.

/// Largest accepted image side, pixels (the same bound as `sl_core::Intrinsics::validate`).
pub const MAX_SIDE: usize = 65536;

/// Largest decoded image we agree to allocate, bytes (512 MiB: a 16384×16384 16-bit image).
pub const MAX_DECODE_BYTES: u64 = 512 * 1024 * 1024;

/// Largest text file (camera JSON, intrinsics, trajectories, associations) we read, bytes.
pub const MAX_TEXT_BYTES: u64 = 256 * 1024 * 1024;

/// The `image` crate limits built from [`MAX_SIDE`] and [`MAX_DECODE_BYTES`].
pub(crate) fn image_limits() -> image::Limits {
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_SIDE as u32);
    limits.max_image_height = Some(MAX_SIDE as u32);
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    limits
}

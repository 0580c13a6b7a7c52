//! Shared helpers: locating and reading the real data.

use std::path::PathBuf;

use sl_core::DepthImage;

/// `../shared/data` relative to the workspace root, if present.
pub fn data_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!("skipping: ../shared/data not found");
        None
    }
}

/// Reads a 16-bit single-channel PNG or TIFF as depth: `value / units_per_m` metres, with 0 and
/// 65535 invalid.
pub fn read_depth(path: &std::path::Path, units_per_m: f64) -> DepthImage {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let g = img.to_luma16();
    let (w, h) = g.dimensions();
    let data = g
        .into_raw()
        .into_iter()
        .map(|v| {
            if v == 0 || v == u16::MAX {
                0.0
            } else {
                (f64::from(v) / units_per_m) as f32
            }
        })
        .collect();
    DepthImage::from_vec(w as usize, h as usize, data).unwrap()
}

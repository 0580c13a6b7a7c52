//! Shared helpers: random depth images with holes, synthetic planes.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sl_core::{DepthImage, Intrinsics, SensorModel};
use sl_filter::{DepthFilter, Isa, Window};

/// A random depth image in `[lo, hi]` metres with a fraction `holes` of invalid pixels, some
/// smooth structure and some depth edges.
pub fn random_image(w: usize, h: usize, lo: f32, hi: f32, holes: f64, seed: u64) -> DepthImage {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let base: f32 = rng.random_range(lo..hi);
    let gx: f32 = rng.random_range(-0.02..0.02);
    let gy: f32 = rng.random_range(-0.02..0.02);
    let edge_x = rng.random_range(0..w.max(1));
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            if rng.random_bool(holes) {
                return if rng.random_bool(0.5) { 0.0 } else { f32::NAN };
            }
            let step = if (i % w) >= edge_x { 0.7 } else { 0.0 };
            let noise: f32 = rng.random_range(-0.03..0.03);
            (base + gx * x + gy * y + step + noise).clamp(lo, hi)
        })
        .collect();
    DepthImage::from_vec(w, h, data).unwrap()
}

/// The filters tested everywhere: every method with a range that matters on `[0.5, 4]` m data,
/// each with the square and the disc window.
pub fn filters(radius: usize, sigma_s: f64, sensor: &SensorModel) -> Vec<DepthFilter> {
    let square = [
        DepthFilter::gaussian(radius, sigma_s),
        DepthFilter::bilateral(radius, sigma_s, 0.02),
        DepthFilter::adaptive(radius, sigma_s, 0.01),
        DepthFilter::disparity(radius, sigma_s, 0.3, sensor),
    ];
    square
        .into_iter()
        .flat_map(|f| [f, f.with_window(Window::Disc)])
        .collect()
}

/// Every instruction set this CPU supports.
pub fn isas() -> Vec<Isa> {
    [Isa::Portable, Isa::Avx2, Isa::Avx512]
        .into_iter()
        .filter(|i| i.is_supported())
        .collect()
}

/// Depth of the plane `n·X = dist` (camera frame) at every pixel, f64.
pub fn plane_depth(k: &Intrinsics, n: [f64; 3], dist: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(k.width * k.height);
    for y in 0..k.height {
        for x in 0..k.width {
            let r = k.ray(x as f64, y as f64);
            out.push(dist / (n[0] * r.x + n[1] * r.y + n[2] * r.z));
        }
    }
    out
}

/// Whether the full `(2r+1)²` window around `(x, y)` is inside the image.
pub fn interior(x: usize, y: usize, w: usize, h: usize, r: usize) -> bool {
    x >= r && y >= r && x + r < w && y + r < h
}

//! # sl-filter — depth-map smoothing that knows the structured-light noise model
//!
//! Smoothing filters for Kinect-class depth maps (paper section 3.1–3.2). Pipeline position:
//! depth frames → `sl-io` → `sl-core` types → **`sl-filter`** → `sl-tsdf` / `sl-planes`.
//!
//! | method | range weight | use |
//! |---|---|---|
//! | [`Method::Gaussian`] | none | reference; blurs depth edges |
//! | [`Method::Bilateral`] | fixed `σ_d` (metres), paper eq. 3–5 | one σ cannot fit near and far |
//! | [`Method::Adaptive`] (default) | `σ_d(p) = k·Z(p)²`, paper eq. 6 | follows `σ_Z = Z²·σ_D/(f·B)` |
//! | [`Method::Disparity`] | fixed σ on `D = f·B/Z` | the same idea in the domain where noise is constant |
//! | [`MultiScale`] (CLI/Python default) | adaptive 7×7, then dilated 5×5 disparity passes | real sensors' spatially correlated error (issue 11) |
//!
//! Every filter works on a [`sl_core::DepthImage`] (`f32` metres, 0 = invalid). **Invalid
//! pixels never contribute and are never filled**: the output is invalid exactly where the input
//! is. **Borders:** the window is clipped at the image border and the weights are renormalised
//! over the valid pixels inside the image (no replication or mirroring).
//!
//! ```
//! use sl_core::{Camera, DepthImage};
//! use sl_filter::{DepthFilter, Method};
//!
//! // A noisy wall 2 m away with a hole: ±6 mm of deterministic "noise".
//! let (w, h) = (64, 48);
//! let mut data: Vec<f32> = (0..w * h).map(|i| 2.0 + 0.006 * (((i * 7919) % 13) as f32 / 6.0 - 1.0)).collect();
//! data[10 * w + 10] = 0.0;
//! let depth = DepthImage::from_vec(w, h, data)?;
//!
//! // The default filter needs no tuning: k comes from the camera's noise model.
//! let cam = Camera::kinect_v1();
//! let filter = DepthFilter::default_for(Method::Adaptive, &cam.sensor);
//! let smooth = filter.apply(&depth)?;
//!
//! assert_eq!(smooth.get(10, 10), Some(0.0)); // holes stay holes
//! let rms = |d: &DepthImage| {
//!     let v: Vec<f32> = d.data().iter().copied().filter(|&z| z > 0.0).collect();
//!     (v.iter().map(|z| (z - 2.0) * (z - 2.0)).sum::<f32>() / v.len() as f32).sqrt()
//! };
//! assert!(rms(&smooth) < 0.5 * rms(&depth));
//! # Ok::<(), sl_filter::FilterError>(())
//! ```
//!
//! ## Defaults (chosen by measurement)
//!
//! [`DepthFilter::default_for`] uses a 7×7 window ([`DEFAULT_RADIUS_PX`]), `σ_s = r/2 = 1.5`
//! px, and `k = m·σ_D/(f·B)` with `m =` [`DEFAULT_K_MULTIPLIER`] `= 10`, i.e. a range σ of ten
//! times the depth noise `σ_Z(Z)`. `cargo xtask validate --only filter` sweeps `m` on simulated
//! Kinect frames (sl-noise: the tilted floor 0.8–3.9 m, a figure before two walls meeting at 90°,
//! a book 1 cm above a table, boxes on a floor; 3 seeds each) and reports the RMSE against
//! ground truth over all valid pixels:
//!
//! | m | 1 | 2 | 3 | 4 | 6 | 8 | **10** | 12 | 16 | 24 | 32 |
//! |---|---|---|---|---|---|---|---|---|---|---|---|
//! | RMSE (mm) | 7.82 | 4.65 | 3.36 | 2.81 | 2.45 | 2.36 | **2.34** | 2.36 | 2.51 | 3.36 | 4.85 |
//!
//! The optimum is broad (8–12 within 1 %). A range σ of 10 σ_Z is large because the Kinect's
//! depth is quantised in steps of about 1.8 σ_Z, which must be averaged; real depth jumps above
//! ~3 σ_d (5 cm at 1 m, 43 cm at 3 m) are still rejected. The disparity variant uses the same
//! multiple, `σ = m·σ_D` in disparity pixels. Explicit `k`, `σ_d`, `σ_s` and radius override
//! every default.
//!
//! **The default of `sldepth filter` and Python `filter`** is not one pass but [`MultiScale`]:
//! the adaptive 7×7 pass followed by 5×5 disparity passes with taps 2, 4 and 8 px apart
//! ([`multiscale_by_default`] says for which methods). Real structured-light error is
//! correlated over the ~9×11 px block-matching window, wider than any single window; the
//! coarse passes remove about a third of the fine-scale plane residual of real walls and floors
//! where the single pass removes a fifth (see [`multiscale`] for the measurements). A coarse
//! pass is used only where its window is one surface: no hole, border or depth jump, and no
//! crease (a corner of two planes, which a symmetric kernel would round; tested against the
//! frame's own measured noise). The library keeps [`DepthFilter::default_for`] the paper's
//! single pass.
//!
//! ## Accuracy (simulated Kinect, 7×7, σ_s = 1.5 px; RMSE in mm)
//!
//! On the floor and figure-before-walls scenes (3 seeds each), per band of the true depth, and
//! at pixels within 2 px of a true depth jump:
//!
//! | method | < 1.5 m | 1.5–2.5 m | > 2.5 m | overall | edges |
//! |---|---|---|---|---|---|
//! | raw | 2.17 | 8.08 | 15.53 | 8.25 | 8.48 |
//! | Gaussian | 48.76 | 26.58 | 72.42 | 48.73 | 322.40 |
//! | bilateral σ_d 20 mm | 0.70 | 3.13 | 10.90 | 5.04 | 4.65 |
//! | bilateral σ_d 240 mm (best single σ_d) | 1.69 | 1.61 | 3.85 | 2.23 | 7.72 |
//! | **adaptive (default)** | **0.69** | 1.67 | 3.92 | **2.00** | **3.11** |
//! | disparity (default) | 0.69 | 1.67 | 3.94 | 2.00 | 3.10 |
//!
//! A fixed σ_d is either too small far away or too large near the camera (and across small
//! steps); the adaptive filter is better than every single σ_d overall (and on the four-scene
//! set, 2.34 vs 2.53 mm for the best bilateral, σ_d = 120 mm). **The disparity-domain variant
//! matches the adaptive filter** (2.00 vs 2.00 mm on the two scenes, 2.32 vs 2.34 mm on four;
//! within 1 %, as expected: to first order `|ΔD| = f·B·|ΔZ|/Z²`, so a constant σ in disparity
//! *is* `σ_d = k·Z²`). It is slightly slower (two divisions per pixel) and, unlike the depth
//! filters, leaves every 3D plane exactly unchanged (see below).
//!
//! ## Bias on tilted planes (the bound the tests check)
//!
//! For a 3D plane, `1/Z` is affine in the pixel coordinates. Write `Z(q) = Z/(1 + t_q)` for the
//! window pixels `q = p + δ` (so `t_{−δ} = −t_δ`). Let the filtered value be
//! `Ẑ = Σ w_q Z(q) / Σ w_q` with `w_q = ŵ_s(δ)·r(Z(q) − Z)`, `r(x) = exp(−x²/2σ²)` (`r ≡ 1` for
//! the Gaussian), the window fully inside the image and valid. Pair `δ` with `−δ`: their
//! spatial weights are equal and `Z(q) − Z = −Z·t/(1+t)` and `+Z·t/(1−t)`. With `g(x) = x·r(x)`
//! (odd, `|g′| ≤ 1` because `|(1 − u)·e^{−u/2}| ≤ 1` for `u ≥ 0`):
//!
//! ```text
//! |pair contribution| = ŵ_s·|g(Zt/(1−t)) − g(Zt/(1+t))| ≤ ŵ_s·2Z·t²/(1 − t²)
//! Σ_q w_q ≥ r_min·Σ ŵ_s,   r_min = exp(−Δ²/2σ²),  Δ = max_q |Z(q) − Z|
//! ⇒ |Ẑ − Z| ≤ (Z / r_min)·Σ_q ŵ_q·t_q²/(1 − t_q²)
//!           ≈ |∇Z|²·M₂ / (Z·r_min)   to second order (t_q ≈ −∇Z·δ/Z),
//! ```
//!
//! where `M₂ = Σ ŵ_q|δ|²` ([`DepthFilter::spatial_second_moment_px2`], ≤ 2σ_s²). For the
//! Gaussian the bound is an equality: its bias is exactly `Z·Σ ŵ t²/(1−t²) > 0` (depth is convex
//! along pixel rows on any tilted plane, so averaging pushes it away from the camera). For the
//! adaptive filter `σ = k·Z(p)²`. Example: a floor at 3 m seen at grazing incidence with
//! `|∇Z| = 3 cm/px`, 7×7 and σ_s = 1.5 px (`M₂ ≈ 4.0`): bias ≤ 0.03²·4.0/3 ≈ 1.2 mm, well below
//! the 14 mm noise there. The disparity filter has no such bias: `D = f·B/Z` is affine, the
//! symmetric kernel cancels exactly and any plane passes unchanged.
//!
//! ## Speed
//!
//! One padded copy of each block of 16 rows (in a reused per-thread buffer; the calling thread
//! and `n − 1` rayon helpers take blocks from one queue), precomputed spatial exponents, no
//! per-pixel allocation or branch, constant-radius fast paths for 3×3, 5×5 and 7×7 (the whole
//! window unrolled, sums in registers), and AVX2+FMA / AVX-512 code selected at run time
//! ([`Isa`]). The range filters' joint weight `w_s·w_d = 2^x` is the *log-linear* `2^x` (the
//! bit pattern of an `f32` read as fixed point, Schraudolph's trick; `weight`): one
//! multiply-add and a truncating conversion per tap, within ±3 % of `2^x` (tested), with the
//! spatial weight folded in for free; weights are carried negated, so that the conversion's
//! out-of-range result is exactly no weight below `2^−127` (far and invalid neighbours).
//! Written by hand: no crate offers a vectorised weight of this kind. With it a tap costs 5
//! vector operations on the AVX-512 and the AVX2 paths (10 and 12 with the degree-3 polynomial
//! `2^x` used before, 6 with the floor at `2^−126` used until session 94); both paths interleave two pixel groups (16 + 16 and 8 + 8
//! lanes) so that the sums' dependency chains overlap, and skip groups whose centres are all
//! invalid (their output is 0). The filters' accuracy did not change measurably with the
//! cheaper weight (`cargo xtask validate --only filter`: every RMSE within 0.01 mm). The
//! multi-scale filter's dilated passes run the same kernels with their taps 2, 4 or 8 px apart
//! on the full image, skip groups of pixels its gates do not keep, and its gates' loops have
//! AVX2 builds chosen at run time too ([`multiscale`]). The
//! runtime dispatch is the crate's only `unsafe`: calling a `#[target_feature]` function after
//! `is_x86_feature_detected!` has confirmed the features (the intrinsics are safe inside it;
//! `bytemuck` converts between arrays and vectors).
//!
//! [`Window::Disc`] (`--window-shape disc`, Python `window="disc"`) restricts the window to
//! `dx² + dy² ≤ r²` as OpenCV's `bilateralFilter` does — 13 instead of 25 taps at 5×5, 29
//! instead of 49 at 7×7 — dropped at compile time in the fast paths: about 0.56–0.62× the time
//! of the square, at a small cost in noise reduction.
//!
//! Speed against OpenCV's `cv2.bilateralFilter` on real frames, with the CPU's instruction set
//! and the machine's load for every figure, is in `docs/bench/README.md` (measurements are kept
//! there, not in the API docs).
#![deny(missing_docs)]

pub mod config;
mod crease;
mod domain;
pub mod error;
pub mod filter;
mod gate;
mod kernel;
pub mod multiscale;
pub mod prefilter;
pub mod reference;
mod weight;

pub use config::FilterConfig;
pub use error::{FilterError, Result};
pub use filter::{
    BILATERAL_DEFAULT_DEPTH_M, DEFAULT_K_MULTIPLIER, DEFAULT_RADIUS_PX, DepthFilter, MAX_DEPTH_M,
    MAX_PIXELS, MAX_RADIUS_PX, MIN_DEPTH_M, Method, RangeKernel, Window, default_k_per_m,
    default_sigma_s_px,
};
pub use kernel::Isa;
pub use multiscale::{MultiScale, multiscale_by_default};
pub use prefilter::{PREFILTER_DILATIONS, Prefilter};

/// Number of threads the filters use when called outside a custom rayon pool.
pub fn current_threads() -> usize {
    rayon::current_num_threads()
}

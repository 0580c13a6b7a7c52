//! The crease test of the multi-scale filter's coarse passes: a wide pass is kept only where its
//! window is one plane.
//!
//! **Why.** A coarse pass is a symmetric kernel in the disparity domain, so it leaves a plane —
//! affine in disparity — exactly in place. Across a *crease* (two planes meeting without a
//! depth jump: a room's corner, a wall meeting the floor, a box's edge seen from outside) the
//! disparity is continuous but its slope changes, no neighbour is more than a range σ from the
//! next, the interior gate lets the window through, and the pass rounds the corner by up to the
//! slope change times the window's half-width. On the simulated corridor's end wall (4.5 m,
//! 90 × 90 px, meeting floor, walls and ceiling whose disparity changes 0.2 px per pixel there)
//! the default multi-scale filter moved the wall's mean depth 17 mm towards the camera and its
//! border pixels by 115 mm; the single 7×7 pass by 3 mm. The rounding is fixed to the camera, so
//! a tracker aligning two filtered frames of a slow forward motion read it as standing still.
//!
//! **The test.** For a pass of half-width `R` at pixel `p` (domain values `u`: disparity for the
//! default coarse kernel), the second differences over the window
//!
//! ```text
//! c_x = u(p − R·x̂) + u(p + R·x̂) − 2·u(p),   c_y likewise,
//! ```
//!
//! are 0 on any plane (up to noise) and `Δg·(R − |t|)` for a crease at `t` pixels from `p` whose
//! slope changes by `Δg` — as large as the rounding the pass would cause there, and 0 for a
//! crease outside the window. The pass is kept where `max(|c_x|, |c_y|) ≤ τ`. `τ` comes from the
//! frame's own noise, not a constant: the second differences over the pixels the interior gate
//! passed are mostly noise (creases are lines, planes are areas), so `σ_c` = 1.4826 × the median
//! of their absolute values (sampled every [`SAMPLE_STRIDE`] pixels) measures it, and
//! `τ = `[`CREASE_SIGMAS`]`·σ_c` — at most a few in 10⁴ plane pixels of a Gaussian noise are
//! refused, and a refused pixel keeps the finer result, so a false refusal costs smoothing,
//! never shape. `τ` never falls below a tenth of the pass's range σ (for the default, the
//! sensor's `σ_D`; on exact synthetic depth the MAD is 0).
//!
//! The decision is per pixel (no dilation): a crease near the window's edge changes the pass's
//! result as little as it changes `c`.
//!
//! **Measured** (docs/bench/README.md, session 54). Real frames (person, TUM fr1, 7-Scenes):
//! `τ` = 0.27–0.40 px; the passes are refused on 2–10 % of the pixels the interior gate passed
//! (the person's body, kitchen objects, room corners), and the real-frame plane residual of
//! `cargo xtask validate --only filter` is unchanged (pooled ≥ 2 m: 0.829 → 0.828× raw). White
//! simulator, floor and figure-walls: surface RMSE 1.36 → 1.27 mm (figure-walls 1.03 → 0.76:
//! its creases are no longer rounded); realistic simulator 4.29 → 4.30 mm. Cost: about 2 M
//! instructions per pass on a 640×480 frame (+12 % for the multi-scale filter; the domain values
//! are now computed once per pass for both gates).

use rayon::prelude::*;

use crate::domain::Domain;
use crate::kernel::avx2_twin;

/// Multiples of the measured σ of the second differences beyond which a window holds a crease
/// (two-sided Gaussian tail: 6·10⁻⁵).
pub(crate) const CREASE_SIGMAS: f32 = 4.0;

/// Pixels between the samples the noise of the second differences is measured on, in x and y.
pub(crate) const SAMPLE_STRIDE: usize = 4;

/// Fewest samples the noise is measured from; with fewer, only the floor applies.
const MIN_SAMPLES: usize = 64;

/// The floor of `τ` as a fraction of the pass's range σ.
const FLOOR_OF_RANGE_SIGMA: f32 = 0.1;

/// `1/Φ⁻¹(3/4)`: the MAD of a Gaussian times this is its σ.
const MAD_TO_SIGMA: f32 = 1.4826;

/// Clears `keep` wherever the pass of half-width `r` would see a crease in its window
/// (module docs). `u` holds the domain values of the frame (`w` wide, [`Domain::image_into`]) and
/// `keep` the interior gate's result for the same `r`: true only where the whole window is
/// inside the image, valid and free of jumps. Returns the measured part of `τ` in the domain's
/// units (NaN for [`Domain::Flat`], the Gaussian's, which is left alone).
pub(crate) fn refuse_creases(
    u: &[f32],
    w: usize,
    domain: Domain,
    r: usize,
    keep: &mut [bool],
    samples: &mut Vec<f32>,
    avx2: bool,
) -> f32 {
    if matches!(domain, Domain::Flat) || w == 0 || u.len() != keep.len() {
        return f32::NAN;
    }
    let h = u.len() / w;
    if r == 0 || 2 * r + 1 > w || 2 * r + 1 > h {
        return f32::NAN;
    }
    let second = |i: usize, step: usize| u[i - step] + u[i + step] - 2.0 * u[i];
    // The noise of the second differences, over the pixels the interior gate passed.
    samples.clear();
    for y in (r..h - r).step_by(SAMPLE_STRIDE) {
        for x in (r..w - r).step_by(SAMPLE_STRIDE) {
            let i = y * w + x;
            if keep[i] {
                samples.push(second(i, r).abs());
                samples.push(second(i, r * w).abs());
            }
        }
    }
    let measured = if samples.len() >= MIN_SAMPLES {
        let mid = samples.len() / 2;
        let (_, m, _) = samples.select_nth_unstable_by(mid, f32::total_cmp);
        CREASE_SIGMAS * MAD_TO_SIGMA * *m
    } else {
        0.0
    };
    keep.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        if y < r || y + r >= h {
            return;
        }
        let (above, centre, below) = (
            &u[(y - r) * w..(y - r + 1) * w],
            &u[y * w..(y + 1) * w],
            &u[(y + r) * w..(y + r + 1) * w],
        );
        refuse_row(avx2, above, centre, below, r, domain, measured, row);
    });
    measured
}

avx2_twin! {
    /// The crease test of one row (`centre`, with the rows `r` above and below) for the pixels
    /// `keep` still passes, with `τ`'s measured part `measured`.
    #[allow(clippy::too_many_arguments)]
    fn refuse_row(
        above: &[f32],
        centre: &[f32],
        below: &[f32],
        r: usize,
        domain: Domain,
        measured: f32,
        keep: &mut [bool],
    ) {
        let w = centre.len();
        let n = w - 2 * r;
        let (left, right) = (&centre[..n], &centre[2 * r..]);
        let (mid, up, down) = (&centre[r..w - r], &above[r..w - r], &below[r..w - r]);
        let row = &mut keep[r..w - r];
        // Branch-free, so the loop vectorises: where `keep` holds, the window is valid (no NaN).
        // One loop per kind of σ: with `domain.sigma` matched per pixel in a single loop LLVM
        // vectorised neither this loop nor the interior gate's (multi-scale call +45 %
        // instructions, callgrind).
        match domain.constant_sigma() {
            Some(sigma) => {
                let tau = measured.max(FLOOR_OF_RANGE_SIGMA * sigma);
                for i in 0..n {
                    let two = 2.0 * mid[i];
                    let cx = (left[i] + right[i] - two).abs();
                    let cy = (up[i] + down[i] - two).abs();
                    row[i] &= (cx <= tau) & (cy <= tau);
                }
            }
            None => {
                for i in 0..n {
                    let tau = measured.max(FLOOR_OF_RANGE_SIGMA * domain.sigma(mid[i]));
                    let two = 2.0 * mid[i];
                    let cx = (left[i] + right[i] - two).abs();
                    let cy = (up[i] + down[i] - two).abs();
                    row[i] &= (cx <= tau) & (cy <= tau);
                }
            }
        }
    }
}

/// One step of Marsaglia's xorshift64 generator: the deterministic noise of this crate's test
/// frames (here and in `multiscale`'s tests).
#[cfg(test)]
pub(crate) fn xorshift_step(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::{DepthImage, SensorModel};

    use crate::filter::RangeKernel;
    use crate::multiscale::MultiScale;

    /// [`refuse_creases`] on a depth image.
    fn refuse(img: &DepthImage, range: &RangeKernel, r: usize, keep: &mut [bool]) -> f32 {
        let domain = Domain::of(range);
        let mut u = Vec::new();
        domain.image_into(img, &mut u, false);
        refuse_creases(&u, img.width(), domain, r, keep, &mut Vec::new(), false)
    }

    /// Two planes meeting in a vertical crease at column `cx` (disparity slopes `g0` left,
    /// `g1` right), with a deterministic noise of amplitude `a` px.
    fn crease(w: usize, h: usize, cx: usize, g0: f32, g1: f32, a: f32, fb: f32) -> DepthImage {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let d = (0..w * h)
            .map(|i| {
                let noise =
                    a * ((xorshift_step(&mut state) >> 40) as f32 / (1u64 << 24) as f32 - 0.5);
                let x = (i % w) as f32 - cx as f32;
                let disp = 10.0 + if x < 0.0 { g0 * x } else { g1 * x } + noise;
                fb / disp
            })
            .collect();
        DepthImage::from_vec(w, h, d).unwrap()
    }

    #[test]
    fn a_crease_is_refused_within_the_window_and_a_plane_is_kept() {
        let s = SensorModel::kinect_v1();
        let range = MultiScale::default_for(&s).coarse.range;
        let fb = s.fb() as f32;
        let (w, h, cx, r) = (96, 64, 48, 8);
        // Slope 0.2 px/px on the left, flat on the right (the corridor's end wall), little noise.
        let img = crease(w, h, cx, -0.2, 0.0, 0.02, fb);
        let mut keep = vec![false; w * h];
        for y in r..h - r {
            keep[y * w + r..y * w + w - r].fill(true);
        }
        let tau = refuse(&img, &range, r, &mut keep);
        assert!(tau > 0.0 && tau < 0.1, "τ {tau}");
        let y = h / 2;
        for x in r..w - r {
            let dist = x.abs_diff(cx);
            let kept = keep[y * w + x];
            // Δg·(R − d) ≥ 0.2 px is well above τ: refused; beyond the window: kept.
            if dist < r - 1 {
                assert!(!kept, "x {x}: crease {dist} px away kept");
            } else if dist > r {
                assert!(kept, "x {x}: plane refused");
            }
        }
    }

    #[test]
    fn a_plane_under_noise_is_almost_never_refused() {
        let s = SensorModel::kinect_v1();
        let range = MultiScale::default_for(&s).coarse.range;
        let fb = s.fb() as f32;
        let (w, h, r) = (160, 120, 8);
        let img = crease(w, h, 0, 0.05, 0.05, 0.3, fb);
        let mut keep = vec![false; w * h];
        for y in r..h - r {
            keep[y * w + r..y * w + w - r].fill(true);
        }
        let before = keep.iter().filter(|&&k| k).count();
        let tau = refuse(&img, &range, r, &mut keep);
        let after = keep.iter().filter(|&&k| k).count();
        // Uniform noise of ±0.15 px: the sum of three has σ 0.21 px, τ ≈ 4σ; none beyond it.
        assert!(tau > 0.5 && tau < 1.2, "τ {tau}");
        assert!(after as f64 >= 0.999 * before as f64, "{after} of {before}");
    }

    #[test]
    fn the_multi_scale_filter_rounds_a_crease_no_more_than_its_base_pass() {
        // Exact depth of a far wall meeting a floor (the corridor's end wall): the coarse
        // passes, taps up to 8 px away, used to pull the wall towards the camera.
        let s = SensorModel::kinect_v1();
        let m = MultiScale::default_for(&s);
        let fb = s.fb() as f32;
        let (w, h, cx) = (120, 64, 60);
        let img = crease(w, h, cx, -0.2, 0.0, 0.0, fb);
        let worst = |out: &DepthImage| {
            let mut worst = 0.0f32;
            for y in 10..h - 10 {
                for x in cx - 12..cx + 12 {
                    let i = y * w + x;
                    worst = worst.max((fb / out.data()[i] - fb / img.data()[i]).abs());
                }
            }
            worst
        };
        let base = worst(&m.base.apply(&img).unwrap());
        let multi = worst(&m.apply(&img).unwrap());
        assert!(
            multi <= base + 1e-3,
            "multi-scale {multi} px, base {base} px"
        );
    }

    #[test]
    fn the_gaussian_has_no_crease_test() {
        let img = crease(40, 30, 20, -0.2, 0.0, 0.0, 40.0);
        let mut keep = vec![true; 40 * 30];
        let tau = refuse(&img, &RangeKernel::None, 4, &mut keep);
        assert!(tau.is_nan());
        assert!(keep.iter().all(|&k| k));
    }
}

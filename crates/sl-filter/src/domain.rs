//! The range kernel's domain: the value a depth maps to (disparity `f·B/Z` for the
//! disparity kernel, the depth itself otherwise) and the range σ there. The multi-scale filter's
//! gates (the interior's jump test, the crease test) read one image of domain values per pass.

use rayon::prelude::*;
use sl_core::DepthImage;

use crate::filter::RangeKernel;
use crate::kernel::avx2_twin;

avx2_twin! {
    /// [`Domain::fill`] of one row.
    fn fill_row(domain: Domain, src: &[f32], dst: &mut [f32]) {
        domain.fill(src, dst)
    }
}

/// The domain of a [`RangeKernel`].
#[derive(Clone, Copy, Debug)]
pub(crate) enum Domain {
    /// No range weight (the Gaussian): every valid value is 0 and nothing is a jump.
    Flat,
    /// Disparity `f·B/Z` with a constant σ.
    Disparity { fb: f32, sigma: f32 },
    /// Depth with `σ = k·Z²`.
    Adaptive { k: f32 },
    /// Depth with a constant σ.
    Fixed { sigma: f32 },
}

impl Domain {
    /// The domain of `range`.
    pub(crate) fn of(range: &RangeKernel) -> Self {
        match *range {
            RangeKernel::None => Self::Flat,
            RangeKernel::Fixed { sigma_d_m } => Self::Fixed {
                sigma: sigma_d_m as f32,
            },
            RangeKernel::Adaptive { k_per_m } => Self::Adaptive { k: k_per_m as f32 },
            RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m,
            } => Self::Disparity {
                fb: fb_px_m as f32,
                sigma: sigma_disp_px as f32,
            },
        }
    }

    /// Writes the domain value of every pixel of `depth` into `out` (NaN where invalid), by
    /// rows in parallel, one branch-free loop per kernel (built for AVX2 with `avx2`, see
    /// `kernel::avx2_twin!`).
    pub(crate) fn image_into(self, depth: &DepthImage, out: &mut Vec<f32>, avx2: bool) {
        let w = depth.width().max(1);
        out.resize(depth.data().len(), f32::NAN);
        out.par_chunks_mut(w)
            .zip(depth.data().par_chunks(w))
            .for_each(|(dst, src)| fill_row(avx2, self, src, dst));
    }

    /// The domain values of a row of depths (NaN where invalid).
    #[inline(always)]
    fn fill(self, src: &[f32], dst: &mut [f32]) {
        // Both comparisons evaluated (`&`, not `&&`) and the value computed for every pixel,
        // so each loop vectorises (a short-circuit made them scalar: 7 instructions a pixel).
        let valid = |z: f32| (z > 0.0) & (z < f32::INFINITY);
        match self {
            Self::Flat => {
                for (o, &z) in dst.iter_mut().zip(src) {
                    *o = if valid(z) { 0.0 } else { f32::NAN };
                }
            }
            Self::Disparity { fb, .. } => {
                for (o, &z) in dst.iter_mut().zip(src) {
                    let u = fb / z;
                    *o = if valid(z) { u } else { f32::NAN };
                }
            }
            Self::Adaptive { .. } | Self::Fixed { .. } => {
                for (o, &z) in dst.iter_mut().zip(src) {
                    *o = if valid(z) { z } else { f32::NAN };
                }
            }
        }
    }

    /// The range σ when it does not depend on the value (infinite for [`Domain::Flat`]).
    #[inline(always)]
    pub(crate) fn constant_sigma(self) -> Option<f32> {
        match self {
            Self::Flat => Some(f32::INFINITY),
            Self::Disparity { sigma, .. } | Self::Fixed { sigma } => Some(sigma),
            Self::Adaptive { .. } => None,
        }
    }

    /// The range σ at domain value `v` (a depth for the depth kernels).
    #[inline(always)]
    pub(crate) fn sigma(self, v: f32) -> f32 {
        match self {
            Self::Flat => f32::INFINITY,
            Self::Disparity { sigma, .. } | Self::Fixed { sigma } => sigma,
            Self::Adaptive { k } => k * v * v,
        }
    }
}

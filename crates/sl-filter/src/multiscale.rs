//! A filter on several scales: the paper's filter, then dilated ("à trous") passes of the
//! disparity-domain bilateral filter, for the spatially correlated error of real sensors.
//!
//! **Why.** A real structured-light camera estimates disparity by block matching over a window
//! of about 9×9 pixels, so neighbouring pixels share their errors: on a real wall the residual's
//! autocorrelation is still 0.2–0.4 at 4–8 px (docs/NOISE_MODEL.md), and the 1/8-px
//! quantisation makes terraces wider than any 7×7 window. A 7×7 filter removes the white part
//! of the error but averages the correlated part over too few independent samples. Averaging a
//! field with correlation length ℓ with a Gaussian of σ_s reduces its variance by about
//! `ℓ²/(ℓ² + 2σ_s²)` (both Gaussian), so halving the RMS needs `σ_s ≈ 1.2ℓ`, i.e. a support of
//! ~25 px for ℓ ≈ 10 px — beyond the paper's windows. And ℓ grows with depth: the 1/q-px
//! quantisation's terraces are `q·Δd`-wide strips whose width in pixels grows as Z² on a
//! slanted surface, so a far wall needs the widest support.
//!
//! **How.** [`MultiScale::apply`] runs the base filter (the paper's adaptive bilateral, 7×7),
//! then for each dilation `s` in [`MultiScale::dilations`] a 5×5 bilateral whose taps are `s`
//! pixels apart, in the disparity domain with the constant range σ `m·σ_D` (the same noise
//! multiple as the adaptive default: to first order it is `σ_d = k·Z²`, the paper's idea). The
//! disparity domain matters at large supports: `D = f·B/Z` is affine on every 3D plane, so the
//! symmetric kernel leaves planes exactly in place, whereas averaging depth over ±8 px would
//! bias tilted planes away from the camera (see the crate docs' bound, which grows with the
//! kernel's second moment). A dilated pass is the fast 5×5 kernel with its taps `s` pixels
//! apart, run on the full image (`DepthFilter`'s dilated fast paths for `s` = 2, 4 and 8, its
//! runtime-radius path otherwise): exactly what filtering each of the image's `s×s` polyphase
//! sub-images (every `s`-th pixel of every `s`-th row) with the ordinary 5×5 filter gives, bit for
//! bit, without copying them out and back; invalid pixels, borders and the SIMD paths are those of
//! [`DepthFilter`]. The range weight keeps depth edges: a neighbour across a jump of more than
//! ~3 range σ contributes nothing, at any dilation. A wide pass is used only where its whole
//! window is inside the image, valid and free of jumps larger than one range σ; elsewhere the
//! finer result is kept. A clipped window averages one side of the pixel only, which on a slope
//! (a floor at grazing incidence, the far side of an edge) shifts the depth by the slope times
//! the window's off-centre mean: without this gate the far floor of the simulated floor scene
//! got 3× worse, with it every band improves and the edge error equals the base filter's. Nor
//! is a wide pass used where its window holds a *crease* (two planes meeting without a jump:
//! the symmetric kernel keeps planes, not corners): the window's second differences are tested
//! against the frame's own measured noise (`crease.rs`; on the simulated corridor the far end
//! wall's mean depth was pulled 17 mm towards the camera without it).
//!
//! Measured (`cargo xtask validate --only filter`, tables "multi-scale filter"; dilations 2, 4
//! and 8 since session 58, the earlier 2 and 4 in brackets): surface RMSE 0.47× raw on the
//! realistic simulator (0.54×; adaptive 7×7: 0.77×), 0.15× on the white one (1.27 → 1.23 mm; 0.24×),
//! edge error equal to the adaptive filter's (0.37× raw, white simulator). On 11 real frames
//! (person, the floor scan, TUM fr1/rpy frames 0–20 and 100/150, 7-Scenes; up to six walls,
//! floors and desks each) the plane residual falls to 0.79–0.88× raw pooled per depth band
//! (0.83–0.89×; adaptive 7×7: 0.91–0.93×) and its fine-scale part (below a σ = 16 px Gaussian)
//! to 0.60–0.64× (0.65–0.67×; 0.79–0.82×); the normal spread halves (person wall: 44° raw, 24°
//! adaptive, 10–11° multi-scale). The rest of the residual lies on scales above 16 px — surface
//! shape and the Kinect's low-frequency distortion — which no filter that keeps shape removes:
//! the issue-11 target of half the raw residual at ≥ 2 m is not reached (0.79×), and the raw
//! residual's own σ = 16 px Gaussian alone is already 0.55× raw there (the report's *floor*
//! row). A fourth pass (dilation 16) gained 0.02 more there but made the white simulator's
//! figure-walls scene worse below 1.5 m (0.24 → 0.29 mm); not taken.
//!
//! **Speed.** person-depth.png (640×480), one thread, minimum of 30, AMD EPYC (session 97):
//! 1.96 ms with the AVX-512 kernels and 2.76 ms with the AVX2 ones (two threads: 1.2 and
//! 1.65 ms), against OpenCV 5.1's `bilateralFilter` at 311 ms at the same 63-pixel support
//! (48.6 ms at d = 31). Session 97 halved it (4.21 and 5.19 ms before), the output byte for byte the
//! same:
//! - the dilated passes run on the full image (above) instead of on polyphase sub-images
//!   copied out and interleaved back, whose 80-pixel rows at dilation 8 also left a third of
//!   every 128-pixel chunk of lanes empty;
//! - the interior gate dilates byte masks by doubling (`gate`) instead of counting every window;
//! - a pass is merged into the finer result block by block, while both are in cache, and the
//!   kernels skip groups of pixels none of which the gates keep (at dilation 8 they keep 35–64 %
//!   of the 16-pixel groups of real frames);
//! - the auxiliary loops vectorise (no short-circuit or select of references in them) and run
//!   in AVX2 builds (`kernel::avx2_twin!`).
//!
//! The passes' buffers are kept by the thread for its next call (`Scratch`). The history of
//! these figures is in docs/bench/README.md (sessions 35, 58, 60 and 97).
//!
//! Beyond the paper: the paper filters once with one window; the dilated passes and the
//! disparity domain at large supports are this crate's additions (issue 11).

use sl_core::{DepthImage, DepthView, SensorModel};

use crate::crease::refuse_creases;
use crate::domain::Domain;
use crate::error::{FilterError, Result};
#[cfg(test)]
use crate::filter::RangeKernel;
use crate::filter::{DEFAULT_K_MULTIPLIER, DepthFilter, Method};
use crate::gate::Gate;
use crate::kernel::Isa;
use crate::kernel::use_avx2;

/// Default dilations of the coarse passes (pixels between taps): 2, 4 and 8, so the passes
/// reach ±4, ±8 and ±16 px and the total support is about 63×63 px.
///
/// The third pass (dilation 8) was added in session 58: the correlated error of a far surface
/// is wider than ±8 px (terraces widen as Z²), and since the crease test (`crease.rs`) a wide
/// pass no longer rounds corners, which is what kept it out before (docs/bench/README.md,
/// sessions 23 and 58). Against dilations 2 and 4 it lowers every error measured
/// (`cargo xtask validate --only filter`): realistic simulator surface RMSE 4.30 → 3.68 mm,
/// white simulator 1.27 → 1.23 mm, real frames' plane residual at ≥ 2 m 0.83 → 0.79× raw,
/// with the same edge error; it costs about 30 % more time.
pub const DEFAULT_DILATIONS: [usize; 3] = [2, 4, 8];

/// Radius of each coarse pass (5×5 taps).
pub const COARSE_RADIUS_PX: usize = 2;

/// Largest dilation accepted.
pub const MAX_DILATION_PX: usize = 32;

/// The base filter followed by dilated disparity-domain passes.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiScale {
    /// The fine pass (the paper's filter; default: adaptive 7×7).
    pub base: DepthFilter,
    /// The filter of every coarse pass, with its taps `s` pixels apart at each dilation `s`.
    pub coarse: DepthFilter,
    /// Dilations of the coarse passes, in order.
    pub dilations: Vec<usize>,
}

impl MultiScale {
    /// The defaults for a sensor: the adaptive default as the base, a 5×5 disparity-domain pass
    /// with σ = `m·σ_D` (σ_s = 1 tap) at each of [`DEFAULT_DILATIONS`].
    pub fn default_for(sensor: &SensorModel) -> Self {
        let coarse = DepthFilter::disparity(
            COARSE_RADIUS_PX,
            1.0,
            DEFAULT_K_MULTIPLIER * sensor.sigma_d_px,
            sensor,
        );
        Self {
            base: DepthFilter::default_for(Method::Adaptive, sensor),
            coarse,
            dilations: DEFAULT_DILATIONS.to_vec(),
        }
    }

    /// Checks both filters and the dilations (each in `1..=`[`MAX_DILATION_PX`]).
    pub fn validate(&self) -> Result<()> {
        self.base.validate()?;
        self.coarse.validate()?;
        if let Some(s) = self
            .dilations
            .iter()
            .find(|&&s| s == 0 || s > MAX_DILATION_PX)
        {
            return Err(FilterError::InvalidParameter(format!(
                "dilation {s} px must be in 1..={MAX_DILATION_PX}"
            )));
        }
        Ok(())
    }

    /// Filters `depth`: the base filter, then each dilated pass. Invalid pixels stay invalid and
    /// never contribute, as for every filter of the crate. Runs on a worker thread of the
    /// caller's rayon pool (in place when called from one, otherwise on the global pool while
    /// the caller waits).
    pub fn apply<'a>(&self, depth: impl Into<DepthView<'a>>) -> Result<DepthImage> {
        self.apply_with_isa(depth, Isa::detect())
    }

    /// Like [`MultiScale::apply`] with an explicit instruction set for every pass (for tests
    /// and benchmarks; an unsupported one falls back to the portable code).
    pub fn apply_with_isa<'a>(
        &self,
        depth: impl Into<DepthView<'a>>,
        isa: Isa,
    ) -> Result<DepthImage> {
        let depth: DepthView<'a> = depth.into();
        // The passes run on a worker thread of the caller's pool (in place when called from
        // one): each of their dozen parallel phases, started from a thread outside the pool,
        // would put that thread to sleep until a worker had done it.
        rayon::scope(|_| self.apply_on_pool(depth, isa))
    }

    /// [`MultiScale::apply_with_isa`] on a worker thread.
    fn apply_on_pool(&self, depth: DepthView<'_>, isa: Isa) -> Result<DepthImage> {
        self.validate()?;
        let mut cur = self.base.apply_with_isa(depth, isa)?;
        let pixels = cur.data().len();
        let mut scratch = Scratch::take();
        let passes = self.coarse_passes(&mut cur, &mut scratch, isa);
        scratch.put_back(pixels);
        passes.map(|()| cur)
    }

    /// The coarse passes over `cur` (the base pass's result), in place.
    fn coarse_passes(&self, cur: &mut DepthImage, scratch: &mut Scratch, isa: Isa) -> Result<()> {
        let (w, h) = (cur.width(), cur.height());
        let Scratch {
            keep,
            gate,
            samples,
            filtered,
        } = scratch;
        let domain = Domain::of(&self.coarse.range);
        let avx2 = use_avx2(isa);
        for &s in &self.dilations {
            let r = self.coarse.radius_px * s;
            gate.interior_into(cur, domain, r, keep, avx2);
            refuse_creases(&gate.values, w, domain, r, keep, samples, avx2);
            // The coarse result inside the interior; outside it the finer result stays. Every
            // value of `filtered` is written; it becomes the current image, and the one before
            // is the next pass's buffer.
            filtered.resize(w * h, 0.0);
            self.coarse
                .apply_dilated_into(DepthView::from(&*cur), s, Some(keep), isa, filtered)?;
            let done = DepthImage::from_vec(w, h, std::mem::take(filtered))?;
            *filtered = std::mem::replace(cur, done).into_image().into_vec();
        }
        Ok(())
    }
}

/// Largest frame, in pixels, whose working buffers a thread keeps for its next call (about
/// 15 bytes a pixel: 31 MB at this size, which holds a 1920×1080 frame, and 4.5 MB for
/// 640×480); the buffers of a larger frame are freed after it.
const KEEP_SCRATCH_MAX_PIXELS: usize = 1 << 21;

/// The coarse passes' working buffers: the interior gate's (`keep` and [`Gate`]) and the
/// filtered image of a pass, each `w·h` values, shared by the passes of a call and kept by the
/// thread for its next call.
///
/// Why kept: freed at the end of every call, these ~4.5 MB (640×480) go back to the system
/// (the allocator trims its heap) and come back as fresh pages, one page fault per 4 KB, on
/// the next call: about a quarter of the multi-scale filter's time on a 640×480 frame
/// (session 60, Zen 4, one thread: 7.8 → 5.9 ms with AVX2, 6.6 → 4.6 ms with AVX-512 when the
/// allocator was told not to trim).
#[derive(Default)]
struct Scratch {
    keep: Vec<bool>,
    gate: Gate,
    /// The crease test's samples.
    samples: Vec<f32>,
    filtered: Vec<f32>,
}

thread_local! {
    /// This thread's [`Scratch`] between calls (empty while a call has it).
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

impl Scratch {
    /// This thread's buffers (empty ones when another call on this thread holds them, or
    /// while the thread shuts down).
    fn take() -> Self {
        SCRATCH
            .try_with(|cell| cell.try_borrow_mut().map(|mut s| std::mem::take(&mut *s)))
            .ok()
            .and_then(|s| s.ok())
            .unwrap_or_default()
    }

    /// Keeps the buffers for this thread's next call, if the frame had at most
    /// [`KEEP_SCRATCH_MAX_PIXELS`] pixels.
    fn put_back(self, pixels: usize) {
        if pixels > KEEP_SCRATCH_MAX_PIXELS {
            return;
        }
        let _ = SCRATCH.try_with(|cell| {
            if let Ok(mut s) = cell.try_borrow_mut() {
                *s = self;
            }
        });
    }
}

/// Whether the CLI and the Python `filter` follow `method` with the coarse passes of
/// [`MultiScale`] when the caller does not say: yes for the two methods whose range kernel
/// comes from the sensor model ([`Method::Adaptive`], the default, and [`Method::Disparity`]),
/// no for the classic Gaussian and fixed-σ bilateral, which stay what their names say.
///
/// Why the multi-scale filter is the default (issue 11, `cargo xtask validate --only filter`):
/// on the realistic simulator its surface RMSE is 0.6× the single adaptive pass's (3.68 against
/// 6.07 mm), with the same edge error; on real frames (person, floor scan, TUM fr1/rpy,
/// 7-Scenes) it removes about two fifths of the fine-scale plane residual where the single pass
/// removes a fifth, and halves the spread of the surface normals; and it costs under a hundredth
/// of OpenCV's `bilateralFilter` at its 63-pixel support (person-depth.png, one thread, Zen 4,
/// session 97: 1.96 ms with AVX-512, 2.8 ms with AVX2, against 311 ms for OpenCV 5.1.0.95).
pub fn multiscale_by_default(method: Method) -> bool {
    matches!(method, Method::Adaptive | Method::Disparity)
}

/// [`Gate::interior_into`] into a new vector (tests).
#[cfg(test)]
fn interior(depth: &DepthImage, range: &RangeKernel, r: usize) -> Vec<bool> {
    let mut out = Vec::new();
    Gate::default().interior_into(depth, Domain::of(range), r, &mut out, false);
    out
}

/// Applies `filter` with its taps `dilation` pixels apart: the same, bit for bit, as splitting
/// the image into its `dilation²` polyphase sub-images, filtering each and interleaving them
/// back, but computed on the full image (fast paths for a 5×5 window at dilations 2, 4 and 8).
pub fn apply_dilated(
    filter: &DepthFilter,
    depth: &DepthImage,
    dilation: usize,
) -> Result<DepthImage> {
    apply_dilated_with_isa(filter, depth, dilation, Isa::detect())
}

/// Like [`apply_dilated`] with an explicit instruction set.
pub fn apply_dilated_with_isa(
    filter: &DepthFilter,
    depth: &DepthImage,
    dilation: usize,
    isa: Isa,
) -> Result<DepthImage> {
    if dilation == 0 || dilation > MAX_DILATION_PX {
        return Err(FilterError::InvalidParameter(format!(
            "dilation {dilation} px must be in 1..={MAX_DILATION_PX}"
        )));
    }
    let (w, h) = (depth.width(), depth.height());
    let mut out = vec![0.0f32; w * h];
    filter.apply_dilated_into(DepthView::from(depth), dilation, None, isa, &mut out)?;
    Ok(DepthImage::from_vec(w, h, out)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crease::xorshift_step;
    use crate::filter::Window;

    /// The range kernel's domain value of a depth and its range σ there (the brute-force
    /// test's own statement of what `RowScratch::values` computes).
    fn domain(range: &RangeKernel, z: f32) -> (f32, f32) {
        match *range {
            RangeKernel::None => (0.0, f32::INFINITY),
            RangeKernel::Fixed { sigma_d_m } => (z, sigma_d_m as f32),
            RangeKernel::Adaptive { k_per_m } => (z, k_per_m as f32 * z * z),
            RangeKernel::Disparity {
                sigma_disp_px,
                fb_px_m,
            } => (fb_px_m as f32 / z, sigma_disp_px as f32),
        }
    }

    /// A `w × h` frame of `surface(x, y)` (metres) with ±2 mm of noise and holes (an isolated
    /// pixel in about 1,000 and a block), deterministic for a `seed`.
    fn noisy_frame(w: usize, h: usize, seed: u64, surface: impl Fn(f32, f32) -> f32) -> DepthImage {
        let mut state = seed;
        let d = (0..w * h)
            .map(|i| {
                let r = xorshift_step(&mut state);
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let noise = (r >> 40) as f32 / (1u64 << 24) as f32 - 0.5;
                if r.is_multiple_of(997) || (x > 40.0 && x < 52.0 && y > 10.0) {
                    return 0.0;
                }
                surface(x, y) + 0.004 * noise
            })
            .collect();
        DepthImage::from_vec(w, h, d).unwrap()
    }

    /// A frame with slopes, steps, noise and holes (deterministic).
    fn frame(w: usize, h: usize) -> DepthImage {
        noisy_frame(w, h, 0x2545_f491_4f6c_dd1d, |x, y| {
            let step = if x > 70.0 { 0.6 } else { 0.0 };
            1.2 + 0.004 * x + 0.002 * y + step
        })
    }

    /// The direct dilated pass is, bit for bit, the filter applied to each polyphase sub-image
    /// (every `dil`-th pixel of every `dil`-th row) — the definition of a dilated pass — for
    /// every kernel (the explicit AVX-512 and AVX2 ones where the CPU has them, the portable
    /// one), the fast dilations and others, both window shapes and several radii and methods.
    #[test]
    fn a_dilated_pass_is_its_sub_images_filtered_one_by_one() {
        let s = SensorModel::kinect_v1();
        let coarse = MultiScale::default_for(&s).coarse;
        let filters = [
            coarse,
            coarse.with_window(Window::Disc),
            DepthFilter::default_for(Method::Adaptive, &s).with_radius(2),
            DepthFilter::default_for(Method::Gaussian, &s).with_radius(2),
            coarse.with_radius(1),
            coarse.with_radius(3).with_window(Window::Disc),
        ];
        let isas = [Isa::Portable, Isa::Avx2, Isa::Avx512];
        for isa in isas.into_iter().filter(|i| i.is_supported()) {
            for f in &filters {
                for (w, h) in [(101, 37), (3, 2), (64, 48), (300, 70)] {
                    let img = frame(w, h);
                    for dil in [2, 3, 4, 8] {
                        let got = apply_dilated_with_isa(f, &img, dil, isa).unwrap();
                        for py in 0..dil.min(h) {
                            for px in 0..dil.min(w) {
                                let (sw, sh) = ((w - px).div_ceil(dil), (h - py).div_ceil(dil));
                                let sub: Vec<f32> = (0..sw * sh)
                                    .map(|k| {
                                        img.data()[(py + k / sw * dil) * w + px + k % sw * dil]
                                    })
                                    .collect();
                                let view = DepthView::new(sw, sh, &sub).unwrap();
                                let want = f.apply_with_isa(view, isa).unwrap();
                                for (k, &v) in want.data().iter().enumerate() {
                                    let (x, y) = (px + k % sw * dil, py + k / sw * dil);
                                    assert_eq!(
                                        got.data()[y * w + x].to_bits(),
                                        v.to_bits(),
                                        "{isa:?} {:?} r {} {w}x{h} dilation {dil} at ({x}, {y})",
                                        f.method(),
                                        f.radius_px
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    /// A `w × h` frame of two 3D planes (`1/Z` affine in the pixel, so the disparity too) meeting
    /// at a 0.7–0.8 m depth jump at x = 70, with ±2 mm of noise and holes: nothing a pass may
    /// not average except the jump and the holes.
    fn two_planes(w: usize, h: usize) -> DepthImage {
        noisy_frame(w, h, 0x9e37_79b9_7f4a_7c15, |x, y| {
            let inv_z = if x > 70.0 {
                0.5 - 0.0008 * x - 0.0005 * y
            } else {
                0.8 - 0.0015 * x - 0.0008 * y
            };
            1.0 / inv_z
        })
    }

    #[test]
    fn multiscale_is_the_base_then_each_pass_inside_its_interior_without_creases() {
        let s = SensorModel::kinect_v1();
        let m = MultiScale::default_for(&s);
        let img = two_planes(157, 61);
        let mut want = m.base.apply(&img).unwrap();
        for &dil in &m.dilations {
            let coarse = apply_dilated(&m.coarse, &want, dil).unwrap();
            let r = m.coarse.radius_px * dil;
            let mut keep = interior(&want, &m.coarse.range, r);
            assert!(keep.iter().any(|&k| k) && keep.iter().any(|&k| !k));
            let inside = keep.iter().filter(|&&k| k).count();
            let domain = Domain::of(&m.coarse.range);
            let mut u = Vec::new();
            domain.image_into(&want, &mut u, false);
            refuse_creases(
                &u,
                want.width(),
                domain,
                r,
                &mut keep,
                &mut Vec::new(),
                false,
            );
            // Planes have no crease, at any dilation: only the noise can refuse a pixel, and
            // the test's bound (4 σ of the frame's own second differences) seldom lets it.
            let kept = keep.iter().filter(|&&k| k).count();
            assert!(kept * 100 >= inside * 97, "{kept} of {inside}");
            for ((v, c), k) in want.data_mut().iter_mut().zip(coarse.data()).zip(keep) {
                if k {
                    *v = *c;
                }
            }
        }
        let got = m.apply(&img).unwrap();
        assert!(
            got.data()
                .iter()
                .zip(want.data())
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    #[test]
    fn dilation_one_is_the_plain_filter_and_holes_stay() {
        let s = SensorModel::kinect_v1();
        let (w, h) = (37, 29);
        let mut d: Vec<f32> = (0..w * h)
            .map(|i| 2.0 + 0.01 * ((i * 7919 % 13) as f32 / 6.0 - 1.0))
            .collect();
        d[5 * w + 7] = 0.0;
        let img = DepthImage::from_vec(w, h, d).unwrap();
        let f = DepthFilter::default_for(Method::Disparity, &s);
        assert_eq!(apply_dilated(&f, &img, 1).unwrap(), f.apply(&img).unwrap());
        let m = MultiScale::default_for(&s).apply(&img).unwrap();
        for (a, b) in m.data().iter().zip(img.data()) {
            assert_eq!(*a == 0.0, *b == 0.0);
        }
        assert!(apply_dilated(&f, &img, 0).is_err());
    }

    #[test]
    fn planes_pass_unchanged_through_the_coarse_passes() {
        // 1/Z affine in the pixel coordinates: a 3D plane.
        let s = SensorModel::kinect_v1();
        let (w, h) = (64, 48);
        let d: Vec<f32> = (0..w * h)
            .map(|i| 1.0 / (0.4 + 0.002 * (i % w) as f32 + 0.001 * (i / w) as f32))
            .collect();
        let img = DepthImage::from_vec(w, h, d).unwrap();
        let f = MultiScale::default_for(&s).coarse;
        let out = apply_dilated(&f, &img, 4).unwrap();
        // Exact where the dilated window is complete (8 px from the border): symmetric taps on
        // an affine disparity. Near the border the clipped window is one-sided; `interior`
        // keeps the finer result there.
        let keep = interior(&img, &f.range, 8);
        let mut checked = 0;
        for ((a, b), k) in out.data().iter().zip(img.data()).zip(&keep) {
            if *k {
                assert!((a - b).abs() < 2e-5 * b * b, "{a} vs {b}");
                checked += 1;
            }
        }
        assert_eq!(checked, (64 - 16) * (48 - 16));
    }
    #[test]
    fn interior_is_the_brute_force_window_test() {
        // A small frame, and one taller than several bands of the parallel vertical pass (its
        // holes and jumps near the bands' edges), with one thread and with three.
        for (w, h, holes) in [
            (23, 17, vec![(4, 3), (18, 9), (2, 14)]),
            (29, 101, vec![(5, 31), (9, 32), (20, 63), (3, 64), (27, 95)]),
        ] {
            for threads in [1, 3] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| interior_matches_brute_force(w, h, &holes));
            }
        }
    }

    /// The buffers a thread keeps between calls (`Scratch`) hold the previous frame's values:
    /// frames of other sizes and contents in a row on one thread give what each gives on a
    /// thread that never filtered before.
    #[test]
    fn buffers_kept_from_an_earlier_frame_do_not_change_the_next() {
        let m = MultiScale::default_for(&SensorModel::kinect_v1());
        let frames = [
            frame(160, 120),
            two_planes(97, 61),
            frame(160, 120),
            two_planes(160, 120),
        ];
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let in_a_row: Vec<DepthImage> =
            one_thread.install(|| frames.iter().map(|f| m.apply(f).unwrap()).collect());
        for (f, got) in frames.iter().zip(&in_a_row) {
            let fresh = std::thread::scope(|t| {
                t.spawn(|| {
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(1)
                        .build()
                        .unwrap()
                        .install(|| m.apply(f).unwrap())
                })
                .join()
                .unwrap()
            });
            let bits = |o: &DepthImage| o.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(got), bits(&fresh), "{}x{}", f.width(), f.height());
        }
    }

    #[test]
    fn the_output_does_not_depend_on_the_number_of_threads() {
        // A slanted wall with a box before it, holes and a pseudo-random error.
        let s = SensorModel::kinect_v1();
        let (w, h) = (203, 151);
        let d: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let e = 0.004 * ((i * 7919 % 101) as f32 / 50.0 - 1.0);
                if (x * 7 + y * 13) % 89 == 0 {
                    0.0
                } else if (60..140).contains(&x) && (40..110).contains(&y) {
                    1.2 + e
                } else {
                    2.0 + 0.004 * x as f32 + 0.002 * y as f32 + e
                }
            })
            .collect();
        let img = DepthImage::from_vec(w, h, d).unwrap();
        let m = MultiScale::default_for(&s);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| m.apply(&img).unwrap())
        };
        let one = run(1);
        for threads in [2, 5] {
            let other = run(threads);
            let bits = |o: &DepthImage| o.data().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&one), bits(&other), "{threads} threads");
        }
        // The coarse passes changed the frame (the test compares something).
        let single = m.base.apply(&img).unwrap();
        assert_ne!(one, single);
    }

    /// The AVX2 builds of the gates (`kernel::avx2_twin!`) decide exactly as the baseline
    /// builds, for every range kernel and several windows, on noisy frames with holes, slopes,
    /// jumps and creases.
    #[test]
    fn the_avx2_builds_of_the_gates_match_the_baseline() {
        if !use_avx2(Isa::Avx2) {
            return;
        }
        let s = SensorModel::kinect_v1();
        let ranges = [
            MultiScale::default_for(&s).coarse.range,
            RangeKernel::Adaptive { k_per_m: 0.003 },
            RangeKernel::Fixed { sigma_d_m: 0.01 },
            RangeKernel::None,
        ];
        for img in [frame(157, 61), two_planes(203, 97), frame(33, 20)] {
            for range in &ranges {
                let domain = Domain::of(range);
                for r in [1, 2, 4, 8, 16] {
                    let mut got = [Vec::new(), Vec::new()];
                    let mut tau = [0.0f32; 2];
                    for (i, avx2) in [false, true].into_iter().enumerate() {
                        let mut gate = Gate::default();
                        gate.interior_into(&img, domain, r, &mut got[i], avx2);
                        let (w, keep) = (img.width(), &mut got[i]);
                        tau[i] =
                            refuse_creases(&gate.values, w, domain, r, keep, &mut Vec::new(), avx2);
                    }
                    assert_eq!(got[0], got[1], "{range:?} r {r}");
                    assert_eq!(tau[0].to_bits(), tau[1].to_bits(), "{range:?} r {r}");
                }
            }
        }
    }

    fn interior_matches_brute_force(w: usize, h: usize, holes: &[(usize, usize)]) {
        let s = SensorModel::kinect_v1();
        // A slope with holes and a jump.
        let jump_row = h * 2 / 3;
        let mut d: Vec<f32> = (0..w * h)
            .map(|i| 1.5 + 0.002 * (i % w) as f32 + if (i / w) > jump_row { 0.4 } else { 0.0 })
            .collect();
        for &(x, y) in holes {
            d[y * w + x] = 0.0;
        }
        let img = DepthImage::from_vec(w, h, d.clone()).unwrap();
        let f = MultiScale::default_for(&s).coarse;
        // The default coarse pass's disparity kernel, and every other range kernel a
        // `MultiScale` may be given.
        let ranges = [
            f.range,
            RangeKernel::Adaptive { k_per_m: 0.003 },
            RangeKernel::Fixed { sigma_d_m: 0.01 },
            RangeKernel::None,
        ];
        for (range, r) in ranges
            .iter()
            .flat_map(|g| [1usize, 2, 3, 4, 5, 8, 9, 16].map(|r| (g, r)))
        {
            let got = interior(&img, range, r);
            for y in 0..h {
                for x in 0..w {
                    let inside = x >= r && y >= r && x + r < w && y + r < h;
                    let want = inside
                        && (y - r..=y + r).all(|yy| {
                            (x - r..=x + r).all(|xx| {
                                let i = yy * w + xx;
                                let (a, sa) = domain(range, d[i]);
                                let jump =
                                    |j: usize| d[j] > 0.0 && (a - domain(range, d[j]).0).abs() > sa;
                                d[i] > 0.0
                                    && !(xx + 1 < w && jump(i + 1))
                                    && !(yy + 1 < h && jump(i + w))
                            })
                        });
                    assert_eq!(got[y * w + x], want, "r {r} at ({x}, {y})");
                }
            }
        }
    }
}

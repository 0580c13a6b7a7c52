//! The fast filter kernel shared by every method.
//!
//! All four filters compute, for each valid pixel `p` with value `v_p`,
//!
//! ```text
//! v̂_p = v_p + (Σ_q w_q·e_q / Σ_q w_q) / s_p,   e_q = s_p·v_q − s_p·v_p,   w_q = 2^(t_q − e_q²)
//! ```
//!
//! where `t_q = −|q − p|²/(2σ_s²)·log2 e` is the precomputed spatial exponent of the tap and
//! `s_p = √(log2 e / (2σ_p²))` the range scale (constant for the bilateral filters,
//! `√a / v_p²` for the adaptive one with `σ_p = k·v_p²`, 1 — and no exponential at all — for
//! the Gaussian). `e_q` is one fused multiply-add per tap (`v_q·s_p − (s_p·v_p)`), the exponent
//! one more. Accumulating the scaled *difference* instead of `w·v_q` keeps full `f32` precision
//! (no cancellation of large depths) and makes symmetric cancellations exact.
//!
//! **Layout.** The input is copied once into a padded buffer (`r` pixels on every side and the
//! width rounded up to the lane count). Invalid pixels and the padding hold a sentinel:
//! a sentinel (10¹⁸) for the range filters — its range exponent is below the cutoff of
//! the weight function (`2^−100`), so its weight is exactly 0 and invalid neighbours need no
//! mask — and 0 with an explicit mask for the Gaussian.
//! This is what makes the border handling "window clipped at the border, weights renormalised
//! over the valid pixels inside the image".
//!
//! **Speed.** Rows are processed in blocks in parallel with rayon; within a row, `L` consecutive
//! output pixels (8 portable, 16 with AVX2, 32 with AVX-512) are computed together, taps in the
//! outer (unrolled for a constant radius) loop and the lanes in the inner loop, which the compiler
//! vectorises. Radii 1, 2 and 3 (3×3, 5×5, 7×7) are monomorphised with a constant radius; other
//! radii use the same code with a runtime radius. On x86-64 the AVX2+FMA and AVX-512 versions
//! are selected at run time after checking the CPU.

use rayon::prelude::*;

use crate::fastexp::exp2_neg;

/// Sentinel stored for invalid pixels and padding in the range filters.
pub(crate) const INVALID_FILL: f32 = 1.0e18;
/// Values at or above this are not valid (the sentinel, or out of range).
pub(crate) const VALID_LIMIT: f32 = 1.0e17;
/// Largest range scale used (keeps `s·v` finite for any supported value).
const MAX_SCALE: f32 = 1.0e15;
/// Rows per rayon task.
const BLOCK_ROWS: usize = 16;

/// How the range scale `s_p` depends on the centre value.
pub(crate) trait RangeMode: Copy + Send + Sync {
    /// Whether there is a range weight at all (false: the Gaussian).
    const RANGE: bool;
    /// `s_p` for a centre value.
    fn scale(self, v: f32) -> f32;
}

/// The Gaussian: spatial weights only.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NoRange;
impl RangeMode for NoRange {
    const RANGE: bool = false;
    #[inline(always)]
    fn scale(self, _v: f32) -> f32 {
        1.0
    }
}

/// A constant range scale `√(log2 e/(2σ²))` (bilateral, in depth or in disparity).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fixed(pub f32);
impl RangeMode for Fixed {
    const RANGE: bool = true;
    #[inline(always)]
    fn scale(self, _v: f32) -> f32 {
        self.0
    }
}

/// `s_p = √a / v_p²`, i.e. `σ(p) = k·v_p²` with `√a = √(log2 e/2) / k`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Adaptive(pub f32);
impl RangeMode for Adaptive {
    const RANGE: bool = true;
    #[inline(always)]
    fn scale(self, v: f32) -> f32 {
        let s = self.0 / (v * v);
        if s < MAX_SCALE { s } else { MAX_SCALE }
    }
}

/// Instruction set used by the kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// Portable code (whatever the compile target allows; SSE2 on a default x86-64 build).
    Portable,
    /// AVX2 + FMA, 16 lanes.
    Avx2,
    /// AVX-512F, 32 lanes.
    Avx512,
}

impl Isa {
    /// The best instruction set this CPU supports.
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Isa::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma")
            {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// Whether this CPU can run `self`.
    pub fn is_supported(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Avx2 => matches!(Isa::detect(), Isa::Avx2 | Isa::Avx512),
            Isa::Avx512 => Isa::detect() == Isa::Avx512,
        }
    }

    /// Short name (`portable`, `avx2`, `avx512`).
    pub fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }
}

/// The input of one filter run: the depth image plus how to map it into the padded buffers.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Source<'a> {
    /// Row-major depth, metres.
    pub data: &'a [f32],
    pub width: usize,
    pub height: usize,
    /// Value stored for invalid pixels and padding.
    pub fill: f32,
    /// `Some(fb)`: filter disparity `fb / Z` instead of depth.
    pub disparity_fb: Option<f32>,
    /// Supported depth range; valid depths outside it are reported.
    pub min_m: f32,
    pub max_m: f32,
}

/// A padded block of rows: row `j` holds image row `y0 + j − r` (fill outside the image), with
/// `r` fill pixels on the left and fill up to `stride` on the right.
#[derive(Debug)]
pub(crate) struct Padded<'a> {
    pub data: &'a [f32],
    pub stride: usize,
    pub width: usize,
}

/// Row stride of the padded blocks.
pub(crate) fn stride_for(width: usize, radius: usize) -> usize {
    width.div_ceil(CHUNK) * CHUNK + 2 * radius.max(MAX_FAST_RADIUS)
}

/// Everything the row kernel needs besides the image.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Taps<'a> {
    pub radius: usize,
    /// `(2r+1)²` spatial exponents (range filters) or linear weights (Gaussian), row-major.
    pub taps: &'a [f32],
}

thread_local! {
    /// Per-thread padded block buffer, reused across calls (no allocation per call once warm).
    static SCRATCH: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Filters `src` into `out` (`width * height`, row-major), in parallel over blocks of rows.
/// Each block is first copied with its `r` rows of context into a per-thread padded buffer
/// (so the copy stays in cache and no image-sized temporary is allocated). Returns `false` if a
/// valid depth lies outside `[min_m, max_m]` (the output is then unspecified).
pub(crate) fn run<M: RangeMode>(
    isa: Isa,
    taps: Taps<'_>,
    src: &Source<'_>,
    out: &mut [f32],
    mode: M,
) -> bool {
    let width = src.width;
    if width == 0 || src.height == 0 {
        return true;
    }
    let r = taps.radius;
    let stride = stride_for(width, r);
    let bad = std::sync::atomic::AtomicBool::new(false);
    out.par_chunks_mut(width * BLOCK_ROWS)
        .enumerate()
        .for_each(|(bi, block)| {
            let y0 = bi * BLOCK_ROWS;
            let rows = block.len() / width;
            SCRATCH.with(|cell| {
                let mut buf = cell.borrow_mut();
                let need = stride * (rows + 2 * r);
                if buf.len() < need {
                    buf.resize(need, 0.0);
                }
                let buf = &mut buf[..need];
                let ok = match src.disparity_fb {
                    None => dispatch::<M, false>(isa, taps, src, y0, stride, buf, block, mode, 0.0),
                    Some(fb) => {
                        dispatch::<M, true>(isa, taps, src, y0, stride, buf, block, mode, fb)
                    }
                };
                if !ok {
                    bad.store(true, std::sync::atomic::Ordering::Relaxed);
                }
            });
        });
    !bad.into_inner()
}

/// Copies image rows `y0 − r .. y0 + rows + r` into `buf` (see [`Padded`]); `false` if a valid
/// depth is out of range.
#[inline(always)]
fn fill_rows<const DISP: bool>(
    src: &Source<'_>,
    y0: usize,
    r: usize,
    stride: usize,
    buf: &mut [f32],
    fb: f32,
) -> bool {
    let (w, h, fill) = (src.width, src.height, src.fill);
    let mut bad = false;
    for (j, row) in buf.chunks_mut(stride).enumerate() {
        let iy = (y0 + j).wrapping_sub(r);
        if iy >= h {
            row.fill(fill);
            continue;
        }
        row[..r].fill(fill);
        row[r + w..].fill(fill);
        let s = &src.data[iy * w..(iy + 1) * w];
        for (o, &z) in row[r..r + w].iter_mut().zip(s) {
            // `z <= f32::MAX` is false for NaN and +inf.
            let valid = z > 0.0 && z <= f32::MAX;
            bad |= valid & !(z >= src.min_m && z <= src.max_m);
            let v = if DISP { fb / z } else { z };
            *o = if valid { v } else { fill };
        }
    }
    !bad
}

/// Pads one block (see [`fill_rows`]) and filters it with the instruction set `isa`; `false`
/// if a valid depth is out of range.
#[allow(clippy::too_many_arguments)]
fn dispatch<M: RangeMode, const DISP: bool>(
    isa: Isa,
    taps: Taps<'_>,
    src: &Source<'_>,
    y0: usize,
    stride: usize,
    buf: &mut [f32],
    out: &mut [f32],
    mode: M,
    fb: f32,
) -> bool {
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 if Isa::Avx512.is_supported() => {
            // SAFETY: the only precondition of a `#[target_feature]` function is that the CPU
            // supports the features, which `is_supported` has just checked at run time.
            #[allow(unsafe_code)]
            unsafe {
                block_avx512::<M, DISP>(taps, src, y0, stride, buf, out, mode, fb)
            }
        }
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 | Isa::Avx512 if Isa::Avx2.is_supported() => {
            // SAFETY: as above — AVX2 and FMA support was checked at run time.
            #[allow(unsafe_code)]
            unsafe {
                block_avx2::<M, DISP>(taps, src, y0, stride, buf, out, mode, fb)
            }
        }
        _ => block_portable::<M, DISP>(taps, src, y0, stride, buf, out, mode, fb),
    }
}

macro_rules! pad_and_filter {
    ($fma:literal, $taps:ident, $src:ident, $y0:ident, $stride:ident, $buf:ident, $out:ident, $mode:ident, $fb:ident) => {{
        let ok = fill_rows::<DISP>($src, $y0, $taps.radius, $stride, $buf, $fb);
        let p = Padded {
            data: $buf,
            stride: $stride,
            width: $src.width,
        };
        let p = &p;
        match $taps.radius {
            1 => block::<1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            2 => block::<2, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            3 => block::<3, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            _ => block::<0, $fma, M, DISP>($taps, p, $out, $mode, $fb),
        }
        ok
    }};
}

#[allow(clippy::too_many_arguments)]
fn block_portable<M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    src: &Source<'_>,
    y0: usize,
    stride: usize,
    buf: &mut [f32],
    out: &mut [f32],
    mode: M,
    fb: f32,
) -> bool {
    pad_and_filter!(false, taps, src, y0, stride, buf, out, mode, fb)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx2<M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    src: &Source<'_>,
    y0: usize,
    stride: usize,
    buf: &mut [f32],
    out: &mut [f32],
    mode: M,
    fb: f32,
) -> bool {
    pad_and_filter!(true, taps, src, y0, stride, buf, out, mode, fb)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx512<M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    src: &Source<'_>,
    y0: usize,
    stride: usize,
    buf: &mut [f32],
    out: &mut [f32],
    mode: M,
    fb: f32,
) -> bool {
    pad_and_filter!(true, taps, src, y0, stride, buf, out, mode, fb)
}

/// Output pixels computed together: the lane loops run over `CHUNK` pixels, long enough for
/// LLVM's loop vectoriser (which is robust, unlike SLP vectorisation of short unrolled loops)
/// and short enough for the accumulators to stay in L1.
pub(crate) const CHUNK: usize = 128;

/// Largest radius with a constant-radius fast path.
pub(crate) const MAX_FAST_RADIUS: usize = 3;
/// Length of the row windows of the fast path: a chunk plus the largest fast-path apron.
const CW: usize = CHUNK + 2 * MAX_FAST_RADIUS;

/// Filters the block of whole rows `out` from its padded block `p`. `R = 0`: runtime radius.
#[inline(always)]
fn block<const R: usize, const FMA: bool, M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    p: &Padded<'_>,
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    let r = if R == 0 { taps.radius } else { R };
    let k = 2 * r + 1;
    let stride = p.stride;
    let width = p.width;
    let tap_w = &taps.taps[..k * k];
    let mut sc = [1.0f32; CHUNK];
    let mut zs = [0.0f32; CHUNK];
    let mut sw = [0.0f32; CHUNK];
    let mut swd = [0.0f32; CHUNK];
    let mut res = [0.0f32; CHUNK];
    for (y, out_row) in out.chunks_mut(width).enumerate() {
        // Rows y .. y + 2r of the padded block are the window rows of output row y.
        let win = &p.data[y * stride..(y + k) * stride];
        let mut x0 = 0;
        while x0 < width {
            // `CW`-long fixed-size row windows: every `row[i + dx]` below is provably in
            // bounds, so the lane loops carry no bounds checks and vectorise.
            let Ok(centre) = <&[f32; CW]>::try_from(&win[r * stride + x0..r * stride + x0 + CW])
            else {
                return;
            };
            for i in 0..CHUNK {
                let z = centre[i + r];
                let s = if M::RANGE { mode.scale(z) } else { 1.0 };
                sc[i] = s;
                zs[i] = s * z;
            }
            // The centre tap has weight exactly 1 (w_s(0)·w_d(0)) and a zero difference: it
            // initialises the sums and is skipped below.
            sw.fill(1.0);
            swd.fill(0.0);
            for dy in 0..k {
                let Ok(row) = <&[f32; CW]>::try_from(&win[dy * stride + x0..dy * stride + x0 + CW])
                else {
                    return;
                };
                let trow = &tap_w[dy * k..dy * k + k];
                if R > 0 {
                    // Fast path: lanes outer (vectorised), the row's taps unrolled inside.
                    if dy == R {
                        accumulate_row::<R, FMA, M, true>(row, trow, &sc, &zs, &mut sw, &mut swd);
                    } else {
                        accumulate_row::<R, FMA, M, false>(row, trow, &sc, &zs, &mut sw, &mut swd);
                    }
                } else {
                    // Runtime radius: taps outer, lanes inner (vectorised).
                    let row = &win[dy * stride + x0..];
                    for (dx, &t) in trow.iter().enumerate() {
                        if dy == r && dx == r {
                            continue;
                        }
                        let nb = &row[dx..dx + CHUNK];
                        for i in 0..CHUNK {
                            let (w, e) = weight::<FMA, M>(nb[i], sc[i], zs[i], t);
                            sw[i] += w;
                            swd[i] = if FMA {
                                w.mul_add(e, swd[i])
                            } else {
                                swd[i] + w * e
                            };
                        }
                    }
                }
            }
            // Written as plain selects: a branchier form (`is_finite`, nested `if`s) can make
            // LLVM's vectorisers give up.
            for i in 0..CHUNK {
                let c = centre[i + r];
                let v = c + swd[i] / sw[i] / sc[i];
                let (v, c_out) = if DISP { (fb / v, fb / c) } else { (v, c) };
                let v = if v > 0.0 && v < f32::INFINITY {
                    v
                } else {
                    c_out
                };
                res[i] = if c > 0.0 && c < VALID_LIMIT { v } else { 0.0 };
            }
            let n = CHUNK.min(width - x0);
            out_row[x0..x0 + n].copy_from_slice(&res[..n]);
            x0 += CHUNK;
        }
    }
}

/// Adds the taps of one window row (constant radius `R`) to the sums of a chunk: lanes outer
/// (vectorised), taps unrolled inside; `SKIP_CENTRE` leaves out the centre tap.
#[inline(always)]
fn accumulate_row<const R: usize, const FMA: bool, M: RangeMode, const SKIP_CENTRE: bool>(
    row: &[f32; CW],
    trow: &[f32],
    sc: &[f32; CHUNK],
    zs: &[f32; CHUNK],
    sw: &mut [f32; CHUNK],
    swd: &mut [f32; CHUNK],
) {
    let trow = &trow[..2 * R + 1];
    for i in 0..CHUNK {
        let (s, z) = (sc[i], zs[i]);
        let (mut s0, mut s1) = (sw[i], swd[i]);
        for dx in 0..2 * R + 1 {
            if SKIP_CENTRE && dx == R {
                continue;
            }
            let (w, e) = weight::<FMA, M>(row[i + dx], s, z, trow[dx]);
            s0 += w;
            s1 = if FMA { w.mul_add(e, s1) } else { s1 + w * e };
        }
        sw[i] = s0;
        swd[i] = s1;
    }
}

/// The weight of neighbour value `nb` and its scaled difference `e = s·nb − zs` to the centre
/// (`zs = s·z`), for the spatial tap `t` (an exponent for the range filters, a linear weight for
/// the Gaussian, where `s = 1` and invalid neighbours are masked explicitly).
#[inline(always)]
fn weight<const FMA: bool, M: RangeMode>(nb: f32, s: f32, zs: f32, t: f32) -> (f32, f32) {
    if M::RANGE {
        let e = if FMA { nb.mul_add(s, -zs) } else { nb * s - zs };
        let x = if FMA { (-e).mul_add(e, t) } else { t - e * e };
        (exp2_neg::<FMA>(x), e)
    } else {
        (if nb > 0.0 { t } else { 0.0 }, nb - zs)
    }
}

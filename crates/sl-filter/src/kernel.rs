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
//! the Gaussian). `e_q` is one fused multiply-add per tap (`v_q·s_p − (s_p·v_p)`). Accumulating
//! the scaled *difference* instead of `w·v_q` keeps full `f32` precision (no cancellation of
//! large depths) and makes symmetric cancellations exact.
//!
//! **The range weight** `2^(t − e²)` (see [`crate::weight`]) is the log-linear `2^x`: with
//! the difference pre-scaled by `2^11.5`, `y = T − e'²` is one multiply-add (`T` folds in the
//! tap's spatial exponent) and the truncated `y` read as an `f32` *is* the weight, negated; a
//! `y` below `−2³¹` (a weight below `2^−127`) converts to `−0.0`, exactly no weight. Per tap: 5
//! vector operations on AVX-512 and AVX2 alike (difference, `y`, conversion, two sums). Both
//! sums carry the negated weights; their ratio is the filter's.
//!
//! **Layout.** The input is copied once into a padded buffer (`r` pixels on every side and the
//! width rounded up to the lane count). Invalid pixels and the padding hold a sentinel:
//! a sentinel (10¹⁸) for the range filters — its range exponent is far below `−127`, so it
//! weighs exactly 0 and invalid neighbours need no mask — and 0 with an explicit mask for the
//! Gaussian.
//! This is what makes the border handling "window clipped at the border, weights renormalised
//! over the valid pixels inside the image".
//!
//! **Speed.** Rows are processed in blocks of 16 by the calling thread and rayon helpers taking
//! blocks from one queue (each block padded into a per-thread buffer). Radii 1, 2 and 3 (3×3,
//! 5×5, 7×7) are monomorphised fast paths: for each group of output pixels the whole window is
//! unrolled, so the sums stay in registers; the portable code (and the Gaussian's AVX2 code)
//! lets the compiler vectorise 128 pixels at a time. The range filters' AVX-512 code (module
//! `x512`) is written with intrinsics, two 16-lane groups interleaved, and skips groups of 32
//! pixels whose centres are all invalid (their output is 0 whatever the neighbours; 10.6 % of
//! `person-depth.png`); their AVX2 code (module `x256`, bit-identical to the compiler-vectorised
//! FMA code) interleaves two 8-lane groups the same way and skips all-invalid
//! groups of 16. Other radii use a runtime-radius loop. On x86-64 the AVX2+FMA and AVX-512 (F + DQ) versions are
//! selected at run time after checking the CPU; every path is tested against
//! [`crate::reference`].
//!
//! **Dilated windows** (`Taps::step` > 1: the taps `step` pixels apart, the multi-scale
//! filter's coarse passes). The padding and the rows of context of a block are the window's
//! reach, `radius · step`, and the blocks are taller (up to 64 rows) so that the context stays a
//! fraction of them. The 5×5 window at steps 2, 4 and 8 has fast paths in every kernel (the
//! step a compile-time constant: tap `(dx, dy)` reads row `dy·step`, column `dx·step`); other
//! steps take the runtime-radius loop. A pass may come with a mask (`Source::keep`) of the pixels
//! whose result is wanted: elsewhere the output is the input, merged block by block, and the
//! fast paths skip groups of pixels (the kernel's groups, or whole chunks) none of which is kept.

use crate::weight::{CENTRE_WEIGHT, TapExp, range_weight};

// The AVX2 builds of the multi-scale filter's auxiliary loops (the gates, the domain values,
// the merge of a pass), chosen at run time. The crate is compiled for the baseline x86-64
// (SSE2), so the compiler vectorises these loops four `f32` or sixteen byte lanes wide.
// `avx2_twin!` compiles one loop body a second time inside a `#[target_feature(enable =
// "avx2")]` function and picks that build where the caller's `Isa` is not the portable one and
// the CPU has AVX2: the same operations in the same order, so the results are bit-identical, on
// vectors twice as wide. Measured on the person frame, one thread, AMD EPYC: the default
// multi-scale filter 2.59 → 1.96 ms with the AVX-512 kernels and 3.37 → 2.81 ms with the AVX2
// ones, as fast as the whole crate built for `x86-64-v3` (docs/bench/README.md, session 97).
// Written by hand: a crate such as `multiversion` does the same with a procedural macro, for
// five small loops not worth a dependency. It lives here because this file is the one place
// `unsafe` is allowed (the runtime ISA dispatch).

/// Whether the AVX2 twins run for `isa` on this CPU.
pub(crate) fn use_avx2(isa: Isa) -> bool {
    cfg!(target_arch = "x86_64") && isa != Isa::Portable && Isa::Avx2.is_supported()
}

/// Defines `fn $name(avx2: bool, args…)`, which runs `$body` compiled with AVX2 when `avx2`
/// is true (the caller checked the CPU with [`use_avx2`]) and for the baseline otherwise.
/// `$body` must not rely on anything but its arguments; functions it calls are inlined into
/// both builds only when they are `#[inline(always)]`.
macro_rules! avx2_twin {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident $(<$($lt:lifetime),*>)? ($($arg:ident : $ty:ty),* $(,)?) $body:block
    ) => {
        $(#[$meta])*
        $vis fn $name $(<$($lt),*>)? (avx2: bool, $($arg: $ty),*) {
            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            fn body $(<$($lt),*>)? ($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            #[allow(clippy::too_many_arguments)]
            fn wide $(<$($lt),*>)? ($($arg: $ty),*) {
                body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: the only precondition of a `#[target_feature]` function is that the
                // CPU supports its features: `avx2` is true only after `use_avx2` checked it.
                #[allow(unsafe_code)]
                unsafe {
                    return wide($($arg),*);
                }
            }
            let _ = avx2;
            body($($arg),*)
        }
    };
}

pub(crate) use avx2_twin;

/// Sentinel stored for invalid pixels and padding in the range filters.
pub(crate) const INVALID_FILL: f32 = 1.0e18;
/// Values at or above this are not valid (the sentinel, or out of range).
pub(crate) const VALID_LIMIT: f32 = 1.0e17;
/// Largest range scale used (keeps `s·v` finite for any supported value).
const MAX_SCALE: f32 = 1.0e15;
/// Rows per block (the unit of work shared between threads).
const BLOCK_ROWS: usize = 16;

/// How the range scale `s_p` depends on the centre value.
pub(crate) trait RangeMode: Copy + Send + Sync {
    /// Whether there is a range weight at all (false: the Gaussian).
    const RANGE: bool;
    /// Whether `s_p = coef / v_p²` (true) or `s_p = coef` (false).
    const ADAPTIVE: bool;
    /// `s_p` for a centre value.
    fn scale(self, v: f32) -> f32;
    /// The constant of [`RangeMode::scale`].
    fn coef(self) -> f32;
}

/// The Gaussian: spatial weights only.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NoRange;
impl RangeMode for NoRange {
    const RANGE: bool = false;
    const ADAPTIVE: bool = false;
    #[inline(always)]
    fn scale(self, _v: f32) -> f32 {
        1.0
    }
    #[inline(always)]
    fn coef(self) -> f32 {
        1.0
    }
}

/// A constant range scale `√(log2 e/(2σ²))` (bilateral, in depth or in disparity).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fixed(pub f32);
impl RangeMode for Fixed {
    const RANGE: bool = true;
    const ADAPTIVE: bool = false;
    #[inline(always)]
    fn scale(self, _v: f32) -> f32 {
        self.0
    }
    #[inline(always)]
    fn coef(self) -> f32 {
        self.0
    }
}

/// `s_p = √a / v_p²`, i.e. `σ(p) = k·v_p²` with `√a = √(log2 e/2) / k`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Adaptive(pub f32);
impl RangeMode for Adaptive {
    const RANGE: bool = true;
    const ADAPTIVE: bool = true;
    #[inline(always)]
    fn scale(self, v: f32) -> f32 {
        let s = self.0 / (v * v);
        if s < MAX_SCALE { s } else { MAX_SCALE }
    }
    #[inline(always)]
    fn coef(self) -> f32 {
        self.0
    }
}

pub use sl_core::Isa;

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
    /// `Some(keep)` (`width × height`): where `keep` is false the output is the input value,
    /// unfiltered (merged block by block while both are in cache).
    pub keep: Option<&'a [bool]>,
}

/// A padded block of rows: row `j` holds image row `y0 + j − r` (fill outside the image), with
/// `r` fill pixels on the left and fill up to `stride` on the right.
#[derive(Debug)]
pub(crate) struct Padded<'a> {
    pub data: &'a [f32],
    pub stride: usize,
    pub width: usize,
    /// The block's rows of [`Source::keep`]: where it is false the output is replaced by the
    /// input afterwards, so the fast paths may skip groups of pixels none of which is kept
    /// (writing 0 there).
    pub keep: Option<&'a [bool]>,
}

impl<'a> Padded<'a> {
    /// The padded block `buf` of the `n` output values from image row `y0` of `src`.
    fn of_block(buf: &'a [f32], stride: usize, src: &Source<'a>, y0: usize, n: usize) -> Self {
        let at = y0 * src.width;
        Self {
            data: buf,
            stride,
            width: src.width,
            keep: src.keep.and_then(|k| k.get(at..at + n)),
        }
    }
}

/// The `k` window rows of the chunk at `x0` of a fast path with taps `S` pixels apart, from
/// `win` (the padded block from the output row's first window row on): rows `0, S, …` of it,
/// each `CW` long from `x0`. `None` if the block is too short (never, for the blocks of
/// [`run`]).
#[inline(always)]
pub(crate) fn window_rows<const S: usize>(
    win: &[f32],
    stride: usize,
    x0: usize,
    k: usize,
) -> Option<[&[f32; CW]; 2 * MAX_FAST_RADIUS + 1]> {
    let mut rows = [&[0.0f32; CW]; 2 * MAX_FAST_RADIUS + 1];
    for (dy, row) in rows.iter_mut().enumerate().take(k) {
        let at = dy * S * stride + x0;
        *row = win.get(at..at + CW)?.try_into().ok()?;
    }
    Some(rows)
}

/// Runs `f` on every chunk of `CHUNK` output pixels of a fast path's block `out` (whole rows
/// of `p`): with the chunk's `k` window rows (taps `S` apart, see [`window_rows`]), its output
/// (a scratch chunk, copied back, for a row's last and partial one) and which of its groups of
/// `G` pixels hold a kept pixel ([`kept_groups`]). A chunk with none is written 0 without a
/// call: its output is replaced by the input afterwards.
#[inline(always)]
pub(crate) fn for_each_chunk<const S: usize, const G: usize>(
    p: &Padded<'_>,
    out: &mut [f32],
    k: usize,
    mut f: impl FnMut(&[&[f32; CW]; 2 * MAX_FAST_RADIUS + 1], &mut [f32; CHUNK], u32),
) {
    let (stride, width) = (p.stride, p.width);
    let mut res = [0.0f32; CHUNK];
    for (y, out_row) in out.chunks_mut(width).enumerate() {
        // Rows y, y + S, …, y + 2R·S of the padded block are the window rows of output row y.
        let win = &p.data[y * stride..];
        let keep_row = p.keep.and_then(|k| k.get(y * width..(y + 1) * width));
        let mut x0 = 0;
        while x0 < width {
            let n = CHUNK.min(width - x0);
            let groups = kept_groups::<G>(keep_row, x0);
            if groups == 0 {
                out_row[x0..x0 + n].fill(0.0);
                x0 += CHUNK;
                continue;
            }
            // `CW`-long fixed-size row windows: every `row[i + dx·S]` of a kernel is provably
            // in bounds, so its lane loops carry no bounds checks.
            let Some(rows) = window_rows::<S>(win, stride, x0, k) else {
                return;
            };
            match <&mut [f32; CHUNK]>::try_from(&mut out_row[x0..x0 + n]) {
                Ok(dst) => f(&rows, dst, groups),
                Err(_) => {
                    f(&rows, &mut res, groups);
                    out_row[x0..x0 + n].copy_from_slice(&res[..n]);
                }
            }
            x0 += CHUNK;
        }
    }
}

/// Whether any of `keep` is true: an OR over the bytes, which vectorises.
#[inline(always)]
pub(crate) fn any_kept(keep: &[bool]) -> bool {
    keep.iter().fold(0u8, |a, &k| a | u8::from(k)) != 0
}

/// The groups of `G` pixels of a chunk starting at `x0` of an output row to compute: bit `g`
/// set when group `g` holds a kept pixel (all set without a mask). A group past the row's
/// end counts as kept; its output is never stored.
#[inline(always)]
pub(crate) fn kept_groups<const G: usize>(keep_row: Option<&[bool]>, x0: usize) -> u32 {
    let Some(row) = keep_row else {
        return u32::MAX;
    };
    let mut bits = 0u32;
    for g in 0..CHUNK / G {
        let (a, b) = (x0 + g * G, x0 + (g + 1) * G);
        let kept = match row.get(a..b.min(row.len())) {
            Some(k) if b <= row.len() => any_kept(k),
            _ => true,
        };
        bits |= u32::from(kept) << g;
    }
    bits
}

/// Row stride of the padded blocks for a window reaching `reach` pixels from its centre.
pub(crate) fn stride_for(width: usize, reach: usize) -> usize {
    width.div_ceil(CHUNK) * CHUNK + 2 * reach.max(MAX_REACH)
}

/// Everything the row kernel needs besides the image.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Taps<'a> {
    pub radius: usize,
    /// Pixels between neighbouring taps: 1 for the ordinary window, `s` for a dilated ("à
    /// trous") one whose taps are `s` pixels apart (supported where [`dilated_fast_path`]
    /// says so).
    pub step: usize,
    /// The window is the disc `dx² + dy² ≤ r²` (OpenCV's rule) rather than the full square:
    /// the taps outside it are skipped, not weighted 0.
    pub disc: bool,
    /// `(2r+1)²` linear spatial weights, row-major (the Gaussian).
    pub taps: &'a [f32],
    /// `(2r+1)²` range-weight constants with the spatial weights folded in, row-major (the
    /// range filters; see [`TapExp`]).
    pub exps: &'a [TapExp],
}

thread_local! {
    /// Per-thread padded block buffer, reused across calls (no allocation per call once warm).
    static SCRATCH: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Filters `src` into `out` (`width * height`, row-major), in parallel over blocks of rows.
/// Each block is first copied with its `r` rows of context into a per-thread padded buffer
/// (so the copy stays in cache and no image-sized temporary is allocated). Returns `false` if a
/// valid depth lies outside `[min_m, max_m]` (the output is then unspecified).
///
/// **Threads.** The calling thread works on the blocks itself and `n − 1` rayon tasks (`n` =
/// threads of the current pool) help, all taking blocks from one shared queue. Compared with a
/// plain `par_chunks_mut` called from outside the pool (where the caller sleeps until pool
/// workers wake up and do everything), the filter starts at once on the caller, and on a busy
/// machine a worker that wakes late just finds fewer blocks left. With one thread (e.g. inside a
/// one-thread pool's `install`) nothing is spawned.
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
    // How far the window reaches from its centre: the padding of every block.
    let r = taps.radius * taps.step;
    let stride = stride_for(width, r);
    // A dilated window reaches further, so its blocks are taller: the rows of context copied
    // with a block stay a fraction of it (at most 50 % for the largest dilated reach).
    let block_rows = BLOCK_ROWS.max(4 * r.min(MAX_REACH));
    let bad = std::sync::atomic::AtomicBool::new(false);
    let queue = std::sync::Mutex::new(out.chunks_mut(width * block_rows).enumerate());
    let drain = || {
        loop {
            // The lock is held only to take the next block (30 blocks for 640×480).
            let next = match queue.lock() {
                Ok(mut blocks) => blocks.next(),
                Err(_) => None,
            };
            let Some((bi, block)) = next else {
                break;
            };
            let y0 = bi * block_rows;
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
                if let Some(keep) = src.keep {
                    keep_where(
                        use_avx2(isa),
                        block,
                        &src.data[y0 * width..],
                        &keep[y0 * width..],
                    );
                }
                if !ok {
                    bad.store(true, std::sync::atomic::Ordering::Relaxed);
                }
            });
        }
    };
    let helpers = rayon::current_num_threads().saturating_sub(1);
    if helpers == 0 {
        drain();
    } else {
        rayon::in_place_scope(|scope| {
            for _ in 0..helpers {
                scope.spawn(|_| drain());
            }
            drain();
        });
    }
    !bad.into_inner()
}

avx2_twin! {
    /// `out[i] = input[i]` where `keep[i]` is false (`out[i]` stays elsewhere). A select on
    /// the bits, so the loop vectorises (a select of the two values became a scalar loop of
    /// conditional loads).
    fn keep_where(out: &mut [f32], input: &[f32], keep: &[bool]) {
        for ((o, &z), &k) in out.iter_mut().zip(input).zip(keep) {
            let filtered = 0u32.wrapping_sub(u32::from(k));
            *o = f32::from_bits((o.to_bits() & filtered) | (z.to_bits() & !filtered));
        }
    }
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
        let reach = $taps.radius * $taps.step;
        let ok = fill_rows::<DISP>($src, $y0, reach, $stride, $buf, $fb);
        let p = Padded::of_block($buf, $stride, $src, $y0, $out.len());
        let p = &p;
        match ($taps.radius, $taps.disc, $taps.step) {
            (1, false, 1) => block::<1, false, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, false, 1) => block::<2, false, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (3, false, 1) => block::<3, false, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (1, true, 1) => block::<1, true, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, true, 1) => block::<2, true, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (3, true, 1) => block::<3, true, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, false, 2) => block::<2, false, 2, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, false, 4) => block::<2, false, 4, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, false, 8) => block::<2, false, 8, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, true, 2) => block::<2, true, 2, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, true, 4) => block::<2, true, 4, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            (2, true, 8) => block::<2, true, 8, $fma, M, DISP>($taps, p, $out, $mode, $fb),
            _ => block::<0, false, 1, $fma, M, DISP>($taps, p, $out, $mode, $fb),
        }
        ok
    }};
}

/// The body of an explicit-kernel block function: the range filters' constant-radius fast
/// paths through the kernel module `$k` (`x256`, `x512`) with the radius and window shape as
/// compile-time constants, everything else through `pad_and_filter!`. A macro, not a function,
/// so that it is compiled inside each `#[target_feature]` block function with its features.
macro_rules! explicit_kernel {
    ($k:ident, $taps:ident, $src:ident, $y0:ident, $stride:ident, $buf:ident, $out:ident, $mode:ident, $fb:ident) => {{
        let fast = (1..=MAX_FAST_RADIUS).contains(&$taps.radius)
            && ($taps.step == 1 || dilated_fast_path($taps.radius, $taps.step));
        if M::RANGE && fast {
            let ok = fill_rows::<DISP>($src, $y0, $taps.radius * $taps.step, $stride, $buf, $fb);
            let p = Padded::of_block($buf, $stride, $src, $y0, $out.len());
            match ($taps.radius, $taps.disc, $taps.step) {
                (1, false, _) => $k::block::<1, false, 1, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, false, 2) => $k::block::<2, false, 2, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, false, 4) => $k::block::<2, false, 4, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, false, 8) => $k::block::<2, false, 8, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, false, _) => $k::block::<2, false, 1, M, DISP>($taps, &p, $out, $mode, $fb),
                (3, false, _) => $k::block::<3, false, 1, M, DISP>($taps, &p, $out, $mode, $fb),
                (1, true, _) => $k::block::<1, true, 1, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, true, 2) => $k::block::<2, true, 2, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, true, 4) => $k::block::<2, true, 4, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, true, 8) => $k::block::<2, true, 8, M, DISP>($taps, &p, $out, $mode, $fb),
                (2, true, _) => $k::block::<2, true, 1, M, DISP>($taps, &p, $out, $mode, $fb),
                _ => $k::block::<3, true, 1, M, DISP>($taps, &p, $out, $mode, $fb),
            }
            ok
        } else {
            pad_and_filter!(true, $taps, $src, $y0, $stride, $buf, $out, $mode, $fb)
        }
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
    explicit_kernel!(x256, taps, src, y0, stride, buf, out, mode, fb)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx2,fma")]
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
    explicit_kernel!(x512, taps, src, y0, stride, buf, out, mode, fb)
}

/// Output pixels computed together: the lane loops run over `CHUNK` pixels, long enough for
/// LLVM's loop vectoriser (which is robust, unlike SLP vectorisation of short unrolled loops)
/// and short enough for the accumulators to stay in L1.
pub(crate) const CHUNK: usize = 128;

/// Largest radius with a constant-radius fast path.
pub(crate) const MAX_FAST_RADIUS: usize = 3;
/// The radius of the dilated fast paths (5×5 taps).
pub(crate) const DILATED_RADIUS: usize = 2;
/// The dilations (pixels between taps) with a fast path of radius [`DILATED_RADIUS`]: those of
/// `MultiScale`'s default passes.
pub(crate) const FAST_STEPS: [usize; 3] = [2, 4, 8];
/// The farthest a fast path's window reaches from its centre (radius × step).
pub(crate) const MAX_REACH: usize = DILATED_RADIUS * FAST_STEPS[FAST_STEPS.len() - 1];
/// Length of the row windows of the fast paths: a chunk plus the largest apron.
const CW: usize = CHUNK + 2 * MAX_REACH;

/// Whether a window of `radius` with taps `step` pixels apart has a dilated fast path.
pub(crate) fn dilated_fast_path(radius: usize, step: usize) -> bool {
    radius == DILATED_RADIUS && FAST_STEPS.contains(&step)
}

/// Filters the block of whole rows `out` from its padded block `p`. `R = 0`: runtime radius.
#[inline(always)]
fn block<
    const R: usize,
    const DISC: bool,
    const S: usize,
    const FMA: bool,
    M: RangeMode,
    const DISP: bool,
>(
    taps: Taps<'_>,
    p: &Padded<'_>,
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    if R > 0 {
        block_fast::<R, DISC, S, FMA, M, DISP>(taps, p, out, mode, fb);
    } else {
        block_any::<FMA, M, DISP>(taps, p, out, mode, fb);
    }
}

/// The per-pixel epilogue: `v̂ = c + Σw·e / (Σw·s)`, converted back from disparity, and 0 where
/// the centre is invalid. Written as plain selects: a branchier form (`is_finite`, nested `if`s)
/// can make LLVM's vectorisers give up.
#[inline(always)]
fn finish<const DISP: bool>(c: f32, s: f32, sw: f32, swd: f32, fb: f32) -> f32 {
    let v = c + swd / (sw * s);
    let (v, c_out) = if DISP { (fb / v, fb / c) } else { (v, c) };
    let v = if v > 0.0 && v < f32::INFINITY {
        v
    } else {
        c_out
    };
    if c > 0.0 && c < VALID_LIMIT { v } else { 0.0 }
}

/// Index of the tap class `(min(|dx|, |dy|), max(|dx|, |dy|))` of window tap `(dx, dy)` for a
/// constant radius `R`: taps of one class have the same spatial weight (the kernel is
/// isotropic), so their constants are loaded once per chunk and shared (exact symmetry).
#[inline(always)]
const fn class<const R: usize>(dy: usize, dx: usize) -> usize {
    let a = dy.abs_diff(R);
    let b = dx.abs_diff(R);
    if a <= b {
        a * (R + 1) + b
    } else {
        b * (R + 1) + a
    }
}

/// Whether `(dx, dy)` (0-based, `0..=2R`) is a non-centre tap of the `(2R+1)²` window, or with
/// `DISC` of the disc `|δ|² ≤ R²` inside it (the unrolled fast paths list the 7×7 positions
/// and drop the others at compile time).
#[inline(always)]
const fn is_tap<const R: usize, const DISC: bool>(dy: usize, dx: usize) -> bool {
    let (a, b) = (dy.abs_diff(R), dx.abs_diff(R));
    is_row::<R>(dy) && dx <= 2 * R && !(dy == R && dx == R) && (!DISC || a * a + b * b <= R * R)
}

/// Whether `dy` is a row of the `(2R+1)²` window.
#[inline(always)]
const fn is_row<const R: usize>(dy: usize) -> bool {
    dy <= 2 * R
}

/// Largest number of tap classes of a fast path (`(R + 1)²` with `R = 3`).
const MAX_CLASSES: usize = (MAX_FAST_RADIUS + 1) * (MAX_FAST_RADIUS + 1);

/// The constant-radius fast path: for each output pixel (lanes vectorised, `CHUNK` at a time)
/// the whole `(2R+1)²` window is unrolled, so the sums stay in registers and the two divisions
/// per pixel overlap with the taps' multiply-adds.
#[inline(always)]
fn block_fast<
    const R: usize,
    const DISC: bool,
    const S: usize,
    const FMA: bool,
    M: RangeMode,
    const DISP: bool,
>(
    taps: Taps<'_>,
    p: &Padded<'_>,
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    let k = 2 * R + 1;
    // Per-class constants (range filters) or linear weights (Gaussian).
    let mut cls = [TapExp::default(); MAX_CLASSES];
    let mut lin = [0.0f32; MAX_CLASSES];
    for dy in 0..k {
        for dx in 0..k {
            let c = class::<R>(dy, dx);
            if M::RANGE {
                cls[c] = taps.exps[dy * k + dx];
            } else {
                lin[c] = taps.taps[dy * k + dx];
            }
        }
    }
    let cls = &cls;
    let lin = &lin;
    for_each_chunk::<S, CHUNK>(p, out, k, |rows, dst, _| {
        chunk::<R, DISC, S, FMA, M, DISP>(
            rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], rows[6], cls, lin, dst, mode, fb,
        );
    });
}

/// One chunk of `CHUNK` output pixels of the fast path (see [`block_fast`]). The window rows
/// are separate reference arguments (not an array of references) so that LLVM knows they do
/// not alias `dst` and vectorises without runtime alias checks.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn chunk<
    const R: usize,
    const DISC: bool,
    const S: usize,
    const FMA: bool,
    M: RangeMode,
    const DISP: bool,
>(
    r0: &[f32; CW],
    r1: &[f32; CW],
    r2: &[f32; CW],
    r3: &[f32; CW],
    r4: &[f32; CW],
    r5: &[f32; CW],
    r6: &[f32; CW],
    cls: &[TapExp; MAX_CLASSES],
    lin: &[f32; MAX_CLASSES],
    dst: &mut [f32; CHUNK],
    mode: M,
    fb: f32,
) {
    let rows = [r0, r1, r2, r3, r4, r5, r6];
    for i in 0..CHUNK {
        let c = rows[R][i + R * S];
        let s = if M::RANGE { mode.scale(c) } else { 1.0 };
        let zs = s * c;
        // The centre tap (difference 0; weight 1 for the Gaussian, the range weight of
        // `x = 0` otherwise) initialises the sums and is skipped.
        let (mut sw, mut swd) = (if M::RANGE { CENTRE_WEIGHT } else { 1.0 }, 0.0f32);
        // The window is unrolled explicitly (the loop vectoriser only handles innermost loops,
        // and LLVM does not fully unroll a 49-tap body by itself); taps outside the
        // `(2R+1)²` window or at the centre are removed at compile time.
        macro_rules! tap {
            ($dy:literal, $dx:literal) => {
                if is_tap::<R, DISC>($dy, $dx) {
                    // Indexing the tap's shifted row (rather than `row[i + dx]`) keeps GVN
                    // from carrying loads from one lane to the next (its load PRE would turn
                    // them into loop-carried values that the loop vectoriser rejects).
                    let Ok(shifted) =
                        <&[f32; CHUNK]>::try_from(&rows[$dy][$dx * S..$dx * S + CHUNK])
                    else {
                        return;
                    };
                    let nb = shifted[i];
                    let cl = class::<R>($dy, $dx);
                    let (w, e) = if M::RANGE {
                        let e = if FMA { nb.mul_add(s, -zs) } else { nb * s - zs };
                        (range_weight::<FMA>(e, &cls[cl]), e)
                    } else {
                        (if nb > 0.0 { lin[cl] } else { 0.0 }, nb - zs)
                    };
                    sw += w;
                    swd = if FMA { w.mul_add(e, swd) } else { swd + w * e };
                }
            };
        }
        macro_rules! row {
            ($dy:literal) => {
                tap!($dy, 0);
                tap!($dy, 1);
                tap!($dy, 2);
                tap!($dy, 3);
                tap!($dy, 4);
                tap!($dy, 5);
                tap!($dy, 6);
            };
        }
        row!(0);
        row!(1);
        row!(2);
        row!(3);
        row!(4);
        row!(5);
        row!(6);
        dst[i] = finish::<DISP>(c, s, sw, swd, fb);
    }
}

/// The runtime-radius path: taps outer, lanes inner (vectorised), sums in `CHUNK`-long arrays.
#[inline(always)]
fn block_any<const FMA: bool, M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    p: &Padded<'_>,
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    let (r, step) = (taps.radius, taps.step);
    let k = 2 * r + 1;
    let stride = p.stride;
    let width = p.width;
    let mut sc = [1.0f32; CHUNK];
    let mut zs = [0.0f32; CHUNK];
    let mut sw = [0.0f32; CHUNK];
    let mut swd = [0.0f32; CHUNK];
    let mut res = [0.0f32; CHUNK];
    for (y, out_row) in out.chunks_mut(width).enumerate() {
        // Rows y, y + step, …, y + 2r·step of the padded block are the window rows of row y.
        let win = &p.data[y * stride..(y + (k - 1) * step + 1) * stride];
        let mut x0 = 0;
        while x0 < width {
            let c0 = r * step * stride + x0 + r * step;
            let centre = &win[c0..c0 + CHUNK];
            for i in 0..CHUNK {
                let z = centre[i];
                let s = if M::RANGE { mode.scale(z) } else { 1.0 };
                sc[i] = s;
                zs[i] = s * z;
            }
            sw.fill(if M::RANGE { CENTRE_WEIGHT } else { 1.0 });
            swd.fill(0.0);
            for dy in 0..k {
                let row = &win[dy * step * stride + x0..];
                for dx in 0..k {
                    let d2 = dy.abs_diff(r).pow(2) + dx.abs_diff(r).pow(2);
                    if d2 == 0 || (taps.disc && d2 > r * r) {
                        continue;
                    }
                    let nb = &row[dx * step..dx * step + CHUNK];
                    let t = dy * k + dx;
                    if M::RANGE {
                        let ke = taps.exps[t];
                        for i in 0..CHUNK {
                            let e = if FMA {
                                nb[i].mul_add(sc[i], -zs[i])
                            } else {
                                nb[i] * sc[i] - zs[i]
                            };
                            let w = range_weight::<FMA>(e, &ke);
                            sw[i] += w;
                            swd[i] = if FMA {
                                w.mul_add(e, swd[i])
                            } else {
                                swd[i] + w * e
                            };
                        }
                    } else {
                        let lw = taps.taps[t];
                        for i in 0..CHUNK {
                            let w = if nb[i] > 0.0 { lw } else { 0.0 };
                            let e = nb[i] - zs[i];
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
            for i in 0..CHUNK {
                res[i] = finish::<DISP>(centre[i], sc[i], sw[i], swd[i], fb);
            }
            let n = CHUNK.min(width - x0);
            out_row[x0..x0 + n].copy_from_slice(&res[..n]);
            x0 += CHUNK;
        }
    }
}

/// The explicit AVX-512 kernel of the range filters' constant-radius fast paths (its own file).
#[cfg(target_arch = "x86_64")]
mod x512;

/// The explicit AVX2 + FMA kernel of the range filters' constant-radius fast paths.
#[cfg(target_arch = "x86_64")]
mod x256;

/// The compiler-vectorised AVX2 + FMA code that `x256` replaced (`pad_and_filter!`), kept for
/// its bit-identity test; does nothing where the CPU lacks AVX2 or FMA (the test skips there).
#[cfg(all(test, target_arch = "x86_64"))]
#[allow(clippy::too_many_arguments)]
fn vectorised_avx2_reference<M: RangeMode, const DISP: bool>(
    taps: Taps<'_>,
    src: &Source<'_>,
    y0: usize,
    stride: usize,
    buf: &mut [f32],
    out: &mut [f32],
    mode: M,
    fb: f32,
) {
    #[target_feature(enable = "avx2,fma")]
    #[allow(clippy::too_many_arguments)]
    fn vectorised<M: RangeMode, const DISP: bool>(
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
    if Isa::Avx2.is_supported() {
        // SAFETY: the only precondition of a `#[target_feature]` function is that the CPU
        // supports the features, checked just above.
        #[allow(unsafe_code)]
        unsafe {
            vectorised::<M, DISP>(taps, src, y0, stride, buf, out, mode, fb);
        }
    }
}

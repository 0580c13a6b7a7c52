//! Block discovery: which 8³ blocks a frame touches. The image is processed in bands of rows;
//! each valid pixel's truncation segment along its ray is traversed cell by cell
//! (Amanatides & Woo) and the keys of the blocks it crosses are emitted once per band.

use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::{Isometry3, Matrix3, Vector3};

use sl_core::Intrinsics;

use super::*;
use sl_core::whole::floor_i32;

/// Rows of the image per strip of the fused table / band pass of [`TsdfVolume::integrate`].
pub(super) const BAND_ROWS: usize = 8;

/// What the per-pixel table needs: the depth range.
pub(super) struct PixelFn {
    pub(super) min_d: f32,
    pub(super) max_d: f32,
}

impl PixelFn {
    /// Fills the table rows `trows` (rows of `w + 2` entries with a border entry at each end)
    /// from the depth rows `drows` (`w` pixels each): the depth, or 0 where the pixel is
    /// invalid or outside the depth range. Returns the number of pixels used.
    pub(super) fn fill(&self, trows: &mut [f32], drows: &[f32], w: usize) -> usize {
        let mut used = 0;
        for (out, row) in trows.chunks_mut(w + 2).zip(drows.chunks(w)) {
            for (o, &d) in out[1..=w].iter_mut().zip(row) {
                let valid = (d > self.min_d) & (d <= self.max_d);
                used += usize::from(valid);
                *o = if valid { d } else { 0.0 };
            }
        }
        used
    }
}

/// The candidate block keys a frame may list before its integration is refused: all strips
/// add to one counter (in steps of [`KEY_FLUSH`]), so the lists stay within the memory
/// budget while they are being built.
pub(super) struct KeyBudget {
    pub(super) emitted: AtomicUsize,
    pub(super) max_keys: usize,
}

/// Keys a strip lists between two updates of the shared [`KeyBudget`] counter.
pub(super) const KEY_FLUSH: usize = 4096;

/// What [`band_rows`] needs of a frame (block-space pose, band).
pub(super) struct BandFrame<'a> {
    /// Camera-to-world rotation scaled to block units.
    pub(super) rot: Matrix3<f32>,
    /// Camera centre in the shifted block space.
    pub(super) t: Vector3<f32>,
    /// Largest block coordinate magnitude accepted.
    pub(super) lim: f32,
    /// The band of each pixel's depth.
    pub(super) band: crate::params::BandFn,
    /// Ray x (at z = 1) of each column.
    pub(super) rx: &'a [f32],
    pub(super) k: &'a Intrinsics,
    /// Bound on the candidate keys (`None`: unbounded).
    pub(super) keys: Option<&'a KeyBudget>,
}

impl<'a> BandFrame<'a> {
    /// The block space is shifted by half a voxel: a point belongs to the block of its nearest
    /// voxel, i.e. block coordinate = floor((x/v + 1/2) / 8).
    pub(super) fn new(
        p: &TsdfConfig,
        k: &'a Intrinsics,
        pose: &Isometry3<f64>,
        rx: &'a [f32],
    ) -> Result<Self> {
        let inv_bs = 1.0 / (p.voxel_m * BLOCK_SIDE as f64);
        let shift = 0.5 / BLOCK_SIDE as f64;
        let rot: Matrix3<f32> =
            (pose.rotation.to_rotation_matrix().into_inner() * inv_bs).cast::<f32>();
        let t: Vector3<f32> = (pose.translation.vector * inv_bs)
            .add_scalar(shift)
            .cast::<f32>();
        let lim = crate::hash::MAX_BLOCK_COORD as f32 - 2.0;
        // A non-finite rotation would make every cell below NaN, and NaN passes the range
        // checks of `band_rows` (its compares are false): refuse it here.
        if rot.iter().any(|c| !c.is_finite()) {
            return Err(TsdfError::OutOfRange(format!(
                "camera rotation {:?} is not finite",
                pose.rotation.coords
            )));
        }
        if t.iter().any(|c| !c.is_finite() || c.abs() > lim) {
            return Err(TsdfError::OutOfRange(format!(
                "camera position {:?} m",
                pose.translation.vector
            )));
        }
        Ok(Self {
            rot,
            t,
            lim,
            band: crate::params::BandFn::new(p),
            rx,
            k,
            keys: None,
        })
    }
}

/// Keys of the blocks within the band of the pixels of image rows `rows` (with few
/// duplicates: the keys already emitted by the strip are filtered through a small cache).
///
/// Per row, a vectorised pass computes each pixel's band segment `a → b`, the cells of its
/// ends and, per axis, the parameter `t` at which the segment crosses its first cell boundary.
/// When the end cells differ by at most one in every axis, the cells the segment passes
/// through are the start cell and then one step per differing axis in the order of these
/// crossings (what a 3-D DDA visits), so the path is determined by the end cells and the order
/// of the crossings: a pixel with the same end cells and order as its left neighbour adds
/// nothing and is skipped. A scalar pass emits the cells of the remaining pixels (a DDA where
/// an axis differs by more than one).
#[inline(never)]
pub(super) fn band_rows(f: &BandFrame<'_>, trows: &[f32], y0: usize) -> Result<Vec<u64>> {
    band_rows_inline(f, trows, y0)
}

/// [`band_rows`], inlined into its caller (the AVX-512 kernel of `integrate`).
#[inline(always)]
pub(super) fn band_rows_inline(f: &BandFrame<'_>, trows: &[f32], y0: usize) -> Result<Vec<u64>> {
    let BandFrame {
        rot,
        t,
        lim,
        band,
        rx,
        k,
        keys,
    } = *f;
    let w = k.width;
    let tw = w + 2;
    let mut out: Vec<u64> = Vec::with_capacity(1024);
    // Direct-mapped cache of the keys already emitted by this strip.
    let mut seen = vec![u64::MAX; SEEN_SLOTS];
    // Keys already added to the shared counter, and whether the budget is exhausted.
    let flushed = Cell::new(0usize);
    let over = Cell::new(false);
    let mut emit = |c: [i32; 3]| {
        if over.get() {
            return;
        }
        // In range: every coordinate was checked against `lim`.
        let key = pack_unchecked(c);
        let s = seen_slot(key);
        if seen[s] != key {
            seen[s] = key;
            out.push(key);
            let fresh = out.len() - flushed.get();
            if fresh >= KEY_FLUSH
                && let Some(kb) = keys
            {
                let total = kb.emitted.fetch_add(fresh, Ordering::Relaxed) + fresh;
                flushed.set(out.len());
                over.set(total > kb.max_keys);
            }
        }
    };
    let over_budget = |kb: &KeyBudget| TsdfError::CandidateBudget {
        candidates: kb.emitted.load(Ordering::Relaxed),
        max_candidates: kb.max_keys,
    };
    let rx_max = rx.iter().fold(0.0f32, |m, r| m.max(r.abs()));
    // This row's end cells and flags (locals, so that pass 1 vectorises), and the previous
    // row's.
    let mut ca: [Vec<i32>; 3] = std::array::from_fn(|_| vec![0; w]);
    let mut cb: [Vec<i32>; 3] = std::array::from_fn(|_| vec![0; w]);
    let mut flags = vec![0u32; w];
    let mut prev = BandRow::new(w);
    let mut need = vec![false; w];
    let mut fars = vec![0.0f32; w];
    for (r, trow) in trows.chunks(tw).enumerate() {
        let y = y0 + r;
        let ry = ((y as f64 - k.cy) / k.fy) as f32;
        let ry2 = ry * ry + 1.0;
        let row = &trow[1..=w];
        // Ray (z = 1) of column x, rotated: base + col·rx[x].
        let base = rot * Vector3::new(0.0, ry, 1.0);
        let col = rot.column(0);
        // The segment of pixel x runs from depth near(x) to far(x) along its ray.
        let ends = |x: usize| -> (f32, f32) {
            let d = row[x];
            let r = rx[x];
            // ±band in range along the ray: dt = band/λ in depth, λ = ‖ray‖.
            let dt = band.band(d) / (r * r + ry2).sqrt();
            let n = d - dt;
            (if n > 0.0 { n } else { 0.0 }, d + dt)
        };
        // Range check: |a|, |b| ≤ |t| + |dir|·far < lim for every far below `far_lim`.
        let far_lim = (0..3)
            .map(|ax| (lim - t[ax].abs()) / (base[ax].abs() + col[ax].abs() * rx_max))
            .fold(f32::INFINITY, f32::min);
        // Pass 1 (vectorised): end cells, crossing order. Slices of length `w`, so that the
        // loop has no bounds checks.
        {
            let [ca0, ca1, ca2] = ca.each_mut().map(|v| &mut v[..w]);
            let [cb0, cb1, cb2] = cb.each_mut().map(|v| &mut v[..w]);
            let ca = [ca0, ca1, ca2];
            let cb = [cb0, cb1, cb2];
            let (flags, fars, rx) = (&mut flags[..w], &mut fars[..w], &rx[..w]);
            for x in 0..w {
                let (near, far) = ends(x);
                let valid = row[x] > 0.0;
                fars[x] = if valid { far } else { 0.0 };
                let mut tc = [0.0f32; 3];
                let mut simple = true;
                for ax in 0..3 {
                    let dir = base[ax] + col[ax] * rx[x];
                    let a = t[ax] + dir * near;
                    let b = t[ax] + dir * far;
                    // Meaningless (but harmless) where out of range: checked below.
                    let (c0, c1) = (floor_i32(a), floor_i32(b));
                    ca[ax][x] = c0;
                    cb[ax][x] = c1;
                    let diff = c1.wrapping_sub(c0);
                    // |diff| ≤ 1, written so that it vectorises.
                    simple &= (diff.wrapping_add(1) as u32) <= 2;
                    // First boundary crossed along this axis, at t ∈ (0, 1] if the end cells
                    // differ; 2 (never) if they do not.
                    let plane = c0.wrapping_add(i32::from(b > a)) as f32;
                    let tt = (plane - a) / (b - a);
                    tc[ax] = if diff != 0 { tt } else { 2.0 };
                }
                let order = u32::from(tc[0] < tc[1])
                    | u32::from(tc[0] < tc[2]) << 1
                    | u32::from(tc[1] < tc[2]) << 2;
                flags[x] = u32::from(valid) | u32::from(simple) << 1 | order << 2;
            }
        }
        let bad = fars
            .iter()
            .fold(false, |b, &f| b | (f >= far_lim) | f.is_nan());
        if bad {
            // Find the offending pixel (NaN fails the compares).
            for x in (0..w).filter(|&x| row[x] > 0.0) {
                let (n, fr) = ends(x);
                let dir = base + col * rx[x];
                let (a, b) = (t + dir * n, t + dir * fr);
                if !a.iter().chain(b.iter()).all(|c| c.abs() < lim) {
                    return Err(TsdfError::OutOfRange(format!(
                        "pixel ({x}, {y}) at depth {} m reaches beyond the {} blocks the volume \
                         addresses on each side of its origin (a camera far from the origin, or \
                         a voxel too small for the depth range)",
                        row[x],
                        crate::hash::MAX_BLOCK_COORD - 2
                    )));
                }
            }
        }
        // Pass 1b (vectorised): a valid pixel needs processing unless its left neighbour or
        // the pixel above (in this strip) is valid and simple with the same order and end
        // cells, i.e. passes through the same cells.
        let mut cur = BandRow { ca, cb, flags };
        cur.need(&prev, r > 0, &mut need);
        // Pass 2 (scalar): emit the cells of the pixels that need it.
        for x in 0..w {
            if !need[x] {
                continue;
            }
            let fl = cur.flags[x];
            let c0 = [cur.ca[0][x], cur.ca[1][x], cur.ca[2][x]];
            let c1 = [cur.cb[0][x], cur.cb[1][x], cur.cb[2][x]];
            if fl & BandRow::SIMPLE != 0 {
                // Step the differing axes in the order of their crossings (rank = number
                // of axes crossed earlier).
                let o = fl >> 2;
                let (lt01, lt02, lt12) = (o & 1, (o >> 1) & 1, (o >> 2) & 1);
                let rank = [(lt01 ^ 1) + (lt02 ^ 1), lt01 + (lt12 ^ 1), lt02 + lt12];
                let mut cell = c0;
                emit(cell);
                for r in 0..3 {
                    for ax in 0..3 {
                        if rank[ax] == r && c0[ax] != c1[ax] {
                            cell[ax] = c1[ax];
                            emit(cell);
                        }
                    }
                }
            } else {
                let (near, far) = ends(x);
                let dir = base + col * rx[x];
                traverse(&(t + dir * near), &(t + dir * far), &mut emit);
            }
            if over.get()
                && let Some(kb) = keys
            {
                return Err(over_budget(kb));
            }
        }
        std::mem::swap(&mut cur, &mut prev);
        BandRow { ca, cb, flags } = cur;
    }
    Ok(out)
}

/// One image row of [`band_rows`] (structure of arrays): the cells of each pixel's segment
/// ends and its flags (bit 0 valid, bit 1 "simple": the end cells differ by at most one in
/// every axis, bits 2..5 the order of the first boundary crossings).
pub(super) struct BandRow {
    pub(super) ca: [Vec<i32>; 3],
    pub(super) cb: [Vec<i32>; 3],
    pub(super) flags: Vec<u32>,
}

impl BandRow {
    const VALID: u32 = 1;
    const SIMPLE: u32 = 2;

    pub(super) fn new(w: usize) -> Self {
        Self {
            ca: std::array::from_fn(|_| vec![0; w]),
            cb: std::array::from_fn(|_| vec![0; w]),
            flags: vec![0; w],
        }
    }

    /// Which valid pixels of this row need processing: not those whose left neighbour or
    /// (with `up`) the pixel above in `prev` is valid and simple with the same flags and end
    /// cells. Vectorised: one loop over slices of equal length.
    pub(super) fn need(&self, prev: &Self, up: bool, need: &mut [bool]) {
        let w = self.flags.len();
        if w == 0 || need.len() < w || prev.flags.len() < w {
            return;
        }
        const VS: u32 = BandRow::VALID | BandRow::SIMPLE;
        // x in 1..w: this pixel (slices from 1), its left neighbour (slices to w − 1) and
        // the pixel above (`prev`, slices from 1).
        let n = w - 1;
        let (f, fl, fu) = (&self.flags[1..], &self.flags[..n], &prev.flags[1..w]);
        let (a0, a1, a2) = (&self.ca[0][1..w], &self.ca[1][1..w], &self.ca[2][1..w]);
        let (b0, b1, b2) = (&self.cb[0][1..w], &self.cb[1][1..w], &self.cb[2][1..w]);
        let (la0, la1, la2) = (&self.ca[0][..n], &self.ca[1][..n], &self.ca[2][..n]);
        let (lb0, lb1, lb2) = (&self.cb[0][..n], &self.cb[1][..n], &self.cb[2][..n]);
        let (ua0, ua1, ua2) = (&prev.ca[0][1..w], &prev.ca[1][1..w], &prev.ca[2][1..w]);
        let (ub0, ub1, ub2) = (&prev.cb[0][1..w], &prev.cb[1][1..w], &prev.cb[2][1..w]);
        let out = &mut need[1..w];
        for x in 0..n {
            let fx = f[x];
            let vs = fx & VS == VS;
            let left = (fx == fl[x])
                & (a0[x] == la0[x])
                & (a1[x] == la1[x])
                & (a2[x] == la2[x])
                & (b0[x] == lb0[x])
                & (b1[x] == lb1[x])
                & (b2[x] == lb2[x]);
            let above = up
                & (fx == fu[x])
                & (a0[x] == ua0[x])
                & (a1[x] == ua1[x])
                & (a2[x] == ua2[x])
                & (b0[x] == ub0[x])
                & (b1[x] == ub1[x])
                & (b2[x] == ub2[x]);
            out[x] = (fx & BandRow::VALID != 0) & !(vs & (left | above));
        }
        // x = 0: no left neighbour.
        let f0 = self.flags[0];
        let above0 = up
            & (f0 == prev.flags[0])
            & (0..3).all(|ax| self.ca[ax][0] == prev.ca[ax][0] && self.cb[ax][0] == prev.cb[ax][0]);
        need[0] = (f0 & BandRow::VALID != 0) & !((f0 & VS == VS) & above0);
    }
}

/// Slots of the per-strip cache of emitted block keys in [`band_rows`].
pub(super) const SEEN_SLOTS: usize = 1024;

#[inline(always)]
pub(super) fn seen_slot(key: u64) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - SEEN_SLOTS.trailing_zeros())) as usize
}

/// [`pack`] for coordinates known to be in range.
#[inline(always)]
pub(super) fn pack_unchecked(b: [i32; 3]) -> u64 {
    const BIAS: i32 = crate::hash::MAX_BLOCK_COORD + 1;
    (b[0] + BIAS) as u64 | (((b[1] + BIAS) as u64) << 21) | (((b[2] + BIAS) as u64) << 42)
}

/// Visits every unit cell of the segment `a → b` (Amanatides & Woo), in order. Coordinates
/// must be finite and well inside the `i32` range (checked by the caller).
#[inline]
pub(super) fn traverse(a: &Vector3<f32>, b: &Vector3<f32>, mut visit: impl FnMut([i32; 3])) {
    let mut cell = [floor_i32(a.x), floor_i32(a.y), floor_i32(a.z)];
    let end = [floor_i32(b.x), floor_i32(b.y), floor_i32(b.z)];
    let d = b - a;
    let mut step = [0i32; 3];
    let mut t_max = [f32::INFINITY; 3];
    let mut t_delta = [f32::INFINITY; 3];
    for ax in 0..3 {
        if d[ax] > 0.0 {
            step[ax] = 1;
            t_max[ax] = (cell[ax] as f32 + 1.0 - a[ax]) / d[ax];
            t_delta[ax] = 1.0 / d[ax];
        } else if d[ax] < 0.0 {
            step[ax] = -1;
            t_max[ax] = (cell[ax] as f32 - a[ax]) / d[ax];
            t_delta[ax] = -1.0 / d[ax];
        }
    }
    // A segment crosses at most |dx| + |dy| + |dz| + 3 cell boundaries; the cap only guards
    // against floating-point surprises.
    let max_steps = (d.abs().sum() as usize) + 4;
    visit(cell);
    for _ in 0..max_steps {
        if cell == end {
            break;
        }
        let ax = if t_max[0] <= t_max[1] && t_max[0] <= t_max[2] {
            0
        } else if t_max[1] <= t_max[2] {
            1
        } else {
            2
        };
        if t_max[ax] > 1.0 {
            break;
        }
        cell[ax] += step[ax];
        t_max[ax] += t_delta[ax];
        visit(cell);
    }
}

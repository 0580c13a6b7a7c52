//! Integration of one depth frame: the argument checks, the per-pixel table of depth, block
//! discovery (see `discovery`), then the parallel voxel update of every touched block with the
//! projective signed distance and the weight of the observation's depth (the per-block kernel
//! and its per-frame constants live here).

use nalgebra::{Isometry3, Matrix3, Vector3};
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;
use sl_core::{CameraToWorld, DepthView, Intrinsics, IsaKernel};

use super::discovery::*;
use super::*;
use crate::par::run_on_threads;
use crate::params::{BandFn, DepthLookup, SAME_SURFACE_MAX_INCIDENCE_DEG, WeightFn};
use sl_core::whole::{exact_u32, round_f32};

impl TsdfVolume {
    /// Integrates one depth frame seen by a camera with intrinsics `k` at camera-to-world
    /// `pose`: allocates the blocks within the truncation band of every valid pixel, then
    /// updates every voxel of those blocks (in parallel, per block) with the projective
    /// line-of-sight signed distance of eq. 11 and the weight of eq. 13.
    ///
    /// On error (size mismatch, memory budget, geometry out of range) the volume is unchanged.
    ///
    /// `depth` is a `&DepthImage` or a [`DepthView`] over a buffer the caller owns (no copy).
    pub fn integrate<'a>(
        &mut self,
        depth: impl Into<DepthView<'a>>,
        k: &Intrinsics,
        pose: &CameraToWorld,
    ) -> Result<IntegrateStats> {
        let depth: DepthView<'a> = depth.into();
        let pose = pose.isometry();
        if depth.width() != k.width || depth.height() != k.height {
            return Err(TsdfError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: depth.width(),
                height: depth.height(),
            });
        }
        k.validate()?;
        // Pixel indices are computed exactly in f32 (< 2^23) and stored as u32.
        if (k.width + 2) * (k.height + 2) >= 1 << 23 {
            return Err(TsdfError::InvalidParameter(format!(
                "image size {}x{} has too many pixels",
                k.width, k.height
            )));
        }
        let mut table = std::mem::take(&mut self.scratch.table);
        let result = self.integrate_with(&mut table, depth, k, pose);
        self.scratch.table = table;
        result
    }

    /// [`TsdfVolume::integrate`] after the argument checks, with the per-pixel table as
    /// scratch space: the depth of pixel `(x, y)` at `(y + 1)·(width + 2) + x + 1`, 0 on a
    /// one-pixel border around the image (voxels projecting outside the image are clamped onto
    /// it) and where the pixel is invalid or outside the depth range.
    fn integrate_with(
        &mut self,
        table: &mut Vec<f32>,
        depth: DepthView<'_>,
        k: &Intrinsics,
        pose: &Isometry3<f64>,
    ) -> Result<IntegrateStats> {
        let (w, h) = (k.width, k.height);
        let tw = w + 2;
        // The border stays 0. Small images get exactly `SMALL_TABLE` entries (the tail stays 0
        // too and is never read).
        let len = tw * (h + 2);
        let len = if len <= SMALL_TABLE { SMALL_TABLE } else { len };
        if table.len() != len {
            table.clear();
            table
                .try_reserve(len)
                .map_err(|_| TsdfError::OutOfMemory("pixel table"))?;
            table.resize(len, 0.0);
        }
        let rx: Vec<f32> = (0..w).map(|x| ((x as f64 - k.cx) / k.fx) as f32).collect();
        // Candidate keys are held three times at most (a strip's list, its new keys, all new
        // keys): bound them to what the budget leaves after the current blocks.
        let remaining = self
            .params
            .memory_budget_bytes
            .saturating_sub(self.blocks.len().saturating_mul(BYTES_PER_BLOCK));
        let key_budget = KeyBudget {
            emitted: std::sync::atomic::AtomicUsize::new(0),
            max_keys: remaining / (3 * std::mem::size_of::<u64>()),
        };
        let mut band = BandFrame::new(&self.params, k, pose, &rx)?;
        band.keys = Some(&key_budget);
        let p = &self.params;
        let pixels = PixelFn {
            min_d: p.min_depth_m as f32,
            max_d: p.max_depth_m as f32,
        };
        // One parallel pass over strips of rows: each fills its rows of the pixel table, finds
        // the blocks in the band of its pixels and marks those already allocated; the others
        // are returned (with few duplicates).
        let touched: Vec<AtomicBool> = (0..self.blocks.len())
            .map(|_| AtomicBool::new(false))
            .collect();
        let index = &self.index;
        let isa = self.params.fusion_isa();
        let strip = |(ci, (trows, drows)): (usize, (&mut [f32], &[f32]))| {
            let used = pixels.fill(trows, drows, w);
            let keys = match isa {
                Some(isa) => isa.run(BandStrip {
                    frame: &band,
                    rows: trows,
                    y0: ci * BAND_ROWS,
                })?,
                None => band_rows(&band, trows, ci * BAND_ROWS)?,
            };
            let mut new = Vec::new();
            for key in keys {
                match index.get(&key) {
                    Some(&slot) => touched[slot as usize].store(true, Ordering::Relaxed),
                    None => new.push(key),
                }
            }
            Ok((used, new))
        };
        let items: Vec<_> = table[tw..tw * (h + 1)]
            .chunks_mut(tw * BAND_ROWS)
            .zip(depth.data().chunks(w * BAND_ROWS))
            .enumerate()
            .collect();
        let strips: Vec<Result<(usize, Vec<u64>)>> = run_on_threads(items, || (), |_, s| strip(s));
        let mut pixels_used = 0;
        let mut new_keys = Vec::new();
        for s in strips {
            let (used, new) = s?;
            pixels_used += used;
            new_keys.extend_from_slice(&new);
        }
        new_keys.sort_unstable();
        new_keys.dedup();
        let mut touched: Vec<bool> = touched.into_iter().map(AtomicBool::into_inner).collect();
        let total = self.blocks.len() + new_keys.len();
        let needed = total.saturating_mul(BYTES_PER_BLOCK);
        if needed > self.params.memory_budget_bytes {
            return Err(TsdfError::MemoryBudget {
                blocks: total,
                needed_bytes: needed,
                budget_bytes: self.params.memory_budget_bytes,
            });
        }
        // The block arena grows geometrically (few reallocations) but never past the number
        // of blocks the budget allows, so that its capacity stays within the budget too.
        if total > self.blocks.capacity() {
            let cap_max = (self.params.memory_budget_bytes / BYTES_PER_BLOCK).max(total);
            let cap = (2 * self.blocks.capacity()).clamp(total, cap_max);
            self.blocks
                .try_reserve_exact(cap - self.blocks.len())
                .map_err(|_| TsdfError::OutOfMemory("voxel blocks"))?;
        }
        if total > self.keys.capacity() {
            let cap = self.blocks.capacity().max(total);
            self.keys
                .try_reserve_exact(cap - self.keys.len())
                .map_err(|_| TsdfError::OutOfMemory("block keys"))?;
        }
        self.index
            .try_reserve(new_keys.len())
            .map_err(|_| TsdfError::OutOfMemory("block index"))?;
        for &key in &new_keys {
            let slot = self.keys.len() as u32;
            self.index.insert(key, slot);
            self.keys.push(key);
        }
        // The new blocks' zeroed memory is touched for the first time here (a page fault per
        // block): in parallel.
        let fresh = self.keys.len() - self.blocks.len();
        self.blocks
            .par_extend(rayon::iter::repeat_n(Block::default(), fresh));
        touched.resize(self.blocks.len(), true);
        self.update_blocks(&touched, table, k, pose);
        self.frames += 1;
        Ok(IntegrateStats {
            blocks_touched: touched.iter().filter(|&&t| t).count(),
            blocks_allocated: new_keys.len(),
            pixels_used,
        })
    }

    /// Updates the voxels of the touched blocks from one frame.
    fn update_blocks(
        &mut self,
        touched: &[bool],
        table: &[f32],
        k: &Intrinsics,
        pose: &Isometry3<f64>,
    ) {
        let frame = FrameConsts::new(&self.params, k, pose);
        // A table of exactly `SMALL_TABLE` entries (see `integrate_with`) is indexed with a mask
        // instead of a bounds check.
        let small = table
            .first_chunk::<SMALL_TABLE>()
            .filter(|_| table.len() == SMALL_TABLE);
        let keys = &self.keys;
        let isa = self.params.fusion_isa();
        let items: Vec<_> = self.blocks.chunks_mut(UPDATE_CHUNK).enumerate().collect();
        run_on_threads(
            items,
            || (),
            |_, (ci, blocks): (usize, &mut [Block])| {
                let first = ci * UPDATE_CHUNK;
                let chunk = UpdateChunk {
                    blocks,
                    touched: touched.get(first..).unwrap_or(&[]),
                    keys: keys.get(first..).unwrap_or(&[]),
                    frame: &frame,
                    small,
                    table,
                };
                match isa {
                    Some(isa) => isa.run(chunk),
                    None => chunk.update::<false>(),
                }
            },
        );
    }
}

/// Block discovery over one strip of rows ([`band_rows`]), run with the volume's instruction
/// set.
struct BandStrip<'a, 'b> {
    frame: &'a BandFrame<'b>,
    rows: &'a [f32],
    /// Image row of the strip's first row.
    y0: usize,
}

impl IsaKernel for BandStrip<'_, '_> {
    type Output = Result<Vec<u64>>;

    #[inline(always)]
    fn run(self) -> Result<Vec<u64>> {
        band_rows_inline(self.frame, self.rows, self.y0)
    }
}

/// Blocks of the arena updated by one task of [`TsdfVolume::integrate`].
const UPDATE_CHUNK: usize = 64;

/// The voxel update of one chunk of the block arena (the touched blocks among them), run with
/// the volume's instruction set.
struct UpdateChunk<'a> {
    blocks: &'a mut [Block],
    /// Whether each block of the chunk is touched, and its key (from the chunk's first).
    touched: &'a [bool],
    keys: &'a [u64],
    frame: &'a FrameConsts,
    /// The table when it has exactly `SMALL_TABLE` entries (indexed with a mask).
    small: Option<&'a [f32; SMALL_TABLE]>,
    table: &'a [f32],
}

impl UpdateChunk<'_> {
    /// The update; `INLINE`: with the per-block kernel inlined (into the instruction set's
    /// trampoline), else through its one out-of-line copy.
    ///
    /// While a block is updated, the next touched block's memory is prefetched, a z slice at a
    /// time (see [`voxel_update`]): the touched blocks lie scattered through the arena, a block
    /// is one 4 KB page, and the hardware prefetcher does not cross pages, so without the hint
    /// the update waited on every block's loads (docs/bench/track.md, session 23).
    #[inline(always)]
    fn update<const INLINE: bool>(self) {
        let Self {
            blocks,
            touched,
            keys,
            frame,
            small,
            table,
        } = self;
        let n = blocks.len().min(touched.len()).min(keys.len());
        let mut touched_slots = (0..n).filter(|&i| touched[i]).peekable();
        while let Some(i) = touched_slots.next() {
            let (head, tail) = blocks.split_at_mut(i + 1);
            let next = touched_slots.peek().and_then(|&j| tail.get(j - i - 1));
            let (blk, b) = (&mut head[i], unpack(keys[i]));
            match small {
                Some(t) => integrate_block_as::<_, INLINE>(blk, next, b, frame, t),
                None => integrate_block_as::<_, INLINE>(blk, next, b, frame, table),
            }
        }
    }
}

impl IsaKernel for UpdateChunk<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        self.update::<true>();
    }
}

/// Voxels in one z slice of a block.
pub(super) const SLICE: usize = BLOCK_SIDE * BLOCK_SIDE;

/// Per-frame constants of the voxel update (camera from world, intrinsics, band).
#[derive(Debug, Clone, Copy)]
pub(super) struct FrameConsts {
    /// [`DepthLookup::Bilinear`]: interpolate between the four pixels around the projection.
    pub(super) bilinear: bool,
    /// [`DepthLookup::Bilinear`]'s same-surface bound per metre of depth: the depth step
    /// across a pixel cell's diagonal of a surface at the steepest interpolated incidence.
    pub(super) same_surface_per_m: f32,
    pub(super) rt: Matrix3<f32>,
    pub(super) tt: Vector3<f32>,
    pub(super) step_x: Vector3<f32>,
    pub(super) step_y: Vector3<f32>,
    pub(super) step_z: Vector3<f32>,
    /// Camera-frame offsets of the 64 voxels of a z slice from the slice's first voxel.
    pub(super) off_x: [f32; SLICE],
    pub(super) off_y: [f32; SLICE],
    pub(super) off_z: [f32; SLICE],
    pub(super) fx: f32,
    pub(super) fy: f32,
    /// Principal point plus one (the table's border column / row).
    pub(super) cx1: f32,
    pub(super) cy1: f32,
    /// Largest clamped column / row in table coordinates: `width + 1`, `height + 1`.
    pub(super) umax: f32,
    pub(super) vmax: f32,
    /// Table row length, `width + 2`.
    pub(super) tw: f32,
    pub(super) band: BandFn,
    /// The observations' weight as a function of their depth.
    pub(super) weight: WeightFn,
    pub(super) max_w: f32,
    pub(super) v: f32,
}

impl FrameConsts {
    pub(super) fn new(p: &TsdfConfig, k: &Intrinsics, pose: &Isometry3<f64>) -> Self {
        let inv = pose.inverse();
        let rt: Matrix3<f32> = inv.rotation.to_rotation_matrix().into_inner().cast::<f32>();
        let tt: Vector3<f32> = inv.translation.vector.cast::<f32>();
        let v = p.voxel_m as f32;
        let step_x = rt.column(0) * v;
        let step_y = rt.column(1) * v;
        let step_z = rt.column(2) * v;
        let off = |a: usize| -> [f32; SLICE] {
            std::array::from_fn(|i| {
                step_y[a] * (i / BLOCK_SIDE) as f32 + step_x[a] * (i % BLOCK_SIDE) as f32
            })
        };
        Self {
            rt,
            tt,
            step_x,
            step_y,
            step_z,
            off_x: off(0),
            off_y: off(1),
            off_z: off(2),
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx1: (k.cx + 1.0) as f32,
            cy1: (k.cy + 1.0) as f32,
            umax: (k.width + 1) as f32,
            vmax: (k.height + 1) as f32,
            tw: (k.width + 2) as f32,
            band: BandFn::new(p),
            weight: WeightFn::new(p.weight, p.z_ref_m),
            max_w: p.max_weight,
            v,
            bilinear: p.depth_lookup == DepthLookup::Bilinear,
            same_surface_per_m: (std::f64::consts::SQRT_2
                * SAME_SURFACE_MAX_INCIDENCE_DEG.to_radians().tan()
                / k.fx.min(k.fy)) as f32,
        }
    }
}

/// Entries of the per-pixel table for images up to about 720×720 pixels: a power of two, so
/// that indices can be masked into range instead of bounds-checked.
pub(super) const SMALL_TABLE: usize = 1 << 19;

/// The per-pixel table as the voxel update reads it: the depth of each pixel, 0 where it is
/// invalid. Depth alone (4 bytes a pixel: 1.2 MB for 640×480, within a core's L2 cache on
/// current CPUs) — the weight is a function of the depth and is computed where it is used: the
/// table is gathered at random from every touched block, and with the weight beside the depth
/// (2.5 MB) those gathers missed the L2 cache (docs/bench/track.md, session 68).
pub(super) trait PixelTable: Sync {
    /// Depth of table entry `i` (`i` is always in range).
    fn entry(&self, i: u32) -> f32;
    /// Entries `i` and `i + 1` (`i + 1` is always in range).
    fn pair(&self, i: u32) -> [f32; 2];
}

impl PixelTable for [f32; SMALL_TABLE] {
    #[inline(always)]
    fn entry(&self, i: u32) -> f32 {
        self[i as usize & (SMALL_TABLE - 1)]
    }
    #[inline(always)]
    fn pair(&self, i: u32) -> [f32; 2] {
        let i = (i as usize).min(SMALL_TABLE - 2);
        [self[i], self[i + 1]]
    }
}

impl PixelTable for [f32] {
    #[inline(always)]
    fn entry(&self, i: u32) -> f32 {
        self.get(i as usize).copied().unwrap_or(0.0)
    }
    #[inline(always)]
    fn pair(&self, i: u32) -> [f32; 2] {
        match self.get(i as usize..i as usize + 2) {
            Some(&[a, b]) => [a, b],
            _ => [0.0; 2],
        }
    }
}

/// The weights of a slice's table depths `ds` into `ws`: `weight(d)` where `d > 0` (a valid
/// pixel: the table holds 0 elsewhere, and valid depths exceed `min_depth_m ≥ 0`), else 0 —
/// bit for bit the weights the table held beside the depth before session 68. One loop per
/// weight mode (each arm binds its variant), so that each vectorises.
#[inline(always)]
fn slice_weights(wf: WeightFn, ds: &[f32; SLICE], ws: &mut [f32; SLICE]) {
    #[inline(always)]
    fn each(ds: &[f32; SLICE], ws: &mut [f32; SLICE], f: impl Fn(f32) -> f32) {
        for i in 0..SLICE {
            let d = ds[i];
            ws[i] = if d > 0.0 { f(d) } else { 0.0 };
        }
    }
    match wf {
        WeightFn::Uniform => each(ds, ws, |_| 1.0),
        wf @ WeightFn::InvZ2 { .. } => each(ds, ws, |d| wf.weight(d)),
        wf @ WeightFn::InvZ4 { .. } => each(ds, ws, |d| wf.weight(d)),
        wf @ WeightFn::Variance { .. } => each(ds, ws, |d| wf.weight(d)),
    }
}

/// [`DepthLookup::Bilinear`] for one z slice: replaces the nearest pixel's depth in `ds` by the
/// inverse depth interpolated at the projection `(us, vs)` (table coordinates, clamped onto the
/// border) where the four pixels around it are valid (positive weight) and on one surface; the
/// weight stays the nearest pixel's. The nearest pixel is one of the four, so an invalid one
/// keeps its weight 0. Branch-free: the gathers (two loads of two neighbouring pixels) in one
/// loop, the weights and the arithmetic in others that the compiler vectorises (a version that
/// skipped the voxels far from the surface branched per voxel and took twice as long).
#[inline(always)]
fn bilinear_depths<T: PixelTable + ?Sized>(
    ds: &mut [f32; SLICE],
    us: &[f32; SLICE],
    vs: &[f32; SLICE],
    fc: &FrameConsts,
    table: &T,
) {
    let mut corners = [[0.0f32; SLICE]; 4];
    let mut fu = [0.0f32; SLICE];
    let mut fv = [0.0f32; SLICE];
    let tw = exact_u32(fc.tw);
    for i in 0..SLICE {
        // `us`, `vs` are in [0, umax], [0, vmax]: the cell's corners stay in the table.
        let u0 = us[i].floor();
        let u0 = if u0 < fc.umax - 1.0 {
            u0
        } else {
            fc.umax - 1.0
        };
        let v0 = vs[i].floor();
        let v0 = if v0 < fc.vmax - 1.0 {
            v0
        } else {
            fc.vmax - 1.0
        };
        fu[i] = us[i] - u0;
        fv[i] = vs[i] - v0;
        let at = exact_u32(v0 * fc.tw + u0);
        [corners[0][i], corners[1][i]] = table.pair(at);
        [corners[2][i], corners[3][i]] = table.pair(at + tw);
    }
    // A corner counts where its weight is positive, as when the table held the weights.
    let mut weights = [[0.0f32; SLICE]; 4];
    for (c, w) in corners.iter().zip(&mut weights) {
        slice_weights(fc.weight, c, w);
    }
    let [ca, cb, cc, cd] = &corners;
    let [wa, wb, wc, wd] = &weights;
    for i in 0..SLICE {
        let (a, b, c, d) = (ca[i], cb[i], cc[i], cd[i]);
        let valid = (wa[i] > 0.0) & (wb[i] > 0.0) & (wc[i] > 0.0) & (wd[i] > 0.0);
        let lo = a.min(b).min(c).min(d);
        let hi = a.max(b).max(c).max(d);
        let same = valid & (hi - lo <= lo * fc.same_surface_per_m + fc.band.band(lo));
        let (u, v) = (fu[i], fv[i]);
        let inv = (1.0 - v) * ((1.0 - u) / a + u / b) + v * ((1.0 - u) / c + u / d);
        ds[i] = if same { 1.0 / inv } else { ds[i] };
    }
}

/// Updates the 512 voxels of block `b` from one frame (`table`: per-pixel depth with an
/// invalid border, see [`PixelFn::fill`]).
#[cfg(test)]
#[inline(always)]
pub(super) fn integrate_block<T: PixelTable + ?Sized>(
    blk: &mut Block,
    b: [i32; 3],
    fc: &FrameConsts,
    table: &T,
) {
    integrate_block_as::<T, false>(blk, None, b, fc, table);
}

/// `integrate_block` (the tests' entry); `INLINE`: the voxel loop inlined into the caller instead of its
/// out-of-line copy [`integrate_block_with`].
#[inline(always)]
fn integrate_block_as<T: PixelTable + ?Sized, const INLINE: bool>(
    blk: &mut Block,
    next: Option<&Block>,
    b: [i32; 3],
    fc: &FrameConsts,
    table: &T,
) {
    // Camera z of the 8 corners: z is affine in the voxel, so if they are all positive, so
    // are all voxels', and the per-voxel test is not needed.
    let o = [0, 1, 2].map(|a| (b[a] * BLOCK_SIDE as i32) as f32 * fc.v);
    let origin = fc.rt * Vector3::new(o[0], o[1], o[2]) + fc.tt;
    let span = (BLOCK_SIDE - 1) as f32;
    let z_min = origin.z
        + span * ((fc.step_x.z).min(0.0) + (fc.step_y.z).min(0.0) + (fc.step_z.z).min(0.0));
    match (z_min > 0.0, INLINE) {
        (true, false) => integrate_block_with::<T, false>(blk, next, &origin, fc, table),
        (false, false) => integrate_block_with::<T, true>(blk, next, &origin, fc, table),
        (true, true) => voxel_update::<T, false>(blk, next, &origin, fc, table),
        (false, true) => voxel_update::<T, true>(blk, next, &origin, fc, table),
    }
}

/// `integrate_block` with the block's origin in camera coordinates; `CHECK_Z`: voxels may
/// be behind the camera; `next`: the block updated next, whose memory is prefetched.
#[inline(never)]
pub(super) fn integrate_block_with<T: PixelTable + ?Sized, const CHECK_Z: bool>(
    blk: &mut Block,
    next: Option<&Block>,
    origin: &Vector3<f32>,
    fc: &FrameConsts,
    table: &T,
) {
    voxel_update::<T, CHECK_Z>(blk, next, origin, fc, table);
}

/// The body of [`integrate_block_with`], inlined into its callers.
#[inline(always)]
fn voxel_update<T: PixelTable + ?Sized, const CHECK_Z: bool>(
    blk: &mut Block,
    next: Option<&Block>,
    origin: &Vector3<f32>,
    fc: &FrameConsts,
    table: &T,
) {
    let (band, max_w) = (fc.band, fc.max_w);
    let mut pix = [0u32; SLICE];
    let mut zs = [0.0f32; SLICE];
    let mut lam = [0.0f32; SLICE];
    let mut xs = [0.0f32; SLICE];
    let mut ys = [0.0f32; SLICE];
    let mut ds = [0.0f32; SLICE];
    let mut ws = [0.0f32; SLICE];
    let mut us = [0.0f32; SLICE];
    let mut vs = [0.0f32; SLICE];
    // One z slice (8×8 voxels, contiguous in the block) at a time: loops of 64 independent
    // lanes that the compiler vectorises.
    for lz in 0..BLOCK_SIDE {
        let base = lz * SLICE;
        // The next block's slice, 8 cache lines: spread over the slices, the hints do not
        // wait for free line-fill buffers as 64 at once do.
        if let Some(n) = next {
            sl_core::prefetch(&n.tsdf[base..base + SLICE]);
            sl_core::prefetch(&n.weight[base..base + SLICE]);
        }
        let s = origin + fc.step_z * lz as f32;
        // Stage 1 (pure f32 arithmetic): camera coordinates, λ = ‖P‖/z, and the pixel the
        // voxel projects to (nearest pixel centre), clamped onto the table's invalid border
        // when outside the image or behind the camera.
        for i in 0..SLICE {
            let z = s.z + fc.off_z[i];
            let inv_z = 1.0 / z;
            let xn = (s.x + fc.off_x[i]) * inv_z;
            let yn = (s.y + fc.off_y[i]) * inv_z;
            lam[i] = (xn * xn + yn * yn + 1.0).sqrt();
            zs[i] = z;
            xs[i] = xn;
            ys[i] = yn;
        }
        for i in 0..SLICE {
            // Plain compares instead of `f32::min`/`max` (whose NaN rules block
            // vectorisation): NaN and z ≤ 0 go to column 0, the border.
            let u = fc.fx * xs[i] + fc.cx1;
            let u = if (u > 0.0) & (!CHECK_Z | (zs[i] > 0.0)) {
                u
            } else {
                0.0
            };
            let u = if u < fc.umax { u } else { fc.umax };
            let v = fc.fy * ys[i] + fc.cy1;
            let v = if v > 0.0 { v } else { 0.0 };
            let v = if v < fc.vmax { v } else { fc.vmax };
            // Exact integers below 2^23 (checked in `integrate`).
            pix[i] = exact_u32(round_f32(v) * fc.tw + round_f32(u));
            us[i] = u;
            vs[i] = v;
        }
        // Stage 2 (scalar gather): the depth of each voxel's pixel, and its weight.
        for i in 0..SLICE {
            ds[i] = table.entry(pix[i]);
        }
        slice_weights(fc.weight, &ds, &mut ws);
        if fc.bilinear {
            bilinear_depths(&mut ds, &us, &vs, fc, table);
        }
        // Stage 3 (branch-free): line-of-sight distance ‖P_surface‖ − ‖P_voxel‖ = (d − z)·λ
        // along the voxel's own ray, clipped to the observation's band `trunc` (see
        // `Truncation`); an invalid pixel (weight 0) or a voxel more than `trunc` behind the
        // surface gets weight 0 and is left unchanged: F + (f − F)·0 = F for the
        // finite f = min(sdf, trunc) (sdf is NaN only for z ≤ 0, whose pixel is the border:
        // then f = trunc).
        let tsdf = &mut blk.tsdf[base..base + SLICE];
        let weight = &mut blk.weight[base..base + SLICE];
        for i in 0..SLICE {
            let (d, wg) = (ds[i], ws[i]);
            let trunc = band.band(d);
            let sdf = (d - zs[i]) * lam[i];
            let wgt = if sdf >= -trunc { wg } else { 0.0 };
            let f = if sdf < trunc { sdf } else { trunc };
            let wn = weight[i] + wgt;
            let den = if wn > f32::MIN_POSITIVE {
                wn
            } else {
                f32::MIN_POSITIVE
            };
            tsdf[i] += (f - tsdf[i]) * (wgt / den);
            weight[i] = if wn < max_w { wn } else { max_w };
        }
    }
}

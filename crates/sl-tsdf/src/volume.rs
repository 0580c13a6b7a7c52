//! The sparse TSDF volume: a hash map of 8³ voxel blocks and projective integration.

use nalgebra::{Matrix3, Vector3};
use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;
#[cfg(test)]
use sl_core::DepthImage;
use sl_core::{DepthView, Intrinsics, Pose};

use crate::error::{Result, TsdfError};
use crate::hash::{BlockMap, pack, unpack};
use crate::par::run_on_threads;
use crate::params::{TsdfConfig, WeightFn};

/// Voxels along one edge of a block.
pub const BLOCK_SIDE: usize = 8;
/// Voxels in a block.
pub const BLOCK_VOXELS: usize = BLOCK_SIDE * BLOCK_SIDE * BLOCK_SIDE;

/// One voxel: the weighted mean signed distance (metres, positive in front of the surface) and
/// the accumulated normalised weight (0 = never observed).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Voxel {
    /// Weighted mean of the truncated line-of-sight signed distances, metres.
    pub tsdf: f32,
    /// Sum of the normalised weights (capped at [`TsdfConfig::max_weight`]).
    pub weight: f32,
}

/// An 8×8×8 brick of voxels, `x` fastest: index `x + 8·y + 64·z`. Stored as two arrays
/// (structure of arrays) so that the integration of a row of 8 voxels vectorises.
#[derive(Debug, Clone)]
pub struct Block {
    /// Weighted mean signed distances, metres.
    pub tsdf: [f32; BLOCK_VOXELS],
    /// Accumulated weights (0 = unobserved).
    pub weight: [f32; BLOCK_VOXELS],
}

impl Default for Block {
    fn default() -> Self {
        Self {
            tsdf: [0.0; BLOCK_VOXELS],
            weight: [0.0; BLOCK_VOXELS],
        }
    }
}

impl Block {
    /// The voxel at local index `i` (see [`local_index`]).
    #[inline(always)]
    pub fn voxel(&self, i: usize) -> Voxel {
        Voxel {
            tsdf: self.tsdf[i],
            weight: self.weight[i],
        }
    }

    /// Sets the voxel at local index `i`.
    #[inline]
    pub fn set_voxel(&mut self, i: usize, v: Voxel) {
        self.tsdf[i] = v.tsdf;
        self.weight[i] = v.weight;
    }
}

/// Index of local voxel `(x, y, z)` (each in `0..8`) within a block.
#[inline(always)]
pub fn local_index(x: usize, y: usize, z: usize) -> usize {
    x + BLOCK_SIDE * (y + BLOCK_SIDE * z)
}

/// Bytes one block costs in the volume: the voxels, its key (8 bytes) and its share of the
/// hash index (56 bytes). An index slot is a 16-byte entry plus a control byte, and the index
/// grows by doubling, so right after a growth it holds up to about two slots per block (three
/// slots for a single block): at most 51 bytes per block as [`TsdfVolume::memory_bytes`]
/// counts it. With this cost [`TsdfVolume::memory_bytes`] stays within
/// [`TsdfConfig::memory_budget_bytes`] whenever the budget check passed.
pub const BYTES_PER_BLOCK: usize = std::mem::size_of::<Block>() + 8 + 56;

/// What one call of [`TsdfVolume::integrate`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IntegrateStats {
    /// Blocks within the truncation band of the frame's pixels.
    pub blocks_touched: usize,
    /// Of these, blocks that were newly allocated.
    pub blocks_allocated: usize,
    /// Valid pixels used (inside the depth range).
    pub pixels_used: usize,
}

/// A sparse truncated signed distance volume (Curless & Levoy; the paper's section 3.3).
///
/// Voxel `(i, j, k)` (integer indices, any sign) sits at the grid point
/// `(i, j, k)·voxel_m` of the world frame; block `(a, b, c)` holds voxels `8a..8a+8` etc.
/// Blocks exist only where some frame saw a surface within the truncation band.
#[derive(Debug, Clone)]
pub struct TsdfVolume {
    params: TsdfConfig,
    index: BlockMap<u32>,
    keys: Vec<u64>,
    blocks: Vec<Block>,
    frames: usize,
    scratch: Scratch,
}

/// Per-frame working memory reused across frames (not part of the volume's state: cloning
/// gives an empty one).
#[derive(Default)]
struct Scratch {
    table: Vec<[f32; 2]>,
}

impl Clone for Scratch {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scratch")
            .field("table_len", &self.table.len())
            .finish()
    }
}

impl TsdfVolume {
    /// An empty volume.
    pub fn new(params: TsdfConfig) -> Result<Self> {
        params.validate()?;
        Ok(Self {
            params,
            index: BlockMap::default(),
            keys: Vec::new(),
            blocks: Vec::new(),
            frames: 0,
            scratch: Scratch::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TsdfConfig {
        &self.params
    }

    /// Number of allocated blocks.
    pub fn block_count(&self) -> usize {
        self.blocks.len()
    }

    /// Number of frames integrated.
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// Bytes held by the blocks, their keys and the hash index (capacity, not just length).
    pub fn memory_bytes(&self) -> usize {
        self.blocks.capacity() * std::mem::size_of::<Block>()
            + self.keys.capacity() * 8
            + self.index.capacity() * (std::mem::size_of::<(u64, u32)>() + 1)
    }

    /// Block coordinates of every allocated block, in allocation order.
    pub fn block_coords(&self) -> impl Iterator<Item = [i32; 3]> + '_ {
        self.keys.iter().map(|&k| unpack(k))
    }

    /// The block at block coordinates `b`, if allocated.
    pub fn block(&self, b: [i32; 3]) -> Option<&Block> {
        let k = pack(b)?;
        self.index.get(&k).map(|&i| &self.blocks[i as usize])
    }

    pub(crate) fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    pub(crate) fn keys(&self) -> &[u64] {
        &self.keys
    }

    pub(crate) fn block_slot(&self, b: [i32; 3]) -> Option<usize> {
        let k = pack(b)?;
        self.index.get(&k).map(|&i| i as usize)
    }

    /// The voxel with global integer indices `v`, if its block is allocated.
    pub fn voxel(&self, v: [i64; 3]) -> Option<Voxel> {
        let s = BLOCK_SIDE as i64;
        let b = [v[0].div_euclid(s), v[1].div_euclid(s), v[2].div_euclid(s)];
        let b32 = [
            i32::try_from(b[0]).ok()?,
            i32::try_from(b[1]).ok()?,
            i32::try_from(b[2]).ok()?,
        ];
        let blk = self.block(b32)?;
        let l = [v[0].rem_euclid(s), v[1].rem_euclid(s), v[2].rem_euclid(s)].map(|c| c as usize);
        Some(blk.voxel(local_index(l[0], l[1], l[2])))
    }

    /// Trilinear interpolation of `F` at a world point; `None` if any of the 8 surrounding
    /// voxels is unobserved.
    pub fn sample(&self, p: &nalgebra::Point3<f64>) -> Option<f32> {
        let g = p.coords / self.params.voxel_m;
        let base = g.map(f64::floor);
        let fr = g - base;
        let mut acc = 0.0f64;
        for c in 0..8usize {
            let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let idx = [0, 1, 2].map(|a| base[a] as i64 + o[a] as i64);
            let vx = self.voxel(idx)?;
            if vx.weight <= 0.0 {
                return None;
            }
            let w: f64 = (0..3)
                .map(|a| if o[a] == 1 { fr[a] } else { 1.0 - fr[a] })
                .product();
            acc += w * f64::from(vx.tsdf);
        }
        Some(acc as f32)
    }

    /// A volume holding an analytic field: every block overlapping the box `[lo_m, hi_m]` is
    /// allocated and each of its voxels set to `field(position)` with weight 1, or left
    /// unobserved where `field` returns `None`. For tests and for comparing against exact
    /// surfaces; fails like [`TsdfVolume::integrate`] when the budget is exceeded.
    pub fn from_field(
        params: TsdfConfig,
        lo_m: [f64; 3],
        hi_m: [f64; 3],
        field: impl Fn(&nalgebra::Point3<f64>) -> Option<f32> + Sync,
    ) -> Result<Self> {
        let mut vol = Self::new(params)?;
        let bs = BLOCK_SIDE as f64 * params.voxel_m;
        let lo = lo_m.map(|c| (c / bs).floor() as i64);
        let hi = hi_m.map(|c| (c / bs).floor() as i64);
        let n: usize = (0..3)
            .map(|a| usize::try_from(hi[a].saturating_sub(lo[a]).saturating_add(1)).unwrap_or(0))
            .fold(1, usize::saturating_mul);
        let needed = n.saturating_mul(BYTES_PER_BLOCK);
        if needed > params.memory_budget_bytes {
            return Err(TsdfError::MemoryBudget {
                blocks: n,
                needed_bytes: needed,
                budget_bytes: params.memory_budget_bytes,
            });
        }
        // Exactly the blocks needed (no geometric growth), so that the capacities stay within
        // the budget like those of `integrate`.
        vol.blocks
            .try_reserve_exact(n)
            .map_err(|_| TsdfError::OutOfMemory("voxel blocks"))?;
        vol.keys
            .try_reserve_exact(n)
            .map_err(|_| TsdfError::OutOfMemory("block keys"))?;
        vol.index
            .try_reserve(n)
            .map_err(|_| TsdfError::OutOfMemory("block index"))?;
        for bz in lo[2]..=hi[2] {
            for by in lo[1]..=hi[1] {
                for bx in lo[0]..=hi[0] {
                    let b = [bx, by, bz].map(|c| c as i32);
                    let key =
                        pack(b).ok_or_else(|| TsdfError::OutOfRange(format!("block {b:?}")))?;
                    vol.index.insert(key, vol.blocks.len() as u32);
                    vol.keys.push(key);
                    vol.blocks.push(Block::default());
                }
            }
        }
        let v = params.voxel_m;
        let keys = &vol.keys;
        vol.blocks.par_iter_mut().enumerate().for_each(|(i, blk)| {
            let b = unpack(keys[i]);
            for lz in 0..BLOCK_SIDE {
                for ly in 0..BLOCK_SIDE {
                    for lx in 0..BLOCK_SIDE {
                        let g = [
                            f64::from(b[0]) * BLOCK_SIDE as f64 + lx as f64,
                            f64::from(b[1]) * BLOCK_SIDE as f64 + ly as f64,
                            f64::from(b[2]) * BLOCK_SIDE as f64 + lz as f64,
                        ];
                        let p = nalgebra::Point3::new(g[0] * v, g[1] * v, g[2] * v);
                        if let Some(f) = field(&p) {
                            blk.set_voxel(
                                local_index(lx, ly, lz),
                                Voxel {
                                    tsdf: f,
                                    weight: 1.0,
                                },
                            );
                        }
                    }
                }
            }
        });
        Ok(vol)
    }

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
        pose: &Pose,
    ) -> Result<IntegrateStats> {
        let depth: DepthView<'a> = depth.into();
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
    /// scratch space: `(depth, weight)` of pixel `(x, y)` at `(y + 1)·(width + 2) + x + 1`,
    /// `[0, 0]` on a one-pixel border around the image (voxels projecting outside the image
    /// are clamped onto it) and where the pixel is invalid or outside the depth range.
    fn integrate_with(
        &mut self,
        table: &mut Vec<[f32; 2]>,
        depth: DepthView<'_>,
        k: &Intrinsics,
        pose: &Pose,
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
            table.resize(len, [0.0; 2]);
        }
        let rx: Vec<f32> = (0..w).map(|x| ((x as f64 - k.cx) / k.fx) as f32).collect();
        let band = BandFrame::new(&self.params, k, pose, &rx)?;
        let p = &self.params;
        let pixels = PixelFn {
            weight: WeightFn::new(p.weight, p.z_ref_m),
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
        let strip = |(ci, (trows, drows)): (usize, (&mut [[f32; 2]], &[f32]))| {
            let used = pixels.fill(trows, drows, w);
            let keys = band_rows(&band, trows, ci * BAND_ROWS)?;
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
        self.blocks.resize(self.keys.len(), Block::default());
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
    fn update_blocks(&mut self, touched: &[bool], table: &[[f32; 2]], k: &Intrinsics, pose: &Pose) {
        let frame = FrameConsts::new(&self.params, k, pose);
        // A table of exactly `SMALL_TABLE` entries (see `integrate_with`) is indexed with a mask
        // instead of a bounds check.
        let small = table
            .first_chunk::<SMALL_TABLE>()
            .filter(|_| table.len() == SMALL_TABLE);
        let keys = &self.keys;
        const CHUNK: usize = 64;
        let items: Vec<_> = self.blocks.chunks_mut(CHUNK).enumerate().collect();
        run_on_threads(
            items,
            || (),
            |_, (ci, blocks): (usize, &mut [Block])| {
                for (j, blk) in blocks.iter_mut().enumerate() {
                    let i = ci * CHUNK + j;
                    if !touched.get(i).copied().unwrap_or(false) {
                        continue;
                    }
                    let b = unpack(keys[i]);
                    match small {
                        Some(t) => integrate_block(blk, b, &frame, t),
                        None => integrate_block(blk, b, &frame, table),
                    }
                }
            },
        );
    }
}

/// Rows of the image per strip of the fused table / band pass of [`TsdfVolume::integrate`].
const BAND_ROWS: usize = 8;

/// What the per-pixel table needs: the weight function and the depth range.
struct PixelFn {
    weight: WeightFn,
    min_d: f32,
    max_d: f32,
}

impl PixelFn {
    /// Fills the table rows `trows` (rows of `w + 2` entries with a border entry at each end)
    /// from the depth rows `drows` (`w` pixels each): `(depth, weight)`, or `[0, 0]` where the
    /// pixel is invalid or outside the depth range. Returns the number of pixels used.
    fn fill(&self, trows: &mut [[f32; 2]], drows: &[f32], w: usize) -> usize {
        // One loop per weight mode, so that it vectorises.
        match self.weight {
            WeightFn::Uniform => self.fill_with(trows, drows, w, |_| 1.0),
            wf @ WeightFn::InvZ2 { .. } => {
                self.fill_with(trows, drows, w, |d| WeightFn::weight(&wf, d))
            }
            WeightFn::InvZ4 { z_ref } => {
                let wf = WeightFn::InvZ4 { z_ref };
                self.fill_with(trows, drows, w, |d| wf.weight(d))
            }
            wf @ WeightFn::Variance { .. } => self.fill_with(trows, drows, w, |d| wf.weight(d)),
        }
    }

    #[inline(always)]
    fn fill_with(
        &self,
        trows: &mut [[f32; 2]],
        drows: &[f32],
        w: usize,
        weight: impl Fn(f32) -> f32,
    ) -> usize {
        let mut used = 0;
        for (out, row) in trows.chunks_mut(w + 2).zip(drows.chunks(w)) {
            for (o, &d) in out[1..=w].iter_mut().zip(row) {
                let valid = (d > self.min_d) & (d <= self.max_d);
                used += usize::from(valid);
                *o = if valid { [d, weight(d)] } else { [0.0; 2] };
            }
        }
        used
    }
}

/// What [`band_rows`] needs of a frame (block-space pose, band).
struct BandFrame<'a> {
    /// Camera-to-world rotation scaled to block units.
    rot: Matrix3<f32>,
    /// Camera centre in the shifted block space.
    t: Vector3<f32>,
    /// Largest block coordinate magnitude accepted.
    lim: f32,
    trunc: f32,
    /// Ray x (at z = 1) of each column.
    rx: &'a [f32],
    k: &'a Intrinsics,
}

impl<'a> BandFrame<'a> {
    /// The block space is shifted by half a voxel: a point belongs to the block of its nearest
    /// voxel, i.e. block coordinate = floor((x/v + 1/2) / 8).
    fn new(p: &TsdfConfig, k: &'a Intrinsics, pose: &Pose, rx: &'a [f32]) -> Result<Self> {
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
            trunc: p.trunc_m as f32,
            rx,
            k,
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
fn band_rows(f: &BandFrame<'_>, trows: &[[f32; 2]], y0: usize) -> Result<Vec<u64>> {
    let BandFrame {
        rot,
        t,
        lim,
        trunc,
        rx,
        k,
    } = *f;
    let w = k.width;
    let tw = w + 2;
    let mut out: Vec<u64> = Vec::with_capacity(1024);
    // Direct-mapped cache of the keys already emitted by this strip.
    let mut seen = vec![u64::MAX; SEEN_SLOTS];
    let mut emit = |c: [i32; 3]| {
        // In range: every coordinate was checked against `lim`.
        let key = pack_unchecked(c);
        let s = seen_slot(key);
        if seen[s] != key {
            seen[s] = key;
            out.push(key);
        }
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
            let d = row[x][0];
            let r = rx[x];
            // ±trunc in range along the ray: dt = trunc/λ in depth, λ = ‖ray‖.
            let dt = trunc / (r * r + ry2).sqrt();
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
                let valid = row[x][0] > 0.0;
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
            for x in (0..w).filter(|&x| row[x][0] > 0.0) {
                let (n, fr) = ends(x);
                let dir = base + col * rx[x];
                let (a, b) = (t + dir * n, t + dir * fr);
                if !a.iter().chain(b.iter()).all(|c| c.abs() < lim) {
                    return Err(TsdfError::OutOfRange(format!(
                        "pixel ({x}, {y}) at depth {} m",
                        row[x][0]
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
        }
        std::mem::swap(&mut cur, &mut prev);
        BandRow { ca, cb, flags } = cur;
    }
    Ok(out)
}

/// One image row of [`band_rows`] (structure of arrays): the cells of each pixel's segment
/// ends and its flags (bit 0 valid, bit 1 "simple": the end cells differ by at most one in
/// every axis, bits 2..5 the order of the first boundary crossings).
struct BandRow {
    ca: [Vec<i32>; 3],
    cb: [Vec<i32>; 3],
    flags: Vec<u32>,
}

impl BandRow {
    const VALID: u32 = 1;
    const SIMPLE: u32 = 2;

    fn new(w: usize) -> Self {
        Self {
            ca: std::array::from_fn(|_| vec![0; w]),
            cb: std::array::from_fn(|_| vec![0; w]),
            flags: vec![0; w],
        }
    }

    /// Which valid pixels of this row need processing: not those whose left neighbour or
    /// (with `up`) the pixel above in `prev` is valid and simple with the same flags and end
    /// cells. Vectorised: one loop over slices of equal length.
    fn need(&self, prev: &Self, up: bool, need: &mut [bool]) {
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
const SEEN_SLOTS: usize = 1024;

#[inline(always)]
fn seen_slot(key: u64) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - SEEN_SLOTS.trailing_zeros())) as usize
}

/// Voxels in one z slice of a block.
const SLICE: usize = BLOCK_SIDE * BLOCK_SIDE;

/// Per-frame constants of the voxel update (camera from world, intrinsics, band).
#[derive(Debug, Clone, Copy)]
struct FrameConsts {
    rt: Matrix3<f32>,
    tt: Vector3<f32>,
    step_x: Vector3<f32>,
    step_y: Vector3<f32>,
    step_z: Vector3<f32>,
    /// Camera-frame offsets of the 64 voxels of a z slice from the slice's first voxel.
    off_x: [f32; SLICE],
    off_y: [f32; SLICE],
    off_z: [f32; SLICE],
    fx: f32,
    fy: f32,
    /// Principal point plus one (the table's border column / row).
    cx1: f32,
    cy1: f32,
    /// Largest clamped column / row in table coordinates: `width + 1`, `height + 1`.
    umax: f32,
    vmax: f32,
    /// Table row length, `width + 2`.
    tw: f32,
    trunc: f32,
    max_w: f32,
    v: f32,
}

impl FrameConsts {
    fn new(p: &TsdfConfig, k: &Intrinsics, pose: &Pose) -> Self {
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
            trunc: p.trunc_m as f32,
            max_w: p.max_weight,
            v,
        }
    }
}

/// `2^23`: adding it to an `x` in `[0, 2^22]` rounds `x` to the nearest integer (ties to
/// even), which is then in the low mantissa bits.
const MAGIC: f32 = 8_388_608.0;

/// The nearest integer to `x ∈ [0, 2^22]` (ties to even), as f32; a plain add and subtract
/// that vectorises (Rust does not reassociate floating-point arithmetic).
#[inline(always)]
fn round_f32(x: f32) -> f32 {
    (x + MAGIC) - MAGIC
}

/// `x as u32` for an integral `x ∈ [0, 2^23)`, without a (saturating, non-vectorising)
/// float-to-int conversion.
#[inline(always)]
fn exact_u32(x: f32) -> u32 {
    (x + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits())
}

/// Entries of the per-pixel table for images up to about 720×720 pixels: a power of two, so
/// that indices can be masked into range instead of bounds-checked.
const SMALL_TABLE: usize = 1 << 19;

/// The per-pixel table as the voxel update reads it.
trait PixelTable: Sync {
    /// Depth and weight of table entry `i` (`i` is always in range).
    fn entry(&self, i: u32) -> [f32; 2];
}

impl PixelTable for [[f32; 2]; SMALL_TABLE] {
    #[inline(always)]
    fn entry(&self, i: u32) -> [f32; 2] {
        self[i as usize & (SMALL_TABLE - 1)]
    }
}

impl PixelTable for [[f32; 2]] {
    #[inline(always)]
    fn entry(&self, i: u32) -> [f32; 2] {
        self.get(i as usize).copied().unwrap_or([0.0; 2])
    }
}

/// Updates the 512 voxels of block `b` from one frame (`table`: per-pixel depth and weight
/// with an invalid border, see [`PixelFn::fill`]).
#[inline(always)]
fn integrate_block<T: PixelTable + ?Sized>(
    blk: &mut Block,
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
    if z_min > 0.0 {
        integrate_block_with::<T, false>(blk, &origin, fc, table);
    } else {
        integrate_block_with::<T, true>(blk, &origin, fc, table);
    }
}

/// [`integrate_block`] with the block's origin in camera coordinates; `CHECK_Z`: voxels may
/// be behind the camera.
#[inline(never)]
fn integrate_block_with<T: PixelTable + ?Sized, const CHECK_Z: bool>(
    blk: &mut Block,
    origin: &Vector3<f32>,
    fc: &FrameConsts,
    table: &T,
) {
    let (trunc, max_w) = (fc.trunc, fc.max_w);
    let mut pix = [0u32; SLICE];
    let mut zs = [0.0f32; SLICE];
    let mut lam = [0.0f32; SLICE];
    let mut xs = [0.0f32; SLICE];
    let mut ys = [0.0f32; SLICE];
    let mut dw = [[0.0f32; 2]; SLICE];
    // One z slice (8×8 voxels, contiguous in the block) at a time: loops of 64 independent
    // lanes that the compiler vectorises.
    for lz in 0..BLOCK_SIDE {
        let base = lz * SLICE;
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
        }
        // Stage 2 (scalar gather): depth and weight of each voxel's pixel.
        for i in 0..SLICE {
            dw[i] = table.entry(pix[i]);
        }
        // Stage 3 (branch-free): line-of-sight distance ‖P_surface‖ − ‖P_voxel‖ = (d − z)·λ
        // along the voxel's own ray; an invalid pixel (weight 0) or a voxel more than `trunc`
        // behind the surface gets weight 0 and is left unchanged: F + (f − F)·0 = F for the
        // finite f = min(sdf, trunc) (sdf is NaN only for z ≤ 0, whose pixel is the border:
        // then f = trunc).
        let tsdf = &mut blk.tsdf[base..base + SLICE];
        let weight = &mut blk.weight[base..base + SLICE];
        for i in 0..SLICE {
            let [d, wg] = dw[i];
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

/// `1.5·2^23`: adding it to an `x` with `|x| < 2^22` rounds `x` to the nearest integer, which
/// is then the low mantissa bits (two's complement relative to the constant's bits).
const MAGIC_SIGNED: f32 = 12_582_912.0;

/// `floor` as an integer for `|x| < 2^22`, without a libm call (the baseline x86-64 target has
/// no SSE4.1 round) or a saturating conversion, so that it vectorises.
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let s = x + MAGIC_SIGNED;
    let r = s - MAGIC_SIGNED;
    let ri = (s.to_bits() as i32).wrapping_sub(MAGIC_SIGNED.to_bits() as i32);
    ri.wrapping_sub(i32::from(r > x))
}

/// [`pack`] for coordinates known to be in range.
#[inline(always)]
fn pack_unchecked(b: [i32; 3]) -> u64 {
    const BIAS: i32 = crate::hash::MAX_BLOCK_COORD + 1;
    (b[0] + BIAS) as u64 | (((b[1] + BIAS) as u64) << 21) | (((b[2] + BIAS) as u64) << 42)
}

/// Visits every unit cell of the segment `a → b` (Amanatides & Woo), in order. Coordinates
/// must be finite and well inside the `i32` range (checked by the caller).
#[inline]
fn traverse(a: &Vector3<f32>, b: &Vector3<f32>, mut visit: impl FnMut([i32; 3])) {
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

#[cfg(test)]
mod reference_tests;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use crate::params::WeightMode;
    use rand::{Rng, SeedableRng};

    /// A depth frame of random patches (steps between them), some invalid pixels.
    fn random_frame(
        rng: &mut rand_chacha::ChaCha8Rng,
        w: usize,
        h: usize,
        range: (f32, f32),
    ) -> Vec<f32> {
        let patch = 5;
        let cells: Vec<f32> = (0..w.div_ceil(patch) * h.div_ceil(patch))
            .map(|_| rng.random_range(range.0..range.1))
            .collect();
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if rng.random_range(0.0f32..1.0) < 0.05 {
                    return 0.0;
                }
                // A tilted patch: depth varies across it, so that segments cross cells
                // at different places.
                let c = cells[x / patch + w.div_ceil(patch) * (y / patch)];
                c + 0.002 * (x % patch) as f32 - 0.0015 * (y % patch) as f32
            })
            .collect()
    }

    /// The band's blocks by brute force: every valid pixel's segment traversed cell by cell.
    fn band_reference(f: &BandFrame<'_>, depth: &[f32]) -> Vec<u64> {
        let k = f.k;
        let mut keys = Vec::new();
        for (i, &d) in depth.iter().enumerate() {
            if d <= 0.0 {
                continue;
            }
            let (x, y) = (i % k.width, i / k.width);
            let ry = ((y as f64 - k.cy) / k.fy) as f32;
            let r = f.rx[x];
            let dt = f.trunc / (r * r + (ry * ry + 1.0)).sqrt();
            // The ray's direction rounded as in `band_rows`.
            let dir = f.rot * Vector3::new(0.0, ry, 1.0) + f.rot.column(0) * r;
            let a = f.t + dir * (d - dt).max(0.0);
            let b = f.t + dir * (d + dt);
            traverse(&a, &b, |c| keys.push(pack_unchecked(c)));
        }
        keys.sort_unstable();
        keys.dedup();
        keys
    }

    #[test]
    fn band_rows_matches_brute_force_traversal() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let k = Intrinsics::new(64, 48, 60.0, 62.0, 31.3, 23.8).unwrap();
        let wf = WeightFn::new(WeightMode::Uniform, 1.0);
        let pixels = PixelFn {
            weight: wf,
            min_d: 0.0,
            max_d: 100.0,
        };
        // Voxel sizes from blocks longer than the band (one or two cells per segment) to
        // much shorter (long segments: the DDA path).
        for (case, &voxel_m) in [0.004, 0.01, 0.001, 0.0005].iter().enumerate() {
            for _ in 0..4 {
                let p = TsdfConfig {
                    voxel_m,
                    trunc_m: 0.02,
                    ..TsdfConfig::default()
                };
                let axis = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let pose = Pose::new(
                    Vector3::new(
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-2.0..2.0),
                    ),
                    axis * rng.random_range(0.0..3.0),
                );
                let depth = random_frame(&mut rng, k.width, k.height, (0.3, 3.0));
                let rx: Vec<f32> = (0..k.width)
                    .map(|x| ((x as f64 - k.cx) / k.fx) as f32)
                    .collect();
                let band = BandFrame::new(&p, &k, &pose, &rx).unwrap();
                let tw = k.width + 2;
                let mut table = vec![[0.0f32; 2]; tw * (k.height + 2)];
                let mut keys = Vec::new();
                for (ci, (trows, drows)) in table[tw..tw * (k.height + 1)]
                    .chunks_mut(tw * BAND_ROWS)
                    .zip(depth.chunks(k.width * BAND_ROWS))
                    .enumerate()
                {
                    pixels.fill(trows, drows, k.width);
                    keys.extend(band_rows(&band, trows, ci * BAND_ROWS).unwrap());
                }
                keys.sort_unstable();
                keys.dedup();
                let reference = band_reference(&band, &depth);
                assert!(reference.len() > 50, "case {case}: {}", reference.len());
                assert_eq!(keys, reference, "case {case}");
            }
        }
        // A depth too far for the block index is refused.
        let p = TsdfConfig {
            voxel_m: 0.001,
            max_depth_m: 1e9,
            ..TsdfConfig::default()
        };
        let rx: Vec<f32> = (0..k.width)
            .map(|x| ((x as f64 - k.cx) / k.fx) as f32)
            .collect();
        let band = BandFrame::new(&p, &k, &Pose::identity(), &rx).unwrap();
        let tw = k.width + 2;
        let mut trows = vec![[0.0f32; 2]; tw * BAND_ROWS];
        trows[tw * 3 + 10] = [1e8, 1.0];
        assert!(matches!(
            band_rows(&band, &trows, 0),
            Err(TsdfError::OutOfRange(_))
        ));
    }

    #[test]
    fn voxel_update_variants_agree() {
        // The masked small-table gather and the bounds-checked one, with and without the
        // per-voxel z test, give bit-identical voxels.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap();
        let tw = k.width + 2;
        let mut table = vec![[0.0f32; 2]; SMALL_TABLE];
        for y in 0..k.height {
            for x in 0..k.width {
                if rng.random_range(0.0f32..1.0) < 0.9 {
                    let d = rng.random_range(0.5f32..3.0);
                    table[(y + 1) * tw + x + 1] = [d, 1.0 / (d * d)];
                }
            }
        }
        let small: &[[f32; 2]; SMALL_TABLE] = table.first_chunk().unwrap();
        let p = TsdfConfig::default();
        let pose = Pose::new(Vector3::new(0.1, -0.2, 0.05), Vector3::new(0.1, 0.2, -0.1));
        let fc = FrameConsts::new(&p, &k, &pose);
        let mut n_updated = 0;
        for _ in 0..200 {
            // Blocks in front of the camera (within 0.5..3 m along its axis).
            let pc = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.8..0.8),
                rng.random_range(0.5..3.0),
            );
            let pw = pose.transform_point(&pc.into());
            let b = [pw.x, pw.y, pw.z].map(|c| (c / (8.0 * p.voxel_m)).floor() as i32);
            let mut blk = Block::default();
            for (i, (t, w)) in blk.tsdf.iter_mut().zip(blk.weight.iter_mut()).enumerate() {
                *t = (i as f32 * 0.37).sin() * 0.02;
                *w = (i % 3) as f32;
            }
            let o = [0, 1, 2].map(|a| (b[a] * BLOCK_SIDE as i32) as f32 * fc.v);
            let origin = fc.rt * Vector3::new(o[0], o[1], o[2]) + fc.tt;
            let mut a = blk.clone();
            let mut c = blk.clone();
            let mut d = blk.clone();
            integrate_block_with::<_, false>(&mut a, &origin, &fc, small);
            integrate_block_with::<_, true>(&mut c, &origin, &fc, small);
            integrate_block_with::<_, false>(&mut d, &origin, &fc, table.as_slice());
            let mut e = blk.clone();
            integrate_block(&mut e, b, &fc, table.as_slice());
            for other in [&c, &d, &e] {
                assert!(
                    a.tsdf
                        .iter()
                        .zip(&other.tsdf)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
                );
                assert!(
                    a.weight
                        .iter()
                        .zip(&other.weight)
                        .all(|(x, y)| x.to_bits() == y.to_bits())
                );
            }
            n_updated += a
                .weight
                .iter()
                .zip(&blk.weight)
                .filter(|(x, y)| x != y)
                .count();
        }
        assert!(n_updated > 10_000, "{n_updated}");
    }

    #[test]
    fn block_arena_stays_within_the_budget() {
        let k = Intrinsics::new(160, 120, 145.0, 145.0, 79.5, 59.5).unwrap();
        let depth = DepthImage::from_vec(k.width, k.height, vec![1.2; k.pixel_count()]).unwrap();
        let poses: Vec<Pose> = (0..6)
            .map(|i| Pose::new(Vector3::new(0.05 * i as f64, 0.0, 0.0), Vector3::zeros()))
            .collect();
        let mut free = TsdfVolume::new(TsdfConfig::default()).unwrap();
        for pose in &poses {
            free.integrate(&depth, &k, pose).unwrap();
        }
        let budget = free.block_count() * BYTES_PER_BLOCK;
        let mut tight = TsdfVolume::new(TsdfConfig {
            memory_budget_bytes: budget,
            ..TsdfConfig::default()
        })
        .unwrap();
        for pose in &poses {
            tight.integrate(&depth, &k, pose).unwrap();
            let arena = tight.blocks.capacity() * (std::mem::size_of::<Block>() + 8);
            assert!(arena <= budget, "{arena} > {budget}");
            assert!(tight.keys.capacity() <= tight.blocks.capacity());
        }
        assert_eq!(tight.block_count(), free.block_count());
        // One more block than the budget allows is refused, the volume unchanged.
        let mut over = TsdfVolume::new(TsdfConfig {
            memory_budget_bytes: budget - 1,
            ..TsdfConfig::default()
        })
        .unwrap();
        let mut refused = false;
        for pose in &poses {
            match over.integrate(&depth, &k, pose) {
                Ok(_) => {}
                Err(TsdfError::MemoryBudget { .. }) => {
                    refused = true;
                    break;
                }
                Err(e) => panic!("{e}"),
            }
        }
        assert!(refused);
        assert!(over.block_count() < free.block_count());
    }

    #[test]
    fn traversal_is_connected_and_reaches_end() {
        let a = Vector3::new(0.2f32, 0.3, -0.7);
        let b = Vector3::new(3.9f32, -2.2, 1.4);
        let mut cells = Vec::new();
        traverse(&a, &b, |c| cells.push(c));
        assert_eq!(floor_i32(-0.5), -1);
        assert_eq!(floor_i32(2.0), 2);
        assert_eq!(pack_unchecked([-3, 4, 5]), pack([-3, 4, 5]).unwrap());
        assert_eq!(cells[0], [0, 0, -1]);
        assert_eq!(*cells.last().unwrap(), [3, -3, 1]);
        for w in cells.windows(2) {
            let d: i32 = (0..3).map(|i| (w[0][i] - w[1][i]).abs()).sum();
            assert_eq!(d, 1);
        }
        // Crosses 3 + 3 + 2 boundaries.
        assert_eq!(cells.len(), 9);
    }

    #[test]
    fn magic_rounding_matches_round_ties_even() {
        let mut xs = vec![
            0.0f32,
            0.5,
            1.5,
            2.5,
            0.499_999_97,
            639.5,
            640.5,
            4_194_304.0,
        ];
        for i in 0..20_000u32 {
            let base = (i / 4) as f32;
            xs.push(base);
            xs.push(f32::from_bits(base.to_bits() + 1));
            xs.push(base + 0.5);
            if base > 0.0 {
                xs.push(f32::from_bits(base.to_bits() - 1));
                xs.push(f32::from_bits((base + 0.5).to_bits() - 1));
            }
            xs.push(i as f32 * 0.37 + 0.013);
        }
        for x in xs {
            let r = round_f32(x);
            assert_eq!(r, x.round_ties_even(), "{x}");
            assert_eq!(exact_u32(r), r as u32, "{x}");
        }
        assert_eq!(exact_u32(8_388_607.0), 8_388_607);
        for i in -40_000i32..40_000 {
            for x in [
                i as f32 * 0.25,
                i as f32 * 97.13 + 0.5,
                f32::from_bits((i as f32).to_bits().wrapping_sub(u32::from(i != 0))),
            ] {
                assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
            }
        }
        for x in [-4_194_303.5f32, 4_194_303.5, -0.0, 1e-30, -1e-30] {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }

    #[test]
    fn voxel_addressing() {
        assert_eq!(local_index(7, 7, 7), BLOCK_VOXELS - 1);
        let vol = TsdfVolume::new(TsdfConfig::default()).unwrap();
        assert_eq!(vol.voxel([-1, 0, 0]), None);
        assert_eq!(vol.block_count(), 0);
    }
}

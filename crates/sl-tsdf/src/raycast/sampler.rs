//! Trilinear samples of the fused field for the ray marcher: the 8 voxels around a point in
//! grid units (voxel `(i, j, k)` at grid point `(i, j, k)`), fetched through a one-block cache
//! with a fast path when they all lie in one block, and the interpolant's gradient.

use crate::hash::pack;
use crate::volume::{BLOCK_SIDE, Block, TsdfVolume, local_index};

/// Grid coordinates beyond this magnitude are outside any block the index can hold.
const GRID_LIMIT: f32 = 1.0e9;

/// `floor(x)` as an integer for `|x| < 2^31` (a truncating conversion and a compare: the
/// baseline x86-64 target has no SSE4.1 `roundss`, and `f32::floor` would be a libm call).
#[inline(always)]
pub(super) fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    i - i32::from(x < i as f32)
}

/// Local-index offsets of the 8 cell corners (x fastest) from the base voxel, within a block.
const CORNER_OFFSETS: [usize; 8] = [
    0,
    1,
    BLOCK_SIDE,
    BLOCK_SIDE + 1,
    BLOCK_SIDE * BLOCK_SIDE,
    BLOCK_SIDE * BLOCK_SIDE + 1,
    BLOCK_SIDE * BLOCK_SIDE + BLOCK_SIDE,
    BLOCK_SIDE * BLOCK_SIDE + BLOCK_SIDE + 1,
];

/// The 8 voxels of one trilinear cell and the point's position in it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cell {
    /// `F` at the corners, index `x + 2y + 4z`.
    pub(super) f: [f32; 8],
    /// Weights at the corners.
    pub(super) w: [f32; 8],
    /// Position in the cell, each in `[0, 1)`.
    pub(super) t: [f32; 3],
}

impl Cell {
    /// Trilinear blend of corner values `v`.
    #[inline(always)]
    fn blend(&self, v: &[f32; 8]) -> f32 {
        let [tx, ty, tz] = self.t;
        let x00 = v[0] + (v[1] - v[0]) * tx;
        let x10 = v[2] + (v[3] - v[2]) * tx;
        let x01 = v[4] + (v[5] - v[4]) * tx;
        let x11 = v[6] + (v[7] - v[6]) * tx;
        let y0 = x00 + (x10 - x00) * ty;
        let y1 = x01 + (x11 - x01) * ty;
        y0 + (y1 - y0) * tz
    }

    /// Interpolated `F`, metres.
    #[inline(always)]
    pub(super) fn value(&self) -> f32 {
        self.blend(&self.f)
    }

    /// Interpolated weight.
    #[inline(always)]
    pub(super) fn weight(&self) -> f32 {
        self.blend(&self.w)
    }

    /// Gradient of the trilinear interpolant at the point, metres of `F` per voxel.
    pub(super) fn gradient(&self) -> [f32; 3] {
        let f = &self.f;
        let [tx, ty, tz] = self.t;
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        // ∂/∂x: the x differences of the four x edges, blended in y and z; likewise y, z.
        let dx = lerp(
            lerp(f[1] - f[0], f[3] - f[2], ty),
            lerp(f[5] - f[4], f[7] - f[6], ty),
            tz,
        );
        let dy = lerp(
            lerp(f[2] - f[0], f[3] - f[1], tx),
            lerp(f[6] - f[4], f[7] - f[5], tx),
            tz,
        );
        let dz = lerp(
            lerp(f[4] - f[0], f[5] - f[1], tx),
            lerp(f[6] - f[2], f[7] - f[3], tx),
            ty,
        );
        [dx, dy, dz]
    }
}

/// Entries of a sampler's block cache (a power of two).
const CACHE: usize = 32;

/// Block lookups for one worker (one image row at a time) through a small direct-mapped cache
/// of recent lookups (allocated or not): the rays of a row cross the same few blocks, and a
/// cell straddling blocks needs up to 8 of them, so most lookups cost no hash probe.
pub(super) struct Sampler<'a> {
    vol: &'a TsdfVolume,
    blocks: &'a [Block],
    /// Packed block keys (`u64::MAX`: empty; no packed key has all bits set).
    keys: [u64; CACHE],
    /// Block index per key (`u32::MAX`: not allocated).
    slots: [u32; CACHE],
}

impl<'a> Sampler<'a> {
    pub(super) fn new(vol: &'a TsdfVolume) -> Self {
        Self {
            vol,
            blocks: vol.blocks(),
            keys: [u64::MAX; CACHE],
            slots: [u32::MAX; CACHE],
        }
    }

    /// The block at block coordinates `b`, if allocated.
    #[inline(always)]
    pub(super) fn block(&mut self, b: [i32; 3]) -> Option<&'a Block> {
        let key = pack(b)?;
        let e = ((key ^ (key >> 21) ^ (key >> 42)) as usize) & (CACHE - 1);
        if self.keys[e] != key {
            self.keys[e] = key;
            self.slots[e] = self
                .vol
                .block_slot(b)
                .and_then(|s| u32::try_from(s).ok())
                .unwrap_or(u32::MAX);
        }
        self.blocks.get(self.slots[e] as usize)
    }

    /// The cell around grid point `g` (voxel units), or `None` where any of its 8 voxels is
    /// unallocated or unobserved (weight 0) or `g` is not finite.
    #[inline]
    pub(super) fn cell(&mut self, g: [f32; 3]) -> Option<Cell> {
        if !g.iter().all(|c| c.abs() < GRID_LIMIT) {
            return None;
        }
        let base = g.map(floor_i32);
        let fl = base.map(|c| c as f32);
        let t = [g[0] - fl[0], g[1] - fl[1], g[2] - fl[2]];
        let local = base.map(|c| c & (BLOCK_SIDE as i32 - 1));
        let mut f = [0.0f32; 8];
        let mut w = [0.0f32; 8];
        let last = BLOCK_SIDE as i32 - 1;
        if local.iter().all(|&l| l < last) {
            // Fast path: the whole cell is in the base voxel's block.
            let blk = self.block(base.map(|c| c >> 3))?;
            let i0 = local_index(local[0] as usize, local[1] as usize, local[2] as usize);
            for (c, off) in CORNER_OFFSETS.iter().enumerate() {
                let i = i0 + off;
                f[c] = blk.tsdf[i];
                w[c] = blk.weight[i];
            }
        } else {
            // The cell straddles up to 8 blocks (each a cache hit after the first).
            for c in 0..8 {
                let v = [
                    base[0] + (c & 1) as i32,
                    base[1] + ((c >> 1) & 1) as i32,
                    base[2] + (c >> 2) as i32,
                ];
                let blk = self.block(v.map(|c| c >> 3))?;
                let l = v.map(|c| (c & (BLOCK_SIDE as i32 - 1)) as usize);
                let i = local_index(l[0], l[1], l[2]);
                f[c] = blk.tsdf[i];
                w[c] = blk.weight[i];
            }
        }
        if w.iter().any(|&x| x <= 0.0) {
            return None;
        }
        Some(Cell { f, w, t })
    }

    /// `F` and weight of the voxel nearest to grid point `g` (one voxel, one block: the cheap
    /// read of the coarse march), or `None` where its block is unallocated.
    #[inline]
    pub(super) fn nearest(&mut self, g: [f32; 3]) -> Option<(f32, f32)> {
        if !g.iter().all(|c| c.abs() < GRID_LIMIT) {
            return None;
        }
        let v = g.map(|c| floor_i32(c + 0.5));
        let blk = self.block(v.map(|c| c >> 3))?;
        let l = v.map(|c| (c & (BLOCK_SIDE as i32 - 1)) as usize);
        let i = local_index(l[0], l[1], l[2]);
        Some((*blk.tsdf.get(i)?, *blk.weight.get(i)?))
    }

    /// Interpolated `F` at grid point `g`.
    #[inline]
    pub(super) fn value(&mut self, g: [f32; 3]) -> Option<f32> {
        self.cell(g).map(|c| c.value())
    }
}

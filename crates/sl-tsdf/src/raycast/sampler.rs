//! Samples of the fused field for the ray marcher: the voxel nearest to a point (the coarse
//! march) and the 8 voxels of its trilinear cell (voxel `(i, j, k)` at grid point `(i, j, k)`),
//! fetched through the last block, a small block cache and the last cell read, with a fast
//! path when the cell lies in one block, and the interpolant's gradient.

use crate::hash::pack;
use crate::volume::{BLOCK_SIDE, Block, TsdfVolume, local_index};

/// Grid coordinates beyond this magnitude are outside any block the index can hold.
const GRID_LIMIT: f32 = 1.0e9;

/// The base voxel `⌊g⌋` of grid point `g` (voxel units), or `None` where `g` is not finite or
/// beyond [`GRID_LIMIT`]. Within `2^22` voxels of the origin (16 km at 4 mm: every practical
/// volume) by an add and a compare per axis ([`sl_core::whole::floor_i32`]); farther by a
/// truncating conversion and a compare.
#[inline(always)]
pub(super) fn base_voxel(g: [f32; 3]) -> Option<[i32; 3]> {
    if g.iter().all(|c| c.abs() < sl_core::whole::EXACT_LIMIT) {
        Some(g.map(sl_core::whole::floor_i32))
    } else if g.iter().all(|c| c.abs() < GRID_LIMIT) {
        // `|x| < 2^31`: the conversion does not saturate.
        Some(g.map(|x| {
            let i = x as i32;
            i - i32::from(x < i as f32)
        }))
    } else {
        None
    }
}

/// The position of grid point `g` in the cell with base voxel `base = ⌊g⌋`, each in `[0, 1)`.
#[inline(always)]
pub(super) fn frac(g: [f32; 3], base: [i32; 3]) -> [f32; 3] {
    [
        g[0] - base[0] as f32,
        g[1] - base[1] as f32,
        g[2] - base[2] as f32,
    ]
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

/// Block lookups for one worker (one image row at a time): the last block looked up (most
/// samples of a ray fall into the block of the previous one: three integer compares), then a
/// small direct-mapped cache of recent lookups (allocated or not): the rays of a row cross the
/// same few blocks, and a cell straddling blocks needs up to 8 of them, so most lookups cost no
/// hash probe. The last trilinear cell read is kept too: the refinement of a zero crossing
/// reads the same cell several times.
pub(super) struct Sampler<'a> {
    vol: &'a TsdfVolume,
    blocks: &'a [Block],
    /// Block coordinates of the last lookup and its block.
    last_b: [i32; 3],
    last_blk: Option<&'a Block>,
    /// Packed block keys (`u64::MAX`: empty; no packed key has all bits set).
    keys: [u64; CACHE],
    /// Block index per key (`u32::MAX`: not allocated).
    slots: [u32; CACHE],
    /// Base voxel of the last observed cell read (`i32::MIN`: none) and its corners.
    cell_base: [i32; 3],
    cell_f: [f32; 8],
    cell_w: [f32; 8],
}

impl<'a> Sampler<'a> {
    pub(super) fn new(vol: &'a TsdfVolume) -> Self {
        Self {
            vol,
            blocks: vol.blocks(),
            // Not a block coordinate `pack` accepts, so never equal to a real lookup.
            last_b: [i32::MIN; 3],
            last_blk: None,
            keys: [u64::MAX; CACHE],
            slots: [u32::MAX; CACHE],
            cell_base: [i32::MIN; 3],
            cell_f: [0.0; 8],
            cell_w: [0.0; 8],
        }
    }

    /// The block at block coordinates `b`, if allocated.
    #[inline(always)]
    pub(super) fn block(&mut self, b: [i32; 3]) -> Option<&'a Block> {
        if b == self.last_b {
            return self.last_blk;
        }
        let blk = self.block_cached(b);
        self.last_b = b;
        self.last_blk = blk;
        blk
    }

    /// The block at `b` through the direct-mapped cache.
    #[inline]
    fn block_cached(&mut self, b: [i32; 3]) -> Option<&'a Block> {
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
        let base = base_voxel(g)?;
        self.cell_at(base, frac(g, base))
    }

    /// The cell with base voxel `base` and the point at `t` in it (`t = g − base`, see
    /// [`frac`]), as [`Sampler::cell`].
    #[inline]
    pub(super) fn cell_at(&mut self, base: [i32; 3], t: [f32; 3]) -> Option<Cell> {
        if base == self.cell_base {
            return Some(Cell {
                f: self.cell_f,
                w: self.cell_w,
                t,
            });
        }
        let local = base.map(|c| (c & (BLOCK_SIDE as i32 - 1)) as usize);
        let mut f = [0.0f32; 8];
        let mut w = [0.0f32; 8];
        let last = BLOCK_SIDE - 1;
        // Axes along which the cell crosses into the next block (bit a: axis a).
        let cross = usize::from(local[0] == last)
            | usize::from(local[1] == last) << 1
            | usize::from(local[2] == last) << 2;
        let b0 = base.map(|c| c >> 3);
        if cross == 0 {
            // Fast path: the whole cell is in the base voxel's block.
            let blk = self.block(b0)?;
            let i0 = local_index(local[0], local[1], local[2]);
            let tsdf = blk.tsdf.get(i0..i0 + CORNER_OFFSETS[7] + 1)?;
            let weight = blk.weight.get(i0..i0 + CORNER_OFFSETS[7] + 1)?;
            for (c, &off) in CORNER_OFFSETS.iter().enumerate() {
                f[c] = tsdf[off];
                w[c] = weight[off];
            }
        } else {
            // The cell straddles 2, 4 or 8 blocks: look each up once (block `j`, bit a set:
            // the next block along axis a), corner `c` is in block `c & cross`.
            let mut blks: [Option<&Block>; 8] = [None; 8];
            for (j, slot) in blks.iter_mut().enumerate() {
                if j & !cross == 0 {
                    let b = [
                        b0[0] + (j & 1) as i32,
                        b0[1] + ((j >> 1) & 1) as i32,
                        b0[2] + (j >> 2) as i32,
                    ];
                    *slot = Some(self.block(b)?);
                }
            }
            for c in 0..8 {
                let blk = blks[c & cross]?;
                let l = [
                    (local[0] + (c & 1)) & last,
                    (local[1] + ((c >> 1) & 1)) & last,
                    (local[2] + (c >> 2)) & last,
                ];
                let i = local_index(l[0], l[1], l[2]);
                f[c] = blk.tsdf[i];
                w[c] = blk.weight[i];
            }
        }
        if w.iter().any(|&x| x <= 0.0) {
            return None;
        }
        self.cell_base = base;
        self.cell_f = f;
        self.cell_w = w;
        Some(Cell { f, w, t })
    }

    /// `F` and weight of the voxel nearest to the point `t` (see [`frac`]) in the cell with
    /// base voxel `base`, whose block (block coordinates `b = base >> 3`) is `blk` (one voxel,
    /// one block: the cheap read of the coarse march), or `None` where the nearest voxel's
    /// block is unallocated.
    #[inline(always)]
    pub(super) fn nearest_at(
        &mut self,
        base: [i32; 3],
        t: [f32; 3],
        b: [i32; 3],
        blk: &'a Block,
    ) -> Option<(f32, f32)> {
        let v = [
            base[0] + i32::from(t[0] >= 0.5),
            base[1] + i32::from(t[1] >= 0.5),
            base[2] + i32::from(t[2] >= 0.5),
        ];
        let vb = v.map(|c| c >> 3);
        let blk = if vb == b { blk } else { self.block(vb)? };
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

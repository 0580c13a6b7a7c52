//! Trilinear samples of the fused field for the ray marcher: the 8 voxels around a point in
//! grid units (voxel `(i, j, k)` at grid point `(i, j, k)`), fetched through a one-block cache
//! with a fast path when they all lie in one block, and the interpolant's gradient.

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

/// Block lookups for one worker (one image row at a time): the last block found is cached,
/// so consecutive samples of a ray cost no hash lookup while they stay in one block.
pub(super) struct Sampler<'a> {
    vol: &'a TsdfVolume,
    blocks: &'a [Block],
    key: [i32; 3],
    slot: Option<usize>,
    cached: bool,
}

impl<'a> Sampler<'a> {
    pub(super) fn new(vol: &'a TsdfVolume) -> Self {
        Self {
            vol,
            blocks: vol.blocks(),
            key: [0; 3],
            slot: None,
            cached: false,
        }
    }

    /// The block at block coordinates `b`, if allocated.
    #[inline(always)]
    pub(super) fn block(&mut self, b: [i32; 3]) -> Option<&'a Block> {
        if !self.cached || self.key != b {
            self.key = b;
            self.slot = self.vol.block_slot(b);
            self.cached = true;
        }
        self.slot.and_then(|s| self.blocks.get(s))
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
            // The cell straddles up to 8 blocks: look each up once.
            let mut found: [Option<Option<&'a Block>>; 8] = [None; 8];
            for c in 0..8 {
                let o = [c & 1, (c >> 1) & 1, (c >> 2) & 1].map(|b| b as i32);
                let v = [base[0] + o[0], base[1] + o[1], base[2] + o[2]];
                let b = v.map(|c| c >> 3);
                let d = (0..3)
                    .map(|a| usize::from(b[a] != base[a] >> 3) << a)
                    .sum::<usize>();
                let blk = match found[d] {
                    Some(x) => x,
                    None => {
                        let x = self.block(b);
                        found[d] = Some(x);
                        x
                    }
                }?;
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

    /// Interpolated `F` at grid point `g`.
    #[inline]
    pub(super) fn value(&mut self, g: [f32; 3]) -> Option<f32> {
        self.cell(g).map(|c| c.value())
    }
}

//! The padded voxel grid of one block and its neighbours (values, weights and sign masks) that
//! marching cubes reads, and the TSDF gradient for vertex normals.

use super::*;

/// Side of the padded voxel grid around a block: local coordinates `-1..=8+1`.
pub(super) const G: usize = BLOCK_SIDE + 3;
/// Rows (along x) of the padded grid.
pub(super) const G2: usize = G * G;
/// Cells of the padded grid.
pub(super) const G3: usize = G2 * G;
/// Rows (along x) of a block.
pub(super) const ROWS: usize = BLOCK_SIDE * BLOCK_SIDE;

/// Index of local voxel `(x, y, z)` (each in `-1..=9`) in the padded grid.
#[inline(always)]
pub(super) fn gidx(x: i32, y: i32, z: i32) -> usize {
    ((x + 1) + G as i32 * ((y + 1) + G as i32 * (z + 1))) as usize
}

/// Index of the row of padded coordinates `(y, z)` (local + 1, each in `0..11`) in the
/// per-row bit masks of a [`BlockGrid`].
#[inline(always)]
pub(super) fn ridx(y: usize, z: usize) -> usize {
    y + G * z
}

/// Bits 1..=8 of a padded row mask: local x in `0..8`, the voxels of the block itself.
pub(super) const OWN: u16 = 0x1FE;

/// Packs 8 bytes, each 0 or 1, into 8 bits (byte `i` → bit `i`).
#[inline(always)]
pub(super) fn pack8(bytes: &[u8]) -> u8 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[..8]);
    // Byte i times byte 7 − i of the constant (2^(7−i)) lands on bit i of the top byte; the
    // partial products of the other bytes do not overlap, so there are no carries.
    (u64::from_le_bytes(b).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u8
}

/// Per block, per row `(y, z)` (index `y + 8z`), bit `x`: the voxel is observed (weight > 0
/// and ≥ the minimum), and observed with `F < 0`.
#[derive(Clone, Copy)]
pub(super) struct BlockBits {
    pub(super) obs: [u8; ROWS],
    pub(super) neg: [u8; ROWS],
}

impl BlockBits {
    const EMPTY: Self = Self {
        obs: [0; ROWS],
        neg: [0; ROWS],
    };

    #[inline(never)]
    pub(super) fn of(blk: &Block, min_w: f32) -> Self {
        // One byte (0 or 1) per voxel, vectorised, then 8 bytes → 8 bits per row.
        let mut ob = [0u8; BLOCK_VOXELS];
        let mut ng = [0u8; BLOCK_VOXELS];
        for i in 0..BLOCK_VOXELS {
            let (f, w) = (blk.tsdf[i], blk.weight[i]);
            let o = (w > 0.0) & (w >= min_w);
            ob[i] = u8::from(o);
            ng[i] = u8::from(o & (f < 0.0));
        }
        let mut bits = Self::EMPTY;
        for r in 0..ROWS {
            bits.obs[r] = pack8(&ob[r * BLOCK_SIDE..]);
            bits.neg[r] = pack8(&ng[r * BLOCK_SIDE..]);
        }
        bits
    }

    /// Bit 0: some observed voxel has `F < 0`; bit 1: some has `F ≥ 0`.
    pub(super) fn signs(&self) -> u8 {
        let (mut neg, mut pos) = (0u8, 0u8);
        for (o, n) in self.obs.iter().zip(&self.neg) {
            neg |= n;
            pos |= o & !n;
        }
        u8::from(neg != 0) | u8::from(pos != 0) << 1
    }
}

/// A block's voxels with a one-voxel border below and a two-voxel border above (local
/// coordinates `-1..=9`), copied from the 27 blocks around it, so that marching cubes reads
/// plain arrays instead of looking up a neighbour block per voxel; and per row along x, bit
/// masks of the observed voxels, the voxels with `F < 0` and the cubes with all 8 corners
/// observed, from which the cubes with a triangle and the edges with a vertex follow with a few
/// word operations per row.
pub(super) struct BlockGrid {
    /// `F` of each voxel (0 outside allocated blocks; only read where observed).
    pub(super) val: [f32; G3],
    /// Accumulated weight of each voxel.
    pub(super) weight: [f32; G3],
    /// Per row `(y, z)` (padded index [`ridx`]), bit `x + 1`: observed.
    pub(super) obs_rows: [u16; G2],
    /// Per row, bit `x + 1`: observed with `F < 0`.
    pub(super) neg_rows: [u16; G2],
    /// Per row `(y, z)` with `y, z` in `-1..=8`, bit `x + 1` (`x` in `-1..=8`): the cube whose
    /// lowest corner is `(x, y, z)` has all 8 corners observed.
    pub(super) cube_rows: [u16; G2],
}

impl BlockGrid {
    pub(super) fn new() -> Box<Self> {
        Box::new(Self {
            val: [0.0; G3],
            weight: [0.0; G3],
            obs_rows: [0; G2],
            neg_rows: [0; G2],
            cube_rows: [0; G2],
        })
    }

    /// Fills the row masks from the bits of the blocks around (`slots`: the slots of the 27
    /// blocks at offsets −1..=1, index `(dx+1) + 3(dy+1) + 9(dz+1)`, `u32::MAX` where not
    /// allocated).
    pub(super) fn fill_masks(&mut self, bits: &[BlockBits], slots: &[u32; 27]) {
        // x = −1 is bit 7 of the −x neighbour's row, x in 0..8 the block's bits, x = 8, 9
        // bits 0, 1 of the +x neighbour.
        let empty = BlockBits::EMPTY;
        let nb: [&BlockBits; 27] =
            std::array::from_fn(|i| bits.get(slots[i] as usize).unwrap_or(&empty));
        let row = |m0: u8, m1: u8, m2: u8| -> u16 {
            u16::from(m0 >> 7) | u16::from(m1) << 1 | u16::from(m2 & 3) << 9
        };
        // Local coordinate range each neighbour contributes, per offset −1, 0, +1; padded
        // coordinate = local + 8·(offset + 1) − 7.
        const LOCAL: [(usize, usize); 3] = [(7, 8), (0, 8), (0, 2)];
        for (oz, &(z0, z1)) in LOCAL.iter().enumerate() {
            for (oy, &(y0, y1)) in LOCAL.iter().enumerate() {
                let i = 3 * oy + 9 * oz;
                let (b0, b1, b2) = (nb[i], nb[i + 1], nb[i + 2]);
                for lz in z0..z1 {
                    for ly in y0..y1 {
                        let r = (ly + BLOCK_SIDE * lz) % ROWS;
                        let pr = ridx(ly + 8 * oy - 7, lz + 8 * oz - 7);
                        self.obs_rows[pr] = row(b0.obs[r], b1.obs[r], b2.obs[r]);
                        self.neg_rows[pr] = row(b0.neg[r], b1.neg[r], b2.neg[r]);
                    }
                }
            }
        }
        let o = &self.obs_rows;
        for z in 0..G - 1 {
            for y in 0..G - 1 {
                let q =
                    o[ridx(y, z)] & o[ridx(y + 1, z)] & o[ridx(y, z + 1)] & o[ridx(y + 1, z + 1)];
                self.cube_rows[ridx(y, z)] = q & (q >> 1);
            }
        }
    }

    /// Copies the voxel values and weights from the blocks around (`slots` as in
    /// [`BlockGrid::fill_masks`]).
    pub(super) fn fill_values(&mut self, blocks: &[Block], slots: &[u32; 27]) {
        // Local coordinate range each neighbour contributes, per offset −1, 0, +1.
        const RANGES: [(i32, i32); 3] = [(7, 8), (0, 8), (0, 2)];
        let s8 = BLOCK_SIDE as i32;
        for dz in -1..=1i32 {
            for dy in -1..=1i32 {
                for dx in -1..=1i32 {
                    let i = ((dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)) as usize;
                    let blk = blocks.get(slots[i] as usize);
                    let (rx, ry, rz) = (
                        RANGES[(dx + 1) as usize],
                        RANGES[(dy + 1) as usize],
                        RANGES[(dz + 1) as usize],
                    );
                    for z in rz.0..rz.1 {
                        for y in ry.0..ry.1 {
                            let src = local_index(rx.0 as usize, y as usize, z as usize);
                            let dst = gidx(dx * s8 + rx.0, dy * s8 + y, dz * s8 + z);
                            // Constant lengths, so that the copies are a few moves.
                            match dx {
                                -1 => self.copy_run::<1>(dst, blk, src),
                                0 => self.copy_run::<8>(dst, blk, src),
                                _ => self.copy_run::<2>(dst, blk, src),
                            }
                        }
                    }
                }
            }
        }
    }

    /// Copies `N` voxels of `blk` from local index `src` to grid index `dst` (zeros, i.e.
    /// unobserved, without a block).
    #[inline(always)]
    pub(super) fn copy_run<const N: usize>(&mut self, dst: usize, blk: Option<&Block>, src: usize) {
        match blk {
            Some(blk) => {
                self.val[dst..dst + N].copy_from_slice(&blk.tsdf[src..src + N]);
                self.weight[dst..dst + N].copy_from_slice(&blk.weight[src..src + N]);
            }
            None => {
                self.val[dst..dst + N].fill(0.0);
                self.weight[dst..dst + N].fill(0.0);
            }
        }
    }
}

/// Central-difference gradient of F at the observed voxel with padded-grid index `g` (local
/// coordinates in `0..=8`), one-sided where a neighbour is unobserved (weight 0 or below
/// `min_w`), 0 where both are; in metres per voxel (only its direction is used).
#[inline]
pub(super) fn gradient(grid: &BlockGrid, g: usize, min_w: f32) -> [f32; 3] {
    // The 3×3×3 neighbourhood spans indices g − G² − G − 1 ..= g + G² + G + 1; one bounds
    // check for the two windows, then constant offsets from their centre.
    const R: usize = G2 + G + 1;
    let (Some(val), Some(wt)) = (
        grid.val.get(g.wrapping_sub(R)..g + R + 1),
        grid.weight.get(g.wrapping_sub(R)..g + R + 1),
    ) else {
        return [0.0; 3];
    };
    let (val, wt): (&[f32; 2 * R + 1], &[f32; 2 * R + 1]) = match (val.try_into(), wt.try_into()) {
        (Ok(v), Ok(w)) => (v, w),
        _ => return [0.0; 3],
    };
    let c = val[R];
    let side = |at: usize| -> (bool, f32) {
        let w = wt[at];
        let ob = (w > 0.0) & (w >= min_w);
        (ob, if ob { val[at] } else { c })
    };
    let d = |(ob_lo, f_lo): (bool, f32), (ob_hi, f_hi): (bool, f32)| -> f32 {
        if ob_lo & ob_hi {
            0.5 * (f_hi - f_lo)
        } else {
            f_hi - f_lo
        }
    };
    [
        d(side(R - 1), side(R + 1)),
        d(side(R - G), side(R + G)),
        d(side(R - G2), side(R + G2)),
    ]
}

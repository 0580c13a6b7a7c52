//! The sparse TSDF volume: a hash map of 8³ voxel blocks (storage, the memory budget, queries
//! and analytic fields here), filled by projective integration (`integrate`, which finds the
//! touched blocks with `discovery`).

use rayon::prelude::*;
#[cfg(test)]
use sl_core::DepthImage;
use sl_core::SensorModel;

use crate::error::{Result, TsdfError};
use crate::hash::{BlockMap, pack, unpack};
use crate::params::{Truncation, TsdfConfig};

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
    table: Vec<f32>,
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

    /// The sensor of a sensor-adaptive band ([`Truncation::SensorAdaptive`]) replaced before
    /// the first frame: a sensor measured noisier than its camera's model says (its frames'
    /// own noise level) needs the wider band of its own `σ_Z`. Does nothing to a fixed band.
    ///
    /// # Errors
    /// [`TsdfError::InvalidParameter`] once a frame is integrated (the blocks were found with
    /// the band as it was), or for a sensor the band cannot use.
    pub fn set_band_sensor(&mut self, sensor: SensorModel) -> Result<()> {
        if self.frames > 0 {
            return Err(TsdfError::InvalidParameter(
                "the band's sensor can only change before the first frame".into(),
            ));
        }
        if let Truncation::SensorAdaptive { sigmas, max_m, .. } = self.params.truncation {
            let mut params = self.params;
            params.truncation = Truncation::SensorAdaptive {
                sensor,
                sigmas,
                max_m,
            };
            params.validate()?;
            self.params = params;
        }
        Ok(())
    }

    /// Replaces the memory budget ([`TsdfConfig::memory_budget_bytes`]) for the frames still to
    /// come: a caller holding several volumes shares one budget between them. A budget below
    /// [`TsdfVolume::memory_bytes`] keeps every block and refuses the next frame that would
    /// allocate one ([`TsdfError::MemoryBudget`], the volume unchanged).
    pub fn set_memory_budget_bytes(&mut self, bytes: usize) {
        self.params.memory_budget_bytes = bytes;
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
}

mod discovery;
mod integrate;

#[cfg(test)]
use discovery::*;
#[cfg(test)]
use integrate::*;
#[cfg(test)]
use nalgebra::{Isometry3, Vector3};
#[cfg(test)]
use sl_core::Intrinsics;

#[cfg(test)]
mod reference_tests;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests;

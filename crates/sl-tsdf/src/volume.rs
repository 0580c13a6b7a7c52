//! The sparse TSDF volume: a hash map of 8³ voxel blocks and projective integration.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use sl_core::{DepthImage, Intrinsics, Pose};

use crate::error::{Result, TsdfError};
use crate::hash::{BlockMap, pack, unpack};
use crate::params::{TsdfParams, WeightFn};

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
    /// Sum of the normalised weights (capped at [`TsdfParams::max_weight`]).
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

/// Bytes one block costs in the volume: the voxels, its key and its hash-map slot.
pub const BYTES_PER_BLOCK: usize = std::mem::size_of::<Block>() + 8 + 24;

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
    params: TsdfParams,
    index: BlockMap<u32>,
    keys: Vec<u64>,
    blocks: Vec<Block>,
    frames: usize,
}

impl TsdfVolume {
    /// An empty volume.
    pub fn new(params: TsdfParams) -> Result<Self> {
        params.validate()?;
        Ok(Self {
            params,
            index: BlockMap::default(),
            keys: Vec::new(),
            blocks: Vec::new(),
            frames: 0,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &TsdfParams {
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
        params: TsdfParams,
        lo_m: [f64; 3],
        hi_m: [f64; 3],
        field: impl Fn(&nalgebra::Point3<f64>) -> Option<f32> + Sync,
    ) -> Result<Self> {
        let mut vol = Self::new(params)?;
        let bs = BLOCK_SIDE as f64 * params.voxel_m;
        let lo = lo_m.map(|c| (c / bs).floor() as i64);
        let hi = hi_m.map(|c| (c / bs).floor() as i64);
        let n: i64 = (0..3).map(|a| (hi[a] - lo[a] + 1).max(0)).product();
        let needed = (n as usize).saturating_mul(BYTES_PER_BLOCK);
        if needed > params.memory_budget_bytes {
            return Err(TsdfError::MemoryBudget {
                blocks: n as usize,
                needed_bytes: needed,
                budget_bytes: params.memory_budget_bytes,
            });
        }
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
    pub fn integrate(
        &mut self,
        depth: &DepthImage,
        k: &Intrinsics,
        pose: &Pose,
    ) -> Result<IntegrateStats> {
        if depth.width() != k.width || depth.height() != k.height {
            return Err(TsdfError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: depth.width(),
                height: depth.height(),
            });
        }
        k.validate()?;
        // Pixel indices are u32 in the inner loop, with one sentinel index past the image.
        if k.width * k.height >= u32::MAX as usize {
            return Err(TsdfError::InvalidParameter(format!(
                "image size {}x{} has too many pixels",
                k.width, k.height
            )));
        }
        let (table, pixels_used) = self.pixel_table(depth, k);
        let keys = self.band_blocks(&table[..k.width * k.height], k, pose)?;
        let new_keys: Vec<u64> = keys
            .iter()
            .copied()
            .filter(|key| !self.index.contains_key(key))
            .collect();
        let total = self.blocks.len() + new_keys.len();
        let needed = total.saturating_mul(BYTES_PER_BLOCK);
        if needed > self.params.memory_budget_bytes {
            return Err(TsdfError::MemoryBudget {
                blocks: total,
                needed_bytes: needed,
                budget_bytes: self.params.memory_budget_bytes,
            });
        }
        self.blocks
            .try_reserve(new_keys.len())
            .map_err(|_| TsdfError::OutOfMemory("voxel blocks"))?;
        self.keys
            .try_reserve(new_keys.len())
            .map_err(|_| TsdfError::OutOfMemory("block keys"))?;
        self.index
            .try_reserve(new_keys.len())
            .map_err(|_| TsdfError::OutOfMemory("block index"))?;
        for &key in &new_keys {
            let slot = self.blocks.len() as u32;
            self.index.insert(key, slot);
            self.keys.push(key);
            self.blocks.push(Block::default());
        }
        let mut touched = vec![false; self.blocks.len()];
        for key in &keys {
            if let Some(&i) = self.index.get(key) {
                touched[i as usize] = true;
            }
        }
        self.update_blocks(&touched, &table, k, pose);
        self.frames += 1;
        Ok(IntegrateStats {
            blocks_touched: keys.len(),
            blocks_allocated: new_keys.len(),
            pixels_used,
        })
    }

    /// Per-pixel precomputation for one frame: `(depth, weight)`, depth 0 where the pixel is
    /// invalid or outside the depth range.
    fn pixel_table(&self, depth: &DepthImage, k: &Intrinsics) -> (Vec<[f32; 2]>, usize) {
        let p = &self.params;
        let wf = WeightFn::new(p.weight, p.z_ref_m);
        let (min_d, max_d) = (p.min_depth_m as f32, p.max_depth_m as f32);
        let w = k.width;
        // One extra entry past the image, always `[0, 0]`: the pixel of voxels that project
        // outside the image, so that the integration gathers without branching.
        let mut table = vec![[0.0f32; 2]; w * k.height + 1];
        let used: usize = table[..w * k.height]
            .par_chunks_mut(w)
            .zip(depth.data().par_chunks(w))
            .map(|(out, row)| {
                let mut used = 0;
                for (o, &d) in out.iter_mut().zip(row) {
                    if d > min_d && d <= max_d {
                        *o = [d, wf.weight(d)];
                        used += 1;
                    }
                }
                used
            })
            .sum();
        (table, used)
    }

    /// Sorted unique keys of the blocks within the band of the frame's valid pixels.
    fn band_blocks(&self, table: &[[f32; 2]], k: &Intrinsics, pose: &Pose) -> Result<Vec<u64>> {
        let w = k.width;
        let p = &self.params;
        // Shifted block space: a point x belongs to the block of its nearest voxel, so block
        // coordinate = floor((x/v + 1/2) / 8). Everything scaled to block units up front.
        let inv_bs = 1.0 / (p.voxel_m * BLOCK_SIDE as f64);
        let shift = 0.5 / BLOCK_SIDE as f64;
        let rot: Matrix3<f32> =
            (pose.rotation.to_rotation_matrix().into_inner() * inv_bs).cast::<f32>();
        let t: Vector3<f32> = (pose.translation.vector * inv_bs)
            .add_scalar(shift)
            .cast::<f32>();
        let lim = crate::hash::MAX_BLOCK_COORD as f32 - 2.0;
        if t.iter().any(|c| !c.is_finite() || c.abs() > lim) {
            return Err(TsdfError::OutOfRange(format!(
                "camera position {:?} m",
                pose.translation.vector
            )));
        }
        let trunc = p.trunc_m as f32;
        let rows_per_chunk = 8usize;
        let chunks: Vec<Result<Vec<u64>>> = table
            .par_chunks(w * rows_per_chunk)
            .enumerate()
            .map(|(ci, chunk)| {
                let mut out: Vec<u64> = Vec::with_capacity(2048);
                let mut recent = [u64::MAX; 8];
                let mut recent_pos = 0usize;
                for (ri, row) in chunk.chunks(w).enumerate() {
                    let y = ci * rows_per_chunk + ri;
                    let ry = ((y as f64 - k.cy) / k.fy) as f32;
                    for (x, px) in row.iter().enumerate() {
                        let d = px[0];
                        if d <= 0.0 {
                            continue;
                        }
                        let rx = ((x as f64 - k.cx) / k.fx) as f32;
                        let lambda = (rx * rx + ry * ry + 1.0).sqrt();
                        let dir = rot * Vector3::new(rx, ry, 1.0);
                        let dt = trunc / lambda;
                        let a = t + dir * (d - dt).max(0.0);
                        let b = t + dir * (d + dt);
                        if a.iter()
                            .chain(b.iter())
                            .any(|c| c.abs() >= lim || c.is_nan())
                        {
                            return Err(TsdfError::OutOfRange(format!(
                                "pixel ({x}, {y}) at depth {d} m"
                            )));
                        }
                        traverse(&a, &b, |cell| {
                            // In range: every coordinate was checked against `lim` above.
                            let key = pack_unchecked(cell);
                            if !recent.contains(&key) {
                                recent[recent_pos & 7] = key;
                                recent_pos += 1;
                                out.push(key);
                            }
                        });
                    }
                }
                out.sort_unstable();
                out.dedup();
                Ok(out)
            })
            .collect();
        let mut all = Vec::new();
        for c in chunks {
            all.extend_from_slice(&c?);
        }
        all.par_sort_unstable();
        all.dedup();
        Ok(all)
    }

    /// Updates the voxels of the touched blocks from one frame.
    fn update_blocks(&mut self, touched: &[bool], table: &[[f32; 2]], k: &Intrinsics, pose: &Pose) {
        let p = self.params;
        let inv = pose.inverse();
        let rt: Matrix3<f32> = inv.rotation.to_rotation_matrix().into_inner().cast::<f32>();
        let tt: Vector3<f32> = inv.translation.vector.cast::<f32>();
        let v = p.voxel_m as f32;
        let step_x = rt.column(0) * v;
        let step_y = rt.column(1) * v;
        let step_z = rt.column(2) * v;
        let (fx, fy, cx, cy) = (
            k.fx as f32,
            k.fy as f32,
            k.cx as f32 + 0.5,
            k.cy as f32 + 0.5,
        );
        let w32 = k.width as u32;
        let outside = (k.width * k.height) as u32;
        let (wf32, hf32) = (k.width as f32, k.height as f32);
        let trunc = p.trunc_m as f32;
        let max_w = p.max_weight;
        let frame = FrameConsts {
            rt,
            tt,
            step_x,
            step_y,
            step_z,
            fx,
            fy,
            cx,
            cy,
            wf32,
            hf32,
            w32,
            outside,
            trunc,
            max_w,
            v,
        };
        let keys = &self.keys;
        self.blocks
            .par_iter_mut()
            .enumerate()
            .filter(|(i, _)| touched[*i])
            .for_each(|(i, blk)| integrate_block(blk, unpack(keys[i]), &frame, table));
    }
}

/// Per-frame constants of the voxel update (camera from world, intrinsics, band).
#[derive(Debug, Clone, Copy)]
struct FrameConsts {
    rt: Matrix3<f32>,
    tt: Vector3<f32>,
    step_x: Vector3<f32>,
    step_y: Vector3<f32>,
    step_z: Vector3<f32>,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    wf32: f32,
    hf32: f32,
    w32: u32,
    outside: u32,
    trunc: f32,
    max_w: f32,
    v: f32,
}

/// Updates the 512 voxels of block `b` from one frame (`table`: per-pixel depth and weight,
/// with the `[0, 0]` sentinel entry at index `frame.outside`).
#[inline(never)]
fn integrate_block(blk: &mut Block, b: [i32; 3], frame: &FrameConsts, table: &[[f32; 2]]) {
    let FrameConsts {
        rt,
        tt,
        step_x,
        step_y,
        step_z,
        fx,
        fy,
        cx,
        cy,
        wf32,
        hf32,
        w32,
        outside,
        trunc,
        max_w,
        v,
    } = *frame;
    let o = [0, 1, 2].map(|a| (b[a] * BLOCK_SIDE as i32) as f32 * v);
    let origin = rt * Vector3::new(o[0], o[1], o[2]) + tt;
    // One z slice (8×8 voxels, contiguous in the block) at a time: loops of 64 independent
    // lanes that the compiler vectorises.
    const N: usize = BLOCK_SIDE * BLOCK_SIDE;
    let lx: [f32; N] = std::array::from_fn(|i| (i % BLOCK_SIDE) as f32);
    let ly: [f32; N] = std::array::from_fn(|i| (i / BLOCK_SIDE) as f32);
    for lz in 0..BLOCK_SIDE {
        let base = lz * N;
        // Stage 1 (pure f32 arithmetic): camera coordinates, the pixel index and λ = ‖P‖/z.
        // Each voxel's position is `((origin + step_y·ly) + step_z·lz) + step_x·lx`.
        let mut xs = [0.0f32; N];
        let mut ys = [0.0f32; N];
        let mut z = [0.0f32; N];
        let sz = step_z * lz as f32;
        for i in 0..N {
            xs[i] = ((origin.x + step_y.x * ly[i]) + sz.x) + step_x.x * lx[i];
            ys[i] = ((origin.y + step_y.y * ly[i]) + sz.y) + step_x.y * lx[i];
            z[i] = ((origin.z + step_y.z * ly[i]) + sz.z) + step_x.z * lx[i];
        }
        let mut pix = [0u32; N];
        let mut lam = [0.0f32; N];
        for i in 0..N {
            let inv_z = 1.0 / z[i];
            // Pixel centres are at integers: +0.5 then truncation rounds.
            let u = fx * xs[i] * inv_z + cx;
            let vv = fy * ys[i] * inv_z + cy;
            lam[i] = (xs[i] * xs[i] + ys[i] * ys[i] + z[i] * z[i]).sqrt() * inv_z;
            let inside = (z[i] > 0.0) & (u >= 0.0) & (vv >= 0.0) & (u < wf32) & (vv < hf32);
            // In range when `inside`: 0 <= u < w, 0 <= v < h.
            let (ui, vi) = (trunc_u32(u), trunc_u32(vv));
            pix[i] = if inside {
                vi.wrapping_mul(w32).wrapping_add(ui)
            } else {
                outside
            };
        }
        // Stage 2 (scalar gather): depth and weight of each voxel's pixel, or `[0, 0]` (the
        // sentinel entry) outside the image or behind the camera.
        let mut d = [0.0f32; N];
        let mut wg = [0.0f32; N];
        for i in 0..N {
            let px = table.get(pix[i] as usize).copied().unwrap_or_default();
            d[i] = px[0];
            wg[i] = px[1];
        }
        // Stage 3 (branch-free): line-of-sight distance ‖P_surface‖ − ‖P_voxel‖ = (d − z)·λ
        // along the voxel's own ray; an invalid pixel (d = 0) or a voxel more than `trunc`
        // behind the surface gets weight 0 and is left unchanged.
        let tsdf = &mut blk.tsdf[base..base + N];
        let weight = &mut blk.weight[base..base + N];
        // Plain compares instead of `f32::min`/`max` (whose NaN rules block vectorisation)
        // and selects through bit masks: the same values, since `sdf` is only used when it is
        // not NaN and `wn` is never NaN.
        for i in 0..N {
            let sdf = (d[i] - z[i]) * lam[i];
            // All ones when in the band; false for NaN (z = 0).
            let in_band = 0u32.wrapping_sub(u32::from(sdf >= -trunc));
            let wgt = f32::from_bits(wg[i].to_bits() & in_band);
            let clipped = if sdf < trunc { sdf } else { trunc };
            let f = f32::from_bits((clipped.to_bits() & in_band) | (tsdf[i].to_bits() & !in_band));
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

/// `x as u32` for `0 ≤ x < 2²³` without a float-to-int conversion, so that a loop of them
/// vectorises (the saturating `as` does not); meaningless for other `x`.
#[inline(always)]
fn trunc_u32(x: f32) -> u32 {
    const MAGIC: f32 = 8_388_608.0; // 2^23: in [2^23, 2^24) the f32 spacing is 1
    let r = (x + MAGIC) - MAGIC; // x rounded to the nearest integer, exactly
    let t = if r > x { r - 1.0 } else { r }; // rounded down: trunc for x ≥ 0
    (t + MAGIC).to_bits().wrapping_sub(MAGIC.to_bits())
}

/// `floor` as an integer without a libm call (the baseline x86-64 target has no SSE4.1 round).
#[inline(always)]
fn floor_i32(x: f32) -> i32 {
    let i = x as i32;
    if (i as f32) > x { i - 1 } else { i }
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
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

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
    fn trunc_u32_matches_cast() {
        let mut xs = vec![
            0.0f32,
            0.5,
            0.999_999_9,
            1.0,
            1.5,
            2.5,
            639.5,
            639.999_97,
            65_535.99,
        ];
        for i in 0..20_000u32 {
            let base = (i / 4) as f32;
            xs.push(base);
            xs.push(f32::from_bits(base.to_bits() + 1));
            xs.push(base + 0.5);
            if base > 0.0 {
                xs.push(f32::from_bits(base.to_bits() - 1));
            }
            xs.push(i as f32 * 0.37 + 0.013);
        }
        xs.push(8_388_607.5);
        for x in xs {
            assert_eq!(trunc_u32(x), x as u32, "{x}");
        }
    }

    #[test]
    fn voxel_addressing() {
        assert_eq!(local_index(7, 7, 7), BLOCK_VOXELS - 1);
        let vol = TsdfVolume::new(TsdfParams::default()).unwrap();
        assert_eq!(vol.voxel([-1, 0, 0]), None);
        assert_eq!(vol.block_count(), 0);
    }
}

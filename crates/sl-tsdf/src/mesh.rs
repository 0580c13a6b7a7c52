//! Indexed triangle meshes and marching-cubes extraction over the sparse blocks.

use rayon::prelude::*;

use crate::par::run_on_threads;

use crate::hash::unpack;
use crate::mc_table::{CORNERS, EDGES, McTable, table};
use crate::volume::{BLOCK_SIDE, BLOCK_VOXELS, Block, TsdfVolume, local_index};

/// An indexed triangle mesh (world frame, metres). Triangles are counter-clockwise seen from
/// the outside (the side with F > 0, towards the cameras); normals point the same way.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals (the normalised TSDF gradient); empty if not requested.
    pub normals: Vec<[f32; 3]>,
    /// Per-vertex confidence: the accumulated weight interpolated along the edge; empty if not
    /// requested.
    pub confidence: Vec<f32>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// Options of [`TsdfVolume::extract_mesh`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtractOptions {
    /// Cubes with a corner whose accumulated weight is below this are skipped (unobserved
    /// corners, weight 0, are always skipped). In normalised weight units: 1 = one observation
    /// at the reference depth.
    pub min_weight: f32,
    /// Compute vertex normals.
    pub normals: bool,
    /// Compute per-vertex confidence.
    pub confidence: bool,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        Self {
            min_weight: 0.0,
            normals: true,
            confidence: true,
        }
    }
}

/// Edge statistics of a mesh: the checks of a closed, manifold, consistently oriented surface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Topology {
    /// Undirected edges.
    pub edges: usize,
    /// Edges with one triangle (holes or the border of the observed region).
    pub boundary_edges: usize,
    /// Edges with more than two triangles.
    pub nonmanifold_edges: usize,
    /// Edges with two triangles traversing them in the same direction.
    pub inconsistent_edges: usize,
    /// Triangles with a repeated vertex index.
    pub degenerate_triangles: usize,
}

impl Topology {
    /// No boundary, every edge shared by exactly two triangles in opposite directions.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.boundary_edges == 0 && self.nonmanifold_edges == 0 && self.inconsistent_edges == 0
    }
}

impl Mesh {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Edge-based topology checks.
    pub fn topology(&self) -> Topology {
        let mut directed: Vec<(u32, u32)> = Vec::with_capacity(self.triangles.len() * 3);
        let mut degenerate = 0;
        for t in &self.triangles {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                degenerate += 1;
            }
            for i in 0..3 {
                directed.push((t[i], t[(i + 1) % 3]));
            }
        }
        let mut undirected: Vec<(u32, u32, bool)> = directed
            .iter()
            .map(|&(a, b)| if a < b { (a, b, true) } else { (b, a, false) })
            .collect();
        undirected.par_sort_unstable();
        let mut topo = Topology {
            degenerate_triangles: degenerate,
            ..Topology::default()
        };
        let mut i = 0;
        while i < undirected.len() {
            let mut j = i;
            while j < undirected.len()
                && undirected[j].0 == undirected[i].0
                && undirected[j].1 == undirected[i].1
            {
                j += 1;
            }
            topo.edges += 1;
            match j - i {
                1 => topo.boundary_edges += 1,
                2 => {
                    if undirected[i].2 == undirected[i + 1].2 {
                        topo.inconsistent_edges += 1;
                    }
                }
                _ => topo.nonmanifold_edges += 1,
            }
            i = j;
        }
        topo
    }

    /// Signed enclosed volume (positive when the triangles face outwards of a closed surface).
    pub fn signed_volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].map(f64::from));
                let cross = [
                    b[1] * c[2] - b[2] * c[1],
                    b[2] * c[0] - b[0] * c[2],
                    b[0] * c[1] - b[1] * c[0],
                ];
                (a[0] * cross[0] + a[1] * cross[1] + a[2] * cross[2]) / 6.0
            })
            .sum()
    }

    /// Total surface area, m².
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| 0.5 * norm(&face_normal(self, t)))
            .sum()
    }

    /// Axis-aligned bounds `(min, max)`, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(mut lo, mut hi), p| {
                    for i in 0..3 {
                        lo[i] = lo[i].min(p[i]);
                        hi[i] = hi[i].max(p[i]);
                    }
                    (lo, hi)
                }),
        )
    }
}

/// Unnormalised normal (twice the area) of a triangle, f64.
pub(crate) fn face_normal(m: &Mesh, t: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = t.map(|i| m.positions[i as usize].map(f64::from));
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

pub(crate) fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Side of the padded voxel grid around a block: local coordinates `-1..=8+1`.
const G: usize = BLOCK_SIDE + 3;
/// Rows (along x) of the padded grid.
const G2: usize = G * G;
/// Cells of the padded grid.
const G3: usize = G2 * G;
/// Rows (along x) of a block.
const ROWS: usize = BLOCK_SIDE * BLOCK_SIDE;

/// Index of local voxel `(x, y, z)` (each in `-1..=9`) in the padded grid.
#[inline(always)]
fn gidx(x: i32, y: i32, z: i32) -> usize {
    ((x + 1) + G as i32 * ((y + 1) + G as i32 * (z + 1))) as usize
}

/// Index of the row of padded coordinates `(y, z)` (local + 1, each in `0..11`) in the
/// per-row bit masks of a [`BlockGrid`].
#[inline(always)]
fn ridx(y: usize, z: usize) -> usize {
    y + G * z
}

/// Bits 1..=8 of a padded row mask: local x in `0..8`, the voxels of the block itself.
const OWN: u16 = 0x1FE;

/// Packs 8 bytes, each 0 or 1, into 8 bits (byte `i` → bit `i`).
#[inline(always)]
fn pack8(bytes: &[u8]) -> u8 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[..8]);
    // Byte i times byte 7 − i of the constant (2^(7−i)) lands on bit i of the top byte; the
    // partial products of the other bytes do not overlap, so there are no carries.
    (u64::from_le_bytes(b).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u8
}

/// Per block, per row `(y, z)` (index `y + 8z`), bit `x`: the voxel is observed (weight > 0
/// and ≥ the minimum), and observed with `F < 0`.
#[derive(Clone, Copy)]
struct BlockBits {
    obs: [u8; ROWS],
    neg: [u8; ROWS],
}

impl BlockBits {
    const EMPTY: Self = Self {
        obs: [0; ROWS],
        neg: [0; ROWS],
    };

    #[inline(never)]
    fn of(blk: &Block, min_w: f32) -> Self {
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
    fn signs(&self) -> u8 {
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
struct BlockGrid {
    /// `F` of each voxel (0 outside allocated blocks; only read where observed).
    val: [f32; G3],
    /// Accumulated weight of each voxel.
    weight: [f32; G3],
    /// Per row `(y, z)` (padded index [`ridx`]), bit `x + 1`: observed.
    obs_rows: [u16; G2],
    /// Per row, bit `x + 1`: observed with `F < 0`.
    neg_rows: [u16; G2],
    /// Per row `(y, z)` with `y, z` in `-1..=8`, bit `x + 1` (`x` in `-1..=8`): the cube whose
    /// lowest corner is `(x, y, z)` has all 8 corners observed.
    cube_rows: [u16; G2],
}

impl BlockGrid {
    fn new() -> Box<Self> {
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
    fn fill_masks(&mut self, bits: &[BlockBits], slots: &[u32; 27]) {
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
    fn fill_values(&mut self, blocks: &[Block], slots: &[u32; 27]) {
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
    fn copy_run<const N: usize>(&mut self, dst: usize, blk: Option<&Block>, src: usize) {
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

/// Per row `(y, z)` of a block (index `y + 8z`), bit `3x + axis`: the edge from local voxel
/// `(x, y, z)` along `axis` carries a vertex; with the number of the block's vertices in the
/// rows before.
struct EdgeMask {
    rows: [u32; ROWS],
    prefix: [u32; ROWS],
}

/// What marching cubes finds in one block.
#[derive(Default)]
struct BlockVertices {
    /// The block's vertices (on the edges it owns), in (voxel, axis) order; `None` if none.
    mask: Option<Box<EdgeMask>>,
    /// Number of the block's vertices.
    count: u32,
    /// Cubes of this block (lowest corner inside it) with all 8 corners observed and a sign
    /// change: local index of the lowest corner and case, in index order.
    cubes: Vec<(u16, u8)>,
    /// Slots of this block and its 7 positive neighbours (index `dx + 2dy + 4dz`),
    /// `u32::MAX` where not allocated.
    slots: [u32; 8],
    /// Slots of the 27 blocks around (see [`BlockGrid::fill_masks`]), where the block has
    /// vertices.
    around: Option<Box<[u32; 27]>>,
}

/// Per-extraction constants.
struct McFrame<'a> {
    vol: &'a TsdfVolume,
    /// Observed / negative voxel bits of each block.
    bits: &'a [BlockBits],
    /// Sign bits of each block (see [`BlockBits::signs`]).
    signs: &'a [u8],
    opts: &'a ExtractOptions,
}

/// Slot of the block at `b + d` (`u32::MAX` if not allocated).
#[inline]
fn neighbour_slot(vol: &TsdfVolume, b: [i32; 3], d: [i32; 3]) -> u32 {
    vol.block_slot([b[0] + d[0], b[1] + d[1], b[2] + d[2]])
        .map_or(u32::MAX, |s| s as u32)
}

/// Phase A of [`TsdfVolume::extract_mesh`] for the block in `slot`: its cubes with a triangle
/// and the vertices on the edges it owns.
#[inline(never)]
fn block_vertices(mc: &McFrame<'_>, grid: &mut BlockGrid, slot: usize) -> BlockVertices {
    let vol = mc.vol;
    let b = unpack(vol.keys()[slot]);
    let mut bv = BlockVertices {
        slots: [u32::MAX; 8],
        ..BlockVertices::default()
    };
    if mc.signs[slot] == 0 {
        // Nothing observed: no cube here has 8 observed corners, no edge here a vertex.
        return bv;
    }
    // The edges this block owns join its voxels to voxels of the block itself or of its +x,
    // +y, +z neighbours: without both signs among them, there is no vertex. Its cubes reach
    // into all 7 positive neighbours: without both signs among those, no cube here has a
    // triangle either.
    let (mut union_own, mut union_all) = (0u8, 0u8);
    for c in 0..8usize {
        let off = [c & 1, (c >> 1) & 1, (c >> 2) & 1].map(|o| o as i32);
        let s = if c == 0 {
            slot as u32
        } else {
            neighbour_slot(vol, b, off)
        };
        bv.slots[c] = s;
        if let Some(&sg) = mc.signs.get(s as usize) {
            union_all |= sg;
            if c.count_ones() <= 1 {
                union_own |= sg;
            }
        }
    }
    if union_all != 3 {
        return bv;
    }
    let mut slots = [u32::MAX; 27];
    for dz in -1..=1i32 {
        for dy in -1..=1i32 {
            for dx in -1..=1i32 {
                let i = ((dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)) as usize;
                slots[i] = if dx >= 0 && dy >= 0 && dz >= 0 {
                    bv.slots[(dx + 2 * dy + 4 * dz) as usize]
                } else {
                    neighbour_slot(vol, b, [dx, dy, dz])
                };
            }
        }
    }
    grid.fill_masks(mc.bits, &slots);
    let (n, c) = (&grid.neg_rows, &grid.cube_rows);
    // Cubes with a triangle: all corners observed, some but not all inside.
    for z in 1..BLOCK_SIDE + 1 {
        for y in 1..BLOCK_SIDE + 1 {
            if c[ridx(y, z)] & OWN == 0 {
                continue;
            }
            let rows = [
                ridx(y, z),
                ridx(y + 1, z),
                ridx(y, z + 1),
                ridx(y + 1, z + 1),
            ];
            let (mut all, mut any) = (u16::MAX, 0u16);
            for r in rows {
                all &= n[r];
                any |= n[r];
            }
            let mut act = c[ridx(y, z)] & (any | any >> 1) & !(all & all >> 1) & OWN;
            while act != 0 {
                let xb = act.trailing_zeros() as usize;
                act &= act - 1;
                let mut case = 0u8;
                for (k, r) in rows.iter().enumerate() {
                    // Corners 2k (at x) and 2k + 1 (at x + 1) of the cube lie in row `rows[k]`.
                    case |= (((n[*r] >> xb) & 3) as u8) << (2 * k);
                }
                let i = local_index(xb - 1, y - 1, z - 1);
                bv.cubes.push((i as u16, case));
            }
        }
    }
    if union_own != 3 {
        return bv;
    }
    let (o, n, c) = (&grid.obs_rows, &grid.neg_rows, &grid.cube_rows);
    let mut mask = Box::new(EdgeMask {
        rows: [0; ROWS],
        prefix: [0; ROWS],
    });
    let mut count = 0u32;
    for z in 1..BLOCK_SIDE + 1 {
        for y in 1..BLOCK_SIDE + 1 {
            let r = ridx(y, z);
            let row = (y - 1) + BLOCK_SIDE * (z - 1);
            mask.prefix[row] = count;
            let (o0, n0) = (o[r], n[r]);
            if o0 & OWN == 0 {
                continue;
            }
            let (ry, rz, ryz) = (ridx(y - 1, z), ridx(y, z - 1), ridx(y - 1, z - 1));
            // Sign changes between observed voxels along each axis, used by one of the four
            // cubes around the edge (lowest corners p, p − e_b, p − e_c, p − e_b − e_c for the
            // two other axes b, c).
            let e = [
                o0 & (o0 >> 1) & (n0 ^ (n0 >> 1)) & (c[r] | c[ry] | c[rz] | c[ryz]),
                o0 & o[ridx(y + 1, z)]
                    & (n0 ^ n[ridx(y + 1, z)])
                    & (c[r] | c[r] << 1 | c[rz] | c[rz] << 1),
                o0 & o[ridx(y, z + 1)]
                    & (n0 ^ n[ridx(y, z + 1)])
                    & (c[r] | c[r] << 1 | c[ry] | c[ry] << 1),
            ]
            .map(|m| m & OWN);
            // Interleave to bit 3x + axis (x = padded bit − 1).
            let [e0, e1, e2] = e.map(|m| usize::from(m >> 1) & 0xFF);
            let bits = SPREAD[e0] | SPREAD[e1] << 1 | SPREAD[e2] << 2;
            count += u32::from(POPCOUNT[e0] + POPCOUNT[e1] + POPCOUNT[e2]);
            mask.rows[row] = bits;
        }
    }
    if count > 0 {
        bv.mask = Some(mask);
        bv.count = count;
        bv.around = Some(Box::new(slots));
    }
    bv
}

/// Phase D of [`TsdfVolume::extract_mesh`]: position, normal and confidence of the vertices
/// of one block, written to `pos`, `nrm` and `conf` (in the block's vertex order; `nrm` and
/// `conf` are empty when not requested).
#[inline(never)]
fn block_vertex_data(
    mc: &McFrame<'_>,
    grid: &mut BlockGrid,
    slot: usize,
    bv: &BlockVertices,
    pos: &mut [[f32; 3]],
    nrm: &mut [[f32; 3]],
    conf: &mut [f32],
) {
    let (Some(mask), Some(around)) = (bv.mask.as_deref(), bv.around.as_deref()) else {
        return;
    };
    let vol = mc.vol;
    grid.fill_values(vol.blocks(), around);
    let b = unpack(vol.keys()[slot]);
    let v = vol.params().voxel_m as f32;
    let min_w = mc.opts.min_weight;
    let origin = b.map(|c| (c * BLOCK_SIDE as i32) as f32);
    const STRIDE: [usize; 3] = [1, G, G * G];
    let mut k = 0usize;
    for (row, &bits) in mask.rows.iter().enumerate() {
        let (ly, lz) = (row % BLOCK_SIDE, row / BLOCK_SIDE);
        let mut m = bits;
        let mut last_x = usize::MAX;
        let mut gr0 = [0.0f32; 3];
        while m != 0 {
            let bit = m.trailing_zeros() as usize;
            m &= m - 1;
            let (lx, axis) = (bit / 3, bit % 3);
            let g0 = gidx(lx as i32, ly as i32, lz as i32);
            if mc.opts.normals && lx != last_x {
                gr0 = gradient(grid, g0, min_w);
                last_x = lx;
            }
            let f0 = grid.val[g0];
            let g1 = g0 + STRIDE[axis];
            let f1 = grid.val[g1];
            let t = f0 / (f0 - f1);
            let mut p = [
                origin[0] + lx as f32,
                origin[1] + ly as f32,
                origin[2] + lz as f32,
            ];
            p[axis] += t;
            if let Some(d) = pos.get_mut(k) {
                *d = p.map(|c| c * v);
            }
            if let Some(d) = nrm.get_mut(k) {
                let gr1 = gradient(grid, g1, min_w);
                let mut g = [0.0f32; 3];
                for i in 0..3 {
                    g[i] = gr0[i] * (1.0 - t) + gr1[i] * t;
                }
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                *d = if len > 0.0 {
                    g.map(|c| c / len)
                } else {
                    // No usable gradient: the edge direction, towards F > 0.
                    let mut e = [0.0f32; 3];
                    e[axis] = if f1 > f0 { 1.0 } else { -1.0 };
                    e
                };
            }
            if let Some(d) = conf.get_mut(k) {
                *d = grid.weight[g0] * (1.0 - t) + grid.weight[g1] * t;
            }
            k += 1;
        }
    }
}

/// Bit `i` of a byte moved to bit `3i`.
const SPREAD: [u32; 256] = {
    let mut t = [0u32; 256];
    let mut v = 0;
    while v < 256 {
        let mut i = 0;
        while i < 8 {
            if (v >> i) & 1 != 0 {
                t[v] |= 1 << (3 * i);
            }
            i += 1;
        }
        v += 1;
    }
    t
};

/// Set bits of a byte (the baseline x86-64 target has no `popcnt`).
const POPCOUNT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut v = 0;
    while v < 256 {
        t[v] = (v as u32).count_ones() as u8;
        v += 1;
    }
    t
};

/// Side of the window of edge owners a block's cubes reach: local voxels `0..=8`.
const W: usize = BLOCK_SIDE + 1;

/// Scratch space of [`block_triangles`]: the global index of the vertex on each edge whose
/// owner voxel is in the window `0..=8` of a block (index `3·(x + 9y + 81z) + axis`), tagged
/// with the call that wrote it (high 32 bits), so that nothing needs clearing between blocks.
struct EdgeWindow {
    vid: Box<[u64; 3 * W * W * W]>,
    tag: u32,
}

impl EdgeWindow {
    fn new() -> Self {
        Self {
            vid: Box::new([0; 3 * W * W * W]),
            tag: 0,
        }
    }
}

/// Phase C of [`TsdfVolume::extract_mesh`]: the triangles of the cubes of one block, with
/// global vertex indices.
#[inline(never)]
fn block_triangles(
    bv: &BlockVertices,
    per_block: &[BlockVertices],
    offsets: &[u32],
    tab: &McTable,
    win: &mut EdgeWindow,
) -> Vec<[u32; 3]> {
    if bv.cubes.is_empty() {
        return Vec::new();
    }
    // A new tag; entries with another tag are stale (after 2^32 calls, start afresh).
    win.tag = win.tag.wrapping_add(1);
    if win.tag == 0 {
        win.vid.fill(0);
        win.tag = 1;
    }
    let tag = u64::from(win.tag) << 32;
    let vid = &mut win.vid;
    // The vertices of this block and of the parts of its 7 positive neighbours in the window.
    for (c, &slot) in bv.slots.iter().enumerate() {
        let Some(Some(mask)) = per_block.get(slot as usize).map(|p| p.mask.as_deref()) else {
            continue;
        };
        let d = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
        // Along an axis with offset 1 only local coordinate 0 is in the window.
        let n = d.map(|o| if o == 1 { 1 } else { BLOCK_SIDE });
        let keep = if d[0] == 1 { 0b111 } else { u32::MAX };
        let base = offsets[slot as usize];
        for lz in 0..n[2] {
            for ly in 0..n[1] {
                let row = ly + BLOCK_SIDE * lz;
                let mut m = mask.rows[row] & keep;
                let mut k = base + mask.prefix[row];
                let wbase = 3
                    * (d[0] * BLOCK_SIDE
                        + W * (d[1] * BLOCK_SIDE + ly)
                        + W * W * (d[2] * BLOCK_SIDE + lz));
                // Ascending bits: the vertices in rank order (`keep` only drops trailing ones).
                while m != 0 {
                    let bit = m.trailing_zeros() as usize;
                    m &= m - 1;
                    vid[wbase + 3 * (bit / 3) + bit % 3] = tag | u64::from(k);
                    k += 1;
                }
            }
        }
    }
    let mut out = Vec::with_capacity(bv.cubes.len() * 2);
    'cube: for &(ci, case) in &bv.cubes {
        let (lx, ly, lz) = (
            usize::from(ci & 7),
            usize::from((ci >> 3) & 7),
            usize::from(ci >> 6),
        );
        let cube = 3 * (lx + W * ly + W * W * lz);
        for tri in tab.triangles(case) {
            let mut idx = [0u32; 3];
            for (k, &e) in tri.iter().enumerate() {
                let i = cube + EDGE_OFFSET[e as usize];
                match vid.get(i) {
                    Some(&g) if g & !u64::from(u32::MAX) == tag => idx[k] = g as u32,
                    _ => continue 'cube,
                }
            }
            out.push(idx);
        }
    }
    out
}

/// Per cube edge, the offset of its owner voxel and axis in the window index of
/// [`block_triangles`] relative to the cube's lowest corner.
const EDGE_OFFSET: [usize; 12] = {
    let mut off = [0usize; 12];
    let mut e = 0;
    while e < 12 {
        let (lo, _, axis) = EDGES[e];
        let o = CORNERS[lo as usize];
        off[e] = 3 * (o[0] + W * o[1] + W * W * o[2]) + axis as usize;
        e += 1;
    }
    off
};

/// Splits `s` into consecutive chunks of the given lengths (which must sum to at most its
/// length; the rest is dropped).
fn split_chunks<T>(mut s: &mut [T], lens: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for len in lens {
        let len = len.min(s.len());
        let (a, b) = std::mem::take(&mut s).split_at_mut(len);
        out.push(a);
        s = b;
    }
    out
}

impl TsdfVolume {
    /// Extracts the zero level set of `F` with marching cubes over all allocated blocks.
    ///
    /// Cubes straddling block borders are handled through the neighbouring blocks. Each
    /// vertex lives on a voxel edge and is created once by the voxel at the edge's lower end,
    /// so the mesh is indexed without duplicates; cubes with an unobserved (or too lightly
    /// weighted) corner are skipped, and so are vertices that no kept cube uses (a vertex is
    /// kept when one of the four cubes around its edge has all 8 corners observed; every such
    /// cube has a sign change on the edge, so its triangulation uses the vertex). The blocks
    /// are processed in parallel; the output does not depend on the number of threads.
    ///
    /// Per block, the observed / negative voxels are bit masks (one 8-bit row per `(y, z)`);
    /// a block's cubes with a triangle and its edges with a vertex follow from word operations
    /// on the rows of its 27-block neighbourhood, before any voxel value is read. Vertex
    /// indices are then the block's vertex offset plus the rank of the edge in its mask, the
    /// vertex data (positions, normals, confidence) is written in place, and the triangles of
    /// a block look their vertices up in a small window of edge indices.
    pub fn extract_mesh(&self, opts: &ExtractOptions) -> Mesh {
        // Blocks per work item of the parallel phases.
        const CHUNK: usize = 32;
        let min_w = opts.min_weight;
        let n_blocks = self.block_count();
        let items: Vec<&[Block]> = self.blocks().chunks(CHUNK).collect();
        let parts = run_on_threads(
            items,
            || (),
            |_, blocks| {
                let bits: Vec<BlockBits> = blocks.iter().map(|b| BlockBits::of(b, min_w)).collect();
                let signs: Vec<u8> = bits.iter().map(BlockBits::signs).collect();
                (bits, signs)
            },
        );
        let mut bits = Vec::with_capacity(n_blocks);
        let mut signs = Vec::with_capacity(n_blocks);
        for (b, s) in parts {
            bits.extend_from_slice(&b);
            signs.extend_from_slice(&s);
        }
        let mc = McFrame {
            vol: self,
            bits: &bits,
            signs: &signs,
            opts,
        };
        // Phase A: the cubes with triangles and the used vertices on edges owned by each block.
        let items: Vec<std::ops::Range<usize>> = (0..n_blocks)
            .step_by(CHUNK)
            .map(|s| s..(s + CHUNK).min(n_blocks))
            .collect();
        let per_block: Vec<BlockVertices> = run_on_threads(items, BlockGrid::new, |grid, slots| {
            slots
                .map(|slot| block_vertices(&mc, grid, slot))
                .collect::<Vec<_>>()
        })
        .into_iter()
        .flatten()
        .collect();

        // Phase B: global vertex offsets.
        let mut offsets = Vec::with_capacity(per_block.len() + 1);
        let mut total = 0u32;
        for bv in &per_block {
            offsets.push(total);
            total += bv.count;
        }
        offsets.push(total);

        // Phases C and D, per block: the triangles of its cubes (global vertex indices), and
        // its vertices, written in place.
        let n = total as usize;
        let mut mesh = Mesh {
            positions: vec![[0.0; 3]; n],
            normals: if opts.normals {
                vec![[0.0; 3]; n]
            } else {
                Vec::new()
            },
            confidence: if opts.confidence {
                vec![0.0; n]
            } else {
                Vec::new()
            },
            triangles: Vec::new(),
        };
        let lens = || per_block.iter().map(|bv| bv.count as usize);
        let pos = split_chunks(&mut mesh.positions, lens());
        let mut nrm = split_chunks(&mut mesh.normals, lens());
        let mut conf = split_chunks(&mut mesh.confidence, lens());
        nrm.resize_with(per_block.len(), || &mut []);
        conf.resize_with(per_block.len(), || &mut []);
        let mut outs = pos.into_iter().zip(nrm).zip(conf).enumerate();
        let mut items = Vec::new();
        loop {
            let chunk: Vec<_> = outs.by_ref().take(CHUNK).collect();
            if chunk.is_empty() {
                break;
            }
            items.push(chunk);
        }
        let tab = table();
        let tri_lists: Vec<Vec<[u32; 3]>> = run_on_threads(
            items,
            || (BlockGrid::new(), EdgeWindow::new()),
            |(grid, win), chunk| {
                let mut tris = Vec::new();
                for (slot, ((p, nr), cf)) in chunk {
                    let bv = &per_block[slot];
                    block_vertex_data(&mc, grid, slot, bv, p, nr, cf);
                    tris.extend_from_slice(&block_triangles(bv, &per_block, &offsets, tab, win));
                }
                tris
            },
        );
        mesh.triangles = vec![[0; 3]; tri_lists.iter().map(Vec::len).sum()];
        let tris = split_chunks(&mut mesh.triangles, tri_lists.iter().map(Vec::len));
        run_on_threads(
            tris.into_iter().zip(&tri_lists).collect(),
            || (),
            |_, (dst, src)| dst.copy_from_slice(src),
        );
        mesh
    }
}

/// Central-difference gradient of F at the observed voxel with padded-grid index `g` (local
/// coordinates in `0..=8`), one-sided where a neighbour is unobserved (weight 0 or below
/// `min_w`), 0 where both are; in metres per voxel (only its direction is used).
#[inline]
fn gradient(grid: &BlockGrid, g: usize, min_w: f32) -> [f32; 3] {
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

//! Vertices: the zero crossings on the edges a block owns, with positions, normals and
//! confidence interpolated along each edge.

use super::*;

/// Per row `(y, z)` of a block (index `y + 8z`), bit `3x + axis`: the edge from local voxel
/// `(x, y, z)` along `axis` carries a vertex; with the number of the block's vertices in the
/// rows before.
pub(super) struct EdgeMask {
    pub(super) rows: [u32; ROWS],
    pub(super) prefix: [u32; ROWS],
}

/// What marching cubes finds in one block.
#[derive(Default)]
pub(super) struct BlockVertices {
    /// The block's vertices (on the edges it owns), in (voxel, axis) order; `None` if none.
    pub(super) mask: Option<Box<EdgeMask>>,
    /// Number of the block's vertices.
    pub(super) count: u32,
    /// Cubes of this block (lowest corner inside it) with all 8 corners observed and a sign
    /// change: local index of the lowest corner and case, in index order.
    pub(super) cubes: Vec<(u16, u8)>,
    /// Slots of this block and its 7 positive neighbours (index `dx + 2dy + 4dz`),
    /// `u32::MAX` where not allocated.
    pub(super) slots: [u32; 8],
    /// Slots of the 27 blocks around (see [`BlockGrid::fill_masks`]), where the block has
    /// vertices.
    pub(super) around: Option<Box<[u32; 27]>>,
}

/// Per-extraction constants.
pub(super) struct McFrame<'a> {
    pub(super) vol: &'a TsdfVolume,
    /// Observed / negative voxel bits of each block.
    pub(super) bits: &'a [BlockBits],
    /// Sign bits of each block (see [`BlockBits::signs`]).
    pub(super) signs: &'a [u8],
    pub(super) opts: &'a MeshConfig,
}

/// Slot of the block at `b + d` (`u32::MAX` if not allocated).
#[inline]
pub(super) fn neighbour_slot(vol: &TsdfVolume, b: [i32; 3], d: [i32; 3]) -> u32 {
    vol.block_slot([b[0] + d[0], b[1] + d[1], b[2] + d[2]])
        .map_or(u32::MAX, |s| s as u32)
}

/// Phase A of [`TsdfVolume::extract_mesh`] for the block in `slot`: its cubes with a triangle
/// and the vertices on the edges it owns.
#[inline(never)]
pub(super) fn block_vertices(mc: &McFrame<'_>, grid: &mut BlockGrid, slot: usize) -> BlockVertices {
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
pub(super) fn block_vertex_data(
    mc: &McFrame<'_>,
    grid: &mut BlockGrid,
    slot: usize,
    bv: &BlockVertices,
    pos: &mut [Point3<f32>],
    nrm: &mut [Vector3<f32>],
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
                *d = Point3::from(p.map(|c| c * v));
            }
            if let Some(d) = nrm.get_mut(k) {
                let gr1 = gradient(grid, g1, min_w);
                let mut g = [0.0f32; 3];
                for i in 0..3 {
                    g[i] = gr0[i] * (1.0 - t) + gr1[i] * t;
                }
                let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                *d = Vector3::from(if len > 0.0 {
                    g.map(|c| c / len)
                } else {
                    // No usable gradient: the edge direction, towards F > 0.
                    let mut e = [0.0f32; 3];
                    e[axis] = if f1 > f0 { 1.0 } else { -1.0 };
                    e
                });
            }
            if let Some(d) = conf.get_mut(k) {
                *d = grid.weight[g0] * (1.0 - t) + grid.weight[g1] * t;
            }
            k += 1;
        }
    }
}

/// Bit `i` of a byte moved to bit `3i`.
pub(super) const SPREAD: [u32; 256] = {
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
pub(super) const POPCOUNT: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut v = 0;
    while v < 256 {
        t[v] = (v as u32).count_ones() as u8;
        v += 1;
    }
    t
};

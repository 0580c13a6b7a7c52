//! Triangles: the marching-cubes case of every cube and the triangle list, indexing the shared
//! vertices of the block and its neighbours.

use super::*;

/// Side of the window of edge owners a block's cubes reach: local voxels `0..=8`.
pub(super) const W: usize = BLOCK_SIDE + 1;

/// Scratch space of [`block_triangles`]: the global index of the vertex on each edge whose
/// owner voxel is in the window `0..=8` of a block (index `3·(x + 9y + 81z) + axis`), tagged
/// with the call that wrote it (high 32 bits), so that nothing needs clearing between blocks.
pub(super) struct EdgeWindow {
    pub(super) vid: Box<[u64; 3 * W * W * W]>,
    pub(super) tag: u32,
}

impl EdgeWindow {
    pub(super) fn new() -> Self {
        Self {
            vid: Box::new([0; 3 * W * W * W]),
            tag: 0,
        }
    }
}

/// Phase C of [`TsdfVolume::extract_mesh`]: the triangles of the cubes of one block, with
/// global vertex indices, written into `out` (room for the table's triangles of each of its
/// cubes); returns how many were written (a cube with an edge vertex not kept has none).
#[inline(never)]
pub(super) fn block_triangles(
    bv: &BlockVertices,
    per_block: &[BlockVertices],
    offsets: &[u32],
    tab: &McTable,
    win: &mut EdgeWindow,
    out: &mut [[u32; 3]],
) -> usize {
    if bv.cubes.is_empty() {
        return 0;
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
    let mut written = 0;
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
            // `out` holds the table's triangles of every cube: a cube skipped leaves room.
            if let Some(slot) = out.get_mut(written) {
                *slot = idx;
                written += 1;
            }
        }
    }
    written
}

/// Per cube edge, the offset of its owner voxel and axis in the window index of
/// [`block_triangles`] relative to the cube's lowest corner.
pub(super) const EDGE_OFFSET: [usize; 12] = {
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
pub(super) fn split_chunks<T>(mut s: &mut [T], lens: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    let mut out = Vec::new();
    for len in lens {
        let len = len.min(s.len());
        let (a, b) = std::mem::take(&mut s).split_at_mut(len);
        out.push(a);
        s = b;
    }
    out
}

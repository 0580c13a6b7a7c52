//! Where rays need to look: every allocated block is projected into the image, and each tile
//! of `TILE × TILE` pixels keeps the smallest and largest camera depth of the blocks that may
//! cover it (InfiniTAM's range image, at tile resolution). A ray marches only through its
//! tile's interval, so the empty space between the camera and the first block, and the
//! unallocated space beyond the last, cost nothing.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::Intrinsics;

use super::march::RayFrame;
use crate::error::{Result, TsdfError};
use crate::hash::unpack;
use crate::volume::{BLOCK_SIDE, TsdfVolume};
use sl_core::whole::{ceil_index, floor_index};

/// Per-tile depth intervals, reused across frames (cloning gives an empty one: it is scratch
/// space, not a result).
#[derive(Debug, Default)]
pub(super) struct Tiles {
    /// Per tile: the nearest and the farthest depth (metres, `f32` bit patterns).
    ranges: Vec<u32>,
    /// The same for the blocks of one piece of the block list each; merged into `ranges`.
    pieces: Vec<Vec<u32>>,
}

impl Clone for Tiles {
    fn clone(&self) -> Self {
        Self::default()
    }
}

/// Tile edge, pixels.
pub(super) const TILE: usize = 8;

/// Blocks per piece of the block list: a fixed size, as every parallel split of the workspace
/// (not a piece per thread), so that both threads of a 2-core machine get several.
const PIECE_BLOCKS: usize = 8192;
/// Most bytes of the pieces' tile grids together (each grid is 2.4 KB at 160×120, 38 KB at
/// 640×480; beyond this the pieces grow instead).
const MAX_PIECES_BYTES: usize = 16 << 20;

/// The interval of a tile no block covers (`lo > hi`).
const EMPTY: [u32; 2] = [0x7f80_0000, 0]; // [+∞, 0.0] as bits

/// Sets every tile of `grid` to [`EMPTY`].
fn clear(grid: &mut [u32]) {
    for pair in grid.chunks_exact_mut(2) {
        pair.copy_from_slice(&EMPTY);
    }
}

/// Tiles per row of an image `width` pixels wide.
fn tiles_x(width: usize) -> usize {
    width.div_ceil(TILE)
}

/// Fills `tiles` (two `f32` bit patterns per tile: nearest and farthest depth, metres) with the
/// depth intervals of the allocated blocks seen by `frame` (made with `k`) within its depth
/// range. Depths are positive, so their bit patterns order like the values. The block list is
/// cut into pieces of [`PIECE_BLOCKS`], one task each on the caller's pool with a tile grid of
/// its own (no atomic updates, no cache line shared between threads), and the grids are
/// merged: minima and maxima do not depend on the order.
pub(super) fn tile_ranges(
    vol: &TsdfVolume,
    frame: &RayFrame,
    k: &Intrinsics,
    tiles: &mut Tiles,
) -> Result<()> {
    tile_ranges_in_pieces(vol, frame, k, tiles, PIECE_BLOCKS)
}

/// [`tile_ranges`] with pieces of `piece_blocks` blocks (the tests compare piece sizes).
pub(super) fn tile_ranges_in_pieces(
    vol: &TsdfVolume,
    frame: &RayFrame,
    k: &Intrinsics,
    tiles: &mut Tiles,
    piece_blocks: usize,
) -> Result<()> {
    let tx = tiles_x(k.width);
    let n = 2 * tx * k.height.div_ceil(TILE);
    let keys = vol.keys();
    // At most `most` grids (the memory bound); every piece gets blocks (none without blocks).
    let most = (MAX_PIECES_BYTES / (4 * n)).max(1);
    let per_piece = piece_blocks.max(keys.len().div_ceil(most)).max(1);
    let pieces = keys.len().div_ceil(per_piece);
    let grid = |v: &mut Vec<u32>| -> Result<()> {
        if v.len() != n {
            v.clear();
            v.try_reserve_exact(n)
                .map_err(|_| TsdfError::OutOfMemory("raycast tiles"))?;
            v.resize(n, 0);
        }
        Ok(())
    };
    grid(&mut tiles.ranges)?;
    // Exactly `pieces` grids kept: memory follows the last rendering's size.
    tiles.pieces.resize_with(pieces, Vec::new);
    for piece in &mut tiles.pieces {
        grid(piece)?;
    }
    let view = BlockView::new(frame, k);
    tiles
        .pieces
        .par_iter_mut()
        .zip(keys.par_chunks(per_piece))
        .for_each(|(grid, keys)| {
            clear(grid);
            for &key in keys {
                let b = unpack(key);
                if view.cull.outside(&view.centre(b)) {
                    continue;
                }
                let Some(([x0, x1, y0, y1], lo, hi)) = view.footprint(b) else {
                    continue;
                };
                let (lo, hi) = (lo.to_bits(), hi.to_bits());
                for j in y0 / TILE..=y1 / TILE {
                    let row = &mut grid[2 * (j * tx + x0 / TILE)..2 * (j * tx + x1 / TILE + 1)];
                    for pair in row.chunks_exact_mut(2) {
                        pair[0] = pair[0].min(lo);
                        pair[1] = pair[1].max(hi);
                    }
                }
            }
        });
    clear(&mut tiles.ranges);
    for piece in &tiles.pieces {
        for (r, p) in tiles.ranges.chunks_exact_mut(2).zip(piece.chunks_exact(2)) {
            r[0] = r[0].min(p[0]);
            r[1] = r[1].max(p[1]);
        }
    }
    Ok(())
}

/// How blocks project into one rendering: the frame (pose, intrinsics, depth range) and the
/// image size.
pub(super) struct BlockView<'a> {
    frame: &'a RayFrame,
    /// Block side, metres.
    side: f32,
    w: f32,
    h: f32,
    pub(super) cull: FrustumCull,
}

impl<'a> BlockView<'a> {
    /// `k`: the intrinsics `frame` was made with.
    pub(super) fn new(frame: &'a RayFrame, k: &Intrinsics) -> Self {
        let side = BLOCK_SIDE as f32 * frame.voxel_m;
        Self {
            frame,
            side,
            w: k.width as f32,
            h: k.height as f32,
            cull: FrustumCull::new(k, frame.min_z, frame.max_z, side),
        }
    }

    /// The world position of block `b`'s low corner, metres.
    fn origin(&self, b: [i32; 3]) -> Point3<f32> {
        Point3::new(b[0] as f32, b[1] as f32, b[2] as f32) * self.side
    }

    /// Block `b`'s centre in camera coordinates.
    pub(super) fn centre(&self, b: [i32; 3]) -> Vector3<f32> {
        self.frame
            .world_to_camera(&(self.origin(b) + Vector3::repeat(0.5 * self.side)))
    }

    /// The pixels `[x0, x1, y0, y1]` whose centres block `b` may cover and its camera depth
    /// interval within the range, or `None` when it is not seen (behind the camera, beyond
    /// the range, outside the image).
    pub(super) fn footprint(&self, b: [i32; 3]) -> Option<([usize; 4], f32, f32)> {
        let f = self.frame;
        let (min_z, max_z, side) = (f.min_z, f.max_z, self.side);
        let o = self.origin(b);
        let mut corners = [Vector3::zeros(); 8];
        let (mut zlo, mut zhi) = (f32::INFINITY, f32::NEG_INFINITY);
        for (c, corner) in corners.iter_mut().enumerate() {
            let d = Vector3::new((c & 1) as f32, ((c >> 1) & 1) as f32, (c >> 2) as f32);
            *corner = self.frame.world_to_camera(&(o + d * side));
            zlo = zlo.min(corner.z);
            zhi = zhi.max(corner.z);
        }
        if !(zhi >= min_z && zlo <= max_z) {
            return None; // behind the camera or beyond the range (or NaN)
        }
        let (ulo, uhi, vlo, vhi) = clipped_bounds(&corners, min_z, f.fx, f.fy, f.cx, f.cy);
        let zlo = zlo.max(min_z);
        let (w, h) = (self.w, self.h);
        // Pixel centres x with ulo ≤ x ≤ uhi (likewise y).
        if !(uhi >= 0.0 && ulo <= w - 1.0 && vhi >= 0.0 && vlo <= h - 1.0) {
            return None;
        }
        let (x0, x1) = (ceil_index(ulo, w - 1.0), floor_index(uhi, w - 1.0));
        let (y0, y1) = (ceil_index(vlo, h - 1.0), floor_index(vhi, h - 1.0));
        if x0 > x1 || y0 > y1 {
            return None;
        }
        Some(([x0, x1, y0, y1], zlo, zhi.min(max_z)))
    }
}

/// The planes through the camera centre just outside the image's sides (a pixel beyond the
/// outermost pixel centres), the near and far planes, and a block's circumscribed radius: a
/// block whose centre is farther than the radius outside one of them has no point that
/// [`tile_ranges`] would keep (all of its points in front of the near plane project beyond the
/// image, or none is in the depth range), so one transform of its centre rejects it before the
/// eight of its corners.
pub(super) struct FrustumCull {
    /// Inward unit normals of the four side planes (through the origin).
    sides: [Vector3<f32>; 4],
    min_z: f32,
    max_z: f32,
    /// The circumscribed radius with a margin for round-off.
    radius: f32,
}

impl FrustumCull {
    fn new(k: &Intrinsics, min_z: f32, max_z: f32, side: f32) -> Self {
        let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
        let (w, h) = (k.width as f32, k.height as f32);
        // u ≥ −1, u ≤ w, v ≥ −1, v ≤ h for z > 0, as `n·p ≥ 0`.
        let sides = [
            Vector3::new(fx, 0.0, cx + 1.0),
            Vector3::new(-fx, 0.0, w - cx),
            Vector3::new(0.0, fy, cy + 1.0),
            Vector3::new(0.0, -fy, h - cy),
        ]
        .map(|n| n.normalize());
        Self {
            sides,
            min_z,
            max_z,
            radius: side * 0.5 * 3.0f32.sqrt() * 1.001 + 1.0e-6,
        }
    }

    /// Whether the block centred at camera point `c` is certainly not seen.
    #[inline(always)]
    pub(super) fn outside(&self, c: &Vector3<f32>) -> bool {
        let r = self.radius;
        c.z + r < self.min_z || c.z - r > self.max_z || self.sides.iter().any(|n| n.dot(c) < -r)
    }
}

/// The image-plane bounds `(u_lo, u_hi, v_lo, v_hi)` of the part of a block in front of the
/// near plane `z = min_z`, given its 8 corners in camera coordinates (index bit 0: x, bit 1: y,
/// bit 2: z; at least one corner at `z ≥ min_z`). The clipped block is convex; its vertices are
/// the corners in front of the plane and the points where the 12 edges cross it, and the
/// projection of a convex body with `z > 0` is the convex hull of its vertices' projections.
/// A block straddling the near plane therefore covers a bounded part of the image (the
/// intersection points are at depth `min_z`), not every tile.
pub(super) fn clipped_bounds(
    corners: &[Vector3<f32>; 8],
    min_z: f32,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
) -> (f32, f32, f32, f32) {
    let (mut ulo, mut uhi) = (f32::INFINITY, f32::NEG_INFINITY);
    let (mut vlo, mut vhi) = (f32::INFINITY, f32::NEG_INFINITY);
    let mut add = |p: &Vector3<f32>| {
        let inv = 1.0 / p.z;
        let (u, v) = (fx * p.x * inv + cx, fy * p.y * inv + cy);
        ulo = ulo.min(u);
        uhi = uhi.max(u);
        vlo = vlo.min(v);
        vhi = vhi.max(v);
    };
    for p in corners.iter().filter(|p| p.z >= min_z) {
        add(p);
    }
    if corners.iter().all(|p| p.z >= min_z) {
        return (ulo, uhi, vlo, vhi); // no edge crosses the near plane
    }
    // The 12 edges: corner pairs that differ in one index bit.
    for a in 0..8usize {
        for bit in [1usize, 2, 4] {
            let b = a | bit;
            if b == a {
                continue;
            }
            let (p, q) = (&corners[a], &corners[b]);
            if (p.z < min_z) != (q.z < min_z) {
                let t = (min_z - p.z) / (q.z - p.z);
                let mut x = p + (q - p) * t;
                x.z = min_z;
                add(&x);
            }
        }
    }
    (ulo, uhi, vlo, vhi)
}

/// The depth interval `[lo, hi]` (metres) pixel `(x, y)` marches through (`lo > hi`: nothing
/// to see).
#[inline]
pub(super) fn pixel_range(tiles: &Tiles, width: usize, x: usize, y: usize) -> (f32, f32) {
    let t = 2 * ((y / TILE) * tiles_x(width) + x / TILE);
    match tiles.ranges.get(t..t + 2) {
        Some(&[lo, hi]) => (f32::from_bits(lo), f32::from_bits(hi)),
        _ => (1.0, 0.0),
    }
}

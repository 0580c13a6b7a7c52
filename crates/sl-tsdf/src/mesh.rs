//! Indexed triangle meshes and marching-cubes extraction over the sparse blocks.

use rayon::prelude::*;

use crate::hash::unpack;
use crate::mc_table::{CORNERS, EDGES, table};
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
/// Cells of the padded grid.
const G3: usize = G * G * G;

/// Index of local voxel `(x, y, z)` (each in `-1..=9`) in the padded grid.
#[inline(always)]
fn gidx(x: i32, y: i32, z: i32) -> usize {
    ((x + 1) + G as i32 * ((y + 1) + G as i32 * (z + 1))) as usize
}

/// A block's voxels with a one-voxel border below and a two-voxel border above (local
/// coordinates `-1..=9`), copied from the 27 blocks around it, so that marching cubes reads
/// plain arrays instead of looking up a neighbour block per voxel. Also the slots of those
/// blocks (for vertex ownership) and which cubes have all 8 corners observed.
struct BlockGrid {
    /// `F` of each voxel (0 outside allocated blocks; only read where `obs` is set).
    val: [f32; G3],
    /// Accumulated weight of each voxel.
    weight: [f32; G3],
    /// Observed with at least the minimum weight (0 or 1).
    obs: [u8; G3],
    /// For the cube whose lowest corner is this voxel (`-1..=8` per axis): all 8 corners
    /// observed (0 or 1).
    cube_ok: [u8; G3],
    /// Marching-cubes case of the cube whose lowest corner is this voxel (see
    /// [`BlockGrid::cases`]; meaningful where `cube_ok`).
    case: [u8; G3],
    /// Slots of the 27 blocks around (offsets −1..=1, index `(dx+1) + 3(dy+1) + 9(dz+1)`),
    /// `u32::MAX` where not allocated.
    slots: [u32; 27],
}

impl BlockGrid {
    fn new() -> Box<Self> {
        Box::new(Self {
            val: [0.0; G3],
            weight: [0.0; G3],
            obs: [0; G3],
            cube_ok: [0; G3],
            case: [0; G3],
            slots: [u32::MAX; 27],
        })
    }

    /// Fills the grid around block `b`.
    fn fill(&mut self, vol: &TsdfVolume, b: [i32; 3], min_w: f32) {
        self.val.fill(0.0);
        self.weight.fill(0.0);
        // Local coordinate range each neighbour contributes, per offset −1, 0, +1.
        const RANGES: [(i32, i32); 3] = [(7, 8), (0, 8), (0, 2)];
        let s8 = BLOCK_SIDE as i32;
        for dz in -1..=1i32 {
            for dy in -1..=1i32 {
                for dx in -1..=1i32 {
                    let i = ((dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)) as usize;
                    self.slots[i] = u32::MAX;
                    let Some(s) = vol.block_slot([b[0] + dx, b[1] + dy, b[2] + dz]) else {
                        continue;
                    };
                    self.slots[i] = s as u32;
                    let blk = &vol.blocks()[s];
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
        for (o, &w) in self.obs.iter_mut().zip(&self.weight) {
            *o = u8::from((w > 0.0) & (w >= min_w));
        }
        // All 8 corners observed, separably along x, y, z over the flat array; the entries that
        // wrap around a row or slice are cubes with a lowest corner at 9, which are never read.
        let mut pair = [0u8; G3];
        for (p, (a, b)) in pair.iter_mut().zip(self.obs.iter().zip(&self.obs[1..])) {
            *p = a & b;
        }
        let mut quad = [0u8; G3];
        for (q, (a, b)) in quad.iter_mut().zip(pair.iter().zip(&pair[G..])) {
            *q = a & b;
        }
        for (c, (a, b)) in self.cube_ok.iter_mut().zip(quad.iter().zip(&quad[G * G..])) {
            *c = a & b;
        }
    }

    /// Copies `N` voxels of `blk` from local index `src` to grid index `dst`.
    #[inline(always)]
    fn copy_run<const N: usize>(&mut self, dst: usize, blk: &Block, src: usize) {
        self.val[dst..dst + N].copy_from_slice(&blk.tsdf[src..src + N]);
        self.weight[dst..dst + N].copy_from_slice(&blk.weight[src..src + N]);
    }

    /// Computes `case` of every cube with its lowest corner in `-1..=8` (bit `c` set when
    /// corner `c` has `F < 0`), over the flat array so that it vectorises.
    fn cases(&mut self) {
        let mut neg = [0u8; G3];
        for (n, &f) in neg.iter_mut().zip(&self.val) {
            *n = u8::from(f < 0.0);
        }
        const OFF: [usize; 8] = [0, 1, G, G + 1, G * G, G * G + 1, G * G + G, G * G + G + 1];
        self.case = [0; G3];
        for (c, off) in OFF.iter().enumerate() {
            for (k, &n) in self.case.iter_mut().zip(&neg[*off..]) {
                *k |= n << c;
            }
        }
    }

    /// `F` at local voxel `p` if observed.
    #[inline(always)]
    fn get(&self, p: [i32; 3]) -> Option<f32> {
        let g = gidx(p[0], p[1], p[2]);
        (self.obs[g] != 0).then_some(self.val[g])
    }

    /// Whether a vertex on the edge from local voxel `p` along `axis` belongs to some kept
    /// cube: one of the four cubes around the edge has all 8 corners observed. (Every such
    /// cube has a sign change on the edge, so its triangulation uses the vertex.)
    #[inline(always)]
    fn edge_used(&self, p: [i32; 3], axis: usize) -> bool {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut any = false;
        for (ob, oc) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let mut q = p;
            q[b] -= ob;
            q[c] -= oc;
            any |= self.cube_ok[gidx(q[0], q[1], q[2])] != 0;
        }
        any
    }
}

const MASK_WORDS: usize = BLOCK_VOXELS * 3 / 64;

/// Which of a block's 1536 edges carry a vertex, with prefix counts for O(1) rank.
#[derive(Clone)]
struct EdgeMask {
    bits: [u64; MASK_WORDS],
    prefix: [u16; MASK_WORDS],
}

impl EdgeMask {
    #[inline(always)]
    fn rank(&self, key: usize) -> Option<u32> {
        let (w, b) = (key / 64, key % 64);
        if (self.bits[w] >> b) & 1 == 0 {
            return None;
        }
        Some(u32::from(self.prefix[w]) + (self.bits[w] & ((1u64 << b) - 1)).count_ones())
    }
}

struct BlockVertices {
    mask: EdgeMask,
    /// Cubes of this block (lowest corner inside it) with all 8 corners observed and a sign
    /// change: local index of the lowest corner and case, in index order.
    cubes: Vec<(u16, u8)>,
    /// Slots of this block and its 7 positive neighbours (index `dx + 2dy + 4dz`),
    /// `u32::MAX` where not allocated.
    slots: [u32; 8],
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    confidence: Vec<f32>,
}

impl TsdfVolume {
    /// Extracts the zero level set of `F` with marching cubes over all allocated blocks.
    ///
    /// Cubes straddling block borders are handled through the neighbouring blocks. Each
    /// vertex lives on a voxel edge and is created once by the voxel at the edge's lower end,
    /// so the mesh is indexed without duplicates; cubes with an unobserved (or too lightly
    /// weighted) corner are skipped, and so are vertices that no kept cube uses. The blocks
    /// are processed in parallel; the output does not depend on the number of threads.
    pub fn extract_mesh(&self, opts: &ExtractOptions) -> Mesh {
        let v = self.params().voxel_m as f32;
        let min_w = opts.min_weight;
        let keys = self.keys();
        // Which signs each block holds among its observed voxels (bit 0: F < 0, bit 1: F ≥ 0).
        let signs: Vec<u8> = self
            .blocks()
            .par_iter()
            .map(|blk| {
                let mut bits = 0u8;
                for (f, w) in blk.tsdf.iter().zip(&blk.weight) {
                    if *w > 0.0 && *w >= min_w {
                        bits |= if *f < 0.0 { 1 } else { 2 };
                    }
                }
                bits
            })
            .collect();
        // Phase A: the used vertices on edges owned by each block, in (voxel, axis) order.
        let per_block: Vec<BlockVertices> = keys
            .par_iter()
            .enumerate()
            .map_init(BlockGrid::new, |grid, (slot, &key)| {
                let b = unpack(key);
                let mut bv = BlockVertices {
                    mask: EdgeMask {
                        bits: [0; MASK_WORDS],
                        prefix: [0; MASK_WORDS],
                    },
                    cubes: Vec::new(),
                    slots: [u32::MAX; 8],
                    positions: Vec::new(),
                    normals: Vec::new(),
                    confidence: Vec::new(),
                };
                // The edges this block owns join its voxels to voxels of the block itself or of
                // its +x, +y, +z neighbours: without both signs among them, there is no vertex.
                // Its cubes reach into all 7 positive neighbours: without both signs among
                // those, no cube here has a triangle either.
                let (mut union_own, mut union_all) = (0u8, 0u8);
                for c in 0..8usize {
                    let off = [c & 1, (c >> 1) & 1, (c >> 2) & 1].map(|o| o as i32);
                    let s = if c == 0 {
                        Some(slot)
                    } else {
                        self.block_slot([b[0] + off[0], b[1] + off[1], b[2] + off[2]])
                    };
                    if let Some(s) = s {
                        union_all |= signs[s];
                        if c.count_ones() <= 1 {
                            union_own |= signs[s];
                        }
                    }
                }
                if union_all != 3 {
                    return bv;
                }
                grid.fill(self, b, min_w);
                grid.cases();
                for c in 0..8usize {
                    bv.slots[c] =
                        grid.slots[13 + (c & 1) + 3 * ((c >> 1) & 1) + 9 * ((c >> 2) & 1)];
                }
                for lz in 0..BLOCK_SIDE as i32 {
                    for ly in 0..BLOCK_SIDE as i32 {
                        for lx in 0..BLOCK_SIDE as i32 {
                            let g = gidx(lx, ly, lz);
                            if grid.cube_ok[g] == 0 {
                                continue;
                            }
                            let case = grid.case[g];
                            if case != 0 && case != 255 {
                                let i = local_index(lx as usize, ly as usize, lz as usize);
                                bv.cubes.push((i as u16, case));
                            }
                        }
                    }
                }
                if union_own != 3 {
                    return bv;
                }
                let origin = b.map(|c| (c * BLOCK_SIDE as i32) as f32);
                for lz in 0..BLOCK_SIDE as i32 {
                    for ly in 0..BLOCK_SIDE as i32 {
                        for lx in 0..BLOCK_SIDE as i32 {
                            let g0 = gidx(lx, ly, lz);
                            if grid.obs[g0] == 0 {
                                continue;
                            }
                            let f0 = grid.val[g0];
                            for axis in 0..3 {
                                let mut n = [lx, ly, lz];
                                n[axis] += 1;
                                let g1 = gidx(n[0], n[1], n[2]);
                                let f1 = grid.val[g1];
                                if grid.obs[g1] == 0 || (f0 < 0.0) == (f1 < 0.0) {
                                    continue;
                                }
                                if !grid.edge_used([lx, ly, lz], axis) {
                                    continue;
                                }
                                let t = f0 / (f0 - f1);
                                let key =
                                    local_index(lx as usize, ly as usize, lz as usize) * 3 + axis;
                                bv.mask.bits[key / 64] |= 1 << (key % 64);
                                let mut p = [
                                    origin[0] + lx as f32,
                                    origin[1] + ly as f32,
                                    origin[2] + lz as f32,
                                ];
                                p[axis] += t;
                                bv.positions.push(p.map(|c| c * v));
                                if opts.normals {
                                    let gr0 = gradient(grid, [lx, ly, lz]);
                                    let gr1 = gradient(grid, n);
                                    let mut g = [0.0f32; 3];
                                    for i in 0..3 {
                                        g[i] = gr0[i] * (1.0 - t) + gr1[i] * t;
                                    }
                                    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                                    if len > 0.0 {
                                        bv.normals.push(g.map(|c| c / len));
                                    } else {
                                        // No usable gradient: the edge direction, towards F > 0.
                                        let mut e = [0.0f32; 3];
                                        e[axis] = if f1 > f0 { 1.0 } else { -1.0 };
                                        bv.normals.push(e);
                                    }
                                }
                                if opts.confidence {
                                    bv.confidence
                                        .push(grid.weight[g0] * (1.0 - t) + grid.weight[g1] * t);
                                }
                            }
                        }
                    }
                }
                let mut acc = 0u16;
                for w in 0..MASK_WORDS {
                    bv.mask.prefix[w] = acc;
                    acc += bv.mask.bits[w].count_ones() as u16;
                }
                bv
            })
            .collect();

        // Phase B: global vertex offsets.
        let mut offsets = Vec::with_capacity(per_block.len() + 1);
        let mut total = 0u32;
        for bv in &per_block {
            offsets.push(total);
            total += bv.positions.len() as u32;
        }
        offsets.push(total);

        // Phase C: triangles of the listed cubes, with global indices.
        let tab = table();
        let tri_lists: Vec<Vec<[u32; 3]>> = per_block
            .par_iter()
            .map(|bv| {
                let mut out = Vec::new();
                'cube: for &(ci, case) in &bv.cubes {
                    let (lx, ly, lz) = (ci & 7, (ci >> 3) & 7, ci >> 6);
                    for tri in tab.triangles(case) {
                        let mut idx = [0u32; 3];
                        for (k, &e) in tri.iter().enumerate() {
                            let (lo, _, axis) = EDGES[e as usize];
                            let o = CORNERS[lo as usize];
                            // The edge's owner voxel, in 0..=8 per axis.
                            let (x, y, z) =
                                (lx as usize + o[0], ly as usize + o[1], lz as usize + o[2]);
                            let slot = bv.slots[(x >> 3) + 2 * (y >> 3) + 4 * (z >> 3)];
                            if slot == u32::MAX {
                                continue 'cube;
                            }
                            let ek = local_index(x & 7, y & 7, z & 7) * 3 + axis as usize;
                            let Some(r) = per_block[slot as usize].mask.rank(ek) else {
                                continue 'cube;
                            };
                            idx[k] = offsets[slot as usize] + r;
                        }
                        out.push(idx);
                    }
                }
                out
            })
            .collect();

        // Phase D: concatenate (every vertex is used by some triangle: see `edge_used`).
        let mut mesh = Mesh::default();
        mesh.positions.reserve(total as usize);
        if opts.normals {
            mesh.normals.reserve(total as usize);
        }
        if opts.confidence {
            mesh.confidence.reserve(total as usize);
        }
        for bv in &per_block {
            mesh.positions.extend_from_slice(&bv.positions);
            mesh.normals.extend_from_slice(&bv.normals);
            mesh.confidence.extend_from_slice(&bv.confidence);
        }
        mesh.triangles.reserve(tri_lists.iter().map(Vec::len).sum());
        for list in &tri_lists {
            mesh.triangles.extend_from_slice(list);
        }
        mesh
    }
}

/// Central-difference gradient of F at local voxel `p` (one-sided where a neighbour is
/// unobserved), in metres per voxel (only its direction is used).
#[inline]
fn gradient(grid: &BlockGrid, p: [i32; 3]) -> [f32; 3] {
    let mut g = [0.0f32; 3];
    let c = grid.get(p);
    for axis in 0..3 {
        let mut lo = p;
        let mut hi = p;
        lo[axis] -= 1;
        hi[axis] += 1;
        let f_lo = grid.get(lo);
        let f_hi = grid.get(hi);
        g[axis] = match (f_lo, c, f_hi) {
            (Some(a), _, Some(b)) => 0.5 * (b - a),
            (None, Some(m), Some(b)) => b - m,
            (Some(a), Some(m), None) => m - a,
            _ => 0.0,
        };
    }
    g
}

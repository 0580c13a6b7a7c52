//! Indexed triangle meshes and marching-cubes extraction over the sparse blocks.

use rayon::prelude::*;

use crate::hash::unpack;
use crate::mc_table::{CORNERS, EDGES, table};
use crate::volume::{BLOCK_SIDE, BLOCK_VOXELS, Block, TsdfVolume, Voxel, local_index};

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

/// The 27 blocks around a block (offsets −1..=1 per axis), for voxel access across borders.
struct Neighbourhood<'a> {
    blocks: [Option<&'a Block>; 27],
    slots: [u32; 27],
}

impl<'a> Neighbourhood<'a> {
    fn new(vol: &'a TsdfVolume, b: [i32; 3]) -> Self {
        let mut blocks = [None; 27];
        let mut slots = [u32::MAX; 27];
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let i = ((dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)) as usize;
                    if let Some(s) = vol.block_slot([b[0] + dx, b[1] + dy, b[2] + dz]) {
                        blocks[i] = Some(&vol.blocks()[s]);
                        slots[i] = s as u32;
                    }
                }
            }
        }
        Self { blocks, slots }
    }

    /// Voxel at local coordinates in `-8..16` relative to the centre block.
    #[inline(always)]
    fn get(&self, x: i32, y: i32, z: i32) -> Option<Voxel> {
        let bi = ((x >> 3) + 1) + 3 * ((y >> 3) + 1) + 9 * ((z >> 3) + 1);
        let blk = self.blocks[bi as usize]?;
        Some(blk.voxel(local_index(
            (x & 7) as usize,
            (y & 7) as usize,
            (z & 7) as usize,
        )))
    }

    /// Slot and local edge key of the edge owned by voxel `(x, y, z)` (in `0..16`) along `axis`.
    #[inline(always)]
    fn edge_owner(&self, x: i32, y: i32, z: i32, axis: usize) -> Option<(u32, usize)> {
        let bi = ((x >> 3) + 1) + 3 * ((y >> 3) + 1) + 9 * ((z >> 3) + 1);
        let s = self.slots[bi as usize];
        if s == u32::MAX {
            return None;
        }
        Some((
            s,
            local_index((x & 7) as usize, (y & 7) as usize, (z & 7) as usize) * 3 + axis,
        ))
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
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    confidence: Vec<f32>,
}

#[inline(always)]
fn observed(v: &Voxel, min_w: f32) -> bool {
    v.weight > 0.0 && v.weight >= min_w
}

impl TsdfVolume {
    /// Extracts the zero level set of `F` with marching cubes over all allocated blocks.
    ///
    /// Cubes straddling block borders are handled through the neighbouring blocks. Each
    /// vertex lives on a voxel edge and is created once by the voxel at the edge's lower end,
    /// so the mesh is indexed without duplicates; cubes with an unobserved (or too lightly
    /// weighted) corner are skipped, and vertices no kept cube uses are dropped.
    pub fn extract_mesh(&self, opts: &ExtractOptions) -> Mesh {
        let v = self.params().voxel_m as f32;
        let min_w = opts.min_weight;
        let keys = self.keys();
        let ta = std::time::Instant::now(); // PROFTMP
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
        // Phase A: vertices on edges owned by each block.
        let per_block: Vec<BlockVertices> = keys
            .par_iter()
            .enumerate()
            .map(|(slot, &key)| {
                let b = unpack(key);
                let mut bv = BlockVertices {
                    mask: EdgeMask {
                        bits: [0; MASK_WORDS],
                        prefix: [0; MASK_WORDS],
                    },
                    positions: Vec::new(),
                    normals: Vec::new(),
                    confidence: Vec::new(),
                };
                // The edges this block owns join its voxels to voxels of the block itself or of
                // its +x, +y, +z neighbours: without both signs among them, there is no vertex.
                let mut union = signs[slot];
                for off in [[1, 0, 0], [0, 1, 0], [0, 0, 1]] {
                    if let Some(s) = self.block_slot([b[0] + off[0], b[1] + off[1], b[2] + off[2]])
                    {
                        union |= signs[s];
                    }
                }
                if union != 3 {
                    return bv;
                }
                let nb = Neighbourhood::new(self, b);
                let origin = b.map(|c| (c * BLOCK_SIDE as i32) as f32);
                for lz in 0..BLOCK_SIDE as i32 {
                    for ly in 0..BLOCK_SIDE as i32 {
                        for lx in 0..BLOCK_SIDE as i32 {
                            let Some(v0) = nb.get(lx, ly, lz) else {
                                continue;
                            };
                            if !observed(&v0, min_w) {
                                continue;
                            }
                            for axis in 0..3 {
                                let mut n = [lx, ly, lz];
                                n[axis] += 1;
                                let Some(v1) = nb.get(n[0], n[1], n[2]) else {
                                    continue;
                                };
                                if !observed(&v1, min_w) || (v0.tsdf < 0.0) == (v1.tsdf < 0.0) {
                                    continue;
                                }
                                let t = v0.tsdf / (v0.tsdf - v1.tsdf);
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
                                    let g0 = gradient(&nb, [lx, ly, lz], min_w);
                                    let g1 = gradient(&nb, n, min_w);
                                    let mut g = [0.0f32; 3];
                                    for i in 0..3 {
                                        g[i] = g0[i] * (1.0 - t) + g1[i] * t;
                                    }
                                    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                                    if len > 0.0 {
                                        bv.normals.push(g.map(|c| c / len));
                                    } else {
                                        // No usable gradient: the edge direction, towards F > 0.
                                        let mut e = [0.0f32; 3];
                                        e[axis] = if v1.tsdf > v0.tsdf { 1.0 } else { -1.0 };
                                        bv.normals.push(e);
                                    }
                                }
                                if opts.confidence {
                                    bv.confidence.push(v0.weight * (1.0 - t) + v1.weight * t);
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

        let tb = std::time::Instant::now(); // PROFTMP
        // Phase B: global vertex offsets.
        let mut offsets = Vec::with_capacity(per_block.len() + 1);
        let mut total = 0u32;
        for bv in &per_block {
            offsets.push(total);
            total += bv.positions.len() as u32;
        }
        offsets.push(total);

        // Phase C: triangles.
        let tab = table();
        let tri_lists: Vec<Vec<[u32; 3]>> = keys
            .par_iter()
            .map(|&key| {
                let b = unpack(key);
                let nb = Neighbourhood::new(self, b);
                let mut out = Vec::new();
                // Every edge of this block's cubes is owned by this block or one of its seven
                // positive neighbours: if none of them has a vertex, no cube here has a
                // triangle.
                let any_vertex = (0..8).any(|c| {
                    let bi = 13 + (c & 1) + 3 * ((c >> 1) & 1) + 9 * ((c >> 2) & 1);
                    let s = nb.slots[bi];
                    s != u32::MAX && !per_block[s as usize].positions.is_empty()
                });
                if !any_vertex {
                    return out;
                }
                let mut vals = [0.0f32; 8];
                for lz in 0..BLOCK_SIDE as i32 {
                    for ly in 0..BLOCK_SIDE as i32 {
                        'cube: for lx in 0..BLOCK_SIDE as i32 {
                            let mut case = 0u8;
                            for (c, off) in CORNERS.iter().enumerate() {
                                let Some(vx) = nb.get(
                                    lx + off[0] as i32,
                                    ly + off[1] as i32,
                                    lz + off[2] as i32,
                                ) else {
                                    continue 'cube;
                                };
                                if !observed(&vx, min_w) {
                                    continue 'cube;
                                }
                                vals[c] = vx.tsdf;
                                if vx.tsdf < 0.0 {
                                    case |= 1 << c;
                                }
                            }
                            if case == 0 || case == 255 {
                                continue;
                            }
                            for tri in tab.triangles(case) {
                                let mut idx = [0u32; 3];
                                for (k, &e) in tri.iter().enumerate() {
                                    let (lo, _, axis) = EDGES[e as usize];
                                    let o = CORNERS[lo as usize];
                                    let Some((slot, ek)) = nb.edge_owner(
                                        lx + o[0] as i32,
                                        ly + o[1] as i32,
                                        lz + o[2] as i32,
                                        axis as usize,
                                    ) else {
                                        continue 'cube;
                                    };
                                    let Some(r) = per_block[slot as usize].mask.rank(ek) else {
                                        continue 'cube;
                                    };
                                    idx[k] = offsets[slot as usize] + r;
                                }
                                out.push(idx);
                            }
                        }
                    }
                }
                out
            })
            .collect();

        let tc = std::time::Instant::now(); // PROFTMP
        // Phase D: keep referenced vertices only, renumbered in order.
        let mut used = vec![false; total as usize];
        for list in &tri_lists {
            for t in list {
                for &i in t {
                    used[i as usize] = true;
                }
            }
        }
        let mut remap = vec![u32::MAX; total as usize];
        let mut mesh = Mesh::default();
        let mut next = 0u32;
        let mut gi = 0usize;
        for bv in &per_block {
            for j in 0..bv.positions.len() {
                if used[gi] {
                    remap[gi] = next;
                    next += 1;
                    mesh.positions.push(bv.positions[j]);
                    if opts.normals {
                        mesh.normals.push(bv.normals[j]);
                    }
                    if opts.confidence {
                        mesh.confidence.push(bv.confidence[j]);
                    }
                }
                gi += 1;
            }
        }
        mesh.triangles.reserve(tri_lists.iter().map(Vec::len).sum());
        for list in tri_lists {
            mesh.triangles
                .extend(list.into_iter().map(|t| t.map(|i| remap[i as usize])));
        }
        let td = std::time::Instant::now(); // PROFTMP
        if std::env::var_os("PROFTMP").is_some() { eprintln!("mc A {:.1} C {:.1} D {:.1}", (tb-ta).as_secs_f64()*1e3, (tc-tb).as_secs_f64()*1e3, (td-tc).as_secs_f64()*1e3); } // PROFTMP
        mesh
    }
}

/// Central-difference gradient of F at local voxel `p` (one-sided where a neighbour is
/// unobserved), in metres per voxel (only its direction is used).
#[inline]
fn gradient(nb: &Neighbourhood<'_>, p: [i32; 3], min_w: f32) -> [f32; 3] {
    let mut g = [0.0f32; 3];
    let c = nb
        .get(p[0], p[1], p[2])
        .filter(|v| observed(v, min_w))
        .map(|v| v.tsdf);
    for axis in 0..3 {
        let mut lo = p;
        let mut hi = p;
        lo[axis] -= 1;
        hi[axis] += 1;
        let f_lo = nb
            .get(lo[0], lo[1], lo[2])
            .filter(|v| observed(v, min_w))
            .map(|v| v.tsdf);
        let f_hi = nb
            .get(hi[0], hi[1], hi[2])
            .filter(|v| observed(v, min_w))
            .map(|v| v.tsdf);
        g[axis] = match (f_lo, c, f_hi) {
            (Some(a), _, Some(b)) => 0.5 * (b - a),
            (None, Some(m), Some(b)) => b - m,
            (Some(a), Some(m), None) => m - a,
            _ => 0.0,
        };
    }
    g
}

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
        // Without a budget nothing can fail.
        self.extract_mesh_inner(opts, usize::MAX)
            .unwrap_or_default()
    }

    /// [`TsdfVolume::extract_mesh`] within a memory budget: after the per-block tables are
    /// built (a fixed cost per block) and before any mesh buffer is allocated, the volume, the
    /// tables and the mesh (vertices with their attributes, triangles twice: per-block lists and
    /// the final array) are counted against `budget_bytes`; past it the result is
    /// [`TsdfError::MeshBudget`](crate::TsdfError::MeshBudget). The mesh is the same as
    /// [`TsdfVolume::extract_mesh`]'s.
    pub fn extract_mesh_within(
        &self,
        opts: &ExtractOptions,
        budget_bytes: usize,
    ) -> crate::Result<Mesh> {
        self.extract_mesh_inner(opts, budget_bytes)
    }

    fn extract_mesh_inner(
        &self,
        opts: &ExtractOptions,
        budget_bytes: usize,
    ) -> crate::Result<Mesh> {
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

        let tab = table();
        if budget_bytes != usize::MAX {
            let triangles: usize = per_block
                .iter()
                .flat_map(|bv| bv.cubes.iter())
                .map(|&(_, case)| tab.triangles(case).len())
                .sum();
            let vertices = total as usize;
            let per_vertex =
                12 + if opts.normals { 12 } else { 0 } + if opts.confidence { 4 } else { 0 };
            let tables: usize = per_block
                .iter()
                .map(|bv| {
                    std::mem::size_of::<BlockVertices>()
                        + bv.cubes.capacity() * std::mem::size_of::<(u16, u8)>()
                        + bv.mask
                            .as_ref()
                            .map_or(0, |_| std::mem::size_of::<EdgeMask>())
                        + bv.around.as_ref().map_or(0, |_| 27 * 4)
                })
                .sum::<usize>()
                + n_blocks * (std::mem::size_of::<BlockBits>() + 1 + 4);
            let needed = self
                .memory_bytes()
                .saturating_add(tables)
                .saturating_add(vertices.saturating_mul(per_vertex))
                .saturating_add(triangles.saturating_mul(2 * 12));
            if needed > budget_bytes {
                return Err(crate::TsdfError::MeshBudget {
                    vertices,
                    triangles,
                    needed_bytes: needed,
                    budget_bytes,
                });
            }
        }

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
        Ok(mesh)
    }
}

mod grid;
mod triangles;
mod vertices;

use grid::*;
use triangles::*;
use vertices::*;

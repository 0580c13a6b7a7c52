//! Indexed triangle meshes and marching-cubes extraction over the sparse blocks.

use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{Mesh, VertexScalar};

use crate::error::{Result, TsdfError};
use crate::io::CONFIDENCE_PROPERTY;
use crate::par::run_on_threads;

use crate::hash::unpack;
use crate::mc_table::{CORNERS, EDGES, McTable, table};
use crate::volume::{BLOCK_SIDE, BLOCK_VOXELS, Block, TsdfVolume, local_index};

/// Configuration of [`TsdfVolume::extract_mesh`].
///
/// `#[non_exhaustive]`: start from [`MeshConfig::default`] and assign the fields you need.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct MeshConfig {
    /// Cubes with a corner whose accumulated weight is below this are skipped (unobserved
    /// corners, weight 0, are always skipped). In normalised weight units: 1 = one observation
    /// at the reference depth.
    pub min_weight: f32,
    /// Compute vertex normals.
    pub normals: bool,
    /// Compute per-vertex confidence (the mesh's scalar named
    /// [`crate::CONFIDENCE_PROPERTY`]).
    pub confidence: bool,
}

/// The former name of [`MeshConfig`].
#[deprecated(
    since = "0.1.0",
    note = "renamed `MeshConfig` (every configuration is a `…Config`)"
)]
pub type ExtractOptions = MeshConfig;

impl MeshConfig {
    /// Checks the parameters: `min_weight` must be a finite, non-negative number.
    pub fn validate(&self) -> Result<()> {
        if !(self.min_weight.is_finite() && self.min_weight >= 0.0) {
            return Err(TsdfError::InvalidParameter(format!(
                "min_weight = {} must be a finite, non-negative weight",
                sl_core::Compact(f64::from(self.min_weight))
            )));
        }
        Ok(())
    }
}

impl Default for MeshConfig {
    fn default() -> Self {
        Self {
            min_weight: 0.0,
            normals: true,
            confidence: true,
        }
    }
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
    pub fn extract_mesh(&self, opts: &MeshConfig) -> Mesh {
        // Without a budget nothing can fail.
        self.extract_mesh_inner(opts, usize::MAX)
            .unwrap_or_default()
    }

    /// [`TsdfVolume::extract_mesh`] within a memory budget: after the per-block tables are
    /// built (a fixed cost per block) and before any mesh buffer is allocated, the volume, the
    /// tables and the mesh (vertices with their attributes, and room for the table's triangles of
    /// every cube, written in place) are counted against `budget_bytes`; past it the result is
    /// [`crate::TsdfError::MeshBudget`]. The mesh is the same as
    /// [`TsdfVolume::extract_mesh`]'s.
    pub fn extract_mesh_within(
        &self,
        opts: &MeshConfig,
        budget_bytes: usize,
    ) -> crate::Result<Mesh> {
        self.extract_mesh_inner(opts, budget_bytes)
    }

    fn extract_mesh_inner(&self, opts: &MeshConfig, budget_bytes: usize) -> crate::Result<Mesh> {
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
        // Per block, the table's triangles of its cubes: room for its triangles (a cube whose
        // edge vertex is not kept has none).
        let tri_room: Vec<usize> = per_block
            .iter()
            .map(|bv| {
                bv.cubes
                    .iter()
                    .map(|&(_, case)| tab.triangles(case).len())
                    .sum()
            })
            .collect();
        let triangles: usize = tri_room.iter().sum();
        if budget_bytes != usize::MAX {
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
                .saturating_add(triangles.saturating_mul(12));
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
            positions: bytemuck::zeroed_vec::<Point3<f32>>(n),
            normals: if opts.normals {
                bytemuck::zeroed_vec::<Vector3<f32>>(n)
            } else {
                Vec::new()
            },
            triangles: Vec::new(),
            scalar: opts.confidence.then(|| VertexScalar {
                name: CONFIDENCE_PROPERTY.to_owned(),
                values: vec![0.0; n],
            }),
        };
        let lens = || per_block.iter().map(|bv| bv.count as usize);
        let pos = split_chunks(&mut mesh.positions, lens());
        let mut nrm = split_chunks(&mut mesh.normals, lens());
        let mut no_confidence = Vec::new();
        let confidence = match mesh.scalar.as_mut() {
            Some(s) => &mut s.values,
            None => &mut no_confidence,
        };
        let mut conf = split_chunks(confidence, lens());
        nrm.resize_with(per_block.len(), || &mut []);
        conf.resize_with(per_block.len(), || &mut []);
        // Each block writes its triangles into its room of one array, which is then compacted
        // in place (no second copy of the triangles).
        let mut all_tris = vec![[0u32; 3]; triangles];
        let rooms = split_chunks(&mut all_tris, tri_room.iter().copied());
        let mut outs = pos.into_iter().zip(nrm).zip(conf).zip(rooms).enumerate();
        let mut items = Vec::new();
        loop {
            let chunk: Vec<_> = outs.by_ref().take(CHUNK).collect();
            if chunk.is_empty() {
                break;
            }
            items.push(chunk);
        }
        let written: Vec<Vec<usize>> = run_on_threads(
            items,
            || (BlockGrid::new(), EdgeWindow::new()),
            |(grid, win), chunk| {
                let mut counts = Vec::with_capacity(chunk.len());
                for (slot, (((p, nr), cf), room)) in chunk {
                    let bv = &per_block[slot];
                    block_vertex_data(&mc, grid, slot, bv, p, nr, cf);
                    counts.push(block_triangles(bv, &per_block, &offsets, tab, win, room));
                }
                counts
            },
        );
        // Blocks in order: each block's triangles move down to follow the ones before.
        let (mut from, mut to) = (0, 0);
        for (room, n) in tri_room.iter().zip(written.iter().flatten()) {
            all_tris.copy_within(from..from + n, to);
            from += room;
            to += n;
        }
        all_tris.truncate(to);
        mesh.triangles = all_tris;
        Ok(mesh)
    }
}

mod grid;
mod triangles;
mod vertices;

use grid::*;
use triangles::*;
use vertices::*;

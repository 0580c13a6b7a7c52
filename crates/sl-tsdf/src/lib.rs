//! # sl-tsdf — noise-weighted volumetric scan merging
//!
//! The paper's section 3.3: every registered depth frame becomes a truncated signed distance
//! function `fᵢ` (the distance along the line of sight from a voxel to the observed surface,
//! positive in front of it, clipped to `[−trunc, trunc]`), and the frames are merged by the
//! weighted running average `F = Σ wᵢ fᵢ / Σ wᵢ` (Curless & Levoy) with the paper's
//! structured-light weight `wᵢ = 1/Zᵢ⁴` — the inverse of the depth variance, since
//! `σ_Z ∝ Z²` — so that a close, precise scan is not blurred by a distant, noisy one. The zero
//! level set of `F` is extracted with marching cubes using a Montani-style disambiguated table
//! (no cracks).
//!
//! Pipeline position: depth frames → `sl-io` → `sl-core` types → (`sl-filter`) → **`sl-tsdf`**
//! → mesh (PLY via `sl-io`). The `sldepth fuse` command drives it.
//!
//! * [`TsdfVolume`]: sparse storage — a hash map of 8³ voxel blocks allocated only within the
//!   truncation band of observed pixels (memory grows with surface area), a memory budget that
//!   fails cleanly ([`TsdfError::MemoryBudget`]), and parallel integration per block (on as
//!   many threads as rayon's pool has, `RAYON_NUM_THREADS`).
//! * [`WeightMode`]: `inv-z4` (default), `uniform`, `inv-z2`, and the sensor-model variance;
//!   weights are normalised at a reference depth so the f32 arithmetic stays O(1)
//!   (see [`TsdfConfig`]).
//! * [`TsdfVolume::extract_mesh`]: marching cubes across block borders, indexed mesh with shared
//!   vertices, normals from the TSDF gradient and per-vertex confidence ([`Mesh`]).
//! * [`TsdfVolume::raycast`] ([`RaycastConfig`], [`Raycast`]): the fused surface seen from a
//!   pose — depth, world points, normals from the trilinear gradient and fused weights of the
//!   first front-facing zero crossing of every pixel's ray, rows in parallel;
//!   [`TsdfVolume::raycast_into`] reuses the buffers of a tracking loop.
//! * [`TsdfVolume::slice`]: cross-sections of `F` with the zero crossing (the paper's Fig. 7).
//! * [`io`]: PLY meshes and PNG images through `sl-io`. (A software mesh renderer and
//!   mesh-accuracy statistics for reports are evaluation tools: they live in `sl-eval`.)
//!
//! ## Numerics of the 1/Z⁴ average
//!
//! Each voxel stores the running mean `F` (metres, f32) and the accumulated weight `W`, and is
//! updated as `W' = W + w`, `F' = F + (f − F)·w/W'` — the incremental form of eq. 12, which
//! never forms the large sums `Σ w f` and stays exact for a single observation. Weights are
//! divided by the weight at a reference depth `z_ref` (1 m), so `w = (1 m / Z)⁴` is 16 at
//! 0.5 m and 1/256 at 4 m instead of 16 and 0.004 in m⁻⁴ — or 10⁻¹² in mm⁻⁴, where f32 would
//! lose it; the constant factor cancels in `F` (the paper's remark after eq. 13). `W` is capped
//! at [`TsdfConfig::max_weight`] (10⁶): below the cap `F` is the exact weighted mean, above it
//! `F` becomes a moving average, and the cap keeps `w/W'` of any observation weighing more
//! than 10⁻⁶ above the f32 resolution (2⁻²⁴ ≈ 6·10⁻⁸), so late observations still move `F`.
//!
//! ## Memory
//!
//! A block is 8³ voxels of 8 bytes (4 KiB) plus its key and its worst-case share of the hash
//! index ([`volume::BYTES_PER_BLOCK`]). Before allocating the blocks a frame needs, the volume
//! checks `blocks × BYTES_PER_BLOCK` against [`TsdfConfig::memory_budget_bytes`] and fails with
//! [`TsdfError::MemoryBudget`] (volume unchanged) if it would be exceeded; the allocations
//! themselves use `try_reserve`, so an allocator failure is [`TsdfError::OutOfMemory`], never
//! an abort. The blocks live in one arena (a vector indexed through the hash map) that grows
//! geometrically but never beyond the number of blocks the budget allows, so its capacity
//! stays within the budget: [`TsdfVolume::memory_bytes`] never exceeds it (a reallocation may
//! briefly hold the old and the new storage while it moves). Per-frame scratch space (the
//! per-pixel depth table, 2 MiB for 640×480) is not counted.
//!
//! ```
//! use sl_core::{Camera, CameraToWorld};
//! use sl_core::nalgebra::{Point3, Vector3};
//! use sl_noise::sim::{Plane, Scene};
//! use sl_tsdf::{MeshConfig, TsdfConfig, TsdfVolume};
//!
//! // A wall 1 m in front of a small camera looking along +Z (exact depth from the ray caster
//! // of `sl-noise`'s simulator).
//! let k = Camera::kinect_v1().intrinsics.scaled(0.25)?;
//! let mut scene = Scene::new();
//! scene.add(Plane::from_normal_offset(Vector3::z(), 1.0)?);
//! let pose = CameraToWorld::identity();
//! let depth = scene.render(&k, &pose).depth;
//!
//! let mut params = TsdfConfig::default();
//! params.voxel_m = 0.02;
//! params.trunc_m = 0.06;
//! let mut volume = TsdfVolume::new(params)?;
//! volume.integrate(&depth, &k, &pose)?;
//! // In front of the wall F is positive, behind it negative.
//! assert!(volume.sample(&Point3::new(0.0, 0.0, 0.97)).unwrap() > 0.0);
//! assert!(volume.sample(&Point3::new(0.0, 0.0, 1.03)).unwrap() < 0.0);
//!
//! let mesh = volume.extract_mesh(&MeshConfig::default());
//! assert!(mesh.triangle_count() > 0);
//! assert!(mesh.positions.iter().all(|p| (p[2] - 1.0).abs() < 1e-3));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod error;
mod hash;
pub mod io;
mod mc_table;
pub mod mesh;
mod par;
pub mod params;
pub mod raycast;
pub mod slice;
pub mod volume;

pub use error::{Result, TsdfError};
pub use io::CONFIDENCE_PROPERTY;
#[allow(deprecated)]
pub use mesh::{ExtractOptions, MeshConfig};
#[allow(deprecated)]
pub use params::{DepthLookup, Truncation, TsdfConfig, TsdfParams, WeightMode};
pub use raycast::{Raycast, RaycastConfig};
/// The mesh type [`TsdfVolume::extract_mesh`] returns (sl-core's, re-exported).
pub use sl_core::{Mesh, Topology};
pub use slice::{Axis, Slice, SliceSpec};
pub use volume::{BLOCK_SIDE, Block, IntegrateStats, TsdfVolume, Voxel};

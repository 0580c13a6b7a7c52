//! One ray per pixel: jump over unallocated blocks, step by a fraction of the sampled distance
//! through observed space (finer near the surface and through unobserved voxels), bracket the
//! first + → − sign change, refine it, and read weight and normal there.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use sl_core::Intrinsics;

use super::RaycastConfig;
use super::occupancy::{Occupancy, SUPER_SHIFT};
use super::sampler::{Sampler, floor_i32, frac};
use crate::error::{Result, TsdfError};
use crate::volume::{BLOCK_SIDE, TsdfVolume};

/// The first front-facing zero crossing along a pixel's ray.
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    /// Camera-frame depth, metres.
    pub(super) z_m: f32,
    /// World point, metres.
    pub(super) point: Point3<f32>,
    /// World unit normal.
    pub(super) normal: Vector3<f32>,
    /// Interpolated fused weight.
    pub(super) weight: f32,
}

/// Per-frame constants of the rays (f32: grid coordinates stay far below 2^24 voxels).
#[derive(Debug, Clone, Copy)]
pub(super) struct RayFrame {
    /// Camera-to-world rotation.
    rot: Matrix3<f32>,
    /// World-to-camera rotation and translation.
    rot_t: Matrix3<f32>,
    trans_t: Vector3<f32>,
    /// Camera centre, world metres and grid units.
    centre: Vector3<f32>,
    centre_g: Vector3<f32>,
    inv_voxel: f32,
    pub(super) voxel_m: f32,
    /// Intrinsics and the depth range, shared with the tile ranges (`range::BlockView`).
    pub(super) fx: f32,
    pub(super) fy: f32,
    pub(super) cx: f32,
    pub(super) cy: f32,
    pub(super) min_z: f32,
    pub(super) max_z: f32,
    step_fraction: f32,
    min_step_m: f32,
    refine: usize,
}

impl RayFrame {
    pub(super) fn new(
        vol: &TsdfVolume,
        pose: &Isometry3<f64>,
        k: &Intrinsics,
        config: &RaycastConfig,
    ) -> Result<Self> {
        let v = vol.params().voxel_m;
        let centre = pose.translation.vector;
        // Beyond ±2^20 blocks nothing is allocated; keep the grid coordinates of the rays
        // well inside f32's exact range.
        let lim = f64::from(crate::hash::MAX_BLOCK_COORD) * (BLOCK_SIDE as f64) * v;
        if centre.iter().any(|c| c.abs() > lim) {
            return Err(TsdfError::OutOfRange(format!(
                "raycast camera position {centre:?} m"
            )));
        }
        let inv = pose.inverse();
        Ok(Self {
            rot: pose
                .rotation
                .to_rotation_matrix()
                .into_inner()
                .cast::<f32>(),
            rot_t: inv.rotation.to_rotation_matrix().into_inner().cast::<f32>(),
            trans_t: inv.translation.vector.cast::<f32>(),
            centre: centre.cast::<f32>(),
            centre_g: (centre / v).cast::<f32>(),
            inv_voxel: (1.0 / v) as f32,
            voxel_m: v as f32,
            fx: k.fx as f32,
            fy: k.fy as f32,
            cx: k.cx as f32,
            cy: k.cy as f32,
            min_z: config.min_depth_m as f32,
            max_z: config.max_depth_m as f32,
            step_fraction: config.step_fraction as f32,
            min_step_m: (config.min_step_voxels * v) as f32,
            refine: config.refine_iterations,
        })
    }

    /// A world point in camera coordinates.
    #[inline(always)]
    pub(super) fn world_to_camera(&self, p: &Point3<f32>) -> Vector3<f32> {
        self.rot_t * p.coords + self.trans_t
    }

    /// Marches the ray of pixel `(x, y)` through camera depths `[lo, hi]` (clipped to the
    /// configured range) and returns its first front-facing zero crossing; `occ` lets it cross
    /// empty super-blocks in one step. `hinted`: `lo` is a hinted start, and the ray gives up
    /// (`None`) when its first observed sample is not in front of a surface (the hint started
    /// it behind one; the caller marches it again from the near end).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn cast(
        &self,
        s: &mut Sampler<'_>,
        occ: &Occupancy,
        x: usize,
        y: usize,
        lo: f32,
        hi: f32,
        hinted: bool,
    ) -> Option<Hit> {
        let dir = self.rot
            * Vector3::new(
                (x as f32 - self.cx) / self.fx,
                (y as f32 - self.cy) / self.fy,
                1.0,
            );
        let len = dir.norm();
        // Grid units per metre of camera depth.
        let d = dir * self.inv_voxel;
        let at = |t: f32| -> [f32; 3] {
            [
                self.centre_g.x + d.x * t,
                self.centre_g.y + d.y * t,
                self.centre_g.z + d.z * t,
            ]
        };
        let end = hi.min(self.max_z);
        let mut t = lo.max(self.min_z);
        // Depth increments: the shortest step, and how a step in metres along the ray maps to
        // camera depth.
        let min_dt = self.min_step_m / len;
        let inv_len = 1.0 / len;
        // Through unobserved voxels of an allocated block: one voxel per step (a sample needs
        // all 8 voxels of its cell observed, so no observed region is thinner than that).
        let voxel_dt = self.voxel_m / len;
        // Nearest-voxel values above this (√3 voxels: the largest distance from a point to its
        // nearest voxel is √3/2 voxel, and |∇F| ≤ 1) are certainly in front of the surface.
        let coarse_f = self.voxel_m * 1.75;
        // The last observed sample `(t, F)`; `fine`: stepping back from a positive sample
        // whose long step landed in unobserved voxels, one shortest step at a time.
        let mut prev: Option<(f32, f32)> = None;
        let mut fine = false;
        let mut hinted = hinted;
        let exit = BlockExit::new(&d, BLOCK_SIDE as f32);
        let super_exit = BlockExit::new(&d, (BLOCK_SIDE << SUPER_SHIFT) as f32);
        while t <= end {
            let g = at(t);
            if !g.iter().all(|c| c.is_finite() && c.abs() < 1.0e9) {
                return None;
            }
            let base = g.map(floor_i32);
            let b = base.map(|c| c >> 3);
            let Some(blk) = s.block(b) else {
                // No sample whose base voxel is in this block is observed: jump to its exit,
                // or to the exit of its super-block when no block of that is allocated.
                let sb = b.map(|c| c >> SUPER_SHIFT);
                t = if occ.maybe_occupied(sb) {
                    exit.next(g, b, t, min_dt)
                } else {
                    super_exit.next(g, sb, t, min_dt)
                };
                prev = None;
                fine = false;
                continue;
            };
            let ft = frac(g, base);
            // Far in front of the surface (the nearest voxel's F above `coarse_f`, so the
            // trilinear F is positive too: it differs by less than one voxel diagonal) one voxel
            // read decides the step; near the surface, behind it, or where the nearest voxel is
            // unobserved, the trilinear cell.
            let sample = match s.nearest_at(base, ft, b, blk) {
                // The nearest voxel is a corner of the cell: where it is unallocated or
                // unobserved, so is the cell.
                None => None,
                Some((_, w)) if w <= 0.0 => None,
                Some((f, _)) if f > coarse_f => Some(f),
                Some(_) => s.cell_at(base, ft).map(|c| c.value()),
            };
            match sample {
                None => {
                    if let Some((tp, fp)) = prev
                        && fp > 0.0
                        && !fine
                        && t - tp > 1.5 * min_dt
                    {
                        // The step may have jumped over the surface into its unobserved
                        // shadow: retry from the last observed sample with short steps.
                        t = tp + min_dt;
                        fine = true;
                        continue;
                    }
                    prev = None;
                    t += voxel_dt;
                }
                Some(f) => {
                    if f <= 0.0 && hinted {
                        return None;
                    }
                    if let Some((tp, fp)) = prev
                        && fp > 0.0
                        && f <= 0.0
                    {
                        // The last positive sample may be a coarse one: bracket with its
                        // trilinear value where that is observed (and positive, as it must be).
                        let fp = s.value(at(tp)).filter(|v| *v > 0.0).unwrap_or(fp);
                        return self.hit(s, &at, (tp, fp), (t, f), &dir);
                    }
                    prev = Some((t, f));
                    hinted = false;
                    fine = false;
                    let step_m = (self.step_fraction * f.abs()).max(self.min_step_m);
                    t += step_m * inv_len;
                }
            }
        }
        None
    }

    /// Refines the crossing bracketed by `(t0, f0 > 0)` and `(t1, f1 ≤ 0)` and reads the hit.
    fn hit(
        &self,
        s: &mut Sampler<'_>,
        at: &impl Fn(f32) -> [f32; 3],
        (mut ta, mut fa): (f32, f32),
        (mut tb, mut fb): (f32, f32),
        dir: &Vector3<f32>,
    ) -> Option<Hit> {
        let mut t = ta + (tb - ta) * fa / (fa - fb);
        for _ in 0..self.refine {
            let Some(ft) = s.value(at(t)) else { break };
            if ft > 0.0 {
                (ta, fa) = (t, ft);
            } else {
                (tb, fb) = (t, ft);
            }
            if fa - fb <= 0.0 {
                break;
            }
            t = ta + (tb - ta) * fa / (fa - fb);
        }
        let g = at(t);
        // The bracket's ends are observed; the point between them may straddle a cell with an
        // unobserved corner: then read the cell of the nearer end.
        let cell = match s.cell(g) {
            Some(c) => c,
            None => {
                let te = if t - ta < tb - t { ta } else { tb };
                s.cell(at(te))?
            }
        };
        let grad = cell.gradient();
        let gv = Vector3::new(grad[0], grad[1], grad[2]);
        let norm = gv.norm();
        let normal = if norm.is_finite() && norm > 0.0 {
            gv / norm
        } else {
            -dir.normalize()
        };
        Some(Hit {
            z_m: t,
            point: Point3::from(self.centre + dir * t),
            normal,
            weight: cell.weight(),
        })
    }
}

/// Where a ray leaves a block (or a super-block): the per-ray choices of the exit face done
/// once (the division stays per step: a reciprocal multiply would move the samples by
/// round-off and change the output).
struct BlockExit {
    /// The ray's direction, grid units per metre of depth.
    d: [f32; 3],
    /// The box's side, voxels.
    side: f32,
    /// The exit plane's offset from the box's low corner per axis: `side` where `d > 0`, else
    /// 0.
    off: [f32; 3],
}

impl BlockExit {
    fn new(d: &Vector3<f32>, side: f32) -> Self {
        Self {
            d: [d.x, d.y, d.z],
            side,
            off: [0, 1, 2].map(|a| if d[a] > 0.0 { side } else { 0.0 }),
        }
    }

    /// Camera depth just past the exit of the ray at depth `t` (grid point `g`) from the
    /// region of box `b` (the points whose base voxel lies in it, `[side·b, side·b + side)` in
    /// grid units).
    #[inline]
    fn next(&self, g: [f32; 3], b: [i32; 3], t: f32, min_dt: f32) -> f32 {
        let mut dt = f32::INFINITY;
        for a in 0..3 {
            if self.d[a] != 0.0 {
                let ta = (b[a] as f32 * self.side + self.off[a] - g[a]) / self.d[a];
                dt = dt.min(ta.max(0.0));
            }
        }
        t + dt + 0.01 * min_dt
    }
}

//! One ray per pixel: jump over unallocated blocks, step by a fraction of the sampled distance
//! through observed space (finer near the surface and through unobserved voxels), bracket the
//! first + → − sign change, refine it, and read weight and normal there. A march is a [`Ray`]
//! advanced a step at a time, so that the raycast can march several rays in turn: a step reads
//! a voxel of a large volume, mostly a cache miss, and the rays' reads then overlap.

use nalgebra::{Isometry3, Matrix3, Point3, Vector3};
use sl_core::Intrinsics;

use super::RaycastConfig;
use super::occupancy::{Occupancy, SUPER_SHIFT};
use super::sampler::{Sampler, base_voxel, frac};
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
    /// Nearest-voxel values above this (√3 voxels: the largest distance from a point to its
    /// nearest voxel is √3/2 voxel, and |∇F| ≤ 1) are certainly in front of the surface.
    coarse_f: f32,
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
            coarse_f: v as f32 * 1.75,
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
    /// it behind one; the caller marches it again from the near end). The raycast marches
    /// several rays together ([`RayFrame::ray`], [`RayFrame::advance`]); this is one alone, for
    /// the tests that compare the two.
    #[cfg(test)]
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
        self.cast_ray(s, occ, self.ray(x, y, lo, hi, hinted))
    }

    /// [`RayFrame::cast`] of a ray already made ([`RayFrame::ray`], [`RayFrame::hinted_ray`]).
    #[cfg(test)]
    pub(super) fn cast_ray(
        &self,
        s: &mut Sampler<'_>,
        occ: &Occupancy,
        mut ray: Ray,
    ) -> Option<Hit> {
        loop {
            if let Some(done) = self.advance(s, occ, &mut ray) {
                return done;
            }
        }
    }

    /// The march of pixel `(x, y)`'s ray through `[lo, hi]`, before its first step (see
    /// `RayFrame::cast`; `RayFrame::advance` takes the steps).
    pub(super) fn ray(&self, x: usize, y: usize, lo: f32, hi: f32, hinted: bool) -> Ray {
        let dir = self.rot
            * Vector3::new(
                (x as f32 - self.cx) / self.fx,
                (y as f32 - self.cy) / self.fy,
                1.0,
            );
        let len = dir.norm();
        // Grid units per metre of camera depth.
        let d = dir * self.inv_voxel;
        Ray {
            dir,
            d,
            end: hi.min(self.max_z),
            t: lo.max(self.min_z),
            // Depth increments: the shortest step, and how a step in metres along the ray maps
            // to camera depth.
            min_dt: self.min_step_m / len,
            inv_len: 1.0 / len,
            // Through unobserved voxels of an allocated block: one voxel per step (a sample
            // needs all 8 voxels of its cell observed, so no observed region is thinner than
            // that).
            voxel_dt: self.voxel_m / len,
            prev: None,
            fine: false,
            hinted,
            from_hint: hinted,
            probe: None,
            exit: BlockExit::new(&d, BLOCK_SIDE as f32),
            super_exit: BlockExit::new(&d, (BLOCK_SIDE << SUPER_SHIFT) as f32),
        }
    }

    /// A hinted ray of pixel `(x, y)` (see [`RayFrame::ray`] with `hinted`): its first sample
    /// is at the hint `z` itself, where the frame just fused saw the surface. In front of the
    /// fused surface there (`F > 0`), the march goes on from it; behind it (`F ≤ 0`), one
    /// sample `|F|` plus the shortest step nearer brackets the crossing (`F > 0` there) and the
    /// crossing is refined at once. Otherwise (that sample unobserved or also behind, or the
    /// hint's own sample unobserved) the ray marches from `lo`, the start before the hint, as a
    /// hinted ray does. Two or three samples instead of the five or six a march from `lo`
    /// through the truncation band takes; what is found is the same crossing (bit-for-bit
    /// equal results are not promised: the bracket differs).
    pub(super) fn hinted_ray(&self, x: usize, y: usize, z: f32, lo: f32, hi: f32) -> Ray {
        let mut ray = self.ray(x, y, lo, hi, true);
        if z > ray.t && z <= ray.end {
            ray.probe = Some(ray.t);
            ray.t = z;
        }
        ray
    }

    /// The first sample of a hinted ray, at the hint (see [`RayFrame::hinted_ray`]); `lo` is
    /// the start before the hint.
    fn probe_hint(&self, s: &mut Sampler<'_>, ray: &mut Ray, lo: f32) -> Option<Option<Hit>> {
        let t = ray.t;
        match s.value(self.at(ray, t)) {
            Some(f) if f > 0.0 => {
                self.step_on(ray, t, f);
                None
            }
            Some(f) => {
                let tn = t - (-f + self.min_step_m) * ray.inv_len;
                if tn > lo
                    && let Some(fnear) = s.value(self.at(ray, tn)).filter(|v| *v > 0.0)
                {
                    let r = &*ray;
                    let at = |t: f32| self.at(r, t);
                    return Some(self.hit(s, &at, (tn, fnear), (t, f), &r.dir));
                }
                ray.t = lo;
                None
            }
            None => {
                ray.t = lo;
                None
            }
        }
    }

    /// The grid point of `ray` at camera depth `t`.
    #[inline(always)]
    fn at(&self, ray: &Ray, t: f32) -> [f32; 3] {
        [
            self.centre_g.x + ray.d.x * t,
            self.centre_g.y + ray.d.y * t,
            self.centre_g.z + ray.d.z * t,
        ]
    }

    /// One step of `ray`'s march: `None` while it goes on, else its outcome (the hit, or
    /// `None` when it ends without one or gives up). Several rays marched a step each in turn
    /// compute exactly what each marched alone computes; their memory reads overlap.
    #[inline]
    pub(super) fn advance(
        &self,
        s: &mut Sampler<'_>,
        occ: &Occupancy,
        ray: &mut Ray,
    ) -> Option<Option<Hit>> {
        if let Some(lo) = ray.probe.take() {
            return self.probe_hint(s, ray, lo);
        }
        let t = ray.t;
        if t > ray.end {
            return Some(None);
        }
        let g = self.at(ray, t);
        let Some(base) = base_voxel(g) else {
            return Some(None);
        };
        let b = base.map(|c| c >> 3);
        let Some(blk) = s.block(b) else {
            // No sample whose base voxel is in this block is observed: jump to its exit, or to
            // the exit of its super-block when no block of that is allocated.
            let sb = b.map(|c| c >> SUPER_SHIFT);
            ray.t = if occ.maybe_occupied(sb) {
                ray.exit.next(g, b, t, ray.min_dt)
            } else {
                ray.super_exit.next(g, sb, t, ray.min_dt)
            };
            ray.prev = None;
            ray.fine = false;
            return None;
        };
        let ft = frac(g, base);
        // Far in front of the surface (the nearest voxel's F above `coarse_f`, so the trilinear
        // F is positive too: it differs by less than one voxel diagonal) one voxel read decides
        // the step; near the surface, behind it, or where the nearest voxel is unobserved, the
        // trilinear cell.
        let sample = match s.nearest_at(base, ft, b, blk) {
            // The nearest voxel is a corner of the cell: where it is unallocated or unobserved,
            // so is the cell.
            None => None,
            Some((_, w)) if w <= 0.0 => None,
            Some((f, _)) if f > self.coarse_f => Some(f),
            Some(_) => s.cell_at(base, ft).map(|c| c.value()),
        };
        match sample {
            None => {
                if let Some((tp, fp)) = ray.prev
                    && fp > 0.0
                    && !ray.fine
                    && t - tp > 1.5 * ray.min_dt
                {
                    // The step may have jumped over the surface into its unobserved shadow:
                    // retry from the last observed sample with short steps.
                    ray.t = tp + ray.min_dt;
                    ray.fine = true;
                    return None;
                }
                ray.prev = None;
                ray.t = t + ray.voxel_dt;
            }
            Some(f) => {
                if f <= 0.0 && ray.hinted {
                    return Some(None);
                }
                if let Some((tp, fp)) = ray.prev
                    && fp > 0.0
                    && f <= 0.0
                {
                    // The last positive sample may be a coarse one: bracket with its trilinear
                    // value where that is observed (and positive, as it must be).
                    let fp = s.value(self.at(ray, tp)).filter(|v| *v > 0.0).unwrap_or(fp);
                    let at = |t: f32| self.at(ray, t);
                    return Some(self.hit(s, &at, (tp, fp), (t, f), &ray.dir));
                }
                self.step_on(ray, t, f);
            }
        }
        None
    }

    /// After an observed sample `f` at depth `t` that is not a crossing: remember it and step
    /// on by a fraction of its distance (at least the shortest step).
    #[inline(always)]
    fn step_on(&self, ray: &mut Ray, t: f32, f: f32) {
        ray.prev = Some((t, f));
        ray.hinted = false;
        ray.fine = false;
        let step_m = (self.step_fraction * f.abs()).max(self.min_step_m);
        ray.t = t + step_m * ray.inv_len;
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

/// One ray's march in progress ([`RayFrame::ray`], [`RayFrame::advance`]).
pub(super) struct Ray {
    /// World direction per metre of camera depth, and the same in grid units.
    dir: Vector3<f32>,
    d: Vector3<f32>,
    /// The last camera depth marched, and the next one.
    end: f32,
    t: f32,
    min_dt: f32,
    inv_len: f32,
    voxel_dt: f32,
    /// The last observed sample `(t, F)`; `fine`: stepping back from a positive sample whose
    /// long step landed in unobserved voxels, one shortest step at a time.
    prev: Option<(f32, f32)>,
    fine: bool,
    /// Whether the march may still give up (it started at a hint and has seen no observed
    /// sample yet), and whether it started at a hint.
    hinted: bool,
    from_hint: bool,
    /// Set while a hinted ray's first sample, at the hint itself (`t`), is pending (see
    /// [`RayFrame::hinted_ray`]): the start before the hint that the ray marches from when
    /// that sample does not settle where the surface is.
    probe: Option<f32>,
    exit: BlockExit,
    super_exit: BlockExit,
}

impl Ray {
    /// Whether the march started at a hint (its failure calls for a march from the near end).
    pub(super) fn is_hinted_start(&self) -> bool {
        self.from_hint
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

//! One Gauss–Newton iteration of noise-weighted point-to-plane ICP: projective association of
//! a pyramid level's points with the reference maps, the 6×6 normal equations summed per row in
//! parallel (rayon, no allocation per pixel), and the SE(3) update.

use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, SymmetricEigen, Translation3, UnitQuaternion, Vector3,
    Vector6,
};
use rayon::prelude::*;
use sl_core::{IsaKernel, SensorModel};

use super::associate::{PassConsts, RowSums, row_sums, row_sums_with};
use super::pyramid::{Level, PointAux};
use super::reference::ReferenceMaps;
use super::{TrackerConfig, WeightMode};
use crate::rolling_shutter::{motion_power, row_offset};

/// Sums of one association pass: the upper triangle of `H = Σ w·J·Jᵀ`, `g = Σ w·J·r`, and counts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sums {
    h: [f64; 21],
    g: [f64; 6],
    /// Points of the level with a valid normal.
    pub valid: f64,
    /// Points that land on a reference pixel with a surface (the overlap).
    pub associated: f64,
    /// Points associated and within the gates.
    pub inliers: f64,
    /// Σ of squared normalised residuals `(r/σ)²` of the inliers.
    pub chi2: f64,
    /// Σ of squared metric residuals of the inliers, m².
    pub r2_m2: f64,
    /// Σ over the associated points of the truncated Huber loss of `r/σ`: an inlier's
    /// `ρ(r/σ)` capped at `ρ(gate_sigmas)`, an associated point outside the gates the cap (see
    /// [`Prior::cost`]).
    pub loss: f64,
}

impl Sums {
    /// The robust objective over every valid point of the level: the truncated Huber loss of
    /// the associated points ([`Sums::loss`]) plus the cap for each point that lands on no
    /// surface of the reference. Lower is better; alignments of one frame to one reference
    /// from different starts compare by it (they share the valid points).
    pub(crate) fn total_loss(&self, gate_sigmas: f64, huber_k: f64) -> f64 {
        self.loss + huber_loss(gate_sigmas, huber_k) * (self.valid - self.associated).max(0.0)
    }

    pub(crate) fn zero() -> Self {
        Self {
            h: [0.0; 21],
            g: [0.0; 6],
            valid: 0.0,
            associated: 0.0,
            inliers: 0.0,
            chi2: 0.0,
            r2_m2: 0.0,
            loss: 0.0,
        }
    }

    fn add(mut self, o: &Self) -> Self {
        for (a, b) in self.h.iter_mut().zip(&o.h) {
            *a += b;
        }
        for (a, b) in self.g.iter_mut().zip(&o.g) {
            *a += b;
        }
        self.valid += o.valid;
        self.associated += o.associated;
        self.inliers += o.inliers;
        self.chi2 += o.chi2;
        self.r2_m2 += o.r2_m2;
        self.loss += o.loss;
        self
    }

    /// The normal-equation matrix.
    pub fn hessian(&self) -> Matrix6<f64> {
        let mut m = Matrix6::zeros();
        let mut k = 0;
        for a in 0..6 {
            for b in a..6 {
                m[(a, b)] = self.h[k];
                m[(b, a)] = self.h[k];
                k += 1;
            }
        }
        m
    }

    /// The gradient vector.
    pub fn gradient(&self) -> Vector6<f64> {
        Vector6::from_column_slice(&self.g)
    }
}

impl Sums {
    /// Adds a row's partial sums; `cap` is the loss of an associated point outside the gates.
    fn add_row(&mut self, r: &RowSums, cap: f64) {
        for (a, b) in self.h.iter_mut().zip(&r.h) {
            *a += f64::from(*b);
        }
        for (a, b) in self.g.iter_mut().zip(&r.g) {
            *a += f64::from(*b);
        }
        self.valid += f64::from(r.valid);
        self.associated += f64::from(r.associated);
        self.inliers += f64::from(r.inliers);
        self.chi2 += f64::from(r.chi2);
        self.r2_m2 += f64::from(r.r2_m2);
        self.loss += f64::from(r.associated) * cap + f64::from(r.loss_below_cap);
    }
}

/// Gates and weighting of one pass.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PassParams {
    /// Residuals within `gate_sigmas·σ + allowance_m` are inliers.
    pub allowance_m: f32,
    /// Cosine of the largest angle between the frame's and the reference's normals.
    pub min_cos: f32,
    /// Every `stride`-th point of every `stride`-th row is used (1 = all).
    pub stride: usize,
    /// The rows' exposure times of a rolling-shutter frame (`None`: one pose for all rows).
    pub timing: Option<RowTiming>,
}

/// Associates the level's points (camera frame) under the pose `pose` (camera to world, about
/// the centre `centre`: the Jacobian is taken with respect to a rotation about it) and sums the
/// normal equations.
pub(crate) fn pass(
    level: &Level,
    reference: &ReferenceMaps,
    pose: &Isometry3<f64>,
    centre: &Vector3<f64>,
    sensor: &SensorModel,
    cfg: &TrackerConfig,
    p: PassParams,
) -> Sums {
    let Some(k) = level.intrinsics() else {
        return Sums::zero();
    };
    let w = k.width;
    let (consts, to_ref) = pass_consts(reference, pose, centre, sensor, cfg, p);
    let rows = p.timing.map(|t| RowPoses::new(&t, pose, &to_ref, k.height));
    let stride = p.stride.max(1);
    let cap = huber_loss(cfg.gate_sigmas, cfg.huber_k);
    // Fixed blocks of rows, each summed in order, and the blocks' sums added in order: the
    // result does not depend on how rayon splits the work, so a sequence tracks identically
    // for any thread count and on every run (a `fold`/`reduce` splits where work is stolen).
    let block = w.max(1) * ROWS_PER_BLOCK;
    let blocks: Vec<Sums> = level
        .points
        .par_chunks(block)
        .zip(level.normals.par_chunks(block))
        .zip(level.aux.par_chunks(block))
        .enumerate()
        .map(|(bi, ((pblock, nblock), ablock))| {
            cfg.isa.run(BlockSums {
                consts: &consts,
                rows: rows.as_ref(),
                points: pblock,
                normals: nblock,
                aux: ablock,
                width: w.max(1),
                first_row: bi * ROWS_PER_BLOCK,
                stride,
                cap,
            })
        })
        .collect();
    blocks.iter().fold(Sums::zero(), |a, b| a.add(b))
}

/// The constants of a pass of [`pass`] at `pose`, and the world-to-reference-camera transform.
fn pass_consts<'a>(
    reference: &'a ReferenceMaps,
    pose: &Isometry3<f64>,
    centre: &Vector3<f64>,
    sensor: &SensorModel,
    cfg: &TrackerConfig,
    p: PassParams,
) -> (PassConsts<'a>, Isometry3<f64>) {
    let to_ref = reference.pose.isometry().inverse();
    // Frame point to reference camera in one transform: `M = R_ref·R`, `m = R_ref·t + t_ref`.
    let to_ref_frame = to_ref * pose;
    let kr = &reference.intrinsics;
    // Image sides are at most 2^16 (`Intrinsics::validate`), so `n − 0.5` is exact.
    let consts = PassConsts {
        rot: mat3(&pose.rotation.to_rotation_matrix().into_inner()),
        tr: vec3(&pose.translation.vector),
        m: mat3(&to_ref_frame.rotation.to_rotation_matrix().into_inner()),
        tm: vec3(&to_ref_frame.translation.vector),
        fx: kr.fx as f32,
        fy: kr.fy as f32,
        cx: kr.cx as f32,
        cy: kr.cy as f32,
        rw: kr.width as f32,
        rh: kr.height as f32,
        gate_sigmas: cfg.gate_sigmas as f32,
        huber_k: cfg.huber_k as f32,
        uniform_sigma: sensor.sigma_z(cfg.z_ref_m) as f32,
        inv_var: cfg.weighting == WeightMode::InvVar,
        ctr: vec3(centre),
        cap: huber_loss(cfg.gate_sigmas, cfg.huber_k) as f32,
        allowance: p.allowance_m,
        min_cos: p.min_cos,
        reference,
    };
    (consts, to_ref)
}

/// Each sample's term of the robust objective at `pose` ([`Sums::total_loss`] is their sum),
/// in the order [`pass`] visits the samples (rows, then columns, every `stride`-th): the
/// truncated Huber loss of an inlier, the cap for a valid sample outside the gates or on no
/// surface, 0 for an invalid one. For comparing two poses sample by sample
/// (`Tracker::keep_better`); written into `out`, which is cleared first.
pub(crate) fn sample_losses(
    level: &Level,
    reference: &ReferenceMaps,
    pose: &Isometry3<f64>,
    sensor: &SensorModel,
    cfg: &TrackerConfig,
    p: PassParams,
    out: &mut Vec<f32>,
) {
    out.clear();
    let Some(k) = level.intrinsics() else {
        return;
    };
    let w = k.width.max(1);
    let (consts, to_ref) = pass_consts(reference, pose, &pose.translation.vector, sensor, cfg, p);
    let rows = p.timing.map(|t| RowPoses::new(&t, pose, &to_ref, k.height));
    let stride = p.stride.max(1);
    let mut push = |l: f32| out.push(l);
    for (y, ((prow, nrow), arow)) in level
        .points
        .chunks(w)
        .zip(level.normals.chunks(w))
        .zip(level.aux.chunks(w))
        .enumerate()
        .step_by(stride)
    {
        match &rows {
            None => {
                row_sums_with(&consts, prow, nrow, arow, stride, &mut push);
            }
            Some(rows) => {
                let (c, _) = rows.row(&consts, y);
                row_sums_with(&c, prow, nrow, arow, stride, &mut push);
            }
        }
    }
}

/// When the rows of the frame being aligned were exposed: a rolling shutter reads the sensor's
/// rows one after the other, so a moving camera sees each row from another pose. The camera is
/// taken to move at constant velocity from the last good pose to the frame's (the same motion
/// model as the tracker's prediction), so the row poses follow from the frame's pose alone and
/// the alignment stays a 6-parameter problem.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RowTiming {
    /// The last good pose (camera to world).
    pub last: Isometry3<f64>,
    /// Frame intervals from the last good frame to this one (≥ 1).
    pub intervals: u32,
    /// The sensor's readout time (first row to last) over the frame interval.
    pub readout_fraction: f64,
}

/// The per-row poses of one pass: row `y` of the level (of `H` rows) is exposed `s = ((y + ½)/H − ½)·readout_fraction` frame intervals after the middle of
/// the readout, from the pose `T·Vˢ` (`V` the motion over one interval, `T` the frame's pose:
/// the middle of the readout). A change `δ` of `T` moves row `y` by `(1 + s/n)·δ` to first
/// order (`V = (T_last⁻¹·T)^(1/n)` changes with it), so its Jacobian is scaled by that factor.
pub(crate) struct RowPoses {
    pose: Isometry3<f64>,
    to_ref: Isometry3<f64>,
    /// `V`, the camera's motion over one frame interval (camera frame).
    motion: Isometry3<f64>,
    level_height: usize,
    readout_fraction: f64,
    intervals: f64,
}

impl RowPoses {
    fn new(
        timing: &RowTiming,
        pose: &Isometry3<f64>,
        to_ref: &Isometry3<f64>,
        level_height: usize,
    ) -> Self {
        Self {
            pose: *pose,
            to_ref: *to_ref,
            motion: nth_root(&(timing.last.inverse() * pose), timing.intervals.max(1)),
            level_height,
            readout_fraction: timing.readout_fraction,
            intervals: f64::from(timing.intervals.max(1)),
        }
    }

    /// The pass's constants for row `y` of the level, and the row's Jacobian factor.
    fn row<'a>(&self, base: &PassConsts<'a>, y: usize) -> (PassConsts<'a>, f32) {
        let s = row_offset(y, self.level_height, self.readout_fraction);
        let row_pose = self.pose * motion_power(&self.motion, s);
        let to_ref_frame = self.to_ref * row_pose;
        let mut c = *base;
        c.rot = mat3(&row_pose.rotation.to_rotation_matrix().into_inner());
        c.tr = vec3(&row_pose.translation.vector);
        c.m = mat3(&to_ref_frame.rotation.to_rotation_matrix().into_inner());
        c.tm = vec3(&to_ref_frame.translation.vector);
        (c, (1.0 + s / self.intervals) as f32)
    }
}

/// Rows of a level summed by one task of [`pass`] (30 blocks at 640×480).
const ROWS_PER_BLOCK: usize = 16;

/// The sums of one block of rows of a level (its rows whose index is a multiple of the
/// stride), run with the tracker's instruction set.
struct BlockSums<'a> {
    consts: &'a PassConsts<'a>,
    /// The poses of the rows of a rolling-shutter frame (`None`: one pose for all rows).
    rows: Option<&'a RowPoses>,
    points: &'a [Point3<f32>],
    normals: &'a [Vector3<f32>],
    aux: &'a [PointAux],
    width: usize,
    /// The level's row index of the block's first row.
    first_row: usize,
    stride: usize,
    /// The loss of an associated point outside the gates.
    cap: f64,
}

impl IsaKernel for BlockSums<'_> {
    type Output = Sums;

    #[inline(always)]
    fn run(self) -> Sums {
        let mut block_sums = Sums::zero();
        let w = self.width;
        for (r, ((prow, nrow), arow)) in self
            .points
            .chunks(w)
            .zip(self.normals.chunks(w))
            .zip(self.aux.chunks(w))
            .enumerate()
            .filter(|(r, _)| (self.first_row + r).is_multiple_of(self.stride))
        {
            let s = match self.rows {
                None => row_sums(self.consts, prow, nrow, arow, self.stride),
                Some(rows) => {
                    let (consts, factor) = rows.row(self.consts, self.first_row + r);
                    let mut s = row_sums(&consts, prow, nrow, arow, self.stride);
                    s.scale_jacobian(factor);
                    s
                }
            };
            block_sums.add_row(&s, self.cap);
        }
        block_sums
    }
}

/// A rotation matrix as `f32`, row-major.
fn mat3(m: &nalgebra::Matrix3<f64>) -> [f32; 9] {
    std::array::from_fn(|i| m[(i / 3, i % 3)] as f32)
}

/// A vector as `f32`.
fn vec3(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// What the normal equations of one level are solved with besides the data: the data's
/// share of independent information and a prior on the camera's position.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Prior {
    /// `s²/N`: the data terms are divided by the number `N` of pixels of the level over which
    /// the depth error is correlated (see [`TrackerConfig::noise_window_x_px`]) and multiplied
    /// by the `s²` pixels each sample stands for (`s`: [`TrackerConfig::sample_stride`]), so
    /// that `H` counts independent measurements.
    pub data_share: f64,
    /// Information of the position prior, `1/σ_t²` per axis, 1/m².
    pub info_t: f64,
    /// The position the prior is centred on (world, metres).
    pub centre_t: Vector3<f64>,
    /// Information of the orientation prior, `1/σ_r²` per axis, 1/rad² (0: none; only a
    /// measured motion, the odometry's, gives one).
    pub info_r: f64,
    /// The orientation the prior is centred on (camera-to-world).
    pub centre_r: UnitQuaternion<f64>,
    /// `Q`: the data's information is taken as `Qᵀ·H·Q` and their gradient as `Qᵀ·g`, so that
    /// they say nothing along the directions `Q` removes (a view's weak directions, left to
    /// the odometry: `odometry::weak_projection`); `None`: all of it.
    pub data_projection: Option<Matrix6<f64>>,
}

impl Prior {
    /// The objective the step control compares between poses: the mean loss of the associated
    /// points (so that points entering or leaving the overlap neither reward nor penalise a
    /// pose), counted for `points` points and scaled by `data_share` like `H`, plus the prior's
    /// `½·|t − centre|²/σ_t²` at the pose's camera centre `t` and, with an orientation prior,
    /// `½·θ²/σ_r²` for the angle `θ` between its rotation and the prior's.
    pub fn cost(&self, s: &Sums, points: f64, pose: &Isometry3<f64>) -> f64 {
        let mean = if s.associated > 0.0 {
            s.loss / s.associated
        } else {
            f64::INFINITY
        };
        let t = pose.translation.vector;
        let mut c = self.data_share * points * mean
            + 0.5 * self.info_t * (t - self.centre_t).norm_squared();
        if self.info_r > 0.0 {
            c += 0.5 * self.info_r * self.rotation_off(pose).norm_squared();
        }
        c
    }

    /// The rotation from the prior's orientation to `pose`'s, as a world-frame rotation vector
    /// (the step's rotation `ω` adds to it to first order: `R ← exp(ω)·R`).
    fn rotation_off(&self, pose: &Isometry3<f64>) -> Vector3<f64> {
        (pose.rotation * self.centre_r.inverse()).scaled_axis()
    }

    /// `H` of the data (scaled by `data_share`) plus the prior's information.
    fn information(&self, s: &Sums) -> Matrix6<f64> {
        let mut h = s.hessian() * self.data_share;
        if let Some(q) = &self.data_projection {
            h = q.transpose() * h * q;
        }
        for i in 0..3 {
            h[(i, i)] += self.info_r;
            h[(3 + i, 3 + i)] += self.info_t;
        }
        h
    }
}

/// Huber's loss of a normalised residual `e` with threshold `k`: `e²/2` within `±k`, linear
/// beyond.
#[inline(always)]
fn huber_loss<T: nalgebra::RealField + Copy>(e: T, k: T) -> T {
    let a = e.abs();
    let half: T = nalgebra::convert(0.5);
    if a <= k {
        half * a * a
    } else {
        k * a - half * k * k
    }
}

/// The Levenberg–Marquardt step `ξ = (ω, v)` at a pose of camera centre `t` (the centre of the
/// step's rotation, so `v` is the move of `t`): solves `(H + λ·diag H)·ξ = −g` with the data
/// terms scaled by the prior's `data_share` and the prior's position (and orientation)
/// information added (`λ = 0`: the Gauss–Newton step), or `None` when the matrix is singular.
pub(crate) fn step(
    s: &Sums,
    prior: &Prior,
    pose: &Isometry3<f64>,
    lambda: f64,
) -> Option<Vector6<f64>> {
    let mut h = prior.information(s);
    for i in 0..6 {
        h[(i, i)] *= 1.0 + lambda;
    }
    let mut g = s.gradient() * prior.data_share;
    if let Some(q) = &prior.data_projection {
        g = q.transpose() * g;
    }
    let off = pose.translation.vector - prior.centre_t;
    let turn = if prior.info_r > 0.0 {
        prior.rotation_off(pose)
    } else {
        Vector3::zeros()
    };
    for i in 0..3 {
        g[i] += prior.info_r * turn[i];
        g[3 + i] += prior.info_t * off[i];
    }
    h.cholesky().map(|c| -c.solve(&g))
}

/// `iso` with its rotation quaternion scaled back to unit length.
///
/// A product of unit quaternions drifts from unit length by round-off, and nalgebra's
/// `UnitQuaternion` trusts its invariant (its inverse is the conjugate, its rotation matrix is
/// built without dividing by the norm). The tracker feeds its poses back into themselves
/// (`velocity = T_{k−1}⁻¹·T_k`, the next prediction `T_k·velocity`), which multiplies the norm
/// error by about 1 + √2 per frame: from round-off to 1–3 % within 35 frames, where the
/// rotation matrices scale the scene by as much. So every pose the tracker composes is
/// renormalised.
pub(crate) fn renormalized(mut iso: Isometry3<f64>) -> Isometry3<f64> {
    iso.rotation.renormalize();
    iso
}

/// How a point of the frame (camera coordinates, with its normal) sits on the reference at
/// the camera-to-world `pose`: `Some` when it lands on a reference surface whose normal is
/// within `max_normal_angle_deg` of its own and its residual is within the alignment's gate in
/// its plain form (`gate_sigmas·σ + allowance_fine_m` with the frame's σ_Z taken whole rather
/// than along the normal, without [`pass`]'s per-point widening) — an inlier — or beyond it by
/// at most `max_correction_m` ([`OnReference::inlier`] false).
pub(crate) fn on_reference_at<'a>(
    reference: &'a ReferenceMaps,
    pose: &Isometry3<f64>,
    sensor: &'a SensorModel,
    cfg: &'a TrackerConfig,
) -> impl Fn(&Point3<f32>, &Vector3<f32>) -> Option<OnReference> + 'a {
    let to_ref = reference.pose.isometry().inverse() * pose;
    let to_world = *pose;
    let k = reference.intrinsics;
    let min_cos = cfg.max_normal_angle_deg.to_radians().cos();
    move |p, n_own| {
        let p = p.cast::<f64>();
        let x = to_ref * p;
        if x.z.is_nan() || x.z <= 0.0 {
            return None;
        }
        let u = (k.fx * x.x / x.z + k.cx).round();
        let v = (k.fy * x.y / x.z + k.cy).round();
        if !(u >= 0.0 && v >= 0.0 && u < k.width as f64 && v < k.height as f64) {
            return None;
        }
        let j = v as usize * k.width + u as usize;
        let (Some(n), Some(q), Some(&var_ref), own_normal) = (
            reference.normals.get(j),
            reference.points.get(j),
            reference.variance_m2.get(j),
            reference.own_normals.get(j).is_none_or(|&own| own),
        ) else {
            return None;
        };
        let (n, var_ref) = (n.cast::<f64>(), f64::from(var_ref));
        if !(n.x.is_finite() && var_ref.is_finite()) {
            return None;
        }
        if (to_world.rotation * n_own.cast::<f64>()).dot(&n) < min_cos {
            return None;
        }
        let r = n.dot(&(to_world * p - q.cast::<f64>()));
        let sigma_z = sensor.sigma_z(p.z);
        let gate = cfg.gate_sigmas * (sigma_z * sigma_z + var_ref).sqrt() + cfg.allowance_fine_m;
        // Beyond the gate but within what a pose off by the largest plausible correction
        // could bring into it: the sample disagrees with this pose (`OnReference::inlier`).
        (r.abs() <= gate + cfg.max_correction_m).then_some(OnReference {
            variance_m2: var_ref,
            residual_m: r,
            inlier: r.abs() <= gate,
            normal: (!own_normal).then(|| to_world.rotation.inverse_transform_vector(&n)),
        })
    }
}

/// How a frame's point sits on the reference surface it lands on ([`on_reference_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct OnReference {
    /// The variance of the reference's surface there, m².
    pub variance_m2: f64,
    /// The signed distance of the point from that surface along the surface's normal, m.
    pub residual_m: f64,
    /// Whether the residual is within the alignment's gate; if not, it is within the gate
    /// plus [`TrackerConfig::max_correction_m`] (a sample the pose disagrees with).
    pub inlier: bool,
    /// The reference surface's unit normal there, in the frame's camera coordinates — the
    /// direction the residual measures — where it is a plane's or a fused model's
    /// ([`ReferenceMaps::own_normals`]); `None` for a pixel's own normal and for the frame
    /// alone.
    pub normal: Option<Vector3<f64>>,
}

impl OnReference {
    /// A frame checked on its own: no reference, nothing to add.
    pub(crate) const NONE: Self = Self {
        variance_m2: 0.0,
        residual_m: 0.0,
        inlier: true,
        normal: None,
    };
}

/// The motion `R` with `Rⁿ = m` (the same screw motion, a fraction `1/n` of it): the per-frame
/// velocity of a camera that moved by `m` over `n` frame intervals. `n = 1` returns `m`.
pub(crate) fn nth_root(m: &Isometry3<f64>, n: u32) -> Isometry3<f64> {
    if n <= 1 {
        return *m;
    }
    let rotation = UnitQuaternion::from_scaled_axis(m.rotation.scaled_axis() / f64::from(n));
    // Rⁿ's translation is (I + R + … + Rⁿ⁻¹)·t: solve for t.
    let r = rotation.to_rotation_matrix().into_inner();
    let mut power = Matrix3::identity();
    let mut sum = Matrix3::zeros();
    for _ in 0..n {
        sum += power;
        power *= r;
    }
    let t = sum
        .try_inverse()
        .map_or(m.translation.vector / f64::from(n), |inv| {
            inv * m.translation.vector
        });
    Isometry3::from_parts(Translation3::from(t), rotation)
}

/// Applies a step about `centre`: `T ← C·exp(ξ)·C⁻¹·T` with `C` the translation to the centre.
pub(crate) fn apply(
    pose: &Isometry3<f64>,
    xi: &Vector6<f64>,
    centre: &Vector3<f64>,
) -> Isometry3<f64> {
    let w = Vector3::new(xi[0], xi[1], xi[2]);
    let v = Vector3::new(xi[3], xi[4], xi[5]);
    let rot = UnitQuaternion::from_scaled_axis(w);
    let c = Translation3::from(*centre);
    let delta = Isometry3::from_parts(Translation3::from(v), rot);
    renormalized(c * delta * c.inverse() * pose)
}

/// Expresses the rotation part (rows and columns 0–2) of a 6×6 information matrix as
/// displacements at depth `scale_m`: a rotation of θ moves a point at that depth by about
/// `scale_m·θ`, so the rotation rows and columns are divided by `scale_m`.
pub(crate) fn rotations_at_depth(h: &mut Matrix6<f64>, scale_m: f64) {
    let inv = 1.0 / scale_m.max(1e-6);
    for a in 0..6 {
        for b in 0..6 {
            let fa = if a < 3 { inv } else { 1.0 };
            let fb = if b < 3 { inv } else { 1.0 };
            h[(a, b)] *= fa * fb;
        }
    }
}

/// Conditioning of the normal equations: the smallest over the largest eigenvalue of `H` with
/// the rotation rows and columns divided by `scale_m` (making them metres like translation).
pub(crate) fn condition(s: &Sums, scale_m: f64) -> f64 {
    let mut h = s.hessian();
    rotations_at_depth(&mut h, scale_m);
    let e = SymmetricEigen::new(h).eigenvalues;
    let max = e.iter().copied().fold(f64::MIN, f64::max);
    let min = e.iter().copied().fold(f64::MAX, f64::min);
    if max > 0.0 { (min / max).max(0.0) } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nth_root_applied_n_times_is_the_motion() {
        let m = Isometry3::new(Vector3::new(0.12, -0.05, 0.3), Vector3::new(0.2, -0.4, 0.1));
        for n in [1u32, 2, 3, 7] {
            let r = nth_root(&m, n);
            let mut again = Isometry3::identity();
            for _ in 0..n {
                again *= r;
            }
            let d = again.inverse() * m;
            assert!(d.translation.vector.norm() < 1e-12, "n = {n}: {d}");
            assert!(d.rotation.angle() < 1e-12, "n = {n}: {d}");
        }
        assert_eq!(nth_root(&m, 1), m);
    }
}

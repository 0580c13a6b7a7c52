//! Geometric verification of motion hypotheses against depth data, and the point-to-plane ICP
//! core shared by [`crate::motion::icp_point_to_plane`] and
//! [`crate::motion::estimate_motion_verified`]. The same two-way check decides whether
//! [`crate::motion::refine_motion_icp_verified`] keeps an ICP refinement.
//!
//! A hypothesis `X_a = R·X_b + t` is checked by moving a grid of frame-B points (with their
//! normals) into frame A, projecting them into A's depth map (projective association) and
//! counting the points that land on A's surface: point-to-plane distance below
//! `inlier_base_m + inlier_sigmas·σ_Z(Z)` (σ_Z from the sensor model) and point distance below
//! three times that.

use nalgebra::{Isometry3, Matrix6, Point3, Translation3, UnitQuaternion, Vector3, Vector6};
use sl_core::{Camera, DepthImage, Intrinsics, SensorModel};

use crate::error::{Result, TrackError};

/// Parameters of the geometric verification of plane-based motion hypotheses
/// ([`crate::motion::estimate_motion_verified`]).
///
/// A point of one frame, moved into the other, *agrees* when it lies within
/// `inlier_base_m + inlier_sigmas·σ_Z(Z)` of the other frame's tangent plane (and within three
/// times that of its point), *contradicts* when it lands on a valid pixel elsewhere, and counts
/// neither way when it leaves the view. The defaults follow from the sensor: a correct
/// alignment of a static scene puts the points on the surface up to the depth noise (`3·σ_Z`,
/// σ_Z = Z²·σ_D/(f·B), 1.6 mm at 1 m for the Kinect v1) plus a metric allowance for what the
/// noise model does not cover (the Kinect's low-frequency depth distortion of a few mm, 1 mm
/// depth rounding, rolling shutter under fast motion, the residual of the short refinement).
/// Contradictions at the right motion come only from occlusions, depth edges and noise tails:
/// a few per cent.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct VerifyConfig {
    /// Largest number of points used per frame (a regular pixel grid with at most this many
    /// points; only points with a valid normal, i.e. away from depth edges, are kept).
    pub max_samples: usize,
    /// Point-to-plane distance allowed for every point whatever its depth, metres.
    pub inlier_base_m: f64,
    /// Depth-noise multiples added to `inlier_base_m` (σ_Z of the sensor model at the depth).
    pub inlier_sigmas: f64,
    /// Weight of a contradicting point against an agreeing one in the score that ranks the
    /// hypotheses (agreeing − weight·contradicting). A point at the wrong depth is direct
    /// evidence against a motion, a point on a surface may agree by coincidence (planes
    /// extend): with ≤ 3 % contradictions at the right motion and ≥ 25 % at a wrong one the
    /// log-likelihood ratios are ln(0.97/0.75) ≈ 0.26 per agreeing and ln(0.03/0.25) ≈ −2.1
    /// per contradicting point, a weight of about 8.
    pub outlier_weight: f64,
    /// Point-to-plane distance of the coarse score that ranks the unrefined plane hypotheses,
    /// metres (loose: a plane hypothesis is only a few degrees accurate).
    pub coarse_inlier_m: f64,
    /// Angular accuracy assumed of an unrefined plane hypothesis, degrees: the coarse score
    /// also allows `tan(coarse_angle_deg)` times a point's distance from the camera (a 3°
    /// error moves a point 2 m away by 10 cm, twice `coarse_inlier_m`: with a fixed tolerance
    /// the right motion, a few degrees off, lost to wrong ones that overlap little).
    pub coarse_angle_deg: f64,
    /// Number of hypotheses (best coarse scores) refined on the data and scored.
    pub refine_hypotheses: usize,
    /// Point-to-plane ICP iterations of the local refinement of a hypothesis.
    pub refine_iterations: usize,
    /// Correspondence distance of the first refinement iteration, metres.
    pub refine_start_m: f64,
    /// Correspondence distance of the last refinement iteration, metres.
    pub refine_end_m: f64,
    /// Smallest fraction of the overlapping points that must agree for a pose to be
    /// consistent with the data: 0.9 leaves room for occlusions, depth edges and moving
    /// objects beyond the few per cent of a static scene (TUM fr1/rpy: 94.5–99.5 % at the
    /// verified motions, at most 82 % for the alternatives 15° or more away).
    pub min_inlier_fraction: f64,
    /// Smallest fraction of the points that must land on a valid pixel of the other frame.
    pub min_overlap_fraction: f64,
}

impl Default for VerifyConfig {
    fn default() -> Self {
        Self {
            max_samples: 4000,
            inlier_base_m: 0.01,
            inlier_sigmas: 3.0,
            outlier_weight: 8.0,
            coarse_inlier_m: 0.05,
            coarse_angle_deg: 3.0,
            refine_hypotheses: 8,
            refine_iterations: 15,
            refine_start_m: 0.10,
            refine_end_m: 0.03,
            min_inlier_fraction: 0.9,
            min_overlap_fraction: 0.15,
        }
    }
}

impl VerifyConfig {
    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let pos = [
            ("inlier_base_m", self.inlier_base_m),
            ("coarse_inlier_m", self.coarse_inlier_m),
            ("coarse_angle_deg", self.coarse_angle_deg),
            ("refine_start_m", self.refine_start_m),
            ("refine_end_m", self.refine_end_m),
        ];
        for (name, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(TrackError::InvalidConfig(format!(
                    "{name} must be positive, got {}",
                    sl_core::Compact(v)
                )));
            }
        }
        let fracs = [
            ("min_inlier_fraction", self.min_inlier_fraction),
            ("min_overlap_fraction", self.min_overlap_fraction),
        ];
        for (name, v) in fracs {
            if !(0.0..=1.0).contains(&v) {
                return Err(TrackError::InvalidConfig(format!(
                    "{name} must lie in [0, 1], got {}",
                    sl_core::Compact(v)
                )));
            }
        }
        if !(self.outlier_weight.is_finite() && self.outlier_weight >= 0.0) {
            return Err(TrackError::InvalidConfig(format!(
                "outlier_weight must be ≥ 0, got {}",
                sl_core::Compact(self.outlier_weight)
            )));
        }
        if !(self.inlier_sigmas.is_finite() && self.inlier_sigmas >= 0.0) {
            return Err(TrackError::InvalidConfig(format!(
                "inlier_sigmas must be ≥ 0, got {}",
                sl_core::Compact(self.inlier_sigmas)
            )));
        }
        if self.max_samples < 100 || self.refine_hypotheses == 0 {
            return Err(TrackError::InvalidConfig(
                "max_samples must be ≥ 100 and refine_hypotheses ≥ 1".into(),
            ));
        }
        Ok(())
    }
}

fn check_size(d: &DepthImage, k: &Intrinsics) -> Result<()> {
    if d.width() != k.width || d.height() != k.height {
        return Err(TrackError::SizeMismatch {
            expected_width: k.width,
            expected_height: k.height,
            width: d.width(),
            height: d.height(),
        });
    }
    Ok(())
}

fn point(d: &DepthImage, k: &Intrinsics, x: usize, y: usize) -> Option<Point3<f64>> {
    let z = f64::from(d.data()[y * k.width + x]);
    (z > 0.0 && z.is_finite()).then(|| k.back_project(x as f64, y as f64, z))
}

/// Normal step of the central differences, pixels.
const NORMAL_STEP: usize = 2;

/// The point of pixel `(x, y)` and its normal from central differences (step 2, rejecting depth
/// jumps over 5 % of the depth), oriented towards the camera.
fn point_normal(
    d: &DepthImage,
    k: &Intrinsics,
    x: usize,
    y: usize,
) -> Option<(Point3<f64>, Vector3<f64>)> {
    let st = NORMAL_STEP;
    if x < st || y < st || x + st >= k.width || y + st >= k.height {
        return None;
    }
    let c = point(d, k, x, y)?;
    let l = point(d, k, x - st, y)?;
    let r = point(d, k, x + st, y)?;
    let u = point(d, k, x, y - st)?;
    let dn = point(d, k, x, y + st)?;
    let jump = 0.05 * c.z;
    if [l, r, u, dn].iter().any(|p| (p.z - c.z).abs() > jump) {
        return None;
    }
    let n = (r - l).cross(&(dn - u));
    let len = n.norm();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let n = n / len;
    Some((c, if n.dot(&c.coords) > 0.0 { -n } else { n }))
}

/// Scale of the normals stored as `i16` (a resolution of 0.002°).
const NORMAL_SCALE: f64 = 32_000.0;
/// Marks a pixel whose normal has not been computed yet.
const UNKNOWN: i16 = i16::MIN;

/// Frame A as an ICP / verification target: per pixel point and normal, the normal computed
/// when the pixel is first looked up (a verification touches a few thousand pixels, not the
/// whole frame) and kept compactly (6 bytes per pixel), the point recomputed from the depth.
#[derive(Debug, Clone)]
pub(crate) struct Target<'d> {
    depth: &'d DepthImage,
    k: Intrinsics,
    sensor: SensorModel,
    /// Per pixel: `[UNKNOWN, ..]` not computed yet, `[0, 0, 0]` no valid normal, else the unit
    /// normal times `NORMAL_SCALE`.
    normals: Vec<[i16; 3]>,
}

impl<'d> Target<'d> {
    pub(crate) fn new(depth: &'d DepthImage, camera: &Camera) -> Result<Self> {
        let k = camera.intrinsics;
        check_size(depth, &k)?;
        Ok(Self {
            depth,
            k,
            sensor: camera.sensor,
            normals: vec![[UNKNOWN, 0, 0]; k.width * k.height],
        })
    }

    /// A's point and normal where `q` (in A's coordinates) projects.
    fn at(&mut self, q: &Point3<f64>) -> Option<(Point3<f64>, Vector3<f64>)> {
        // The nearest pixel, as `Intrinsics::project_to_pixel` but without `f64::round` (a
        // libm call on the hot path).
        let (u, v) = self.k.project(q)?;
        let (w, h) = (self.k.width as f64, self.k.height as f64);
        if !(u > -0.5 && u < w - 0.5 && v > -0.5 && v < h - 0.5) {
            return None;
        }
        let (x, y) = ((u + 0.5) as usize, (v + 0.5) as usize);
        let i = y * self.k.width + x;
        let mut n = self.normals[i];
        if n[0] == UNKNOWN {
            n = point_normal(self.depth, &self.k, x, y).map_or([0; 3], |(_, n)| {
                // |n| = 1, so every component fits in i16 after scaling.
                n.map(|c| (c * NORMAL_SCALE).round() as i16).into()
            });
            self.normals[i] = n;
        }
        if n == [0; 3] {
            return None;
        }
        let p = point(self.depth, &self.k, x, y)?;
        Some((
            p,
            Vector3::new(n[0].into(), n[1].into(), n[2].into()) / NORMAL_SCALE,
        ))
    }
}

/// All valid points of `depth` on a grid of `stride` pixels.
pub(crate) fn grid_points(depth: &DepthImage, k: &Intrinsics, stride: usize) -> Vec<Point3<f64>> {
    let s = stride.max(1);
    (0..k.height)
        .step_by(s)
        .flat_map(|y| (0..k.width).step_by(s).map(move |x| (x, y)))
        .filter_map(|(x, y)| point(depth, k, x, y))
        .collect()
}

/// Points of `depth` on a regular grid of at most about `max_samples` points, keeping only
/// those with a valid normal (no depth jump nearby: mixed pixels at depth edges are the
/// usual outliers of a correct alignment).
pub(crate) fn grid_samples(
    depth: &DepthImage,
    camera: &Camera,
    max_samples: usize,
) -> Result<Vec<Point3<f64>>> {
    let k = camera.intrinsics;
    check_size(depth, &k)?;
    let stride = ((k.width * k.height) as f64 / max_samples.max(1) as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let half = stride / 2;
    Ok((half..k.height)
        .step_by(stride)
        .flat_map(|y| (half..k.width).step_by(stride).map(move |x| (x, y)))
        .filter_map(|(x, y)| point_normal(depth, &k, x, y).map(|(p, _)| p))
        .collect())
}

/// Point-to-plane ICP of `src` (frame B points) onto `target` from `init`, with the
/// correspondence distance decreasing linearly from `max_d` to `min_d`. Returns the pose, the
/// correspondences of the last iteration and their RMS point-to-plane residual.
pub(crate) fn icp(
    target: &mut Target<'_>,
    src: &[Point3<f64>],
    init: &Isometry3<f64>,
    iterations: usize,
    max_d: f64,
    min_d: f64,
) -> Result<(Isometry3<f64>, usize, f64)> {
    let mut pose = *init;
    let mut inliers = 0usize;
    let mut rms = 0.0;
    let iters = iterations.max(1);
    for it in 0..iters {
        let frac = if iters > 1 {
            it as f64 / (iters - 1) as f64
        } else {
            1.0
        };
        let maxd = max_d + (min_d - max_d) * frac;
        let mut ata = Matrix6::<f64>::zeros();
        let mut atb = Vector6::<f64>::zeros();
        let (mut n_in, mut ss) = (0usize, 0.0);
        for p in src {
            let q = pose * p;
            let Some((a, n)) = target.at(&q) else {
                continue;
            };
            if (q - a).norm() > maxd {
                continue;
            }
            let e = n.dot(&(q - a));
            let c = q.coords.cross(&n);
            let j = Vector6::new(c.x, c.y, c.z, n.x, n.y, n.z);
            ata += j * j.transpose();
            atb -= j * e;
            n_in += 1;
            ss += e * e;
        }
        inliers = n_in;
        if n_in < 6 {
            return Err(TrackError::MotionUndetermined(format!(
                "ICP found only {n_in} correspondences"
            )));
        }
        rms = (ss / n_in as f64).sqrt();
        let Some(x) = ata.cholesky().map(|c| c.solve(&atb)) else {
            return Err(TrackError::MotionUndetermined(
                "ICP normal equations are singular".into(),
            ));
        };
        let dr = UnitQuaternion::from_scaled_axis(Vector3::new(x[0], x[1], x[2]));
        let dt = Vector3::new(x[3], x[4], x[5]);
        pose = Isometry3::from_parts(
            Translation3::from(dr * pose.translation.vector + dt),
            dr * pose.rotation,
        );
        if x.norm() < 1e-7 && frac >= 1.0 {
            break;
        }
    }
    Ok((pose, inliers, rms))
}

/// How well a pose explains frame B's samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Score {
    /// Samples on A's surface.
    pub inliers: usize,
    /// Samples that land on a pixel of A with a valid point and normal.
    pub overlap: usize,
    /// All samples.
    pub total: usize,
}

impl Score {
    /// Inliers among the overlapping samples.
    pub fn inlier_fraction(&self) -> f64 {
        self.inliers as f64 / self.overlap.max(1) as f64
    }
    /// Overlapping samples among all.
    pub fn overlap_fraction(&self) -> f64 {
        self.overlap as f64 / self.total.max(1) as f64
    }
    /// The evidence for the pose: inliers minus `outlier_weight` times the overlapping
    /// samples that contradict it.
    pub fn evidence(&self, outlier_weight: f64) -> f64 {
        self.inliers as f64 - outlier_weight * (self.overlap - self.inliers) as f64
    }
}

/// Scores `pose` (`X_a = R·X_b + t`): samples within `base_m + per_m·|X| + sigmas·σ_Z` of A's
/// tangent plane and within three times that of A's point (`|X|`: the moved point's distance
/// from A's camera).
pub(crate) fn score(
    target: &mut Target<'_>,
    samples: &[Point3<f64>],
    pose: &Isometry3<f64>,
    (base_m, per_m, sigmas): (f64, f64, f64),
) -> Score {
    let mut s = Score {
        total: samples.len(),
        ..Score::default()
    };
    for p in samples {
        let q = pose * p;
        let Some((a, na)) = target.at(&q) else {
            continue;
        };
        s.overlap += 1;
        let tol = base_m + per_m * q.coords.norm() + sigmas * target.sensor.sigma_z(a.z);
        let d = q - a;
        if na.dot(&d).abs() < tol && d.norm() < 3.0 * tol {
            s.inliers += 1;
        }
    }
    s
}

/// Whether sample `p` of B is an inlier of `pose` on A (the rule of [`score`]); `None` where it
/// does not overlap A.
fn is_inlier(
    target: &mut Target<'_>,
    p: &Point3<f64>,
    pose: &Isometry3<f64>,
    base_m: f64,
    sigmas: f64,
) -> Option<bool> {
    let q = pose * p;
    let (a, na) = target.at(&q)?;
    let tol = base_m + sigmas * target.sensor.sigma_z(a.z);
    let d = q - a;
    Some(na.dot(&d).abs() < tol && d.norm() < 3.0 * tol)
}

/// The discordant samples of two poses (McNemar's pairs): how many samples are inliers of
/// `first` only and how many of `second` only (a sample outside A's overlap counts as not an
/// inlier).
fn discordant(
    target: &mut Target<'_>,
    samples: &[Point3<f64>],
    first: &Isometry3<f64>,
    second: &Isometry3<f64>,
    base_m: f64,
    sigmas: f64,
) -> (usize, usize) {
    let (mut only_first, mut only_second) = (0, 0);
    for p in samples {
        let a = is_inlier(target, p, first, base_m, sigmas).unwrap_or(false);
        let b = is_inlier(target, p, second, base_m, sigmas).unwrap_or(false);
        only_first += usize::from(a && !b);
        only_second += usize::from(b && !a);
    }
    (only_first, only_second)
}

/// Centroid (in A's coordinates) of the samples that are inliers of `pose` under the
/// tolerance `(base_m, sigmas)`.
fn inlier_centroid(
    target: &mut Target<'_>,
    samples: &[Point3<f64>],
    pose: &Isometry3<f64>,
    (base_m, sigmas): (f64, f64),
) -> Option<Point3<f64>> {
    let (mut sum, mut n) = (Vector3::zeros(), 0usize);
    for p in samples {
        let q = pose * p;
        let Some((a, na)) = target.at(&q) else {
            continue;
        };
        let tol = base_m + sigmas * target.sensor.sigma_z(a.z);
        let d = q - a;
        if na.dot(&d).abs() < tol && d.norm() < 3.0 * tol {
            sum += q.coords;
            n += 1;
        }
    }
    (n > 0).then(|| Point3::from(sum / n as f64))
}

/// Which of the sample sets of [`TwoWay`] to score on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Density {
    /// The fewest points: ranking many hypotheses.
    Coarse,
    /// Refinement and perturbation checks.
    Sparse,
    /// All samples: the final scores.
    Full,
}

/// Points of frame A and of frame B.
type SamplePair = (Vec<Point3<f64>>, Vec<Point3<f64>>);

/// Both frames prepared for checking motions `X_a = R·X_b + t` in both directions: B's points
/// against A's surface and A's points (moved by the inverse) against B's surface.
#[derive(Debug, Clone)]
pub(crate) struct TwoWay<'d> {
    target_a: Target<'d>,
    target_b: Target<'d>,
    /// Sample sets of A and B: full, sparse, coarse.
    sets: [SamplePair; 3],
}

impl<'d> TwoWay<'d> {
    /// Targets and grid samples of both frames: at most `max_samples` per frame, thinned to
    /// `sparse` and `coarse` points.
    pub(crate) fn new(
        depth_a: &'d DepthImage,
        depth_b: &'d DepthImage,
        camera: &Camera,
        max_samples: usize,
        (sparse, coarse): (usize, usize),
    ) -> Result<Self> {
        let samples_a = grid_samples(depth_a, camera, max_samples)?;
        let samples_b = grid_samples(depth_b, camera, max_samples)?;
        let thin = |s: &[Point3<f64>], n: usize| -> Vec<Point3<f64>> {
            let step = s.len().div_ceil(n.max(1)).max(1);
            s.iter().step_by(step).copied().collect()
        };
        let sparse_set = (thin(&samples_a, sparse), thin(&samples_b, sparse));
        let coarse_set = (thin(&samples_a, coarse), thin(&samples_b, coarse));
        Ok(Self {
            target_a: Target::new(depth_a, camera)?,
            target_b: Target::new(depth_b, camera)?,
            sets: [(samples_a, samples_b), sparse_set, coarse_set],
        })
    }

    /// The fewer samples of the two frames.
    pub(crate) fn samples(&self) -> usize {
        self.sets[0].0.len().min(self.sets[0].1.len())
    }

    /// The score of `pose` in both directions (sums of the two), with the tolerance
    /// `base_m + sigmas·σ_Z`.
    pub(crate) fn score(
        &mut self,
        pose: &Isometry3<f64>,
        (base_m, sigmas): (f64, f64),
        density: Density,
    ) -> Score {
        self.score_ranging(pose, (base_m, 0.0, sigmas), density)
    }

    /// [`Self::score`] with a tolerance that also grows with the points' distance from the
    /// camera, `base_m + per_m·|X| + sigmas·σ_Z` (an unrefined rotation error moves a point by
    /// about its distance times the angle).
    pub(crate) fn score_ranging(
        &mut self,
        pose: &Isometry3<f64>,
        tol: (f64, f64, f64),
        density: Density,
    ) -> Score {
        let (sa, sb) = match density {
            Density::Full => &self.sets[0],
            Density::Sparse => &self.sets[1],
            Density::Coarse => &self.sets[2],
        };
        let ab = score(&mut self.target_a, sb, pose, tol);
        let ba = score(&mut self.target_b, sa, &pose.inverse(), tol);
        Score {
            inliers: ab.inliers + ba.inliers,
            overlap: ab.overlap + ba.overlap,
            total: ab.total + ba.total,
        }
    }

    /// The discordant samples of `first` and `second` in both directions (sums of the two):
    /// inliers of `first` only, inliers of `second` only.
    pub(crate) fn discordant(
        &mut self,
        first: &Isometry3<f64>,
        second: &Isometry3<f64>,
        (base_m, sigmas): (f64, f64),
        density: Density,
    ) -> (usize, usize) {
        let (sa, sb) = match density {
            Density::Full => &self.sets[0],
            Density::Sparse => &self.sets[1],
            Density::Coarse => &self.sets[2],
        };
        let ab = discordant(&mut self.target_a, sb, first, second, base_m, sigmas);
        let ba = discordant(
            &mut self.target_b,
            sa,
            &first.inverse(),
            &second.inverse(),
            base_m,
            sigmas,
        );
        (ab.0 + ba.0, ab.1 + ba.1)
    }

    /// Short point-to-plane ICP of B's sparse samples onto A from `pose`.
    pub(crate) fn refine(
        &mut self,
        pose: &Isometry3<f64>,
        iterations: usize,
        start_m: f64,
        end_m: f64,
    ) -> Result<Isometry3<f64>> {
        icp(
            &mut self.target_a,
            &self.sets[1].1,
            pose,
            iterations,
            start_m,
            end_m,
        )
        .map(|(p, _, _)| p)
    }

    /// Two-way scores (on the sparse samples) of `pose` turned by ±`angle_rad` about each of
    /// `axes` (unit vectors in A's coordinates) through the centroid of B's inliers in A; empty
    /// without inliers.
    pub(crate) fn perturbed(
        &mut self,
        pose: &Isometry3<f64>,
        axes: &[Vector3<f64>],
        angle_rad: f64,
        tol: (f64, f64),
    ) -> Vec<Score> {
        let Some(c) = inlier_centroid(&mut self.target_a, &self.sets[1].1, pose, tol) else {
            return Vec::new();
        };
        let to_c = Isometry3::translation(c.x, c.y, c.z);
        let mut out = Vec::with_capacity(2 * axes.len());
        for axis in axes {
            for sign in [1.0, -1.0] {
                let turn = Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_scaled_axis(axis * (sign * angle_rad)),
                );
                out.push(self.score(&(to_c * turn * to_c.inverse() * pose), tol, Density::Sparse));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::Plane;

    /// A 160x120 camera looking at a tilted wall 2 m away.
    fn wall() -> (Camera, DepthImage, Plane) {
        let k = Intrinsics::new(160, 120, 120.0, 120.0, 79.5, 59.5).unwrap();
        let cam = Camera {
            intrinsics: k,
            sensor: SensorModel::kinect_v1(),
        };
        let plane = Plane::new(Vector3::new(0.3, -0.2, -1.0), 2.0)
            .unwrap()
            .facing_origin();
        let z: Vec<f32> = (0..k.width * k.height)
            .map(|i| {
                plane
                    .depth_at(&k, (i % k.width) as f64, (i / k.width) as f64)
                    .unwrap_or(0.0) as f32
            })
            .collect();
        (
            cam,
            DepthImage::from_vec(k.width, k.height, z).unwrap(),
            plane,
        )
    }

    #[test]
    fn target_normals_are_the_plane_normal() {
        let (cam, depth, plane) = wall();
        let mut t = Target::new(&depth, &cam).unwrap();
        let q = cam
            .intrinsics
            .back_project(80.0, 60.0, f64::from(depth.data()[60 * 160 + 80]));
        let (p, n) = t.at(&q).unwrap();
        assert!((p - q).norm() < 1e-5);
        assert!(n.angle(&plane.normal) < 1e-3, "{n:?}");
        // The second lookup reads the stored normal.
        assert_eq!(t.at(&q), Some((p, n)));
    }

    #[test]
    fn scores_tell_the_right_pose_from_a_shifted_one() {
        let (cam, depth, _) = wall();
        let mut two = TwoWay::new(&depth, &depth, &cam, 2000, (500, 200)).unwrap();
        let tol = (0.01, 3.0);
        let right = two.score(&Isometry3::identity(), tol, Density::Full);
        assert!(right.inlier_fraction() > 0.99, "{right:?}");
        assert!(right.overlap_fraction() > 0.9, "{right:?}");
        // 10 cm along the optical axis: on the surface nowhere.
        let off = two.score(&Isometry3::translation(0.0, 0.0, 0.1), tol, Density::Full);
        assert!(off.inlier_fraction() < 0.05, "{off:?}");
        assert!(off.evidence(8.0) < 0.0 && right.evidence(8.0) > 0.0);
        // A turn about the wall's own normal slides it in itself: still consistent (the
        // degeneracy the perturbation check looks for), unlike a turn about the x axis.
        let (_, _, plane) = wall();
        let about_x = two.perturbed(&Isometry3::identity(), &[Vector3::x()], 0.2, tol);
        assert_eq!(about_x.len(), 2);
        assert!(
            about_x.iter().all(|s| s.inlier_fraction() < 0.5),
            "{about_x:?}"
        );
        let about_n = two.perturbed(&Isometry3::identity(), &[plane.normal], 0.2, tol);
        assert!(
            about_n.iter().all(|s| s.inlier_fraction() > 0.95),
            "{about_n:?}"
        );
    }

    #[test]
    fn config_ranges_are_checked() {
        assert!(VerifyConfig::default().validate().is_ok());
        for bad in [
            VerifyConfig {
                min_inlier_fraction: 1.5,
                ..VerifyConfig::default()
            },
            VerifyConfig {
                inlier_base_m: 0.0,
                ..VerifyConfig::default()
            },
            VerifyConfig {
                max_samples: 10,
                ..VerifyConfig::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}

//! Motion between two frames from matched planes (paper section 3.5), and point-to-plane ICP.
//!
//! Convention: the motion `(R, t)` maps frame B's camera coordinates into frame A's,
//! `X_a = R·X_b + t`; a plane `n_b·X + d_b = 0` of B becomes `n_a = R·n_b`,
//! `d_a = d_b − n_a·t` in A.
//!
//! * **Matching.** Candidate pairs are planes whose normals (after an optional initial guess)
//!   differ by less than `max_angle_deg` and offsets by less than `max_offset_m`. Every two
//!   candidate pairs with non-parallel normals and a consistent mutual angle propose a rotation
//!   (Kabsch on the two normals); the proposal supported by the largest pixel weight of
//!   one-to-one matches within `inlier_angle_deg` whose offsets agree with one translation
//!   (within `inlier_offset_m`) wins.
//! * **Rotation** from all matches by weighted Kabsch (SVD of `Σ w·n_a·n_bᵀ`, weights = the
//!   smaller pixel count of the pair): needs ≥ 2 non-parallel normals.
//! * **Translation** from `n_a·t = d_b − d_a` by weighted least squares; it is reported as
//!   determined only when the matched normals span 3D (≥ 3 independent planes).
//! * **ICP**: point-to-plane with projective data association, the reference the paper used.

use nalgebra::{
    Isometry3, Matrix3, Matrix6, Point3, Rotation3, SymmetricEigen, Translation3, UnitQuaternion,
    Vector3, Vector6,
};
use sl_core::{Camera, DepthImage};

use crate::error::{PlanesError, Result};
use crate::extract::PlaneInfo;

/// Parameters of plane matching and motion estimation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionConfig {
    /// Largest normal angle of a candidate match (after the initial guess), degrees.
    pub max_angle_deg: f64,
    /// Largest offset difference of a candidate match (after the initial guess), metres.
    pub max_offset_m: f64,
    /// Normal angle under a rotation hypothesis for a match to count as inlier, degrees.
    pub inlier_angle_deg: f64,
    /// Two normals closer than this are treated as parallel, degrees.
    pub min_spread_deg: f64,
    /// Largest disagreement of a match's offset with the common translation, metres.
    pub inlier_offset_m: f64,
    /// Smallest eigenvalue of the normalised normal scatter `Σw·n·nᵀ / Σw` for the translation
    /// to count as determined.
    pub min_translation_eigen: f64,
}

impl Default for MotionConfig {
    fn default() -> Self {
        Self {
            max_angle_deg: 45.0,
            max_offset_m: 0.5,
            inlier_angle_deg: 4.0,
            min_spread_deg: 15.0,
            inlier_offset_m: 0.08,
            min_translation_eigen: 0.02,
        }
    }
}

/// A matched pair of planes: index into frame A's and frame B's plane lists.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneMatch {
    /// Index in frame A's planes.
    pub a: usize,
    /// Index in frame B's planes.
    pub b: usize,
    /// Weight (smaller pixel count of the two).
    pub weight: f64,
}

/// The motion of frame B relative to frame A estimated from planes.
#[derive(Debug, Clone, PartialEq)]
pub struct PlaneMotion {
    /// Rotation `R` of `X_a = R·X_b + t`.
    pub rotation: UnitQuaternion<f64>,
    /// The translation, when the matched normals span 3D.
    pub translation_m: Option<Vector3<f64>>,
    /// The least-squares translation restricted to the directions the normals determine
    /// (minimum norm; equal to `translation_m` when that is determined).
    pub translation_partial_m: Vector3<f64>,
    /// The matched planes.
    pub matches: Vec<PlaneMatch>,
    /// Weighted RMS angle between matched normals after the rotation, degrees.
    pub rms_angle_deg: f64,
}

impl PlaneMotion {
    /// The motion as an isometry (`translation_partial_m` when the translation is not fully
    /// determined).
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::from(self.translation_m.unwrap_or(self.translation_partial_m)),
            self.rotation,
        )
    }
}

/// The rotation `R` minimising `Σ w·|a − R·b|²` (weighted Kabsch/SVD); `None` when the
/// weighted vectors do not determine it (fewer than two non-parallel directions).
pub fn weighted_kabsch(pairs: &[(Vector3<f64>, Vector3<f64>, f64)]) -> Option<Rotation3<f64>> {
    let mut hm = Matrix3::zeros();
    for (a, b, w) in pairs {
        hm += *w * b * a.transpose();
    }
    let svd = hm.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut sv = svd.singular_values;
    sv.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    let rank2 = sv[1] > 1e-9 * sv[0].max(1e-300);
    if !rank2 {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let fix = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
    Some(Rotation3::from_matrix_unchecked(v * fix * u.transpose()))
}

/// Minimum-norm weighted least-squares `t` of `n·t = δ` over `(n, δ, w)` rows, restricted to
/// the eigen-directions of `Σw·n·nᵀ/Σw` above `min_eigen`.
fn partial_translation(rows: &[(Vector3<f64>, f64, f64)], min_eigen: f64) -> Vector3<f64> {
    let mut m = Matrix3::zeros();
    let mut v = Vector3::zeros();
    let mut sw = 0.0;
    for (n, delta, w) in rows {
        m += *w * n * n.transpose();
        v += *w * n * *delta;
        sw += w;
    }
    if sw <= 0.0 {
        return Vector3::zeros();
    }
    let eig = SymmetricEigen::new(m / sw);
    let mut t = Vector3::zeros();
    for i in 0..3 {
        let l = eig.eigenvalues[i];
        if l > min_eigen {
            let e = eig.eigenvectors.column(i).into_owned();
            t += e * (e.dot(&(v / sw)) / l);
        }
    }
    t
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Matches the planes of two frames and estimates the motion of B in A's coordinates.
/// `guess` is an initial `X_a = R₀·X_b + t₀` (identity when `None`).
pub fn estimate_motion(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    guess: Option<&Isometry3<f64>>,
    cfg: &MotionConfig,
) -> Result<PlaneMotion> {
    let g = guess.copied().unwrap_or_else(Isometry3::identity);
    let bt: Vec<_> = planes_b.iter().map(|p| p.plane.transformed(&g)).collect();
    let mut cands: Vec<PlaneMatch> = Vec::new();
    for (i, pa) in planes_a.iter().enumerate() {
        for (j, pb) in bt.iter().enumerate() {
            if pa.plane.angle_deg(pb) < cfg.max_angle_deg
                && (pa.plane.offset_m - pb.offset_m).abs() < cfg.max_offset_m
            {
                cands.push(PlaneMatch {
                    a: i,
                    b: j,
                    weight: planes_a[i].pixels.min(planes_b[j].pixels) as f64,
                });
            }
        }
    }
    cands.sort_by(|x, y| y.weight.total_cmp(&x.weight));
    let na = |m: &PlaneMatch| planes_a[m.a].plane.normal;
    let nb = |m: &PlaneMatch| bt[m.b].normal;
    // Greedy one-to-one inliers of a rotation hypothesis.
    let inliers = |r: &Rotation3<f64>| -> (f64, Vec<PlaneMatch>) {
        let mut used_a = vec![false; planes_a.len()];
        let mut used_b = vec![false; planes_b.len()];
        let mut out = Vec::new();
        for m in &cands {
            if used_a[m.a] || used_b[m.b] {
                continue;
            }
            if angle_deg(&na(m), &(r * nb(m))) < cfg.inlier_angle_deg {
                used_a[m.a] = true;
                used_b[m.b] = true;
                out.push(*m);
            }
        }
        // Offsets must agree with one translation: d_a = d_b − n_a·t (least squares over the
        // directions the normals determine).
        let rows: Vec<(Vector3<f64>, f64, f64)> = out
            .iter()
            .map(|m| {
                (
                    na(m),
                    bt[m.b].offset_m - planes_a[m.a].plane.offset_m,
                    m.weight,
                )
            })
            .collect();
        let t = partial_translation(&rows, cfg.min_translation_eigen);
        let kept: Vec<PlaneMatch> = out
            .into_iter()
            .zip(&rows)
            .filter(|(_, (n, delta, _))| (delta - n.dot(&t)).abs() < cfg.inlier_offset_m)
            .map(|(m, _)| m)
            .collect();
        let score = kept.iter().map(|m| m.weight).sum();
        (score, kept)
    };
    let mut best: Option<(f64, Vec<PlaneMatch>)> = None;
    for (x, m1) in cands.iter().enumerate() {
        for m2 in &cands[x + 1..] {
            if m1.a == m2.a || m1.b == m2.b {
                continue;
            }
            let spread_a = angle_deg(&na(m1), &na(m2));
            let spread_b = angle_deg(&nb(m1), &nb(m2));
            if spread_a < cfg.min_spread_deg || spread_a > 180.0 - cfg.min_spread_deg {
                continue;
            }
            if (spread_a - spread_b).abs() > 2.0 * cfg.inlier_angle_deg {
                continue;
            }
            let Some(r) =
                weighted_kabsch(&[(na(m1), nb(m1), m1.weight), (na(m2), nb(m2), m2.weight)])
            else {
                continue;
            };
            let (score, ms) = inliers(&r);
            if best.as_ref().is_none_or(|(s, _)| score > *s) {
                best = Some((score, ms));
            }
        }
    }
    let Some((_, mut matches)) = best else {
        return Err(PlanesError::MotionUndetermined(format!(
            "need two matched non-parallel planes ({} planes in A, {} in B, {} candidate pairs)",
            planes_a.len(),
            planes_b.len(),
            cands.len()
        )));
    };
    // Refine on all inliers, then re-collect once.
    let refine = |ms: &[PlaneMatch]| {
        weighted_kabsch(
            &ms.iter()
                .map(|m| (na(m), nb(m), m.weight))
                .collect::<Vec<_>>(),
        )
    };
    let mut r = refine(&matches)
        .ok_or_else(|| PlanesError::MotionUndetermined("degenerate normals".into()))?;
    let (_, again) = inliers(&r);
    if again.len() >= 2
        && let Some(r2) = refine(&again)
    {
        r = r2;
        matches = again;
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&(r * g.rotation.to_rotation_matrix()));
    // Translation from the original (untransformed) B planes: n_a·t = d_b − d_a.
    let (translation_m, translation_partial_m, matches) =
        solve_translation(planes_a, planes_b, &rotation, matches, cfg);
    let (mut sw, mut sa) = (0.0, 0.0);
    for m in &matches {
        let a = angle_deg(
            &planes_a[m.a].plane.normal,
            &(rotation * planes_b[m.b].plane.normal),
        );
        sw += m.weight;
        sa += m.weight * a * a;
    }
    Ok(PlaneMotion {
        rotation,
        translation_m,
        translation_partial_m,
        rms_angle_deg: if sw > 0.0 { (sa / sw).sqrt() } else { 0.0 },
        matches,
    })
}

fn solve_translation(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    rotation: &UnitQuaternion<f64>,
    matches: Vec<PlaneMatch>,
    cfg: &MotionConfig,
) -> (Option<Vector3<f64>>, Vector3<f64>, Vec<PlaneMatch>) {
    let solve = |ms: &[PlaneMatch]| {
        let mut m = Matrix3::zeros();
        let mut v = Vector3::zeros();
        let mut sw = 0.0;
        for mt in ms {
            let (pa, pb) = (&planes_a[mt.a].plane, &planes_b[mt.b].plane);
            let n = (pa.normal + rotation * pb.normal).normalize();
            m += mt.weight * n * n.transpose();
            v += mt.weight * n * (pb.offset_m - pa.offset_m);
            sw += mt.weight;
        }
        if sw <= 0.0 {
            return (None, Vector3::zeros());
        }
        let eig = SymmetricEigen::new(m / sw);
        let mut t = Vector3::zeros();
        let mut full = true;
        for i in 0..3 {
            let l = eig.eigenvalues[i];
            let e = eig.eigenvectors.column(i).into_owned();
            if l > cfg.min_translation_eigen {
                t += e * (e.dot(&(v / sw)) / l);
            } else {
                full = false;
            }
        }
        (full.then_some(t), t)
    };
    let (full, partial) = solve(&matches);
    // Drop matches whose offsets disagree with the translation by more than 10 cm (unless that
    // would leave fewer than two).
    let kept: Vec<PlaneMatch> = matches
        .iter()
        .copied()
        .filter(|mt| {
            let (pa, pb) = (&planes_a[mt.a].plane, &planes_b[mt.b].plane);
            let n = rotation * pb.normal;
            (pb.offset_m - n.dot(&partial) - pa.offset_m).abs() < 0.1
        })
        .collect();
    if kept.len() >= 2 && kept.len() < matches.len() {
        let (f2, p2) = solve(&kept);
        return (f2, p2, kept);
    }
    (full, partial, matches)
}

/// Parameters of point-to-plane ICP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpConfig {
    /// Iterations.
    pub iterations: usize,
    /// Pixel stride of the source (B) samples.
    pub stride: usize,
    /// Correspondence distance at the first iteration, metres.
    pub max_dist_m: f64,
    /// Correspondence distance at the last iteration, metres.
    pub min_dist_m: f64,
}

impl Default for IcpConfig {
    fn default() -> Self {
        Self {
            iterations: 30,
            stride: 4,
            max_dist_m: 0.15,
            min_dist_m: 0.02,
        }
    }
}

/// The result of ICP.
#[derive(Debug, Clone, PartialEq)]
pub struct IcpResult {
    /// The motion `X_a = R·X_b + t`.
    pub pose: Isometry3<f64>,
    /// Correspondences used in the last iteration.
    pub inliers: usize,
    /// RMS point-to-plane residual of the last iteration, metres.
    pub rms_m: f64,
}

/// Point-to-plane ICP aligning depth frame B to frame A (same camera), with projective data
/// association into A and normals of A from the depth image; starts from `init`.
pub fn icp_point_to_plane(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    init: &Isometry3<f64>,
    cfg: &IcpConfig,
) -> Result<IcpResult> {
    let k = &camera.intrinsics;
    for d in [depth_a, depth_b] {
        if d.width() != k.width || d.height() != k.height {
            return Err(PlanesError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: d.width(),
                height: d.height(),
            });
        }
    }
    let (w, h) = (k.width, k.height);
    let pt = |d: &DepthImage, x: usize, y: usize| -> Option<Point3<f64>> {
        let z = f64::from(d.data()[y * w + x]);
        (z > 0.0 && z.is_finite()).then(|| k.back_project(x as f64, y as f64, z))
    };
    // Normals of A by central differences (step 2), rejecting depth jumps.
    let st = 2usize;
    let mut normals: Vec<Option<(Point3<f64>, Vector3<f64>)>> = vec![None; w * h];
    for y in st..h.saturating_sub(st) {
        for x in st..w.saturating_sub(st) {
            let (Some(c), Some(l), Some(r), Some(u), Some(dn)) = (
                pt(depth_a, x, y),
                pt(depth_a, x - st, y),
                pt(depth_a, x + st, y),
                pt(depth_a, x, y - st),
                pt(depth_a, x, y + st),
            ) else {
                continue;
            };
            let jump = 0.05 * c.z;
            if [l, r, u, dn].iter().any(|p| (p.z - c.z).abs() > jump) {
                continue;
            }
            let n = (r - l).cross(&(dn - u));
            let len = n.norm();
            if len > 0.0 {
                let mut n = n / len;
                if n.dot(&c.coords) > 0.0 {
                    n = -n;
                }
                normals[y * w + x] = Some((c, n));
            }
        }
    }
    let src: Vec<Point3<f64>> = (0..h)
        .step_by(cfg.stride.max(1))
        .flat_map(|y| (0..w).step_by(cfg.stride.max(1)).map(move |x| (x, y)))
        .filter_map(|(x, y)| pt(depth_b, x, y))
        .collect();
    let mut pose = *init;
    let mut inliers = 0usize;
    let mut rms = 0.0;
    let iters = cfg.iterations.max(1);
    for it in 0..iters {
        let frac = if iters > 1 {
            it as f64 / (iters - 1) as f64
        } else {
            1.0
        };
        let maxd = cfg.max_dist_m + (cfg.min_dist_m - cfg.max_dist_m) * frac;
        let mut ata = Matrix6::<f64>::zeros();
        let mut atb = Vector6::<f64>::zeros();
        let (mut n_in, mut ss) = (0usize, 0.0);
        for p in &src {
            let q = pose * p;
            let Some(pix) = k.project_to_pixel(&q) else {
                continue;
            };
            let Some((a, n)) = normals[pix.1 * w + pix.0] else {
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
            return Err(PlanesError::MotionUndetermined(format!(
                "ICP found only {n_in} correspondences"
            )));
        }
        rms = (ss / n_in as f64).sqrt();
        let Some(x) = ata.cholesky().map(|c| c.solve(&atb)) else {
            return Err(PlanesError::MotionUndetermined(
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
    Ok(IcpResult {
        pose,
        inliers,
        rms_m: rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kabsch_recovers_rotation() {
        let r = Rotation3::from_scaled_axis(Vector3::new(0.2, -0.4, 0.1));
        let bs = [
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(0.0, -1.0, 0.1).normalize(),
        ];
        let pairs: Vec<_> = bs.iter().map(|b| (r * b, *b, 1.0)).collect();
        let est = weighted_kabsch(&pairs).unwrap();
        assert!(est.angle_to(&r) < 1e-9);
        // Parallel normals do not determine a rotation.
        let par = [(bs[0], bs[0], 1.0), (bs[0] * 2.0, bs[0] * 2.0, 1.0)];
        assert!(weighted_kabsch(&par).is_none());
    }
}

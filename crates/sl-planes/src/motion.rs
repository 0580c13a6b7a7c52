//! Motion between two frames from matched planes (paper section 3.5), verified against the
//! depth data, and point-to-plane ICP.
//!
//! Convention: the motion `(R, t)` maps frame B's camera coordinates into frame A's,
//! `X_a = R·X_b + t`; a plane `n_b·X + d_b = 0` of B becomes `n_a = R·n_b`,
//! `d_a = d_b − n_a·t` in A.
//!
//! * **Hypotheses.** Candidate pairs are all (A plane, B plane) pairs, or with a prior only
//!   those whose normals (after the prior) differ by less than `max_angle_deg` and offsets by
//!   less than `max_offset_m`. Every two candidate pairs with non-parallel normals whose mutual
//!   angles agree (∠(n_a1, n_a2) ≈ ∠(n_b1, n_b2)) propose a rotation (Kabsch on the two
//!   normals). Each proposal collects its one-to-one plane matches within `inlier_angle_deg`
//!   whose offsets agree with one translation (within `inlier_offset_m`), is refined by
//!   weighted Kabsch over them, and is scored by their support (sum of the smaller pixel count
//!   of each match). Proposals closer than `inlier_angle_deg` are merged.
//! * **Planes only** ([`estimate_motion`], the identity as prior when no guess is given): the
//!   proposal with the largest support wins. Plane normals alone are often ambiguous — two
//!   monitors at the same angle to a desk, a desk split into near-parallel bands that inflate
//!   the support of a wrong proposal (TUM fr1/rpy: 37° wrong at 20° of motion) — so the result
//!   is marked [`MotionConfidence::Ambiguous`] when a proposal more than `distinct_deg` away
//!   has `ambiguity_ratio` of the winner's support, and [`MotionConfidence::Unverified`]
//!   otherwise: nothing in the planes alone proves it right.
//! * **Verified** ([`estimate_motion_verified`], recommended when the depth maps are at hand,
//!   no prior needed): every proposal is checked against the data. A grid of points of each
//!   frame is moved into the other and projected into its depth map (projective association);
//!   a point on the other surface agrees, a point in front of or behind it contradicts, a
//!   point out of view counts neither way (see [`VerifyConfig`]). The proposals are ranked by
//!   agreement minus weighted contradictions; the best are refined by a short point-to-plane
//!   ICP and scored again, and must keep two non-parallel consistent plane matches. The winner
//!   must explain `min_inlier_fraction` of the overlapping points while no alternative more
//!   than `distinct_deg` away does — neither another proposal nor the winner itself turned by
//!   `distinct_deg` about the camera axes or a plane normal (which catches views that share
//!   mostly one plane, where a rotation about its normal is invisible). Otherwise the motion
//!   is reported as not determined ([`PlanesError::MotionNotVerified`]) rather than guessed.
//!   The returned rotation is the weighted Kabsch over the plane matches consistent with the
//!   verified alignment; [`Verification`] gives the numbers.
//! * **Rotation** from matches by weighted Kabsch (SVD of `Σ w·n_b·n_aᵀ`, weights = the smaller
//!   pixel count of the pair): needs ≥ 2 non-parallel normals.
//! * **Translation** from `n_a·t = d_b − d_a` by weighted least squares; it is reported as
//!   determined only when the matched normals span 3D (≥ 3 independent planes).
//! * **ICP**: point-to-plane with projective data association, the reference the paper used
//!   ([`icp_point_to_plane`]). ICP only minimises residuals and can make a verified estimate
//!   worse: at large motion and small overlap a wide correspondence gate matches points to the
//!   wrong surfaces, which pull the rotation about a dominant plane's normal (TUM fr1/rpy
//!   0 → 15: 34.8° of motion, 27 % overlap, the plane estimate 3.8° off, ICP from it 10° off).
//!   [`refine_motion_icp_verified`] starts from the verified alignment with a tight gate
//!   ([`IcpConfig::refinement`]) and accepts the result only when the same depth-data check
//!   verifies it and it explains no smaller a share of the overlap ([`IcpOutcome`]);
//!   otherwise the plane estimate stands.

use nalgebra::{
    Isometry3, Matrix3, Rotation3, SymmetricEigen, Translation3, UnitQuaternion, Vector3,
};
use sl_core::{Camera, DepthImage};

use crate::error::{PlanesError, Result};
use crate::extract::PlaneInfo;
use crate::plane::Plane3;
pub use crate::verify::VerifyConfig;
use crate::verify::{self, Density, Score, Target, TwoWay};

/// Parameters of plane matching and motion estimation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionConfig {
    /// Largest normal angle of a candidate match after the initial guess, degrees. Applies to
    /// [`estimate_motion`] always (the identity without a guess) and to
    /// [`estimate_motion_verified`] only when a guess is given (without one every pair of
    /// planes is a candidate).
    pub max_angle_deg: f64,
    /// Largest offset difference of a candidate match after the initial guess, metres (applies
    /// like `max_angle_deg`).
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
    /// Two rotation hypotheses further apart than this are distinct alternatives, degrees.
    /// Real Kinect planes are bent by the sensor's low-frequency distortion (the bands of one
    /// desk disagree by up to ~6°), so proposals from different bands of the same planes
    /// scatter by several degrees; 15° is over twice that.
    pub distinct_deg: f64,
    /// Planes only: a distinct alternative with at least this fraction of the winner's support
    /// makes the result [`MotionConfidence::Ambiguous`]. Support counts pixels and real planes
    /// are often split into several bands that each count, so only a clear margin means
    /// anything.
    pub ambiguity_ratio: f64,
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
            distinct_deg: 15.0,
            ambiguity_ratio: 0.7,
        }
    }
}

impl MotionConfig {
    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        let angles = [
            ("max_angle_deg", self.max_angle_deg),
            ("inlier_angle_deg", self.inlier_angle_deg),
            ("min_spread_deg", self.min_spread_deg),
            ("distinct_deg", self.distinct_deg),
        ];
        for (name, v) in angles {
            if !(v > 0.0 && v <= 180.0) {
                return Err(PlanesError::InvalidConfig(format!(
                    "{name} must lie in (0, 180], got {v}"
                )));
            }
        }
        for (name, v) in [
            ("max_offset_m", self.max_offset_m),
            ("inlier_offset_m", self.inlier_offset_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(PlanesError::InvalidConfig(format!(
                    "{name} must be positive, got {v}"
                )));
            }
        }
        if !(0.0..=1.0).contains(&self.ambiguity_ratio)
            || !(0.0..1.0).contains(&self.min_translation_eigen)
        {
            return Err(PlanesError::InvalidConfig(
                "ambiguity_ratio must lie in [0, 1] and min_translation_eigen in [0, 1)".into(),
            ));
        }
        Ok(())
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

/// How far a [`PlaneMotion`] can be trusted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionConfidence {
    /// Checked against both depth maps ([`estimate_motion_verified`]): the alignment explains
    /// most overlapping points and no distinct alternative comes close (see
    /// [`PlaneMotion::verification`]).
    Verified,
    /// From planes only; no distinct rotation hypothesis has comparable plane support.
    Unverified,
    /// From planes only, and a distinct rotation hypothesis (more than
    /// [`MotionConfig::distinct_deg`] away) has nearly the same plane support
    /// ([`PlaneMotion::runner_up_support`]): the rotation may be wrong by a large angle.
    Ambiguous,
}

impl MotionConfidence {
    /// Lower-case name (`verified`, `unverified`, `ambiguous`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Verified => "verified",
            Self::Unverified => "unverified",
            Self::Ambiguous => "ambiguous",
        }
    }
}

/// The result of checking a motion against the depth maps.
#[derive(Debug, Clone, PartialEq)]
pub struct Verification {
    /// Fraction of the overlapping points that lie on the other frame's surface after the
    /// winning hypothesis' local refinement (B's points in A and A's points in B together).
    pub inlier_fraction: f64,
    /// Fraction of the points that land on a valid pixel of the other frame.
    pub overlap_fraction: f64,
    /// The largest inlier fraction of a distinct alternative (another plane hypothesis more
    /// than `distinct_deg` away, refined on the data); 0 when there is none. Below
    /// `min_inlier_fraction` for a verified motion.
    pub alternative_inlier_fraction: f64,
    /// The largest inlier fraction of the winning alignment turned by `distinct_deg` about one
    /// of several axes (camera axes and plane normals, through the inliers' centroid): close
    /// to the winner's when the shared view cannot pin the rotation down. Below
    /// `min_inlier_fraction` for a verified motion.
    pub turned_inlier_fraction: f64,
    /// Distinct plane hypotheses scored on the data.
    pub hypotheses: usize,
    /// Points used per frame (the fewer of the two).
    pub samples: usize,
    /// The winning hypothesis after the short data refinement (a coarse ICP result, not the
    /// plane estimate).
    pub aligned: Isometry3<f64>,
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
    /// How far the result can be trusted.
    pub confidence: MotionConfidence,
    /// Plane support of the best distinct alternative hypothesis relative to the winner's
    /// (0 when there is none).
    pub runner_up_support: f64,
    /// The check against the depth maps ([`estimate_motion_verified`] only).
    pub verification: Option<Verification>,
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
/// the eigen-directions of `Σw·n·nᵀ/Σw` above `min_eigen`; also whether all three are.
fn partial_translation(rows: &[(Vector3<f64>, f64, f64)], min_eigen: f64) -> (Vector3<f64>, bool) {
    let mut m = Matrix3::zeros();
    let mut v = Vector3::zeros();
    let mut sw = 0.0;
    for (n, delta, w) in rows {
        m += *w * n * n.transpose();
        v += *w * n * *delta;
        sw += w;
    }
    if sw <= 0.0 {
        return (Vector3::zeros(), false);
    }
    let eig = SymmetricEigen::new(m / sw);
    let mut t = Vector3::zeros();
    let mut full = true;
    for i in 0..3 {
        let l = eig.eigenvalues[i];
        if l > min_eigen {
            let e = eig.eigenvectors.column(i).into_owned();
            t += e * (e.dot(&(v / sw)) / l);
        } else {
            full = false;
        }
    }
    (t, full)
}

/// The angle between two rotations, radians, robust near 180° (`Rotation3::angle_to` goes
/// through `acos` of the trace and turns NaN there).
fn rotation_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    UnitQuaternion::from_rotation_matrix(a).angle_to(&UnitQuaternion::from_rotation_matrix(b))
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// A rotation hypothesis with its plane consensus (in the guess-transformed frame of B).
#[derive(Debug, Clone)]
struct Hypothesis {
    rotation: Rotation3<f64>,
    support: f64,
    matches: Vec<PlaneMatch>,
    translation: Vector3<f64>,
}

/// Plane matching between A and B (B transformed by the initial guess).
struct Matcher<'p> {
    planes_a: &'p [PlaneInfo],
    planes_b: &'p [PlaneInfo],
    /// B's planes after the guess.
    bt: Vec<Plane3>,
    /// Candidate pairs, by decreasing weight.
    cands: Vec<PlaneMatch>,
    cfg: MotionConfig,
}

impl<'p> Matcher<'p> {
    /// Candidates near `prior` (all pairs without one).
    fn new(
        planes_a: &'p [PlaneInfo],
        planes_b: &'p [PlaneInfo],
        prior: Option<&Isometry3<f64>>,
        cfg: &MotionConfig,
    ) -> Self {
        let g = prior.copied().unwrap_or_else(Isometry3::identity);
        let bt: Vec<Plane3> = planes_b.iter().map(|p| p.plane.transformed(&g)).collect();
        let mut cands = Vec::new();
        for (i, pa) in planes_a.iter().enumerate() {
            for (j, pb) in bt.iter().enumerate() {
                let near = pa.plane.angle_deg(pb) < cfg.max_angle_deg
                    && (pa.plane.offset_m - pb.offset_m).abs() < cfg.max_offset_m;
                if prior.is_none() || near {
                    cands.push(PlaneMatch {
                        a: i,
                        b: j,
                        weight: pa.pixels.min(planes_b[j].pixels) as f64,
                    });
                }
            }
        }
        cands.sort_by(|x, y| y.weight.total_cmp(&x.weight));
        Self {
            planes_a,
            planes_b,
            bt,
            cands,
            cfg: *cfg,
        }
    }

    fn na(&self, m: &PlaneMatch) -> Vector3<f64> {
        self.planes_a[m.a].plane.normal
    }

    fn nb(&self, m: &PlaneMatch) -> Vector3<f64> {
        self.bt[m.b].normal
    }

    /// Greedy one-to-one matches of a rotation whose offsets agree with one translation, their
    /// support and that translation.
    fn inliers(&self, r: &Rotation3<f64>) -> (f64, Vec<PlaneMatch>, Vector3<f64>) {
        let mut used_a = vec![false; self.planes_a.len()];
        let mut used_b = vec![false; self.planes_b.len()];
        let mut out = Vec::new();
        for m in &self.cands {
            if used_a[m.a] || used_b[m.b] {
                continue;
            }
            if angle_deg(&self.na(m), &(r * self.nb(m))) < self.cfg.inlier_angle_deg {
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
                    self.na(m),
                    self.bt[m.b].offset_m - self.planes_a[m.a].plane.offset_m,
                    m.weight,
                )
            })
            .collect();
        let (t, _) = partial_translation(&rows, self.cfg.min_translation_eigen);
        let kept: Vec<PlaneMatch> = out
            .into_iter()
            .zip(&rows)
            .filter(|(_, (n, delta, _))| (delta - n.dot(&t)).abs() < self.cfg.inlier_offset_m)
            .map(|(m, _)| m)
            .collect();
        let score = kept.iter().map(|m| m.weight).sum();
        (score, kept, t)
    }

    fn kabsch(&self, ms: &[PlaneMatch]) -> Option<Rotation3<f64>> {
        weighted_kabsch(
            &ms.iter()
                .map(|m| (self.na(m), self.nb(m), m.weight))
                .collect::<Vec<_>>(),
        )
    }

    /// All distinct rotation hypotheses, by decreasing support.
    fn hypotheses(&self) -> Vec<Hypothesis> {
        let cfg = &self.cfg;
        let mut all: Vec<Hypothesis> = Vec::new();
        for (x, m1) in self.cands.iter().enumerate() {
            for m2 in &self.cands[x + 1..] {
                if m1.a == m2.a || m1.b == m2.b {
                    continue;
                }
                let spread_a = angle_deg(&self.na(m1), &self.na(m2));
                if spread_a < cfg.min_spread_deg || spread_a > 180.0 - cfg.min_spread_deg {
                    continue;
                }
                let spread_b = angle_deg(&self.nb(m1), &self.nb(m2));
                if (spread_a - spread_b).abs() > 2.0 * cfg.inlier_angle_deg {
                    continue;
                }
                let Some(r0) = self.kabsch(&[*m1, *m2]) else {
                    continue;
                };
                let (s0, ms0, t0) = self.inliers(&r0);
                // One refinement over the inliers, kept when it does not lose support.
                let refined = self.kabsch(&ms0).map(|r1| (r1, self.inliers(&r1)));
                let h = match refined {
                    Some((r1, (s1, ms1, t1))) if s1 >= s0 && self.kabsch(&ms1).is_some() => {
                        Hypothesis {
                            rotation: r1,
                            support: s1,
                            matches: ms1,
                            translation: t1,
                        }
                    }
                    _ => Hypothesis {
                        rotation: r0,
                        support: s0,
                        matches: ms0,
                        translation: t0,
                    },
                };
                all.push(h);
            }
        }
        all.sort_by(|x, y| y.support.total_cmp(&x.support));
        // Merge hypotheses closer than the inlier angle (they share their matches).
        let mut out: Vec<Hypothesis> = Vec::new();
        let merge = cfg.inlier_angle_deg.to_radians();
        for h in all {
            if out
                .iter()
                .all(|o| rotation_between(&o.rotation, &h.rotation) > merge)
            {
                out.push(h);
            }
        }
        out
    }

    /// The largest support of a hypothesis more than `distinct_deg` from `r`, relative to the
    /// support of the winner's `matches`.
    fn runner_up(&self, hyps: &[Hypothesis], r: &Rotation3<f64>, matches: &[PlaneMatch]) -> f64 {
        let d = self.cfg.distinct_deg.to_radians();
        let own: f64 = matches.iter().map(|m| m.weight).sum();
        hyps.iter()
            .filter(|h| rotation_between(&h.rotation, r) > d)
            .map(|h| h.support)
            .fold(0.0, f64::max)
            / own.max(1.0)
    }

    fn undetermined(&self) -> PlanesError {
        PlanesError::MotionUndetermined(format!(
            "need two matched non-parallel planes ({} planes in A, {} in B, {} candidate pairs)",
            self.planes_a.len(),
            self.planes_b.len(),
            self.cands.len()
        ))
    }
}

/// The weighted RMS angle of matched normals under `rotation`, degrees.
fn rms_angle(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    rotation: &UnitQuaternion<f64>,
    matches: &[PlaneMatch],
) -> f64 {
    let (mut sw, mut sa) = (0.0, 0.0);
    for m in matches {
        let a = angle_deg(
            &planes_a[m.a].plane.normal,
            &(rotation * planes_b[m.b].plane.normal),
        );
        sw += m.weight;
        sa += m.weight * a * a;
    }
    if sw > 0.0 { (sa / sw).sqrt() } else { 0.0 }
}

/// Matches the planes of two frames and estimates the motion of B in A's coordinates from the
/// planes alone. `guess` is an initial `X_a = R₀·X_b + t₀`, the identity when `None`: only
/// plane pairs within `max_angle_deg` / `max_offset_m` of it are candidates, so without a
/// guess the motion must be small (below about `max_angle_deg`). Plane normals alone cannot
/// break the symmetries of man-made scenes (opposite walls, several surfaces at the same angle
/// to the floor) without such a prior.
///
/// The result is [`MotionConfidence::Unverified`], or [`MotionConfidence::Ambiguous`] when a
/// distinct rotation has nearly the same plane support: plane normals alone cannot always tell
/// similar structures apart. Use [`estimate_motion_verified`] when the depth maps are
/// available.
pub fn estimate_motion(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    guess: Option<&Isometry3<f64>>,
    cfg: &MotionConfig,
) -> Result<PlaneMotion> {
    cfg.validate()?;
    // Without data to check against, plane matching needs a prior to break the symmetries of
    // man-made scenes (opposite walls, repeated structures): the identity when none is given.
    let g = guess.copied().unwrap_or_else(Isometry3::identity);
    let mt = Matcher::new(planes_a, planes_b, Some(&g), cfg);
    let hyps = mt.hypotheses();
    let Some(best) = hyps.first() else {
        return Err(mt.undetermined());
    };
    // Refine on all inliers, then re-collect once.
    let mut matches = best.matches.clone();
    let mut r = mt
        .kabsch(&matches)
        .ok_or_else(|| PlanesError::MotionUndetermined("degenerate normals".into()))?;
    let (_, again, _) = mt.inliers(&r);
    if again.len() >= 2
        && let Some(r2) = mt.kabsch(&again)
    {
        r = r2;
        matches = again;
    }
    let runner_up_support = mt.runner_up(&hyps, &r, &matches);
    let rotation = UnitQuaternion::from_rotation_matrix(&(r * g.rotation.to_rotation_matrix()));
    // Translation from the original (untransformed) B planes: n_a·t = d_b − d_a.
    let (translation_m, translation_partial_m, matches) =
        solve_translation(planes_a, planes_b, &rotation, matches, cfg);
    Ok(PlaneMotion {
        rotation,
        translation_m,
        translation_partial_m,
        rms_angle_deg: rms_angle(planes_a, planes_b, &rotation, &matches),
        matches,
        confidence: if runner_up_support >= cfg.ambiguity_ratio {
            MotionConfidence::Ambiguous
        } else {
            MotionConfidence::Unverified
        },
        runner_up_support,
        verification: None,
    })
}

/// One frame for [`estimate_motion_verified`]: its depth map and its planes (extracted from
/// that depth map).
#[derive(Debug, Clone, Copy)]
pub struct MotionFrame<'a> {
    /// Depth map, metres (0 = invalid).
    pub depth: &'a DepthImage,
    /// Planes extracted from `depth`.
    pub planes: &'a [PlaneInfo],
}

/// Fewest usable frame-B points for a verification.
const MIN_SAMPLES: usize = 100;

/// Points per frame of the coarse score that ranks the unrefined hypotheses.
const COARSE_SAMPLES: usize = 300;

/// Points per frame of the local refinement and of the perturbation check.
const SPARSE_SAMPLES: usize = 1000;

/// Plane normals (besides the camera axes) about which the verified alignment is perturbed.
const MAX_PERTURB_PLANES: usize = 6;

/// A plane hypothesis after the check against the data.
#[derive(Debug, Clone)]
struct Checked {
    /// The hypothesis after the local refinement on the data.
    aligned: Isometry3<f64>,
    score: Score,
    /// Plane support of the hypothesis.
    support: f64,
    /// Plane matches consistent with `aligned` (or the hypothesis' own, see below).
    matches: Vec<PlaneMatch>,
    /// Weighted Kabsch rotation of `matches`.
    rotation: Rotation3<f64>,
}

/// Whether two of the matched planes (in A) are at least `min_spread_deg` from parallel: only
/// then do the matches determine a rotation about every axis.
fn spread_ok(planes_a: &[PlaneInfo], matches: &[PlaneMatch], cfg: &MotionConfig) -> bool {
    matches.iter().enumerate().any(|(k, m1)| {
        matches[k + 1..].iter().any(|m2| {
            let s = angle_deg(&planes_a[m1.a].plane.normal, &planes_a[m2.a].plane.normal);
            s >= cfg.min_spread_deg && s <= 180.0 - cfg.min_spread_deg
        })
    })
}

/// Weighted Kabsch over matches of A's and B's planes.
fn kabsch_ab(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    matches: &[PlaneMatch],
) -> Option<Rotation3<f64>> {
    let pairs: Vec<_> = matches
        .iter()
        .map(|m| {
            (
                planes_a[m.a].plane.normal,
                planes_b[m.b].plane.normal,
                m.weight,
            )
        })
        .collect();
    weighted_kabsch(&pairs)
}

/// Matches the planes of two frames, checks every rotation hypothesis against the depth maps
/// and estimates the motion of B in A's coordinates (`X_a = R·X_b + t`). Frames A and B come
/// from the same `camera`; `guess` is an optional initial motion (without it every rotation is
/// considered).
///
/// Every plane hypothesis (see the module docs) is scored on grids of points of both frames,
/// each moved into the other frame: points on the other frame's surface agree, points landing
/// in front of or behind it contradict (see [`VerifyConfig`]). The best `refine_hypotheses`
/// (agreement − `outlier_weight`·contradictions) are refined by a short point-to-plane ICP,
/// scored again and kept when two non-parallel plane matches are consistent with them. The
/// best one must
/// * overlap the other frame with `min_overlap_fraction` of the points and explain
///   `min_inlier_fraction` of the overlapping ones;
/// * be the only such hypothesis: no alternative more than `distinct_deg` away may explain
///   `min_inlier_fraction` of its overlapping points;
/// * not stay consistent when turned by `distinct_deg` about the camera axes or a plane normal
///   (through its inliers' centroid): otherwise the shared view (e.g. mostly one plane) cannot
///   tell such rotations apart.
///
/// The returned rotation is then the weighted Kabsch over the plane matches consistent with
/// the verified alignment, and the translation comes from their offsets.
///
/// # Errors
/// [`PlanesError::MotionUndetermined`] when the planes propose no rotation (fewer than two
/// non-parallel planes seen in both frames) or a frame has too few usable points;
/// [`PlanesError::MotionNotVerified`] when no hypothesis explains the data with two plane
/// matches, two distinct ones explain it, or the shared view does not constrain the
/// rotation; size and configuration errors.
///
/// ```
/// use sl_core::{Camera, DepthImage, nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3}};
/// use sl_planes::{MotionConfidence, MotionConfig, MotionFrame, Plane3, PlaneConfig,
///     PlaneExtractor, VerifyConfig, estimate_motion_verified};
///
/// // A room (floor, ceiling, three walls, none at right angles) seen by a wide 160x120 camera,
/// // and the same room after the camera turned 35° about the vertical axis and moved 5 cm.
/// let k = sl_core::Intrinsics::new(160, 120, 60.0, 60.0, 79.5, 59.5)?;
/// let cam = Camera { intrinsics: k, sensor: sl_core::SensorModel::kinect_v1() };
/// let room = [
///     Plane3::new(Vector3::new(0.0, -1.0, 0.0), 0.8)?,
///     Plane3::new(Vector3::new(-0.048, 0.999, -0.012), 1.6)?,
///     Plane3::new(Vector3::new(-0.982, -0.1, 0.158), 1.5)?,
///     Plane3::new(Vector3::new(0.856, -0.472, 0.213), 1.1)?,
///     Plane3::new(Vector3::new(-0.213, 0.164, -0.963), 3.0)?,
/// ];
/// let render = |planes: &[Plane3]| {
///     let z = (0..k.width * k.height).map(|i| {
///         let (x, y) = ((i % k.width) as f64, (i / k.width) as f64);
///         let z = planes.iter().filter_map(|p| p.depth_at(&k, x, y)).fold(f64::INFINITY, f64::min);
///         if z.is_finite() { z as f32 } else { 0.0 }
///     });
///     DepthImage::from_vec(k.width, k.height, z.collect())
/// };
/// let truth = Isometry3::from_parts(
///     Translation3::new(0.05, 0.0, 0.0),
///     UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 35f64.to_radians()),
/// );
/// let room_b: Vec<Plane3> = room.iter().map(|p| p.transformed(&truth.inverse())).collect();
/// let (da, db) = (render(&room)?, render(&room_b)?);
/// let mut ex = PlaneExtractor::new(PlaneConfig { min_pixels: 200, ..PlaneConfig::default() })?;
/// let (sa, sb) = (ex.extract_depth(&da, &cam)?, ex.extract_depth(&db, &cam)?);
/// let m = estimate_motion_verified(
///     MotionFrame { depth: &da, planes: &sa.planes },
///     MotionFrame { depth: &db, planes: &sb.planes },
///     &cam, None, &MotionConfig::default(), &VerifyConfig::default(),
/// )?;
/// assert_eq!(m.confidence, MotionConfidence::Verified);
/// assert!(m.rotation.angle_to(&truth.rotation).to_degrees() < 0.5);
/// assert!(m.verification.as_ref().is_some_and(|v| v.inlier_fraction > 0.9));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn estimate_motion_verified(
    a: MotionFrame<'_>,
    b: MotionFrame<'_>,
    camera: &Camera,
    guess: Option<&Isometry3<f64>>,
    cfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<PlaneMotion> {
    cfg.validate()?;
    vcfg.validate()?;
    let g = guess.copied().unwrap_or_else(Isometry3::identity);
    let mt = Matcher::new(a.planes, b.planes, guess, cfg);
    let hyps = mt.hypotheses();
    if hyps.is_empty() {
        return Err(mt.undetermined());
    }
    let mut check = TwoWay::new(
        a.depth,
        b.depth,
        camera,
        vcfg.max_samples,
        (SPARSE_SAMPLES, COARSE_SAMPLES),
    )?;
    if check.samples() < MIN_SAMPLES {
        return Err(PlanesError::MotionUndetermined(format!(
            "only {} usable points in a frame (need {MIN_SAMPLES})",
            check.samples()
        )));
    }
    let w_out = vcfg.outlier_weight;
    let tol = (vcfg.inlier_base_m, vcfg.inlier_sigmas);
    // Coarse score of every hypothesis as proposed by the planes, on few samples
    // (hypotheses that move the frames mostly out of each other's view are left out).
    let mut coarse: Vec<(usize, Isometry3<f64>, f64)> = Vec::with_capacity(hyps.len());
    for (i, h) in hyps.iter().enumerate() {
        let pose = Isometry3::from_parts(
            Translation3::from(h.translation),
            UnitQuaternion::from_rotation_matrix(&h.rotation),
        ) * g;
        let s = check.score(&pose, (vcfg.coarse_inlier_m, 0.0), Density::Coarse);
        if s.overlap_fraction() >= vcfg.min_overlap_fraction {
            coarse.push((i, pose, s.evidence(w_out)));
        }
    }
    coarse.sort_by(|x, y| y.2.total_cmp(&x.2).then(x.0.cmp(&y.0)));
    let distinct = cfg.distinct_deg.to_radians();
    // Local refinement and the final score of the best ones.
    let mut checked: Vec<Checked> = Vec::new();
    for (i, pose, _) in coarse.iter().take(vcfg.refine_hypotheses) {
        let Ok(aligned) = check.refine(
            pose,
            vcfg.refine_iterations,
            vcfg.refine_start_m,
            vcfg.refine_end_m,
        ) else {
            continue;
        };
        let score = check.score(&aligned, tol, Density::Full);
        if score.overlap_fraction() < vcfg.min_overlap_fraction {
            continue;
        }
        // A motion from planes needs planes: two plane matches at least `min_spread_deg`
        // apart, consistent with the refined alignment, or else those of the hypothesis itself
        // if it lies within `distinct_deg` of the alignment (the bands of one bent desk
        // determine no rotation about its normal).
        let consistent = consistent_matches(a.planes, b.planes, &aligned, cfg);
        let own = &hyps[*i].matches;
        let own_rotation = UnitQuaternion::from_rotation_matrix(&hyps[*i].rotation) * g.rotation;
        let Some((rotation, matches)) = [consistent, own.clone()]
            .into_iter()
            .enumerate()
            .filter(|(k, _)| *k == 0 || own_rotation.angle_to(&aligned.rotation) < distinct)
            .find_map(|(_, ms)| {
                spread_ok(a.planes, &ms, cfg)
                    .then(|| kabsch_ab(a.planes, b.planes, &ms))
                    .flatten()
                    .map(|r| (r, ms))
            })
        else {
            continue;
        };
        checked.push(Checked {
            aligned,
            score,
            support: hyps[*i].support,
            matches,
            rotation,
        });
    }
    checked.sort_by(|x, y| {
        y.score
            .evidence(w_out)
            .total_cmp(&x.score.evidence(w_out))
            .then(y.support.total_cmp(&x.support))
    });
    let Some(best) = checked.first() else {
        return Err(PlanesError::MotionNotVerified {
            reason: format!(
                "none of the {} plane hypotheses, refined on the data, overlaps the other \
                 frame with {:.0} % of the points and keeps two non-parallel plane matches",
                hyps.len(),
                100.0 * vcfg.min_overlap_fraction
            ),
            inlier_fraction: 0.0,
            alternative_inlier_fraction: 0.0,
        });
    };
    let aligned = best.aligned;
    let inlier_fraction = best.score.inlier_fraction();
    let overlap_fraction = best.score.overlap_fraction();
    // A pose is consistent with the data when it explains `min_inlier_fraction` of the
    // overlapping points; the winner must be, and no distinct alternative may be.
    let consistent = |s: &Score| {
        s.overlap_fraction() >= vcfg.min_overlap_fraction
            && s.inlier_fraction() >= vcfg.min_inlier_fraction
    };
    let alternative = checked
        .iter()
        .filter(|c| c.aligned.rotation.angle_to(&aligned.rotation) > distinct)
        .map(|c| c.score)
        .max_by(|x, y| x.inlier_fraction().total_cmp(&y.inlier_fraction()));
    let alternative_inlier_fraction = alternative.map_or(0.0, |s| s.inlier_fraction());
    let not_verified = |reason: String, alt: f64| PlanesError::MotionNotVerified {
        reason,
        inlier_fraction,
        alternative_inlier_fraction: alt,
    };
    if !consistent(&best.score) {
        return Err(not_verified(
            format!(
                "the best of {} plane hypotheses explains {:.0} % of the overlapping points \
                 (< {:.0} %)",
                hyps.len(),
                100.0 * inlier_fraction,
                100.0 * vcfg.min_inlier_fraction
            ),
            alternative_inlier_fraction,
        ));
    }
    if alternative.as_ref().is_some_and(consistent) {
        return Err(not_verified(
            format!(
                "ambiguous: a rotation more than {}° away from the best also explains {:.0} % \
                 of its overlapping points",
                cfg.distinct_deg,
                100.0 * alternative_inlier_fraction
            ),
            alternative_inlier_fraction,
        ));
    }
    // Can the data tell the winner from rotations `distinct_deg` away at all? Turning the
    // alignment about the normal of a dominant plane (through the inliers' centroid) slides
    // that plane in itself: when the shared view is mostly one plane such a turn stays
    // consistent, and an alternative there could not have been rejected.
    let mut axes: Vec<Vector3<f64>> = vec![Vector3::x(), Vector3::y(), Vector3::z()];
    for p in a.planes {
        if axes.len() >= 3 + MAX_PERTURB_PLANES {
            break;
        }
        if axes[3..]
            .iter()
            .all(|n| angle_deg(n, &p.plane.normal) > cfg.distinct_deg)
        {
            axes.push(p.plane.normal);
        }
    }
    let turned = check
        .perturbed(&aligned, &axes, distinct, tol)
        .into_iter()
        .max_by(|x, y| x.inlier_fraction().total_cmp(&y.inlier_fraction()));
    let turned_inlier_fraction = turned.map_or(0.0, |s| s.inlier_fraction());
    if turned.as_ref().is_some_and(consistent) {
        return Err(not_verified(
            format!(
                "the shared view does not pin the rotation down (mostly one plane?): the \
                 alignment turned by {}° still explains {:.0} % of the overlapping points",
                cfg.distinct_deg,
                100.0 * turned_inlier_fraction
            ),
            turned_inlier_fraction,
        ));
    }
    // The plane estimate: weighted Kabsch over the matches consistent with the alignment.
    let (r, matches) = (best.rotation, best.matches.clone());
    let rotation = UnitQuaternion::from_rotation_matrix(&r);
    let (translation_m, translation_partial_m, matches) =
        solve_translation(a.planes, b.planes, &rotation, matches, cfg);
    // The matches index the same planes in the guess-transformed frame of the matcher.
    let runner_up_support = mt.runner_up(
        &hyps,
        &(r * g.rotation.to_rotation_matrix().inverse()),
        &matches,
    );
    Ok(PlaneMotion {
        rotation,
        translation_m,
        translation_partial_m,
        rms_angle_deg: rms_angle(a.planes, b.planes, &rotation, &matches),
        matches,
        confidence: MotionConfidence::Verified,
        runner_up_support,
        verification: Some(Verification {
            inlier_fraction,
            overlap_fraction,
            alternative_inlier_fraction,
            turned_inlier_fraction,
            hypotheses: hyps.len(),
            samples: check.samples(),
            aligned,
        }),
    })
}

/// Greedy one-to-one plane matches (by decreasing weight) consistent with a motion: normals
/// within `inlier_angle_deg`, offsets within `inlier_offset_m`.
fn consistent_matches(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    pose: &Isometry3<f64>,
    cfg: &MotionConfig,
) -> Vec<PlaneMatch> {
    let mut cands: Vec<PlaneMatch> = Vec::new();
    for (i, pa) in planes_a.iter().enumerate() {
        for (j, pb) in planes_b.iter().enumerate() {
            let n = pose.rotation * pb.plane.normal;
            let d = pb.plane.offset_m - n.dot(&pose.translation.vector);
            if angle_deg(&pa.plane.normal, &n) < cfg.inlier_angle_deg
                && (d - pa.plane.offset_m).abs() < cfg.inlier_offset_m
            {
                cands.push(PlaneMatch {
                    a: i,
                    b: j,
                    weight: pa.pixels.min(pb.pixels) as f64,
                });
            }
        }
    }
    cands.sort_by(|x, y| y.weight.total_cmp(&x.weight));
    let mut used_a = vec![false; planes_a.len()];
    let mut used_b = vec![false; planes_b.len()];
    cands
        .into_iter()
        .filter(|m| {
            let free = !used_a[m.a] && !used_b[m.b];
            if free {
                used_a[m.a] = true;
                used_b[m.b] = true;
            }
            free
        })
        .collect()
}

fn solve_translation(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    rotation: &UnitQuaternion<f64>,
    matches: Vec<PlaneMatch>,
    cfg: &MotionConfig,
) -> (Option<Vector3<f64>>, Vector3<f64>, Vec<PlaneMatch>) {
    let solve = |ms: &[PlaneMatch]| {
        let rows: Vec<(Vector3<f64>, f64, f64)> = ms
            .iter()
            .map(|mt| {
                let (pa, pb) = (&planes_a[mt.a].plane, &planes_b[mt.b].plane);
                let n = (pa.normal + rotation * pb.normal).normalize();
                (n, pb.offset_m - pa.offset_m, mt.weight)
            })
            .collect();
        let (t, full) = partial_translation(&rows, cfg.min_translation_eigen);
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
    /// From a rough start (e.g. the identity): correspondences up to 15 cm apart at first.
    fn default() -> Self {
        Self {
            iterations: 30,
            stride: 4,
            max_dist_m: 0.15,
            min_dist_m: 0.02,
        }
    }
}

impl IcpConfig {
    /// For refining a verified alignment ([`refine_motion_icp_verified`]): as the default
    /// but with correspondences at most 5 cm apart from the first iteration. The verified
    /// alignment already puts ≥ 90 % of the overlapping points within the inlier tolerance
    /// of [`VerifyConfig`] (1 cm + 3σ_Z, under 3 cm up to 3 m), so a pair further apart is
    /// almost always a point matched to the wrong surface. With the default 15 cm such pairs
    /// dominate when the views overlap little and pull the rotation about a dominant plane's
    /// normal, which the rest of the view constrains only weakly (TUM fr1/rpy 0 → 15: 34.8° of
    /// motion, 27 % overlap; 15 cm from the verified alignment ends 3.6° from the motion
    /// capture, 5 cm ends 1.5° away and explains 99 % instead of 96 % of the overlap).
    pub fn refinement() -> Self {
        Self {
            max_dist_m: 0.05,
            ..Self::default()
        }
    }

    /// Checks the ranges of the parameters.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 || self.stride == 0 {
            return Err(PlanesError::InvalidConfig(
                "ICP iterations and stride must be ≥ 1".into(),
            ));
        }
        if !(self.min_dist_m.is_finite()
            && self.min_dist_m > 0.0
            && self.max_dist_m.is_finite()
            && self.max_dist_m >= self.min_dist_m)
        {
            return Err(PlanesError::InvalidConfig(format!(
                "ICP needs 0 < min_dist_m ≤ max_dist_m, got {} and {}",
                self.min_dist_m, self.max_dist_m
            )));
        }
        Ok(())
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
///
/// ICP only minimises residuals: nothing checks that the result explains the data better
/// than its start. To refine a verified motion use [`refine_motion_icp_verified`], which
/// accepts the refinement only when the depth data confirm it.
pub fn icp_point_to_plane(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    init: &Isometry3<f64>,
    cfg: &IcpConfig,
) -> Result<IcpResult> {
    let mut target = Target::new(depth_a, camera)?;
    let k = &camera.intrinsics;
    if depth_b.width() != k.width || depth_b.height() != k.height {
        return Err(PlanesError::SizeMismatch {
            expected_width: k.width,
            expected_height: k.height,
            width: depth_b.width(),
            height: depth_b.height(),
        });
    }
    let src = verify::grid_points(depth_b, k, cfg.stride);
    let (pose, inliers, rms_m) = verify::icp(
        &mut target,
        &src,
        init,
        cfg.iterations,
        cfg.max_dist_m,
        cfg.min_dist_m,
    )?;
    Ok(IcpResult {
        pose,
        inliers,
        rms_m,
    })
}

/// Largest loss of inlier fraction (of the overlapping points, see [`Verification`]) with
/// which an ICP refinement is still accepted by [`refine_motion_icp_verified`]: 0.001, i.e.
/// 8 of the 8000 points of the default two-way check. The fraction is a ratio of counts, and
/// a refinement that moves the pose by a hundredth of a degree flips a few points at the
/// tolerance boundary either way; a loss beyond that is a real loss.
pub const ICP_INLIER_TOLERANCE: f64 = 1e-3;

/// Why [`refine_motion_icp_verified`] kept the plane estimate.
#[derive(Debug, Clone, PartialEq)]
pub enum IcpRejection {
    /// ICP itself failed (too few correspondences, singular normal equations).
    Failed(String),
    /// The refined pose is not consistent with the data: it explains fewer than
    /// `min_inlier_fraction` of the overlapping points or overlaps the other frame with fewer
    /// than `min_overlap_fraction` of the points ([`VerifyConfig`]).
    NotVerified,
    /// The refined pose explains a smaller fraction of the overlapping points than the
    /// verified estimate (by more than [`ICP_INLIER_TOLERANCE`]).
    LostInliers,
    /// The refined rotation is more than [`MotionConfig::distinct_deg`] from the start: a
    /// distinct alternative that the verification did not rule in.
    MovedTooFar,
}

impl IcpRejection {
    /// Short lower-case name (`icp-failed`, `not-verified`, `lost-inliers`, `moved-too-far`).
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Failed(_) => "icp-failed",
            Self::NotVerified => "not-verified",
            Self::LostInliers => "lost-inliers",
            Self::MovedTooFar => "moved-too-far",
        }
    }
}

/// The result of [`refine_motion_icp_verified`].
#[derive(Debug, Clone, PartialEq)]
pub struct IcpOutcome {
    /// Whether the ICP refinement was accepted (`rejection` is `None` exactly then).
    pub accepted: bool,
    /// Why it was not.
    pub rejection: Option<IcpRejection>,
    /// The motion to use: ICP's pose when accepted, else the plane estimate
    /// ([`PlaneMotion::isometry`]).
    pub pose: Isometry3<f64>,
    /// Where ICP started: the verified alignment ([`Verification::aligned`]) when the motion
    /// has one, else the plane estimate.
    pub start: Isometry3<f64>,
    /// ICP's own result (also when rejected); `None` when ICP failed.
    pub icp: Option<IcpResult>,
    /// Inlier fraction of the estimate before the refinement: the verification's
    /// ([`Verification::inlier_fraction`]), or for an unverified motion that of the plane
    /// estimate, scored the same way.
    pub inlier_fraction_before: f64,
    /// Inlier fraction of ICP's pose (two-way, as in the verification); `None` when ICP
    /// failed.
    pub inlier_fraction_after: Option<f64>,
    /// Overlap fraction of ICP's pose; `None` when ICP failed.
    pub overlap_fraction_after: Option<f64>,
}

/// Refines a plane-based motion by point-to-plane ICP and accepts the refinement only when
/// the depth data confirm it; otherwise keeps the plane estimate.
///
/// ICP starts from the verified alignment ([`Verification::aligned`], the pose the
/// verification scored) when the motion has one, else from [`PlaneMotion::isometry`]; use
/// [`IcpConfig::refinement`] (a tight correspondence gate) for a verified start. The ICP pose
/// is then checked exactly like a hypothesis in [`estimate_motion_verified`] (the same
/// two-way grid samples of both depth maps and the same tolerances of `vcfg`) and accepted
/// only when
/// * it overlaps the other frame with `min_overlap_fraction` of the points and explains
///   `min_inlier_fraction` of the overlapping ones (it is itself verified);
/// * it explains no smaller a fraction than the estimate did, up to
///   [`ICP_INLIER_TOLERANCE`];
/// * its rotation lies within `mcfg.distinct_deg` of the start (a rotation further away is an
///   alternative that the verification's ambiguity checks never saw).
///
/// The decision uses the depth maps only, never a reference trajectory. When rejected, the
/// outcome's `pose` is the plane estimate and `rejection` says why; ICP's own result is kept
/// for inspection.
///
/// # Errors
/// Size and configuration errors only; a failing ICP is a rejection.
///
/// ```
/// use sl_core::{Camera, DepthImage, nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3}};
/// use sl_planes::{IcpConfig, MotionConfig, MotionFrame, Plane3, PlaneConfig, PlaneExtractor,
///     VerifyConfig, estimate_motion_verified, refine_motion_icp_verified};
///
/// // Floor, ceiling and two walls seen by a 160x120 camera, which then turns 10° and moves.
/// let k = sl_core::Intrinsics::new(160, 120, 80.0, 80.0, 79.5, 59.5)?;
/// let cam = Camera { intrinsics: k, sensor: sl_core::SensorModel::kinect_v1() };
/// let room = [
///     Plane3::new(Vector3::new(0.0, -1.0, 0.0), 0.8)?,
///     Plane3::new(Vector3::new(-0.048, 0.999, -0.012), 1.6)?,
///     Plane3::new(Vector3::new(-0.982, -0.1, 0.158), 1.5)?,
///     Plane3::new(Vector3::new(-0.213, 0.164, -0.963), 3.0)?,
/// ];
/// let render = |planes: &[Plane3]| {
///     let z = (0..k.width * k.height).map(|i| {
///         let (x, y) = ((i % k.width) as f64, (i / k.width) as f64);
///         let z = planes.iter().filter_map(|p| p.depth_at(&k, x, y)).fold(f64::INFINITY, f64::min);
///         if z.is_finite() { z as f32 } else { 0.0 }
///     });
///     DepthImage::from_vec(k.width, k.height, z.collect())
/// };
/// let truth = Isometry3::from_parts(
///     Translation3::new(0.03, 0.0, 0.02),
///     UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 10f64.to_radians()),
/// );
/// let room_b: Vec<Plane3> = room.iter().map(|p| p.transformed(&truth.inverse())).collect();
/// let (da, db) = (render(&room)?, render(&room_b)?);
/// let mut ex = PlaneExtractor::new(PlaneConfig { min_pixels: 200, ..PlaneConfig::default() })?;
/// let (sa, sb) = (ex.extract_depth(&da, &cam)?, ex.extract_depth(&db, &cam)?);
/// let (mcfg, vcfg) = (MotionConfig::default(), VerifyConfig::default());
/// let m = estimate_motion_verified(
///     MotionFrame { depth: &da, planes: &sa.planes },
///     MotionFrame { depth: &db, planes: &sb.planes },
///     &cam, None, &mcfg, &vcfg,
/// )?;
/// let out = refine_motion_icp_verified(&da, &db, &cam, &m, &IcpConfig::refinement(), &mcfg, &vcfg)?;
/// assert!(out.accepted, "{:?}", out.rejection);
/// assert!(out.inlier_fraction_after.is_some_and(|f| f + 1e-3 >= out.inlier_fraction_before));
/// assert!(out.pose.rotation.angle_to(&truth.rotation).to_degrees() < 0.5);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn refine_motion_icp_verified(
    depth_a: &DepthImage,
    depth_b: &DepthImage,
    camera: &Camera,
    motion: &PlaneMotion,
    cfg: &IcpConfig,
    mcfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<IcpOutcome> {
    cfg.validate()?;
    mcfg.validate()?;
    vcfg.validate()?;
    let estimate = motion.isometry();
    let start = motion.verification.as_ref().map_or(estimate, |v| v.aligned);
    let mut check = TwoWay::new(
        depth_a,
        depth_b,
        camera,
        vcfg.max_samples,
        (SPARSE_SAMPLES, COARSE_SAMPLES),
    )?;
    let tol = (vcfg.inlier_base_m, vcfg.inlier_sigmas);
    // The verification scored `aligned` on these same samples and tolerances.
    let inlier_fraction_before = match &motion.verification {
        Some(v) => v.inlier_fraction,
        None => check.score(&estimate, tol, Density::Full).inlier_fraction(),
    };
    let mut outcome = IcpOutcome {
        accepted: false,
        rejection: None,
        pose: estimate,
        start,
        icp: None,
        inlier_fraction_before,
        inlier_fraction_after: None,
        overlap_fraction_after: None,
    };
    let icp = match icp_point_to_plane(depth_a, depth_b, camera, &start, cfg) {
        Ok(r) => r,
        Err(PlanesError::MotionUndetermined(why)) => {
            outcome.rejection = Some(IcpRejection::Failed(why));
            return Ok(outcome);
        }
        Err(e) => return Err(e),
    };
    let score = check.score(&icp.pose, tol, Density::Full);
    let (inl, ovl) = (score.inlier_fraction(), score.overlap_fraction());
    outcome.inlier_fraction_after = Some(inl);
    outcome.overlap_fraction_after = Some(ovl);
    outcome.rejection = if ovl < vcfg.min_overlap_fraction || inl < vcfg.min_inlier_fraction {
        Some(IcpRejection::NotVerified)
    } else if inl + ICP_INLIER_TOLERANCE < inlier_fraction_before {
        Some(IcpRejection::LostInliers)
    } else if icp.pose.rotation.angle_to(&start.rotation) > mcfg.distinct_deg.to_radians() {
        Some(IcpRejection::MovedTooFar)
    } else {
        None
    };
    outcome.accepted = outcome.rejection.is_none();
    if outcome.accepted {
        outcome.pose = icp.pose;
    }
    outcome.icp = Some(icp);
    Ok(outcome)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_angle_is_finite_at_180_degrees() {
        let a = Rotation3::from_scaled_axis(Vector3::new(0.1, 0.2, -0.3));
        let b = a * Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
        let d = rotation_between(&a, &b);
        assert!((d - std::f64::consts::PI).abs() < 1e-6, "{d}");
        assert!(rotation_between(&a, &a).abs() < 1e-6);
    }

    #[test]
    fn icp_config_ranges_are_checked() {
        assert!(IcpConfig::default().validate().is_ok());
        assert!(IcpConfig::refinement().validate().is_ok());
        assert!(IcpConfig::refinement().max_dist_m < IcpConfig::default().max_dist_m);
        for bad in [
            IcpConfig {
                iterations: 0,
                ..IcpConfig::default()
            },
            IcpConfig {
                min_dist_m: 0.0,
                ..IcpConfig::default()
            },
            IcpConfig {
                max_dist_m: 0.01,
                ..IcpConfig::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn icp_rejection_names() {
        assert_eq!(IcpRejection::LostInliers.as_str(), "lost-inliers");
        assert_eq!(IcpRejection::Failed("x".into()).as_str(), "icp-failed");
    }

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

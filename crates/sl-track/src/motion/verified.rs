//! The verified estimate ([`estimate_motion_verified`]): every hypothesis checked against both
//! depth maps, the best refined and scored again, and the decision (determined, or not).

use super::*;

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
pub(super) const MIN_SAMPLES: usize = 100;

/// Points per frame of the coarse score that ranks the unrefined hypotheses.
pub(super) const COARSE_SAMPLES: usize = 300;

/// Points per frame of the local refinement and of the perturbation check.
pub(super) const SPARSE_SAMPLES: usize = 1000;

/// Most alignments [`estimate_motion_verified_or_candidates`] hands back when it cannot decide.
const MAX_CANDIDATES: usize = 3;

/// Plane normals (besides the camera axes) about which the verified alignment is perturbed.
pub(super) const MAX_PERTURB_PLANES: usize = 6;

/// A plane hypothesis after the check against the data.
#[derive(Debug, Clone)]
pub(super) struct Checked {
    /// The hypothesis after the local refinement on the data.
    pub(super) aligned: Isometry3<f64>,
    pub(super) score: Score,
    /// Plane support of the hypothesis.
    pub(super) support: f64,
    /// Plane matches consistent with `aligned` (or the hypothesis' own, see below).
    pub(super) matches: Vec<PlaneMatch>,
    /// Weighted Kabsch rotation of `matches`.
    pub(super) rotation: Rotation3<f64>,
}

/// Whether two of the matched planes (in A) are at least `min_spread_deg` from parallel: only
/// then do the matches determine a rotation about every axis.
pub(super) fn spread_ok(
    planes_a: &[PlaneInfo],
    matches: &[PlaneMatch],
    cfg: &MotionConfig,
) -> bool {
    matches.iter().enumerate().any(|(k, m1)| {
        matches[k + 1..].iter().any(|m2| {
            let s = angle_deg(&planes_a[m1.a].plane.normal, &planes_a[m2.a].plane.normal);
            s >= cfg.min_spread_deg && s <= 180.0 - cfg.min_spread_deg
        })
    })
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
/// [`TrackError::MotionUndetermined`] when the planes propose no rotation (fewer than two
/// non-parallel planes seen in both frames) or a frame has too few usable points;
/// [`TrackError::MotionNotVerified`] when no hypothesis explains the data with two plane
/// matches, two distinct ones explain it, or the shared view does not constrain the
/// rotation; size and configuration errors.
///
/// ```
/// use sl_core::{Camera, DepthImage, nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3}};
/// use sl_track::{MotionConfidence, MotionConfig, MotionFrame, Plane, PlaneConfig,
///     PlaneExtractor, VerifyConfig, estimate_motion_verified};
///
/// // A room (floor, ceiling, three walls, none at right angles) seen by a wide 160x120 camera,
/// // and the same room after the camera turned 35° about the vertical axis and moved 5 cm.
/// let k = sl_core::Intrinsics::new(160, 120, 60.0, 60.0, 79.5, 59.5)?;
/// let cam = Camera { intrinsics: k, sensor: sl_core::SensorModel::kinect_v1() };
/// let room = [
///     Plane::new(Vector3::new(0.0, -1.0, 0.0), 0.8)?.facing_origin(),
///     Plane::new(Vector3::new(-0.048, 0.999, -0.012), 1.6)?.facing_origin(),
///     Plane::new(Vector3::new(-0.982, -0.1, 0.158), 1.5)?.facing_origin(),
///     Plane::new(Vector3::new(0.856, -0.472, 0.213), 1.1)?.facing_origin(),
///     Plane::new(Vector3::new(-0.213, 0.164, -0.963), 3.0)?.facing_origin(),
/// ];
/// let render = |planes: &[Plane]| {
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
/// let room_b: Vec<Plane> = room.iter().map(|p| p.transformed(&truth.inverse()).facing_origin()).collect();
/// let (da, db) = (render(&room)?, render(&room_b)?);
/// let mut cfg = PlaneConfig::default();
/// cfg.min_pixels = 200;
/// let mut ex = PlaneExtractor::new(cfg)?;
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
    guess: Option<&CameraToCamera>,
    cfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<PlaneMotion> {
    let (motion, _) = estimate_motion_verified_or_candidates(a, b, camera, guess, cfg, vcfg)?;
    motion
}

/// [`estimate_motion_verified`], and when its decision is "not verified", the refined
/// alignments the data could not rule out (best first, each more than `distinct_deg` from
/// those before it): for a caller with evidence of its own to tell them apart, such as the
/// tracker's fused model. Empty when the estimate is verified or no alignment is left.
pub(crate) fn estimate_motion_verified_or_candidates(
    a: MotionFrame<'_>,
    b: MotionFrame<'_>,
    camera: &Camera,
    guess: Option<&CameraToCamera>,
    cfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<(Result<PlaneMotion>, Vec<CameraToCamera>)> {
    cfg.validate()?;
    vcfg.validate()?;
    let guess = guess.map(CameraToCamera::isometry);
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
        return Err(TrackError::MotionUndetermined(format!(
            "only {} usable points in a frame (need {MIN_SAMPLES})",
            check.samples()
        )));
    }
    // hypothesise (above) → rank → refine → decide → the plane estimate.
    let coarse = rank(&hyps, &g, &mut check, vcfg);
    let checked = refine(&coarse, &hyps, &g, &mut check, a, b, cfg, vcfg);
    let decision = match decide(&checked, hyps.len(), &mut check, a, cfg, vcfg) {
        Ok(d) => d,
        Err(e @ TrackError::MotionNotVerified { .. }) => {
            return Ok((Err(e), unrefuted(&checked, cfg, vcfg)));
        }
        Err(e) => return Err(e),
    };
    let (best, aligned) = (&checked[decision.best], checked[decision.best].aligned);
    let Decision {
        inlier_fraction,
        overlap_fraction,
        alternative_inlier_fraction,
        turned_inlier_fraction,
        ..
    } = decision;
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
    let motion = PlaneMotion {
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
            aligned: CameraToCamera::from_isometry(aligned),
        }),
    };
    Ok((Ok(motion), Vec::new()))
}

/// The refined alignments of `checked` (best first) that the data do not rule out: each overlaps
/// the other frame with `min_overlap_fraction` of the points and explains a share of them not
/// significantly below `min_inlier_fraction` (the test `decide` applies to the alternatives),
/// and lies more than `distinct_deg` from every one kept before it; at most
/// [`MAX_CANDIDATES`].
fn unrefuted(checked: &[Checked], cfg: &MotionConfig, vcfg: &VerifyConfig) -> Vec<CameraToCamera> {
    let distinct = cfg.distinct_deg.to_radians();
    let mut kept: Vec<Isometry3<f64>> = Vec::new();
    for c in checked {
        if kept.len() >= MAX_CANDIDATES {
            break;
        }
        let s = &c.score;
        let possible = s.overlap_fraction() >= vcfg.min_overlap_fraction
            && inlier_share_upper_bound(s) >= vcfg.min_inlier_fraction;
        if possible
            && kept
                .iter()
                .all(|k| k.rotation.angle_to(&c.aligned.rotation) > distinct)
        {
            kept.push(c.aligned);
        }
    }
    kept.into_iter()
        .map(CameraToCamera::from_isometry)
        .collect()
}

/// Greedy one-to-one plane matches (by decreasing weight) consistent with a motion: normals
/// within `inlier_angle_deg`, offsets within `inlier_offset_m`.
pub(super) fn consistent_matches(
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

/// Stage "rank": the coarse score of every hypothesis as proposed by the planes, on few
/// samples (hypotheses that move the frames mostly out of each other's view are left out),
/// best first.
fn rank(
    hyps: &[Hypothesis],
    g: &Isometry3<f64>,
    check: &mut TwoWay<'_>,
    vcfg: &VerifyConfig,
) -> Vec<(usize, Isometry3<f64>, f64)> {
    let w_out = vcfg.outlier_weight;
    let mut coarse: Vec<(usize, Isometry3<f64>, f64)> = Vec::with_capacity(hyps.len());
    for (i, h) in hyps.iter().enumerate() {
        let pose = Isometry3::from_parts(
            Translation3::from(h.translation),
            UnitQuaternion::from_rotation_matrix(&h.rotation),
        ) * *g;
        let per_m = vcfg.coarse_angle_deg.to_radians().tan();
        let s = check.score_ranging(&pose, (vcfg.coarse_inlier_m, per_m, 0.0), Density::Coarse);
        if s.overlap_fraction() >= vcfg.min_overlap_fraction {
            coarse.push((i, pose, s.evidence(w_out)));
        }
    }
    coarse.sort_by(|x, y| y.2.total_cmp(&x.2).then(x.0.cmp(&y.0)));
    coarse
}

/// Stage "refine": the best coarse hypotheses refined locally on the data, scored on all
/// samples, and kept when they overlap enough and keep two non-parallel plane matches; best
/// first.
#[allow(clippy::too_many_arguments)]
fn refine(
    coarse: &[(usize, Isometry3<f64>, f64)],
    hyps: &[Hypothesis],
    g: &Isometry3<f64>,
    check: &mut TwoWay<'_>,
    a: MotionFrame<'_>,
    b: MotionFrame<'_>,
    cfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Vec<Checked> {
    let w_out = vcfg.outlier_weight;
    let tol = (vcfg.inlier_base_m, vcfg.inlier_sigmas);
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
    checked
}

/// What stage "decide" found: the winner (an index into the refined hypotheses) and the shares
/// of the overlapping points explained by it, by the best distinct alternative and by the
/// winner turned by `distinct_deg`.
struct Decision {
    best: usize,
    inlier_fraction: f64,
    overlap_fraction: f64,
    alternative_inlier_fraction: f64,
    turned_inlier_fraction: f64,
}

/// Stage "decide": the best refined hypothesis must explain `min_inlier_fraction` of the
/// overlapping points while no alternative more than `distinct_deg` away does — neither
/// another hypothesis nor the winner turned about the camera axes or a dominant plane normal.
fn decide(
    checked: &[Checked],
    hypotheses: usize,
    check: &mut TwoWay<'_>,
    a: MotionFrame<'_>,
    cfg: &MotionConfig,
    vcfg: &VerifyConfig,
) -> Result<Decision> {
    let tol = (vcfg.inlier_base_m, vcfg.inlier_sigmas);
    let distinct = cfg.distinct_deg.to_radians();
    let Some(best) = checked.first() else {
        return Err(TrackError::MotionNotVerified {
            reason: format!(
                "none of the {} plane hypotheses, refined on the data, overlaps the other \
                 frame with {:.0} % of the points and keeps two non-parallel plane matches",
                hypotheses,
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
    // An alternative is ruled out only when the samples say so beyond their sampling error:
    // its inlier share, measured on a few hundred sparse samples, must lie significantly
    // below `min_inlier_fraction` (the upper Wilson bound at one-sided 99.9 %, the level of
    // ICP's McNemar test). A turned alignment at 89 % of 500 samples is not significantly
    // below 90 %: the data cannot tell it from the winner.
    let not_ruled_out = |s: &Score| {
        s.overlap_fraction() >= vcfg.min_overlap_fraction
            && inlier_share_upper_bound(s) >= vcfg.min_inlier_fraction
    };
    let alternative = checked
        .iter()
        .filter(|c| c.aligned.rotation.angle_to(&aligned.rotation) > distinct)
        .map(|c| c.score)
        .max_by(|x, y| x.inlier_fraction().total_cmp(&y.inlier_fraction()));
    let alternative_inlier_fraction = alternative.map_or(0.0, |s| s.inlier_fraction());
    let not_verified = |reason: String, alt: f64| TrackError::MotionNotVerified {
        reason,
        inlier_fraction,
        alternative_inlier_fraction: alt,
    };
    if !consistent(&best.score) {
        return Err(not_verified(
            format!(
                "the best of {} plane hypotheses explains {:.0} % of the overlapping points \
                 (< {:.0} %)",
                hypotheses,
                100.0 * inlier_fraction,
                100.0 * vcfg.min_inlier_fraction
            ),
            alternative_inlier_fraction,
        ));
    }
    if alternative.as_ref().is_some_and(not_ruled_out) {
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
    if turned.as_ref().is_some_and(not_ruled_out) {
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
    Ok(Decision {
        best: 0,
        inlier_fraction,
        overlap_fraction,
        alternative_inlier_fraction,
        turned_inlier_fraction,
    })
}

/// Upper bound of the inlier share behind `s` (its overlapping samples are binomial draws):
/// the Wilson score interval's upper end at one-sided 99.9 % ([`ICP_LOSS_Z`] standard
/// deviations). Wilson's interval stays inside [0, 1] and keeps its coverage near 0 and 1,
/// where the plain `p ± z·√(p(1−p)/n)` collapses to a point.
fn inlier_share_upper_bound(s: &Score) -> f64 {
    let n = s.overlap as f64;
    if n < 1.0 {
        return 1.0;
    }
    let p = s.inlier_fraction();
    let z2 = ICP_LOSS_Z * ICP_LOSS_Z;
    let centre = p + z2 / (2.0 * n);
    let spread = ICP_LOSS_Z * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    ((centre + spread) / (1.0 + z2 / n)).min(1.0)
}

#[cfg(test)]
mod wilson_tests {
    use super::*;

    fn score(inliers: usize, overlap: usize) -> Score {
        Score {
            inliers,
            overlap,
            total: 2 * overlap,
        }
    }

    #[test]
    fn the_bound_covers_sampling_error_and_tightens_with_more_samples() {
        // TUM fr1/rpy 0 -> 20: a 15° turn kept 89 % of 493 overlapping samples; at 99.9 % that
        // is not significantly below 90 %.
        let few = inlier_share_upper_bound(&score(439, 493));
        assert!(few > 0.9 && few < 0.95, "{few}");
        // The same share on a hundred times the samples is.
        let many = inlier_share_upper_bound(&score(43900, 49300));
        assert!(many < 0.9 && many > 0.89, "{many}");
        // Never below the share itself, never above 1, 1 without samples.
        for (i, n) in [(0, 10), (10, 10), (5, 10), (999, 1000)] {
            let b = inlier_share_upper_bound(&score(i, n));
            let p = i as f64 / n as f64;
            assert!(b >= p && b <= 1.0, "{i}/{n}: {b}");
        }
        assert_eq!(inlier_share_upper_bound(&score(0, 0)), 1.0);
    }

    fn checked(turn_deg: f64, inliers: usize, overlap: usize, total: usize) -> Checked {
        Checked {
            aligned: Isometry3::rotation(Vector3::y() * turn_deg.to_radians()),
            score: Score {
                inliers,
                overlap,
                total,
            },
            support: 1.0,
            matches: Vec::new(),
            rotation: Rotation3::identity(),
        }
    }

    #[test]
    fn the_candidates_are_the_distinct_alignments_the_samples_do_not_rule_out() {
        let (cfg, vcfg) = (MotionConfig::default(), VerifyConfig::default());
        let angles = |c: &[Checked]| -> Vec<f64> {
            unrefuted(c, &cfg, &vcfg)
                .iter()
                .map(|p| p.rotation_angle_deg().round())
                .collect()
        };
        // TUM fr1/rpy 65 -> 70 (every 5th frame): two rotations 15°+ apart at 89 % each.
        let two = [checked(0.0, 439, 493, 900), checked(20.0, 438, 493, 900)];
        assert_eq!(angles(&two), [0.0, 20.0]);
        // Best first; one within `distinct_deg` of a kept one is the same minimum.
        let near = [
            checked(0.0, 439, 493, 900),
            checked(10.0, 439, 493, 900),
            checked(30.0, 439, 493, 900),
        ];
        assert_eq!(angles(&near), [0.0, 30.0]);
        // Significantly below `min_inlier_fraction` (70 % of 2,000), or overlapping too
        // little (100 of 2,000 samples < 15 %): ruled out.
        let out = [
            checked(0.0, 1400, 2000, 2000),
            checked(40.0, 95, 100, 2000),
            checked(80.0, 450, 493, 900),
        ];
        assert_eq!(angles(&out), [80.0]);
        // At most `MAX_CANDIDATES`.
        let many: Vec<Checked> = (0..6)
            .map(|k| checked(20.0 * f64::from(k), 480, 493, 900))
            .collect();
        assert_eq!(unrefuted(&many, &cfg, &vcfg).len(), MAX_CANDIDATES);
    }
}

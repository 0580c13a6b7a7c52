//! Hypotheses from plane pairs: every two candidate pairs with agreeing mutual angles propose
//! a rotation; each collects its one-to-one matches, is refined and scored by support; the
//! planes-only estimate ([`estimate_motion`]) takes the best.

use super::*;

/// A rotation hypothesis with its plane consensus (in the guess-transformed frame of B).
#[derive(Debug, Clone)]
pub(super) struct Hypothesis {
    pub(super) rotation: Rotation3<f64>,
    pub(super) support: f64,
    pub(super) matches: Vec<PlaneMatch>,
    pub(super) translation: Vector3<f64>,
}

/// Plane matching between A and B (B transformed by the initial guess).
pub(super) struct Matcher<'p> {
    pub(super) planes_a: &'p [PlaneInfo],
    pub(super) planes_b: &'p [PlaneInfo],
    /// B's planes after the guess.
    pub(super) bt: Vec<Plane>,
    /// Candidate pairs, by decreasing weight.
    pub(super) cands: Vec<PlaneMatch>,
    pub(super) cfg: MotionConfig,
}

impl<'p> Matcher<'p> {
    /// Candidates near `prior` (all pairs without one).
    pub(super) fn new(
        planes_a: &'p [PlaneInfo],
        planes_b: &'p [PlaneInfo],
        prior: Option<&Isometry3<f64>>,
        cfg: &MotionConfig,
    ) -> Self {
        let g = prior.copied().unwrap_or_else(Isometry3::identity);
        let bt: Vec<Plane> = planes_b
            .iter()
            .map(|p| p.plane.transformed(&g).facing_origin())
            .collect();
        let mut cands = Vec::new();
        for (i, pa) in planes_a.iter().enumerate() {
            for (j, pb) in bt.iter().enumerate() {
                let near = pa.plane.angle_to_deg(pb) < cfg.max_angle_deg
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

    pub(super) fn na(&self, m: &PlaneMatch) -> Vector3<f64> {
        self.planes_a[m.a].plane.normal
    }

    pub(super) fn nb(&self, m: &PlaneMatch) -> Vector3<f64> {
        self.bt[m.b].normal
    }

    /// Greedy one-to-one matches of a rotation whose offsets agree with one translation, their
    /// support and that translation.
    pub(super) fn inliers(&self, r: &Rotation3<f64>) -> (f64, Vec<PlaneMatch>, Vector3<f64>) {
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

    pub(super) fn kabsch(&self, ms: &[PlaneMatch]) -> Option<Rotation3<f64>> {
        weighted_kabsch(
            &ms.iter()
                .map(|m| (self.na(m), self.nb(m), m.weight))
                .collect::<Vec<_>>(),
        )
    }

    /// All distinct rotation hypotheses, by decreasing support.
    pub(super) fn hypotheses(&self) -> Vec<Hypothesis> {
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
    pub(super) fn runner_up(
        &self,
        hyps: &[Hypothesis],
        r: &Rotation3<f64>,
        matches: &[PlaneMatch],
    ) -> f64 {
        let d = self.cfg.distinct_deg.to_radians();
        let own: f64 = matches.iter().map(|m| m.weight).sum();
        hyps.iter()
            .filter(|h| rotation_between(&h.rotation, r) > d)
            .map(|h| h.support)
            .fold(0.0, f64::max)
            / own.max(1.0)
    }

    pub(super) fn undetermined(&self) -> TrackError {
        TrackError::MotionUndetermined(format!(
            "need two matched non-parallel planes ({} planes in A, {} in B, {} candidate pairs)",
            self.planes_a.len(),
            self.planes_b.len(),
            self.cands.len()
        ))
    }
}

/// The weighted RMS angle of matched normals under `rotation`, degrees.
pub(super) fn rms_angle(
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
    guess: Option<&CameraToCamera>,
    cfg: &MotionConfig,
) -> Result<PlaneMotion> {
    cfg.validate()?;
    let guess = guess.map(CameraToCamera::isometry);
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
        .ok_or_else(|| TrackError::MotionUndetermined("degenerate normals".into()))?;
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

//! The tracker's alignment of a frame to a reference: coarse-to-fine Gauss–Newton (or
//! Levenberg–Marquardt when damped) over the pyramid (`Tracker::iterate`), then the
//! acceptance checks (`Tracker::judge`). The two are apart so that the first alignment of a
//! frame can run beside the structure check, which `judge` needs.

use nalgebra::Isometry3;

use super::pyramid;
use super::solve::{self, PassParams, Sums};
use super::structure::MustAgree;
use super::{ReferenceMaps, Tracker};

/// Where the iterations of one alignment ended, before the acceptance checks.
pub(super) struct Iterated {
    pub(super) pose: Isometry3<f64>,
    pub(super) stats: Sums,
    pub(super) iterations: usize,
}

/// One alignment attempt's outcome.
pub(super) struct Attempt {
    pub(super) pose: Isometry3<f64>,
    pub(super) stats: Sums,
    pub(super) condition: f64,
    pub(super) iterations: usize,
    /// The weakest-direction σ of the part of the frame that overlaps the reference at `pose`
    /// (NaN when not checked).
    pub(super) overlap_sigma_m: f64,
    /// Whether the samples beyond the gates dispute the pose (`structure::Weakest`).
    pub(super) disputed: bool,
    pub(super) failure: Option<String>,
    /// What the part of the frame that overlaps the reference says of the pose, when checked
    /// (for the odometry's projection of its weak directions, `Tracker::align_on_overlap`).
    pub(super) overlap: Option<super::structure::Weakest>,
}

impl Tracker {
    /// The mean valid depth of the finest alignment level (the scene's scale for the
    /// conditioning), metres.
    pub(super) fn finest_mean_depth(&self) -> f64 {
        let finest_l = self
            .cfg
            .finest_level
            .min(self.pyramid.levels.len().saturating_sub(1));
        self.pyramid.levels.get(finest_l).map_or(1.0, mean_depth)
    }

    /// The parameters of a pass at pyramid level `l`: its allowance, normal gate, sample
    /// stride and the frame's row timing.
    pub(super) fn pass_params(&self, l: usize) -> PassParams {
        let cfg = &self.cfg;
        PassParams {
            allowance_m: (cfg.allowance_fine_m * f64::from(1u32 << l)) as f32,
            min_cos: cfg.max_normal_angle_deg.to_radians().cos() as f32,
            stride: cfg.sample_stride(l, self.camera.pixels_per_sensor_pixel()),
            timing: self.row_timing,
        }
    }

    /// Coarse-to-fine Gauss–Newton from `start` with a Gaussian prior of variance
    /// `prior_var_m2` per axis on the camera's position about `start`'s, then the acceptance
    /// checks.
    pub(super) fn align(
        &self,
        start: &Isometry3<f64>,
        reference: &ReferenceMaps,
        prior_var_m2: f64,
        damped: bool,
    ) -> Attempt {
        let iterated = self.iterate(start, reference, prior_var_m2, damped);
        let attempt = self.judge(start, reference, iterated);
        self.align_on_overlap(start, reference, prior_var_m2, damped, attempt)
    }

    /// With an odometry, `attempt` again from `start` when the part of the frame that overlaps
    /// the reference pins some direction worse than the odometry (a model that holds one wall
    /// so far): its data then say nothing along those directions either
    /// (`odometry::weak_projection` of the overlap's information, which is weaker than the
    /// whole frame's in every direction), and the pose there is the odometry's. Without an
    /// odometry, or when the overlap pins every direction, `attempt` as it is.
    pub(super) fn align_on_overlap(
        &self,
        start: &Isometry3<f64>,
        reference: &ReferenceMaps,
        prior_var_m2: f64,
        damped: bool,
        attempt: Attempt,
    ) -> Attempt {
        let (Some(o), Some(overlap)) = (&self.frame_odometry, &attempt.overlap) else {
            return attempt;
        };
        // NaN (not checked) or within the odometry's σ: the overlap pins every direction.
        let weaker = overlap.sigma_m > o.sigma_t_m();
        if !weaker {
            return attempt;
        }
        let Some(q) = super::odometry::weak_projection(overlap, o.var_t_m2) else {
            return attempt;
        };
        let again = self.iterate_with(start, reference, prior_var_m2, damped, Some(q));
        let mut judged = self.judge(start, reference, again);
        judged.iterations += attempt.iterations;
        judged
    }

    /// The iterations of [`Tracker::align`]: the pose they reach and the finest level's
    /// statistics there. Reads the pyramid, the configuration and the camera only (not the
    /// structure check), so it can run beside [`StructureCheck::segment`](super::structure::StructureCheck::segment).
    pub(super) fn iterate(
        &self,
        start: &Isometry3<f64>,
        reference: &ReferenceMaps,
        prior_var_m2: f64,
        damped: bool,
    ) -> Iterated {
        self.iterate_with(
            start,
            reference,
            prior_var_m2,
            damped,
            self.frame_projection,
        )
    }

    /// [`Tracker::iterate`] with the odometry's prior seeing the data through `projection`
    /// (`odometry::weak_projection`).
    fn iterate_with(
        &self,
        start: &Isometry3<f64>,
        reference: &ReferenceMaps,
        prior_var_m2: f64,
        damped: bool,
        projection: Option<nalgebra::Matrix6<f64>>,
    ) -> Iterated {
        let cfg = &self.cfg;
        let sensor = &self.camera.sensor;
        let mut pose = *start;
        let mut iterations = 0;
        // The sums of the finest level's last pass: they are the final statistics (same
        // level, gates and pose), so no pass is run for them.
        let mut stats = Sums::zero();
        let finest_l = cfg
            .finest_level
            .min(self.pyramid.levels.len().saturating_sub(1));
        let stride_of = |l: usize| cfg.sample_stride(l, self.camera.pixels_per_sensor_pixel());
        for l in (finest_l..self.pyramid.levels.len()).rev() {
            let level = &self.pyramid.levels[l];
            let stride = stride_of(l);
            let params = self.pass_params(l);
            let data_share = (stride * stride) as f64
                / cfg.correlated_pixels(l, self.camera.pixels_per_sensor_pixel());
            // A measured motion (the odometry's) is the prior of every start; otherwise the
            // position prior is centred on the start.
            let prior = match &self.frame_odometry {
                Some(o) => o.prior(data_share, projection),
                None => solve::Prior {
                    data_share,
                    info_t: 1.0 / prior_var_m2,
                    centre_t: start.translation.vector,
                    info_r: 0.0,
                    centre_r: start.rotation,
                    data_projection: None,
                },
            };
            // With `damped`, Levenberg–Marquardt step control: a step is taken only when it
            // lowers the objective (`Prior::cost`); one that does not is retried with the
            // diagonal damped ten times more. Where the geometry constrains a direction weakly
            // (far, noisy walls, few planes) the undamped step along it can be centimetres long
            // and carry the pose out of the basin of convergence. Undamped (plain Gauss–Newton)
            // every step is taken: on well-constrained frames it is the more accurate (the
            // truncated loss is not smooth under the 1/8-pixel disparity quantisation, and
            // rejected steps stop the iteration early), so it is the first attempt.
            let pass_at = |p: &Isometry3<f64>| {
                solve::pass(
                    level,
                    reference,
                    p,
                    &p.translation.vector,
                    sensor,
                    cfg,
                    params,
                )
            };
            let mut s = pass_at(&pose);
            iterations += 1;
            let mut lambda = 0.0;
            // `max_iterations` counts the steps taken; rejected ones (at most six in a row
            // before the damping gives up) do not use up the budget.
            let mut taken = 0;
            while taken < cfg.max_iterations {
                if (s.inliers as usize) < (self.min_points(l) / (stride * stride)).max(6) {
                    break;
                }
                let t = pose.translation.vector;
                let Some(xi) = solve::step(&s, &prior, &pose, lambda) else {
                    break;
                };
                if !xi.iter().all(|v| v.is_finite()) {
                    break;
                }
                let candidate = solve::apply(&pose, &xi, &t);
                let (w, v) = (xi.fixed_rows::<3>(0).norm(), xi.fixed_rows::<3>(3).norm());
                let negligible = w < STEP_NEGLIGIBLE && v < STEP_NEGLIGIBLE;
                if negligible && !damped {
                    // Converged: the step is taken without a pass at the pose it reaches, and
                    // the sums at the pose it left stand for the final ones (0.1 mm / 0.006°
                    // away: the same associations, statistics equal to their last digits).
                    // This saves one pass per level — at full resolution about a third of the
                    // tracker's time — and leaves every pose bit-identical.
                    pose = candidate;
                    break;
                }
                let sc = pass_at(&candidate);
                iterations += 1;
                let points = s.associated;
                if !damped || prior.cost(&sc, points, &candidate) < prior.cost(&s, points, &pose) {
                    pose = candidate;
                    s = sc;
                    taken += 1;
                    lambda = if lambda > LM_LAMBDA_START {
                        lambda / 10.0
                    } else {
                        0.0
                    };
                    if negligible {
                        break;
                    }
                } else {
                    lambda = if lambda == 0.0 {
                        LM_LAMBDA_START
                    } else {
                        lambda * 10.0
                    };
                    if lambda > LM_LAMBDA_MAX {
                        break;
                    }
                }
            }
            if l == finest_l {
                stats = s;
            }
        }
        Iterated {
            pose,
            stats,
            iterations,
        }
    }

    /// The acceptance checks of [`Tracker::align`] on what [`Tracker::iterate`] reached from
    /// `start`, the degenerate-overlap check with the structure check's planes of this frame.
    pub(super) fn judge(
        &self,
        start: &Isometry3<f64>,
        reference: &ReferenceMaps,
        it: Iterated,
    ) -> Attempt {
        let cfg = &self.cfg;
        let sensor = &self.camera.sensor;
        let Iterated {
            pose,
            stats,
            iterations,
        } = it;
        let finest_l = cfg
            .finest_level
            .min(self.pyramid.levels.len().saturating_sub(1));
        let stride_of = |l: usize| cfg.sample_stride(l, self.camera.pixels_per_sensor_pixel());
        let scale_m = self
            .finest_mean_depth_m
            .unwrap_or_else(|| self.finest_mean_depth());
        let condition = solve::condition(&stats, scale_m);
        let correction = start.inverse() * pose;
        let frac = ratio(stats.inliers, stats.associated);
        let finest_stride = stride_of(finest_l);
        // Against the last frame on its planes' normals, the normal equations hold no false
        // constraints from the frame's own noise (`frame_planes`): their smallest eigenvalue
        // is as small as the geometry makes it (a corridor's axis pinned by its end wall 4.5 m
        // away), and whether that is too small is for the degenerate-overlap check below to
        // say, from the sensor model. The relative bound stays for a model's normals (the fused
        // field's) and for a last frame without planes or without the check.
        let checked_by_planes = cfg.degenerate_check
            && std::ptr::eq(reference, &self.last_ref)
            && !self.last_planes.planes.is_empty();
        let failure = if (stats.inliers as usize)
            < self.min_points(finest_l) / (finest_stride * finest_stride)
        {
            Some(format!("{} inliers, too few", stats.inliers))
        } else if frac < cfg.min_inlier_fraction {
            Some(format!(
                "inlier fraction {frac:.3} below {}",
                cfg.min_inlier_fraction
            ))
        } else if condition < cfg.min_condition
            && !checked_by_planes
            && self.frame_odometry.is_none()
        {
            Some(format!(
                "conditioning {condition:.2e} below {:.0e}",
                cfg.min_condition
            ))
        } else if correction.translation.vector.norm() > cfg.max_correction_m
            || correction.rotation.angle().to_degrees() > cfg.max_correction_deg
        {
            Some(format!(
                "correction of {:.3} m / {:.1}° from the start is implausible",
                correction.translation.vector.norm(),
                correction.rotation.angle().to_degrees()
            ))
        } else {
            None
        };
        // The frame can pin the pose down while the part of it that overlaps the reference
        // does not (a model that holds one wall of the room so far, surfaces beyond the fused
        // range): the alignment is then as undetermined as a degenerate view's, whatever its
        // residuals say. The degenerate-view bound, on the samples that are inliers of the
        // reference at this pose, with the reference's variance added to theirs as in the
        // alignment.
        let mut overlap_sigma_m = f64::NAN;
        let mut disputed = false;
        let mut overlap = None;
        let check_level = self.check_level();
        // Planes vouch only for what they agree with against the fused model, and against the
        // last frame when the start is a guess (see `StructureCheck::weakest_sigma_m`). Not
        // with the rolling-shutter model: the agreement is measured at the frame's one pose,
        // while its rows are aligned each from its own, so a plane's mean residual there holds
        // the readout's skew.
        let on_last_frame = std::ptr::eq(reference, &self.last_ref);
        let one_pose = self.row_timing.is_none();
        let planes = (!on_last_frame && one_pose) || self.start_is_a_guess();
        // The samples on no plane (see `StructureCheck::weakest_sigma_m`) also vouch only for
        // what they agree with against the last frame when it is the fallback after the
        // model's alignment was rejected: a second opinion held to the first one's standard.
        let samples = planes || (on_last_frame && self.model_given && one_pose);
        let failure = match (failure, self.pyramid.levels.get(check_level)) {
            (None, Some(level)) if cfg.degenerate_check => {
                let weakest = self.structure.weakest_sigma_m(
                    level,
                    check_level,
                    &self.camera,
                    cfg,
                    solve::on_reference_at(reference, &pose, sensor, cfg),
                    MustAgree { planes, samples },
                );
                overlap_sigma_m = weakest.sigma_m;
                overlap = Some(weakest);
                let bound = cfg.motion_prior_sigma_m();
                // With odometry a direction the overlap leaves free takes the odometry's value.
                if overlap_sigma_m > bound && self.frame_odometry.is_none() {
                    Some(format!(
                        "degenerate overlap: the part of the view that overlaps the reference leaves the pose uncertain by {:.1} mm (1σ) along one direction, more than the motion prior's {:.1} mm",
                        overlap_sigma_m * 1e3,
                        bound * 1e3
                    ))
                } else {
                    disputed = weakest.disputed_sigma_m.is_some();
                    weakest.disputed_sigma_m.map(|sigma| {
                        format!(
                            "disputed overlap: samples of the view that land on the reference beyond the gates pin one direction of the pose to {:.1} mm (1σ), better than those that agree with it",
                            sigma * 1e3
                        )
                    })
                }
            }
            (failure, _) => failure,
        };
        Attempt {
            pose,
            stats,
            condition,
            iterations,
            overlap_sigma_m,
            disputed,
            failure,
            overlap,
        }
    }
}

/// A Gauss–Newton step shorter than this in rotation (radians) and in translation (metres)
/// ends a level's iterations: 0.1 mm and 0.006°, a small fraction of one frame's pose noise.
const STEP_NEGLIGIBLE: f64 = 1e-4;

/// First damping of a Levenberg–Marquardt retry (relative to the diagonal of `H`).
const LM_LAMBDA_START: f64 = 1e-3;
/// Damping beyond which no step lowers the objective: the pose is a minimum at this level.
const LM_LAMBDA_MAX: f64 = 1e4;

pub(super) fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 { a / b } else { 0.0 }
}

/// Mean valid depth of a level (the scene's scale for the conditioning), metres.
fn mean_depth(level: &pyramid::Level) -> f64 {
    let (s, n) = level
        .depth
        .iter()
        .filter(|z| **z > 0.0)
        .fold((0.0f64, 0usize), |(s, n), z| (s + f64::from(*z), n + 1));
    if n > 0 { s / n as f64 } else { 1.0 }
}

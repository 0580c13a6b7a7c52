//! A frame's alignments after the first, while none passes the checks: damped restarts, the
//! last good frame as the reference, the verified plane-based estimate, the keyframes, and
//! for a frame that starts from a guess the starts turned about the camera's axes (the order of
//! the module documentation).

use nalgebra::Isometry3;
use sl_core::{CameraToCamera, DepthImage};

use super::align::{Attempt, Iterated};
use super::frame::AlignPlan;
use super::{RELOCALISATION_TURN_DEG, ReferenceMaps, Tracker};
use crate::depth_motion::{DepthMotion, motion_between_depths};
use crate::error::Result;

/// What a frame's alignments came to: the attempt kept and how it was found.
pub(super) struct Outcome {
    /// The attempt kept (its `failure` set when none passed).
    pub(super) first: Attempt,
    /// Gauss–Newton iterations of every attempt.
    pub(super) iterations: usize,
    /// Found from the plane-based estimate or at a keyframe.
    pub(super) recovered: bool,
    /// Found against the last good frame after the model's alignments failed.
    pub(super) against_frame: bool,
    /// Why the plane fallback, when tried, gave no pose either (for the lost frame's report).
    pub(super) fallback_failure: Option<String>,
    /// The keyframe's pose the frame was found at.
    pub(super) keyframe_pose: Option<Isometry3<f64>>,
    /// The plane-based estimate between the last good frame and this one, once asked for
    /// (by the challenge of a pose found against the last frame, or by the plane fallback).
    planes: Option<DepthMotion>,
}

impl Outcome {
    fn failed(&self) -> bool {
        self.first.failure.is_some()
    }
}

impl Tracker {
    /// The first alignment (judged from `first_iterated` when the iterations ran beside the
    /// structure check) and, while it fails, the fallbacks in turn.
    pub(super) fn align_with_fallbacks(
        &mut self,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        plan: &AlignPlan,
        first_iterated: Option<Iterated>,
    ) -> Result<Outcome> {
        let AlignPlan {
            last,
            predicted,
            predicted_var,
            unknown_var,
            ..
        } = *plan;
        let reference = model.unwrap_or(&self.last_ref);
        let first = match first_iterated {
            Some(it) => {
                let judged = self.judge(&predicted, reference, it);
                self.align_on_overlap(&predicted, reference, predicted_var, false, judged)
            }
            None => self.align(&predicted, reference, predicted_var, false),
        };
        let mut o = Outcome {
            iterations: first.iterations,
            first,
            recovered: false,
            against_frame: false,
            fallback_failure: None,
            keyframe_pose: None,
            planes: None,
        };
        // The damped starts: the prediction and the last good pose. After a few lost frames
        // the prediction is the last good pose with the same prior (the velocity is
        // forgotten), and the same start would give the same result: it runs once.
        let starts = [(predicted, predicted_var), (last, unknown_var)];
        let distinct = if starts[0] == starts[1] { 1 } else { 2 };
        // Not after a disputed pose: the damped starts are for an iteration that did not
        // converge, and from another start against the same reference the alignment can slide
        // further along the disputed direction, where the objecting samples leave the window
        // they are counted in (room 3021 with a shaking camera: 34 mm, session 41). The last
        // frame, a reference of its own, is asked next.
        let model_disputed = o.first.disputed && model.is_some();
        let restarts = if model_disputed { 0 } else { distinct };
        if o.failed() {
            self.restart_damped(&mut o, &starts[..restarts], model);
        }
        if o.failed() && model.is_some() {
            self.align_against_last_frame(&mut o, &starts[..distinct], predicted, predicted_var);
            if !o.failed() && self.cfg.plane_fallback {
                self.challenge_from_planes(&mut o, depth, last, unknown_var)?;
            }
        }
        if o.failed() && self.cfg.plane_fallback {
            self.align_from_planes(&mut o, depth, model, last, unknown_var)?;
        }
        // Where the camera looks at something seen before: each keyframe from its own pose.
        if o.failed() && self.cfg.keyframe_relocalisation {
            let search = self.relocalise_on_keyframes(&last, unknown_var)?;
            o.iterations += search.iterations;
            if let Some((pose, attempt)) = search.found {
                o.first = attempt;
                o.keyframe_pose = Some(pose);
                o.recovered = true;
            }
        }
        // A frame found at a keyframe is judged as a relocalisation too.
        if !o.failed() && (self.start_is_a_guess() || o.keyframe_pose.is_some()) {
            self.align_from_turned_starts(&mut o, model, last, unknown_var);
        }
        Ok(o)
    }

    /// Every damped restart from `starts` against the same reference; one that passes the
    /// checks is kept only over another that fits clearly worse (`Tracker::keep_better`): a
    /// fallback runs because the frame left the prediction's basin, and the first start that
    /// passes can have settled in a wrong minimum of its own.
    fn restart_damped(
        &self,
        o: &mut Outcome,
        starts: &[(Isometry3<f64>, f64)],
        model: Option<&ReferenceMaps>,
    ) {
        let reference = model.unwrap_or(&self.last_ref);
        let mut found = None;
        for &(start, var) in starts {
            let again = self.align(&start, reference, var, true);
            o.iterations += again.iterations;
            if again.failure.is_none() {
                found = Some(self.keep_better(found, again, reference));
            }
        }
        if let Some(attempt) = found {
            o.first = attempt;
        }
    }

    /// The alignments against the last good frame after the model's failed: plain
    /// Gauss–Newton from the prediction, then the damped `starts`.
    ///
    /// The model can disagree with a frame where the last frame does not. On TUM fr1/rpy
    /// (hand-held, turning at up to 120°/s), one step against a model fused with the
    /// motion-capture poses errs by 2–6 cm where the same step against the previous frame
    /// errs by 0.2–1 cm: likely a view-dependent depth distortion or the rolling shutter,
    /// which differ between the views the model averages and agree between consecutive
    /// frames. Try the last good frame before the plane fallback, in the order the model
    /// was tried: plain Gauss–Newton from the prediction first, then the damped starts.
    /// Damped steps are taken only when they lower the robust objective, which the 1/8-pixel
    /// quantisation makes rough: along a weakly constrained direction they stop early, short
    /// of the data's optimum and near the prediction, so the next velocity lags the camera
    /// and the next prediction with it. On the simulated Kinect corridor, where every frame
    /// falls back to the last one (the end wall lies beyond the fused range), that shrinkage
    /// lost 0.5 mm per 4 mm step along the axis (six noise seeds: −13 mm by frame 28, every
    /// seed short; plain Gauss–Newton first: −3 mm, within the noise; docs/bench/track.md,
    /// session 55). The damped starts run too, and one of them is kept only where it fits
    /// the frame clearly better (`Tracker::keep_better`): from the prediction, centimetres
    /// from a shaking camera, plain Gauss–Newton can pass every check in a wrong minimum
    /// (simulated room 6006 with the camera shaken: 33 mm off, reported σ 6.6 mm, while
    /// the damped start from the last pose reaches the camera within 2 mm and a robust
    /// objective 21 % lower; docs/bench/track.md, session 63).
    fn align_against_last_frame(
        &mut self,
        o: &mut Outcome,
        starts: &[(Isometry3<f64>, f64)],
        predicted: Isometry3<f64>,
        predicted_var: f64,
    ) {
        self.refresh_last_ref();
        let plain = std::iter::once((predicted, predicted_var, false));
        let damped = starts.iter().map(|&(s, v)| (s, v, true));
        let mut found = None;
        for (start, var, damped) in plain.chain(damped) {
            let again = self.align(&start, &self.last_ref, var, damped);
            o.iterations += again.iterations;
            if again.failure.is_none() {
                found = Some(self.keep_better(found, again, &self.last_ref));
            }
        }
        if let Some(attempt) = found {
            o.first = attempt;
            o.against_frame = true;
        }
    }

    /// The plane-based estimate between the last good frame and `depth`: the one kept in `o`
    /// when this frame has computed it already (taken out; put it back to share it), else
    /// computed.
    fn planes_between(&self, o: &mut Outcome, depth: &DepthImage) -> Result<DepthMotion> {
        match o.planes.take() {
            Some(p) => Ok(p),
            None => {
                motion_between_depths(&self.last_depth, depth, &self.camera, &self.cfg.fallback)
            }
        }
    }

    /// A pose found against the last good frame after the model refused the frame, challenged
    /// by the alignment from the verified plane-based estimate against the same frame: the
    /// starts of that stage lie near the last good pose, and at fast motion, where the model's
    /// alignments fail, the frames' overlap is small and the first start that passes can have
    /// settled in a wrong minimum. Where the planes' alignment fits the frame clearly better
    /// (`Tracker::fits_clearly_better`), it replaces the pose if it passes the checks, and
    /// neither is a pose if it fails one (the frame goes on to the plane fallback against the
    /// model). TUM fr1/rpy-200 taken every 8th frame (28° a step): frame 15 passed against
    /// frame 14 6.7° off the motion capture's step (inliers 68 %, overlap 40 %); the alignment
    /// from the planes' estimate ends 1.3° off it and fits clearly better, but corrects its
    /// start by 61 mm, beyond `max_correction_m` (docs/bench/track.md, session 85).
    fn challenge_from_planes(
        &self,
        o: &mut Outcome,
        depth: &DepthImage,
        last: Isometry3<f64>,
        unknown_var: f64,
    ) -> Result<()> {
        let planes = self.planes_between(o, depth)?;
        let pose = planes.pose();
        // Kept for the plane fallback, should this pose be refuted.
        o.planes = Some(planes);
        let Some(m) = pose else {
            return Ok(());
        };
        let start = start_from_planes(last, m);
        let alt = self.align(&start, &self.last_ref, unknown_var, true);
        o.iterations += alt.iterations;
        if !self.fits_clearly_better(&alt, &o.first, &self.last_ref) {
            return Ok(());
        }
        match &alt.failure {
            None => o.first = alt,
            Some(why) => {
                // Two minima against one reference, and the one that passed fits worse: it is
                // no pose (the frame goes on to the model from the planes' estimate).
                o.first.failure = Some(format!(
                    "against the last frame, the alignment from the planes' verified estimate \
                     fits the frame clearly better {:.1}° away, and fails: {why}",
                    alt.pose
                        .rotation
                        .angle_to(&o.first.pose.rotation)
                        .to_degrees()
                ));
                o.against_frame = false;
            }
        }
        Ok(())
    }

    /// The alignment from the verified plane-based estimate between the last good frame and
    /// this one; why it gave no pose goes into `o.fallback_failure`.
    fn align_from_planes(
        &self,
        o: &mut Outcome,
        depth: &DepthImage,
        model: Option<&ReferenceMaps>,
        last: Isometry3<f64>,
        unknown_var: f64,
    ) -> Result<()> {
        let planes = self.planes_between(o, depth)?;
        if let Some(m) = planes.pose() {
            let start = start_from_planes(last, m);
            let again = self.align(&start, model.unwrap_or(&self.last_ref), unknown_var, true);
            o.iterations += again.iterations;
            match again.failure {
                None => {
                    o.first = again;
                    o.recovered = true;
                }
                Some(why) => {
                    o.fallback_failure = Some(format!(
                        "plane fallback: the alignment from its verified estimate failed: {why}"
                    ));
                }
            }
        } else if let Err(e) = &planes.motion {
            let reference = model.unwrap_or(&self.last_ref);
            let starts: Vec<Isometry3<f64>> = planes
                .candidates
                .iter()
                .map(|&c| start_from_planes(last, c))
                .collect();
            let (found, iterations) = self.align_from_candidates(&starts, reference, unknown_var);
            o.iterations += iterations;
            match found {
                Ok(attempt) => {
                    o.first = attempt;
                    o.recovered = true;
                }
                Err(why) => o.fallback_failure = Some(format!("plane fallback: {e}{why}")),
            }
        }
        Ok(())
    }

    /// The alignments from the plane-based candidates the two frames alone could not tell
    /// apart (`DepthMotion::candidates`, best first), against `reference`, which has more to
    /// say: the fused model has seen more than the last frame. A pose is kept only where both
    /// agree: the two frames' best candidate passes the checks against the reference, and the
    /// reference refutes every other by its fit — each other alignment, passing or not, has
    /// converged within the matcher's `distinct_deg` of it or fits the frame clearly worse
    /// (`Tracker::fits_clearly_better`). Anything else is no pose. In simulated rectangular
    /// rooms seen by a D435 or a D415 (`rooms_track --camera`) the camera's own turn, ranked
    /// first by the planes, failed the degenerate-overlap check where the room turned by about
    /// 180° passed and fitted better (2.2–2.5 m off): neither a passing alternative alone nor
    /// the reference's preference alone is evidence enough. Returns the pose found, or why
    /// there is none (empty without candidates, else a clause for the lost frame's report),
    /// and the iterations spent.
    fn align_from_candidates(
        &self,
        starts: &[Isometry3<f64>],
        reference: &ReferenceMaps,
        unknown_var: f64,
    ) -> (std::result::Result<Attempt, String>, usize) {
        let mut iterations = 0;
        let mut attempts: Vec<Attempt> = Vec::with_capacity(starts.len());
        for start in starts {
            let a = self.align(start, reference, unknown_var, true);
            iterations += a.iterations;
            attempts.push(a);
        }
        let n = attempts.len();
        let best = match attempts.first() {
            None => return (Err(String::new()), iterations),
            Some(a) => match &a.failure {
                Some(why) => {
                    let of = if n == 1 {
                        "the one alignment it could not rule out".to_owned()
                    } else {
                        format!("the best of the {n} alignments it could not rule out")
                    };
                    return (
                        Err(format!("; against the model, {of} fails: {why}")),
                        iterations,
                    );
                }
                None => a,
            },
        };
        let distinct = self.cfg.fallback.motion.distinct_deg.to_radians();
        let refuted = attempts[1..].iter().all(|a| {
            a.pose.rotation.angle_to(&best.pose.rotation) <= distinct
                || self.fits_clearly_better(best, a, reference)
        });
        let found = if refuted {
            Ok(attempts.swap_remove(0))
        } else {
            Err(format!(
                "; of the {n} alignments it could not rule out, the best passes against the \
                 model, but another ends more than {}° from it without fitting clearly worse",
                self.cfg.fallback.motion.distinct_deg
            ))
        };
        (found, iterations)
    }

    /// Relocalising, or the first step of the sequence: the start (the last good pose, or
    /// the prediction) may be several frames' motion from the camera, where point-to-plane
    /// ICP can settle in a wrong minimum that trades a rotation for a translation and still
    /// passes every check (docs/bench/track.md, "Session 17"). Align again from starts turned
    /// about the camera's horizontal and vertical axes and keep the best fit by the robust
    /// objective over all the frame's points.
    fn align_from_turned_starts(
        &self,
        o: &mut Outcome,
        model: Option<&ReferenceMaps>,
        last: Isometry3<f64>,
        unknown_var: f64,
    ) {
        let reference = match (o.keyframe_pose, self.keyframes.reference()) {
            (Some(_), Some(keyframe)) => keyframe,
            _ if o.against_frame => &self.last_ref,
            _ => model.unwrap_or(&self.last_ref),
        };
        let centre = o.keyframe_pose.unwrap_or(last);
        let cfg = &self.cfg;
        let mut best = o.first.stats.total_loss(cfg.gate_sigmas, cfg.huber_k);
        for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)] {
            let mut turn = nalgebra::Vector3::zeros();
            turn[axis] = sign * RELOCALISATION_TURN_DEG.to_radians();
            let start = centre * Isometry3::rotation(turn);
            let alt = self.align(&start, reference, unknown_var, true);
            o.iterations += alt.iterations;
            let cost = alt.stats.total_loss(cfg.gate_sigmas, cfg.huber_k);
            if alt.failure.is_none() && cost < best {
                best = cost;
                o.first = alt;
            }
        }
    }
}

/// The camera's pose a plane-based motion `step` (this frame in the last good frame's
/// coordinates, `X_last = step · X_this`) puts it at from the `last` good pose.
fn start_from_planes(last: Isometry3<f64>, step: CameraToCamera) -> Isometry3<f64> {
    super::solve::renormalized(last * step.into_isometry())
}

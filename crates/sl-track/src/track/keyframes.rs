//! Keyframes for relocalisation: depth frames the tracker accepted, kept at poses spread over
//! the views seen so far, so that a lost camera can be found again where it looks at something
//! it saw before — not only near the last good pose.
//!
//! A hand-held camera that loses track in a fast turn rarely comes back to where it was lost
//! but often to what it saw a moment before: on TUM fr1/rpy taken every fourth frame, the
//! frames lost after frame 13 turn 13–73° away from it, yet each lies within 3–5° of one of
//! frames 2–9 (docs/bench/track.md, session 62). An alignment started at a keyframe's pose against that
//! keyframe's own depth succeeds when the camera is within the alignment's reach of it; the
//! result is judged by every acceptance check, as any relocalisation.
//!
//! Memory: at most [`MAX_KEYFRAMES`] depth images (1.2 MB each at 640×480), and one pyramid
//! level and one reference built on demand when a frame is lost (about 21 MB at 640×480).

use nalgebra::Isometry3;
use sl_core::{CameraToWorld, DepthImage, Intrinsics, SensorModel};

use super::Tracker;
use super::align::Attempt;
use super::pyramid::{Pyramid, normal_radius};
use super::reference::ReferenceMaps;
use crate::error::Result;

/// The most keyframes kept; the oldest goes first. At the spacing below, 16 keyframes span a
/// sweep of 160° or 80 cm.
pub(super) const MAX_KEYFRAMES: usize = 16;

/// A keyframe is added when no kept one is within half the largest correction an alignment
/// may make (`max_correction_deg` / 2 in rotation, `max_correction_m` in translation): the
/// views then lie closer together than an alignment's acceptance bounds reach.
fn is_new_view(a: &Isometry3<f64>, b: &Isometry3<f64>, max_m: f64, max_deg: f64) -> bool {
    let d = a.inverse() * b;
    d.translation.vector.norm() > max_m || d.rotation.angle().to_degrees() > max_deg / 2.0
}

/// One kept frame.
#[derive(Debug)]
struct Keyframe {
    pose: Isometry3<f64>,
    depth: DepthImage,
}

/// The keyframes of a tracker and the scratch space to turn one into a reference.
#[derive(Debug, Default)]
pub(super) struct Keyframes {
    frames: Vec<Keyframe>,
    scratch: Pyramid,
    /// The reference of the keyframe last built ([`Keyframes::build`]).
    reference: Option<ReferenceMaps>,
    /// Which keyframe `reference` holds.
    built: Option<usize>,
}

impl Keyframes {
    /// Keeps `depth` at `pose` when no keyframe is near it (see [`is_new_view`]).
    pub(super) fn offer(
        &mut self,
        depth: &DepthImage,
        pose: &Isometry3<f64>,
        max_m: f64,
        max_deg: f64,
    ) {
        if !self
            .frames
            .iter()
            .all(|f| is_new_view(&f.pose, pose, max_m, max_deg))
        {
            return;
        }
        if self.frames.len() < MAX_KEYFRAMES {
            self.frames.push(Keyframe {
                pose: *pose,
                depth: depth.clone(),
            });
            return;
        }
        // Full: the oldest goes, its buffer reused for the new one.
        self.built = None;
        let mut frame = self.frames.remove(0);
        frame.pose = *pose;
        if frame.depth.width() == depth.width() && frame.depth.height() == depth.height() {
            frame.depth.data_mut().copy_from_slice(depth.data());
        } else {
            frame.depth = depth.clone();
        }
        self.frames.push(frame);
    }

    /// The poses of the keyframes not within reach of `except` (already tried from there),
    /// newest first.
    pub(super) fn candidates(
        &self,
        except: &Isometry3<f64>,
        max_m: f64,
        max_deg: f64,
    ) -> Vec<(usize, Isometry3<f64>)> {
        self.frames
            .iter()
            .enumerate()
            .rev()
            .filter(|(_, f)| is_new_view(&f.pose, except, max_m, max_deg))
            .map(|(i, f)| (i, f.pose))
            .collect()
    }

    /// Builds keyframe `i` as the reference ([`Keyframes::reference`]: its points, normals and
    /// variances in world coordinates at its pose); false when there is no keyframe `i`.
    pub(super) fn build(
        &mut self,
        i: usize,
        k: &Intrinsics,
        sensor: &SensorModel,
        lateral_sigma_px: f64,
    ) -> Result<bool> {
        let Some(frame) = self.frames.get(i) else {
            return Ok(false);
        };
        if self.built == Some(i) {
            return Ok(true);
        }
        self.built = None;
        self.scratch.build(frame.depth.data(), k, sensor, 1, 1)?;
        let Some(level) = self.scratch.levels.first_mut() else {
            return Ok(false);
        };
        level.complete_normals(sensor, k.fx as f32, normal_radius(0));
        let reference = self
            .reference
            .get_or_insert_with(|| ReferenceMaps::empty(k));
        reference.set_from_level(
            level,
            k,
            sensor,
            &CameraToWorld::from_isometry(frame.pose),
            lateral_sigma_px,
        );
        self.built = Some(i);
        Ok(true)
    }

    /// The reference last built.
    pub(super) fn reference(&self) -> Option<&ReferenceMaps> {
        self.reference.as_ref()
    }

    /// How many are kept.
    #[cfg(test)]
    pub(super) fn len(&self) -> usize {
        self.frames.len()
    }
}

/// What [`Tracker::relocalise_on_keyframes`] found: the keyframe pose it started from and the
/// attempt that passed, if any, and the iterations spent.
pub(super) struct KeyframeSearch {
    pub(super) found: Option<(Isometry3<f64>, Attempt)>,
    pub(super) iterations: usize,
}

impl Tracker {
    /// Aligns the frame being tracked against every keyframe not within reach of `last`
    /// (tried already), each from its own pose with the wide prior (`prior_var_m2`), and
    /// returns the pose it started from and the attempt that passed every check with the
    /// lowest robust objective (its keyframe's reference is then the one built).
    pub(super) fn relocalise_on_keyframes(
        &mut self,
        last: &Isometry3<f64>,
        prior_var_m2: f64,
    ) -> Result<KeyframeSearch> {
        self.row_timing = None;
        let (k, sensor) = (self.camera.intrinsics, self.camera.sensor);
        let cfg = self.cfg;
        let mut best: Option<(usize, Isometry3<f64>, Attempt, f64)> = None;
        let mut iterations = 0;
        for (i, pose) in
            self.keyframes
                .candidates(last, cfg.max_correction_m, cfg.max_correction_deg)
        {
            if !self.keyframes.build(i, &k, &sensor, cfg.lateral_sigma_px)? {
                continue;
            }
            let Some(reference) = self.keyframes.reference() else {
                continue;
            };
            let attempt = self.align(&pose, reference, prior_var_m2, false);
            iterations += attempt.iterations;
            let loss = attempt.stats.total_loss(cfg.gate_sigmas, cfg.huber_k);
            if attempt.failure.is_none() && best.as_ref().is_none_or(|b| loss < b.3) {
                best = Some((i, pose, attempt, loss));
            }
        }
        let Some((i, pose, attempt, _)) = best else {
            return Ok(KeyframeSearch {
                found: None,
                iterations,
            });
        };
        self.keyframes.build(i, &k, &sensor, cfg.lateral_sigma_px)?;
        Ok(KeyframeSearch {
            found: Some((pose, attempt)),
            iterations,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn keyframes_are_spread_and_bounded() {
        let mut kf = Keyframes::default();
        let depth = DepthImage::from_vec(4, 3, vec![1.0; 12]).unwrap();
        let at = |deg: f64| Isometry3::new(Vector3::zeros(), Vector3::y() * deg.to_radians());
        // 5 cm and 20° bounds: a new keyframe every 10°.
        for i in 0..100 {
            kf.offer(&depth, &at(f64::from(i)), 0.05, 20.0);
        }
        assert_eq!(kf.len(), 10, "one every 11° over 0–99°");
        // Near a kept one: not kept again.
        kf.offer(&depth, &at(3.0), 0.05, 20.0);
        assert_eq!(kf.len(), 10);
        for i in 0..400 {
            kf.offer(&depth, &at(f64::from(i)), 0.05, 20.0);
        }
        assert_eq!(kf.len(), MAX_KEYFRAMES);
        // Candidates leave out those within reach of the pose already tried, newest first.
        let c = kf.candidates(&at(395.0), 0.05, 20.0);
        assert!(c.len() < MAX_KEYFRAMES);
        assert!(c.windows(2).all(|w| w[0].0 > w[1].0));
    }
}

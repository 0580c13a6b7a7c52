//! Tracking in a map that does not change: [`track_in_map`] aligns a sequence's frames one
//! after the other to a fused model built beforehand (from another recording of the place, or
//! from a data set's reference poses), as [`crate::Reconstruction`] aligns them to the model it
//! is building, but fuses nothing.
//!
//! With a map fused at a data set's own reference poses it measures how far those poses are
//! from the ones that align the frames best (the tracked pose explains its frame better), i.e.
//! the least error a depth tracker can be shown to have against that reference
//! (docs/bench/track.md, "Session 28"; the example `gt_model_probe`).

use sl_core::{Camera, CameraToWorld, DepthImage};
use sl_tsdf::TsdfVolume;

use crate::error::Result;
use crate::reconstruction::ReconstructionConfig;
use crate::track::{FrameResult, Tracker};

/// Tracks `frames` (metres, 0 = invalid; smooth them first as `sldepth track` does) one after
/// the other against `map`, each from the raycast of the map at the last tracked pose (at
/// `cfg.model_scale`, by default [`crate::ModelReference::default_scale`]), starting at `start`: the
/// first frame is anchored there, as a tracker's first frame is. The tracker is
/// `cfg.tracker`'s; nothing is fused into `map`. One result per frame, lost frames included.
///
/// # Errors
/// A frame of another size than the camera ([`crate::TrackError::SizeMismatch`]), or an
/// invalid configuration.
pub fn track_in_map<'a>(
    camera: Camera,
    cfg: &ReconstructionConfig,
    map: &TsdfVolume,
    start: CameraToWorld,
    frames: impl IntoIterator<Item = &'a DepthImage>,
) -> Result<Vec<FrameResult>> {
    track_in_map_with_noise(
        camera,
        cfg,
        map,
        start,
        frames.into_iter().map(|d| (d, None)),
    )
}

/// [`track_in_map`] with each frame's noise scale measured by the caller on the raw frame
/// (`Some`, [`Tracker::set_noise_scale`]): frames smoothed before tracking no longer show their
/// sensor's noise, so a caller that prefilters measures them first, as `sldepth track` does.
/// `None` lets the tracker measure the frame given (with `cfg.tracker.estimate_noise`).
///
/// # Errors
/// As [`track_in_map`].
pub fn track_in_map_with_noise<'a>(
    camera: Camera,
    cfg: &ReconstructionConfig,
    map: &TsdfVolume,
    start: CameraToWorld,
    frames: impl IntoIterator<Item = (&'a DepthImage, Option<f64>)>,
) -> Result<Vec<FrameResult>> {
    let mut model = cfg.model_reference(&camera)?;
    let mut tracker = Tracker::new(camera, cfg.tracker)?;
    tracker.set_initial_pose(start);
    let mut out = Vec::new();
    for (i, (depth, noise_scale)) in frames.into_iter().enumerate() {
        tracker.set_noise_scale(noise_scale);
        let result = if i == 0 {
            tracker.track(depth, None)?
        } else {
            let from = tracker.last_good_pose().unwrap_or(start);
            model.update(map, &from, &camera.sensor)?;
            tracker.track(depth, model.maps())?
        };
        out.push(result);
    }
    Ok(out)
}

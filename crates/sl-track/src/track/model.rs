//! The fused model as the tracker's reference ([`ModelReference`]): after each tracked frame
//! the volume is raycast from the new pose, at a fraction of the camera's resolution, into the
//! [`ReferenceMaps`] the next frame is aligned to. The `sldepth track` command and the Python
//! `Tracker` share it, so both render the model the same way.

use sl_core::{CameraToWorld, Intrinsics, SensorModel};
use sl_tsdf::{Raycast, RaycastConfig, TsdfVolume};

use super::ReferenceMaps;
use crate::error::{Result, TrackError};

/// The raycast of the fused model that the next frame is tracked against, reusing its buffers
/// from frame to frame.
///
/// The reference need not have the frame's resolution: association projects each frame point
/// into the reference's own intrinsics, and the residual is measured to the reference point's
/// tangent plane, which a coarser raycast samples just as well on smooth surfaces. At half the
/// resolution ([`ModelReference::DEFAULT_SCALE`]) the raycast costs about a third (TUM fr1/rpy,
/// 200 frames: 69 against 221 ms per frame) and the trajectories are as accurate
/// (docs/bench/track.md).
#[derive(Debug, Clone)]
pub struct ModelReference {
    intrinsics: Intrinsics,
    config: RaycastConfig,
    raycast: Raycast,
    maps: ReferenceMaps,
    rendered: bool,
}

impl ModelReference {
    /// Fraction of the camera's resolution the model is rendered at by default.
    pub const DEFAULT_SCALE: f64 = 0.5;

    /// A reference for a camera with intrinsics `camera`, rendered at `scale` of its resolution
    /// (in `(0, 1]`), marching rays with `config`. Nothing is rendered until
    /// [`ModelReference::update`].
    ///
    /// # Errors
    /// `scale` outside `(0, 1]`, intrinsics that do not scale to at least one pixel, or an
    /// invalid `config`.
    pub fn new(camera: &Intrinsics, scale: f64, config: RaycastConfig) -> Result<Self> {
        if !(scale > 0.0 && scale <= 1.0) {
            return Err(TrackError::InvalidConfig(format!(
                "model reference scale {scale} must be in (0, 1]"
            )));
        }
        config.validate()?;
        let intrinsics = if scale == 1.0 {
            *camera
        } else {
            camera.scaled(scale)?
        };
        Ok(Self {
            intrinsics,
            config,
            raycast: Raycast::default(),
            maps: ReferenceMaps::empty(&intrinsics),
            rendered: false,
        })
    }

    /// Renders `volume` from `pose` into the reference maps, with model variances from the
    /// sensor model (see [`ReferenceMaps::set_from_model`]; `z_ref_m` is the volume's
    /// [`sl_tsdf::TsdfConfig::z_ref_m`]).
    ///
    /// # Errors
    /// A pose the raycast rejects (not finite, or beyond the volume's coordinate range).
    pub fn update(
        &mut self,
        volume: &TsdfVolume,
        pose: &CameraToWorld,
        sensor: &SensorModel,
    ) -> Result<()> {
        let z_ref_m = volume.params().z_ref_m;
        volume.raycast_into(pose, &self.intrinsics, &self.config, &mut self.raycast)?;
        self.maps
            .set_from_model(&self.raycast, pose, &self.intrinsics, sensor, z_ref_m)?;
        self.rendered = true;
        Ok(())
    }

    /// The maps of the last [`ModelReference::update`], or `None` before the first.
    pub fn maps(&self) -> Option<&ReferenceMaps> {
        self.rendered.then_some(&self.maps)
    }

    /// The intrinsics the model is rendered with.
    pub fn intrinsics(&self) -> &Intrinsics {
        &self.intrinsics
    }

    /// The raycast of the last update (depth, points, normals, weights).
    pub fn raycast(&self) -> &Raycast {
        &self.raycast
    }
}

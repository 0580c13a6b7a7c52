//! A depth camera: pinhole [`Intrinsics`] plus the disparity [`SensorModel`].

use crate::error::Result;
use crate::intrinsics::Intrinsics;
use crate::sensor::{DEFAULT_SIGMA_D_PX, SensorModel};

/// Intrinsics and sensor model of one structured-light camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// Disparity sensor model.
    pub sensor: SensorModel,
}

/// Default projector–camera baseline of a Kinect v1, metres.
pub const KINECT_BASELINE_M: f64 = 0.075;
/// Default sub-pixel disparity steps of a Kinect v1.
pub const KINECT_SUBPIXEL_STEPS: u32 = 8;

impl Camera {
    /// The `kinect-v1` preset: 640×480, f = 580 px, c = (319.5, 239.5), B = 0.075 m, 1/8 px.
    pub fn kinect_v1() -> Self {
        Self {
            intrinsics: Intrinsics::kinect_v1(),
            sensor: SensorModel::kinect_v1(),
        }
    }

    /// The paper's Kinect: f = 587 px, B = 75 mm, 1/8 px.
    pub fn paper_kinect() -> Self {
        Self {
            intrinsics: Intrinsics::paper_kinect(),
            sensor: SensorModel::paper_kinect(),
        }
    }

    /// A camera with the given intrinsics and a Kinect-like sensor: focal length `fx`,
    /// baseline and sub-pixel steps from the Kinect defaults unless given.
    pub fn from_intrinsics(
        intrinsics: Intrinsics,
        baseline_m: Option<f64>,
        subpixel_steps: Option<u32>,
    ) -> Result<Self> {
        intrinsics.validate()?;
        let sensor = SensorModel::new(
            intrinsics.fx,
            baseline_m.unwrap_or(KINECT_BASELINE_M),
            subpixel_steps.unwrap_or(KINECT_SUBPIXEL_STEPS),
            DEFAULT_SIGMA_D_PX,
        )?;
        Ok(Self { intrinsics, sensor })
    }
}

impl Default for Camera {
    fn default() -> Self {
        Self::kinect_v1()
    }
}

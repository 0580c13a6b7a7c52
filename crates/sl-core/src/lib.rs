//! # sl-core — the structured-light camera model
//!
//! The foundation of the `sldepth` workspace: camera [`Intrinsics`], the disparity
//! [`SensorModel`] of the paper (`Z = f·B/D`, `σ_Z = Z²·σ_D/(f·B)`), typed [`DepthImage`] (metres)
//! and [`DisparityImage`] (pixels) with 0 as the invalid value, back-projection to points, the
//! geometry vocabulary of the workspace ([`Plane`] with the one plane fit [`fit_plane`], [`Mesh`])
//! and rigid camera poses typed by direction ([`CameraToWorld`], [`WorldToCamera`],
//! [`CameraToCamera`], [`WorldToWorld`]), and the instruction sets ([`Isa`]) hot loops are
//! compiled for, chosen at run time ([`Isa::run`]), and [`whole`]: the rounding of bounded `f32`
//! values to integers in a way that vectorises. Every other crate (`sl-noise`, `sl-io`, and the filters, fusion and plane
//! crates) speaks these types. `sl-core` does no I/O.
//!
//! ```
//! use sl_core::{Camera, DepthImage};
//!
//! let cam = Camera::kinect_v1();
//! // Depth noise grows with the square of depth: 4× from 1.5 m to 3 m.
//! let ratio = cam.sensor.sigma_z(3.0) / cam.sensor.sigma_z(1.5);
//! assert!((ratio - 4.0).abs() < 1e-12);
//!
//! // A flat wall 2 m away, seen as disparity: f·B/Z = 580·0.075/2 = 21.75 px everywhere.
//! let depth = DepthImage::from_vec(640, 480, vec![2.0; 640 * 480])?;
//! let disparity = depth.to_disparity(&cam.sensor);
//! assert!((disparity.get(10, 10).unwrap_or(0.0) - 21.75).abs() < 1e-4);
//! let points = depth.to_points(&cam.intrinsics)?;
//! assert_eq!(points.len(), 640 * 480);
//! # Ok::<(), sl_core::CoreError>(())
//! ```
#![deny(missing_docs)]

pub mod camera;
pub mod compact;
pub mod error;
pub mod image;
pub mod intrinsics;
pub mod isa;
pub mod lens;
pub mod mesh;
pub mod plane;
pub mod pose;
pub mod preset;
pub mod sensor;
pub mod view;
pub mod whole;

pub use camera::Camera;
pub use compact::Compact;
pub use error::{CoreError, Result};
pub use image::{DepthImage, DisparityImage, Image, PixelPoint, ValidStats};
pub use intrinsics::Intrinsics;
pub use isa::{Isa, IsaKernel, prefetch};
pub use lens::{LensDistortion, Undistorter};
pub use mesh::{Mesh, Topology, VertexScalar};
pub use plane::{Plane, PlaneFit, fit_plane};
#[allow(deprecated)]
pub use pose::Pose;
pub use pose::{
    CameraToCamera, CameraToWorld, WorldToCamera, WorldToWorld, pose_from_matrix,
    pose_from_row_major, pose_from_translation_quaternion, pose_to_matrix,
};
pub use preset::SensorPreset;
pub use sensor::SensorModel;
pub use view::DepthView;

/// Re-export of the nalgebra version used in the public API.
pub use nalgebra;

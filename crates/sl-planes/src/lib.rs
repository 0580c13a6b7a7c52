//! # sl-planes — plane extraction in the disparity domain
//!
//! Section 3.4–3.5 of the paper. A structured-light camera measures disparity `D = f·B/Z` with
//! a noise that is constant in pixels, and on a plane `D` is an affine function of the pixel
//! (eq. 14, see [`plane`]). Working on the disparity, one **fixed** threshold in pixels is right
//! at 0.6 m and at 4 m, while a metric threshold is too tight far away or too loose nearby.
//!
//! Pipeline position: depth frames → `sl-io` → `sl-core` types → (`sl-filter`) → **`sl-planes`**.
//!
//! * [`PlaneExtractor`] / [`extract_planes`]: the frame's own noise level measured on its
//!   patches (the camera's model is a floor: a noisier sensor is tested with its measured noise,
//!   [`PlaneExtractor::noise_scale`]) → box-LoG planarity mask → affine fits of 16×16-pixel
//!   patches of planar 4×4-pixel cells, merged while a χ² test from the noise model (σ_D, 1/q,
//!   the correlation of the disparity error) accepts one plane → k-means refinement on the cells with merging
//!   → growth over the connected cells each plane explains within the noise → coplanar pieces
//!   with free space between them split → per-pixel assignment with neighbour disambiguation →
//!   adjacent pieces of one surface bent by the sensor's distortion joined → label image + [`PlaneInfo`] (3D
//!   normal/offset, disparity-affine coefficients, RMS in px and m, and how well the noise
//!   model says the plane is determined: `normal_sigma_deg`, `offset_sigma_m`). About 3 ms per 640×480
//!   frame on one core; reuse one extractor for a video ([`PlaneExtractor::stage_times`] gives
//!   the time per stage).
//! * [`ransac::metric_ransac`]: the fixed metric-threshold baseline (Open3D `segment_plane` style).
//!   (Scoring a segmentation — the Hoover et al. SegComp comparison — and colour overlays of the
//!   labels are evaluation tools: they live in `sl-eval`.)
//! * Motion between frames from these planes (plane matching, weighted Kabsch, the depth-data
//!   verification, point-to-plane ICP) lives in the `sl-track` crate, which builds on this one.
//!
//! ```
//! use sl_core::{Camera, DepthImage, nalgebra::Vector3};
//! use sl_planes::{Plane, PlaneConfig, extract_planes};
//!
//! // A 160x120 camera looking at a wall 2 m away, tilted 20 degrees about the vertical axis.
//! let k = sl_core::Intrinsics::kinect_v1().scaled(0.25)?;
//! let cam = Camera { intrinsics: k, sensor: sl_core::SensorModel::kinect_v1() };
//! let wall = Plane::new(Vector3::new(20f64.to_radians().sin(), 0.0, -20f64.to_radians().cos()), 2.0)?.facing_origin();
//! let depth: Vec<f32> = (0..k.width * k.height)
//!     .map(|i| wall.depth_at(&k, (i % k.width) as f64, (i / k.width) as f64).unwrap_or(0.0) as f32)
//!     .collect();
//! let depth = DepthImage::from_vec(k.width, k.height, depth)?;
//! let mut cfg = PlaneConfig::default();
//! cfg.min_pixels = 200;
//! let seg = extract_planes(&depth, &cam, &cfg)?;
//! assert_eq!(seg.planes.len(), 1);
//! assert!(seg.planes[0].plane.angle_to_deg(&wall) < 0.1);
//! assert!((seg.planes[0].plane.offset_m - 2.0).abs() < 0.01);
//! // How well the sensor's noise model says the plane is determined (a whole wall: well).
//! assert!(seg.planes[0].normal_sigma_deg < 0.5 && seg.planes[0].offset_sigma_m < 0.005);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

mod components;
pub mod error;
mod extend;
pub mod extract;
mod fit;
mod kernels;
mod log;
pub mod plane;
mod quadratic;
pub mod ransac;
mod uncertainty;

pub use error::{PlanesError, Result};
pub use extract::{
    NoiseMeter, PlaneConfig, PlaneExtractor, PlaneInfo, PlaneSegmentation, RegionExplanation,
    RejectReason, Stage, StageTimes, extract_planes, frame_noise_scale,
};
pub use plane::DisparityAffine;
pub use ransac::{RansacConfig, metric_ransac};
/// The workspace's plane type (re-exported from sl-core), which extraction reports facing the camera.
pub use sl_core::Plane;

//! # sl-io — files in, files out
//!
//! The I/O layer of the `sldepth` workspace. Depth frames enter the pipeline here and results
//! leave through here:
//!
//! ```text
//! depth frames ─▶ sl-io ─▶ sl-core types ─▶ sl-filter ─▶ sl-tsdf / sl-planes ─▶ sl-io ─▶ files
//! ```
//!
//! - [`depth`]: 16-bit PNG / TIFF depth at any scale (1000 units/m default, 5000 for TUM; 0 and
//!   65535 invalid), floating-point TIFF (metres by default), NYU Depth v2 raw Kinect disparity
//!   PGM, SUN RGB-D bit-rotated PNG. Reading
//!   returns the [`DepthEncoding`] so output can be written the way the input was stored.
//! - [`rgb`]: colour frames in (PNG, TIFF, PPM), 8-bit RGB / grey and 16-bit label PNGs out.
//! - [`camera`]: Open3D `PinholeCameraIntrinsic` JSON plus sensor-model keys → [`sl_core::Camera`];
//!   7-Scenes `camera-intrinsics.txt`.
//! - [`ply`]: point clouds and triangle meshes (normals, colours, a per-vertex scalar), binary or
//!   ASCII, through `ply-rs`.
//! - [`trajectory`]: TUM `groundtruth.txt` + `associations.txt` or `depth.txt`, Open3D `.log`,
//!   7-Scenes `frame-*.pose.txt`, all as [`Frame`]s with [`sl_core::CameraToWorld`] poses.
//! - [`rosbag`]: robot recordings — ROS 1 bags, ROS 2 bags in MCAP or SQLite (one file or a
//!   split recording's folder), RealSense recordings — a recording's depth topic frame by
//!   frame, its camera info, and a RealSense sensor's depth units, device and timestamps.
//! - [`sequence`]: a recording's folder as `sldepth track DIR` and `sldepth fuse DIR` read it
//!   (its layout and depth scale, its frames, their poses, the camera it implies).
//! - [`atomic`]: every file is written through [`atomic::write_atomic`] (temp file + fsync +
//!   rename), so readers never see half-written output.
//!
//! Every malformed input gives an [`IoError`] naming the file and the problem (with the line
//! number for text formats). Every reader is bounded by a [`Limits`] value (the plain functions
//! use [`Limits::default`], the `*_with_limits` ones take it): image headers are checked before
//! decoding, camera sizes at load, text is counted while it streams in, and no buffer is sized
//! from an unchecked header.
//!
//! ```
//! use sl_io::{DepthEncoding, ReadConfig, read_depth, write_depth};
//! use sl_core::DepthImage;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("depth.png");
//!
//! // A 4×2 frame: 1.2346 m everywhere except one invalid pixel, saved the TUM way (1/5000 m).
//! let mut depth = DepthImage::from_vec(4, 2, vec![1.2346; 8])?;
//! depth.data_mut()[3] = 0.0;
//! write_depth(&path, &depth, &DepthEncoding::tum())?;
//!
//! // Reading needs the scale (a PNG does not record it; only a frame in a TUM folder's `depth`
//! // folder is read at TUM's 5000 without one); the encoding comes back for writing.
//! let loaded = read_depth(&path, &ReadConfig::default().with_scale(5000.0))?;
//! assert_eq!(loaded.encoding, DepthEncoding::tum());
//! assert_eq!(loaded.depth.valid_count(), 7);
//! assert!((loaded.depth.get(0, 0).unwrap_or(0.0) - 1.2346).abs() < 1e-6);
//!
//! // Depth beyond what 16 bits hold at this scale (65534 / 5000 = 13.1068 m) is an error.
//! depth.data_mut()[0] = 20.0;
//! assert!(write_depth(&path, &depth, &DepthEncoding::tum()).is_err());
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]
// Tests may unwrap / panic; library code may not (docs/ARCHITECTURE.md, invariants).
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod atomic;
pub mod camera;
pub mod depth;
pub mod error;
mod float_tiff;
pub mod limits;
pub mod ply;
mod pnm;
mod raster;
pub mod rgb;
pub mod ros_camera;
pub mod rosbag;
pub mod sequence;
mod text;
pub mod trajectory;

pub use camera::{
    read_7scenes_intrinsics, read_camera, read_camera_json, read_intrinsics_txt, write_camera_json,
};
#[allow(deprecated)]
pub use depth::ReadOptions;
pub use depth::{
    DepthEncoding, DepthFormat, LoadedDepth, RawDepth, ReadConfig, read_depth, read_nyu_raw,
    read_raw_depth, write_depth, write_raw_depth,
};
pub use error::{IoError, Result};
pub use limits::Limits;
pub use ply::{
    PlyData, PlyFormat, VertexScalar, read_mesh_ply, read_ply, write_mesh_ply, write_ply,
};
pub use rgb::{read_gray16, read_rgb, write_gray8_png, write_gray16_png, write_rgb_png};
pub use trajectory::{
    DEFAULT_MAX_DT_S, Frame, TimedPose, TumSequence, read_7scenes_sequence, read_open3d_log,
    read_open3d_log_frames, read_tum_sequence,
};

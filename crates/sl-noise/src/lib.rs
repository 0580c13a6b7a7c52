//! # sl-noise — the noise of structured-light depth cameras
//!
//! A structured-light camera such as the Kinect v1 measures disparity `D` to `1/q` pixel
//! (q = 8) and reports depth `Z = f·B/D` rounded to 1 mm, so its depth resolution and noise grow
//! with `Z²` (the paper's section 2). This crate holds the three tools the paper's argument is
//! built on:
//!
//! * [`mod@algorithm1`] — the paper's Algorithm 1 (synthetic depths 0.5–3 m through a 1/8-px
//!   disparity quantiser; the log-log slope of the depth steps, 1.946);
//! * [`analysis`] — the depth-resolution analysis of any depth map (sorted unique depths,
//!   `ln ΔZ` vs `ln Z` slopes, the quantum `c` of `ΔZ ≈ c·Z²`, the implied `f·B`, and the
//!   disparity sub-pixel resolution; `sl-eval` draws it as the paper's Figure 2);
//! * [`sim`] — a seeded Kinect simulator: analytic scenes (planes, rectangles, boxes, spheres,
//!   cylinders, relief plates) rendered to exact depth, labels and normals, then through the
//!   sensor (by default the realistic model of [`sim::realistic`]: block-matching-correlated
//!   disparity error, `1/q` quantisation, 1 mm rounding, occlusion bands, drop-outs; or the
//!   paper's white Gaussian noise, [`sim::NoiseModel::White`]). Later stages use it for ground
//!   truth;
//! * [`stats`] — the noise statistics of a depth map on planar regions (σ_D per depth band,
//!   residual autocorrelation, terrace widths, occlusion-band widths), to compare real frames
//!   with the simulator.
//!
//! Where it sits: depth frames → `sl-io` → `sl-core` types → **`sl-noise`** (analysis and
//! simulation, beside the pipeline) → `sl-filter` → `sl-tsdf` / `sl-planes`, which test
//! themselves against `sl-noise` scenes.
//!
//! ```
//! use sl_noise::{analysis, sim::{KinectSimulator, named_scene}};
//!
//! // The paper's Algorithm 1.
//! let a1 = sl_noise::algorithm1::algorithm1();
//! assert!((a1.slope_ols - 1.946).abs() < 5e-4);
//!
//! // Simulate the tilted floor of the paper's Figure 1 (quarter resolution) and analyse it.
//! let floor = named_scene("floor")?;
//! let k = floor.intrinsics.scaled(0.25)?;
//! let sim = KinectSimulator::kinect_v1().white();
//! let frame = sim.simulate(&floor.scene, &k, &floor.pose, 7);
//! let r = analysis::analyze(&frame.depth, &sim.sensor)?;
//! assert!((r.slope - 2.0).abs() < 0.1);
//! assert!((r.fb_px_m.unwrap_or(0.0) / sim.sensor.fb() - 1.0).abs() < 0.01);
//! assert_eq!(r.subpixel_steps, Some(8));
//! # Ok::<(), sl_noise::NoiseError>(())
//! ```
#![deny(missing_docs)]
// Tests may unwrap: a failed unwrap is a failed test.
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod algorithm1;
pub mod analysis;
pub mod error;
pub mod sim;
pub mod stats;

pub use algorithm1::{Algorithm1, Algorithm1Params, algorithm1, algorithm1_with};
#[allow(deprecated)]
pub use analysis::AnalysisOptions;
pub use analysis::{AnalysisConfig, ResolutionAnalysis, analyze, analyze_with};
pub use error::{NoiseError, Result};

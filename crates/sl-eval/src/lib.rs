//! # sl-eval — evaluation support: metrics, scores, renderings and plots
//!
//! What `cargo xtask validate`, the `sldepth` CLI and the tests use to *judge* and *show* the
//! output of the production crates, kept out of them so that a user who depends on `sl-filter`
//! gets a filter, not a report generator. Not published (`publish = false`).
//!
//! | module | role | used by |
//! |---|---|---|
//! | [`filter`] | RMSE per depth band, depth-edge masks, dominant-plane region and plane-fit residual | `xtask validate --only filter`, `sl-filter` tests |
//! | [`planes`] | the Hoover et al. SegComp score ([`planes::segcomp`](mod@planes::segcomp)) and label overlays ([`planes::overlay`]) | `sldepth planes --overlay`, `xtask validate --only planes`, `sl-planes` tests |
//! | [`tsdf`] | distances from a fused mesh to a reference surface ([`DistanceStats`]) | `xtask validate --only tsdf`, `sl-tsdf` tests |
//! | [`render`] | shaded surface normals of a depth map ([`render::normals`]) and a software mesh renderer ([`render::mesh`]) | `sldepth filter --normals`, `sldepth fuse --render-png`, reports |
//! | [`trajectory`] | ATE after Horn's alignment and RPE per frame or second, TUM benchmark definitions ([`trajectory::ate`], [`trajectory::rpe`]), and the clock offset of an estimate ([`trajectory::estimate_time_offset`]) | `sldepth eval-traj`, tracking tests |
//! | [`plot`] | the paper's Figure 2 (depth-resolution analysis) as SVG or RGB | `sldepth analyze --plot`, `xtask validate --only noise` |
//!
//! Where it sits: beside the pipeline, on top of it. It depends on `sl-core`, `sl-noise` (the
//! resolution analysis it plots) and `sl-tsdf` (the mesh type it measures and renders); the
//! production crates use it only as a dev-dependency, never the other way round.
//!
//! **I/O:** like the binaries, `sl-eval` is a support crate and exempt from the rule that
//! library crates do no file I/O; when it needs files it goes through `sl-io`. Today every
//! function returns its result in memory (an SVG string, an RGB [`sl_core::Image`], numbers)
//! and the caller saves it.
//!
//! Errors are one enum, [`EvalError`].
//!
//! ```
//! use sl_eval::filter::{KINECT_BANDS_M, pooled, rmse_by_band};
//! use sl_eval::planes::segcomp;
//! use sl_filter::{DepthFilter, Method};
//! use sl_noise::sim::{KinectSimulator, named_scene};
//!
//! // A simulated Kinect frame (quarter resolution, the paper's white noise) of a wall, with its
//! // exact depth and labels.
//! let wall = named_scene("wall")?;
//! let k = wall.intrinsics.scaled(0.25)?;
//! let sim = KinectSimulator::kinect_v1().white();
//! let frame = sim.simulate(&wall.scene, &k, &wall.pose, 7);
//!
//! // Does the adaptive filter bring the depth closer to the truth? (7.3 mm → 1.5 mm RMSE)
//! let smooth = DepthFilter::default_for(Method::Adaptive, &sim.sensor).apply(&frame.depth)?;
//! let (raw_m, _) = pooled(&rmse_by_band(&frame.depth, &frame.truth, None, &KINECT_BANDS_M)?);
//! let (filtered_m, pixels) = pooled(&rmse_by_band(&smooth, &frame.truth, None, &KINECT_BANDS_M)?);
//! assert!(pixels > 0 && filtered_m < 0.5 * raw_m);
//!
//! // SegComp of the true labels against themselves: every region is a correct detection.
//! let score = segcomp(&frame.labels, &frame.labels, None, 0.8, 1)?;
//! assert_eq!(score.correct, score.gt_regions);
//!
//! // A picture for the report: shaded normals of the raw and the filtered frame.
//! let raw_img = sl_eval::render::shaded_normals(&frame.depth, &k)?;
//! let smooth_img = sl_eval::render::shaded_normals(&smooth, &k)?;
//! let both = sl_eval::render::side_by_side(&[&raw_img, &smooth_img])?;
//! assert_eq!(both.width(), 2 * k.width + 4);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod error;
pub mod filter;
pub mod planes;
pub mod plot;
pub mod render;
pub mod trajectory;
pub mod tsdf;

pub use error::{EvalError, Result};
pub use planes::{SegCompScore, segcomp};
pub use tsdf::{DistanceStats, vertex_distances};

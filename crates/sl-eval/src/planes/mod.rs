//! Evaluation of plane extraction: the Hoover et al. segmentation comparison ([`segcomp`](mod@segcomp)) and
//! colour overlays of plane labels ([`overlay`]).
//!
//! Both work on `u16` label images (0 = no plane), the output format of `sl-planes`, so they
//! score and draw any segmentation, including ground truth from `sl-noise` scenes.

pub mod overlay;
pub mod segcomp;

pub use overlay::{depth_to_rgb, label_color, overlay_rgb};
pub use segcomp::{SegCompDetail, SegCompScore, segcomp, segcomp_detail};

//! One module per subcommand.

pub mod analyze;
pub mod cameras;
pub mod cloud;
pub mod eval_traj;
pub mod filter;
pub mod fuse;
pub mod info;
pub mod motion;
pub mod noise_stats;
pub mod planes;
pub mod simulate;
pub mod track;

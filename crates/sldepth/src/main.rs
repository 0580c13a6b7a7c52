//! `sldepth`: command-line tools for structured-light depth cameras (Kinect v1, PrimeSense,
//! Xtion). Run `sldepth --help` for the list of commands; every option names its unit.

mod cmd;
mod common;

use clap::{Parser, Subcommand};

/// Structured-light depth camera toolkit: noise analysis, simulation, filtering, fusion and
/// plane extraction for Kinect-class depth maps.
#[derive(Debug, Parser)]
#[command(name = "sldepth", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Size and depth statistics of a depth map.
    Info(cmd::info::Args),
    /// Depth resolution analysis (the paper's Figure 2): unique depths, log-log slope, quantum,
    /// implied f·B, disparity sub-pixel steps.
    Analyze(cmd::analyze::Args),
    /// Render a seeded synthetic scene through the Kinect noise model.
    Simulate(cmd::simulate::Args),
    /// Back-project a depth map to a PLY point cloud.
    Cloud(cmd::cloud::Args),
    /// Merge registered depth frames into a mesh: sparse TSDF with 1/Z^4 noise weights and
    /// crack-free marching cubes (paper section 3.3).
    Fuse(cmd::fuse::Args),
    /// Smooth a depth map: Gaussian, bilateral, the paper's adaptive bilateral (σ_d = k·Z², the
    /// default, tuned from the sensor model) or a disparity-domain bilateral (section 3.2).
    Filter(cmd::filter::Args),
    /// Extract planes with a fixed threshold in disparity (paper section 3.4), or with the
    /// fixed-metric-threshold RANSAC baseline; writes a 16-bit label image.
    Planes(cmd::planes::Args),
    /// Camera motion between two depth frames from matched planes (section 3.5), optionally
    /// refined by point-to-plane ICP.
    Motion(cmd::motion::Args),
    /// List the camera presets `--camera NAME` accepts: intrinsics, baseline, disparity
    /// sub-pixel steps, noise, range and the source of the numbers.
    Cameras(cmd::cameras::Args),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Info(a) => cmd::info::run(a),
        Command::Analyze(a) => cmd::analyze::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Cloud(a) => cmd::cloud::run(a),
        Command::Fuse(a) => cmd::fuse::run(a),
        Command::Filter(a) => cmd::filter::run(a),
        Command::Planes(a) => cmd::planes::run(a),
        Command::Motion(a) => cmd::motion::run(a),
        Command::Cameras(a) => cmd::cameras::run(a),
    }
}

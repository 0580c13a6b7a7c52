//! `sldepth cloud`: back-project a depth map to a PLY point cloud.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::common::{InputArgs, LensArgs, check_output, load_depth};

/// Options of `sldepth cloud`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Depth map to back-project.
    #[arg(value_name = "DEPTH")]
    pub depth: PathBuf,
    /// Output PLY file (points in metres, camera frame: x right, y down, z forward).
    #[arg(long, short, value_name = "FILE.ply")]
    pub output: PathBuf,
    /// Write ASCII PLY instead of binary little-endian.
    #[arg(long)]
    pub ascii: bool,
    #[command(flatten)]
    pub lens: LensArgs,
    #[command(flatten)]
    pub input: InputArgs,
}

/// Runs `sldepth cloud`.
pub fn run(args: Args) -> Result<()> {
    check_output("--output", &args.output, &["ply"])?;
    crate::common::check_outputs_spare_inputs(
        &[("--output", Some(args.output.as_path()))],
        [args.depth.as_path()],
    )?;
    let mut loaded = load_depth(&args.depth, &args.input)?;
    if let Some(u) = crate::common::undistorter(
        &args.lens,
        &args.input,
        loaded.implied_preset,
        &loaded.camera,
    ) {
        loaded.depth = u.apply(&loaded.depth)?;
    }
    let points = loaded.depth.to_points(&loaded.camera.intrinsics)?;
    let ply = sl_io::ply::PlyData {
        positions: points.iter().map(|p| [p.x, p.y, p.z]).collect(),
        ..Default::default()
    };
    let format = if args.ascii {
        sl_io::ply::PlyFormat::Ascii
    } else {
        sl_io::ply::PlyFormat::BinaryLittleEndian
    };
    sl_io::ply::write_ply(&args.output, &ply, format)
        .with_context(|| format!("writing {}", args.output.display()))?;
    errln!("wrote {} points to {}", points.len(), args.output.display());
    Ok(())
}

//! The reconstruction's configuration from the options: the tracker's (weighting, fallbacks,
//! noise, pyramid, rolling shutter, instruction set), the volume's and the fragments'.

use anyhow::Result;
use sl_core::Camera;
use sl_track::{ReconstructionConfig, WeightMode};
use sl_tsdf::Truncation;

use super::Args;
use crate::common::limits;

/// The configuration of the run's `Reconstruction` for `camera`, tracking with `weighting`;
/// `implied` is the camera preset the source implies (for the rolling shutter's `auto`).
pub(super) fn reconstruction_config(
    args: &Args,
    camera: &Camera,
    weighting: WeightMode,
    implied: Option<&str>,
) -> Result<ReconstructionConfig> {
    let mut cfg = ReconstructionConfig::default_for(camera.sensor);
    cfg.tracker.weighting = weighting;
    cfg.tracker.plane_fallback = !args.no_plane_fallback;
    cfg.tracker.keyframe_relocalisation = !args.no_keyframes;
    cfg.tracker.estimate_noise = !args.model_noise_only;
    cfg.tracker.finest_level = usize::from(args.finest_level);
    cfg.tracker.rolling_shutter_readout_s = rolling_shutter_readout_s(args, implied)?;
    if let Some(isa) = args.isa.as_deref().and_then(sl_core::Isa::from_name) {
        cfg.tracker.isa = isa;
        cfg.tsdf.isa = isa;
    }
    cfg.tsdf.voxel_m = args.voxel_m;
    cfg.tsdf.trunc_m = args.trunc_m.unwrap_or(5.0 * args.voxel_m);
    cfg.tsdf.truncation = match args.trunc_m {
        Some(_) => Truncation::Fixed,
        None => Truncation::sensor_adaptive(camera.sensor),
    };
    cfg.tsdf.max_depth_m = args.max_depth_m;
    cfg.tsdf.depth_lookup = args.depth_lookup;
    // The volume's share (`Limits::tsdf_budget_bytes`), so that the mesh of a full model fits
    // beside it at the end (`Limits::mesh_budget_bytes`).
    cfg.tsdf.memory_budget_bytes = limits().tsdf_budget_bytes;
    cfg.frame_to_model = !args.frame_to_frame;
    cfg.model_scale = args.model_scale;
    cfg.new_fragment_after_s = args
        .new_fragment_after_s
        .is_finite()
        .then_some(args.new_fragment_after_s);
    cfg.new_volume_when_full = args.when_model_full == "continue";
    if args.odometry.given() {
        args.odometry.configure(&mut cfg.tracker)?;
    }
    Ok(cfg)
}

/// `--rolling-shutter-ms` in seconds: the number given, or with `auto` the readout of the
/// camera's preset (`--camera NAME`, else `implied`, the one the source implies) when tracking
/// against the model, else 0. Says so on standard error when it models one.
fn rolling_shutter_readout_s(args: &Args, implied: Option<&str>) -> Result<f64> {
    let value = args.rolling_shutter_ms.trim();
    if !value.eq_ignore_ascii_case("auto") {
        let ms: f64 = value.parse().map_err(|_| {
            anyhow::anyhow!("--rolling-shutter-ms must be `auto` or milliseconds, got {value:?}")
        })?;
        // The range is the tracker's to check (at most the frame interval).
        return Ok(ms / 1000.0);
    }
    if args.frame_to_frame {
        return Ok(0.0);
    }
    let Some(name) = crate::common::preset_name(&args.input, implied) else {
        return Ok(0.0);
    };
    let readout_s = sl_core::preset::find(&name).map_or(0.0, |p| p.rolling_shutter_readout_s);
    if readout_s > 0.0 {
        errln!(
            "note: modelling the `{name}` rolling shutter ({:.0} ms readout; --rolling-shutter-ms 0 for a global shutter)",
            readout_s * 1e3
        );
    }
    Ok(readout_s)
}

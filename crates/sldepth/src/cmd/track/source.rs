//! The sequence to track: its depth frames and camera from `--tum`, `--7scenes` or `--o3d`,
//! the other files of the source (which no output may replace) and the camera preset the
//! source implies.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use sl_core::Camera;
use sl_io::sequence::{SequenceFrame, SequenceLayout};

use super::Args;
use crate::common::{folder_camera, limits};

/// A sequence folder given without its layout (`sldepth track DIR`) becomes the option of the
/// layout it holds (`--tum`, `--7scenes` or `--o3d`).
pub(super) fn resolve_layout(args: &mut Args) -> Result<()> {
    let Some(dir) = args.sequence.take() else {
        return Ok(());
    };
    if sl_io::rosbag::is_bag_file(&dir) {
        args.bag = Some(dir);
        return Ok(());
    }
    match crate::common::sequence_layout(&dir)? {
        SequenceLayout::Tum => args.tum = Some(dir),
        SequenceLayout::SevenScenes => args.seven_scenes = Some(dir),
        SequenceLayout::Open3d => args.o3d = Some(dir),
        other => bail!(
            "{}: a {other:?} folder is not read by `sldepth track`",
            dir.display()
        ),
    }
    Ok(())
}

/// The files of the chosen source besides its depth frames, which no output may replace.
pub(super) fn source_files(args: &Args) -> Vec<PathBuf> {
    let o3d_camera = args
        .o3d
        .as_ref()
        .and_then(|d| sl_io::sequence::camera_file_of(d, SequenceLayout::Open3d));
    crate::common::sequence_files(
        args.tum.as_deref(),
        args.seven_scenes.as_deref(),
        o3d_camera.into_iter().chain(args.input.camera.clone()),
    )
}

/// The frames, the camera and the default depth scale of the chosen source.
pub(super) fn load_source(args: &Args) -> Result<(Vec<SequenceFrame>, Camera, f64)> {
    let lim = limits();
    // A folder without a frame: an error naming the folder and what was looked for in it.
    if let Some(dir) = &args.tum {
        let frames = sl_io::sequence::read_tum_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            let assoc = dir.join("associations.txt");
            let (list, line) = if assoc.is_file() {
                (assoc, "RGB_TIME RGB_FILE DEPTH_TIME DEPTH_FILE")
            } else {
                (dir.join("depth.txt"), "TIME DEPTH_FILE")
            };
            bail!(
                "--tum {}: {} lists no depth frames (expected lines `{line}`)",
                dir.display(),
                list.display()
            );
        }
        Ok((
            frames,
            crate::common::tum_camera(dir, &args.input)?,
            SequenceLayout::Tum.depth_scale(),
        ))
    } else if let Some(dir) = &args.seven_scenes {
        let frames = sl_io::sequence::read_7scenes_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            bail!(
                "--7scenes {}: no depth frames in the folder (expected 7-Scenes files named \
                 frame-NNNNNN.depth.png, e.g. frame-000000.depth.png)",
                dir.display()
            );
        }
        let camera = folder_camera(&args.input, dir, SequenceLayout::SevenScenes)?;
        Ok((frames, camera, SequenceLayout::SevenScenes.depth_scale()))
    } else if let Some(dir) = &args.o3d {
        let frames = sl_io::sequence::read_open3d_depth_frames(dir, &lim)?;
        if frames.is_empty() {
            let sub = dir.join("depth");
            bail!(
                "--o3d {}: no depth images in {} (expected .png, .tif, .tiff or .pgm files)",
                dir.display(),
                if sub.is_dir() { sub } else { dir.clone() }.display()
            );
        }
        let camera = folder_camera(&args.input, dir, SequenceLayout::Open3d)?;
        Ok((frames, camera, SequenceLayout::Open3d.depth_scale()))
    } else {
        bail!("give the sequence with --tum DIR, --7scenes DIR or --o3d DIR")
    }
}

/// The preset of the sensor the source implies when no `--camera` is given
/// (`sl_io::sequence::sensor_preset`): a TUM folder's, 7-Scenes', or the `ros-default` of an
/// Open3D folder without a camera file (Open3D's PrimeSenseDefault).
pub(super) fn implied_preset(args: &Args) -> Option<&'static str> {
    let (dir, layout) = folder(args)?;
    sl_io::sequence::sensor_preset(dir, layout)
}

/// The sequence folder of the source and its layout (`--tum`, `--7scenes` or `--o3d`).
pub(super) fn folder(args: &Args) -> Option<(&Path, SequenceLayout)> {
    if let Some(dir) = &args.tum {
        Some((dir, SequenceLayout::Tum))
    } else if let Some(dir) = &args.seven_scenes {
        Some((dir, SequenceLayout::SevenScenes))
    } else {
        Some((args.o3d.as_ref()?, SequenceLayout::Open3d))
    }
}

/// How the source's stamps and frame are read (`--tum` only): whether its stamps are frame
/// numbers (`sl_io::sequence::tum_stamps_are_frame_numbers`), returned, and whether it is one of
/// ICL-NUIM's TUM-format folders, whose frame has y up (`args.data_y_up` is set); each said once
/// on standard error.
pub(super) fn stamps_and_frame(args: &mut Args) -> bool {
    let Some(dir) = &args.tum else {
        return false;
    };
    if !sl_io::sequence::tum_stamps_are_frame_numbers(dir) {
        return false;
    }
    if sl_io::sequence::icl_nuim_tum_folder(dir) {
        errln!(
            "note: {} is one of ICL-NUIM's TUM-format folders: its frame numbers are taken as \
             frames 1/30 s apart, and the trajectory and mesh are written in its y-up frame, as \
             its *.gt.freiburg ground truth",
            dir.display()
        );
        args.data_y_up = true;
    } else {
        errln!(
            "note: {} stamps its frames with numbers (associations depth first): taken as frames \
             1/30 s apart",
            dir.display()
        );
    }
    true
}

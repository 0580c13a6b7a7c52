//! A sequence folder's depth frames with the poses of a trajectory file rather than its own:
//! an estimate (`sldepth track`'s output, another SLAM system's) to fuse the folder along.

use std::path::Path;

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::trajectory::{Frame, is_open3d_log, nearest_pose, read_trajectory_with_limits};

use super::{PosedFrames, SequenceLayout, icl_nuim_tum_folder, read_depth_frames};

/// The depth frames of the sequence folder `dir` (in `layout`, as [`super::read_depth_frames`]
/// reads them) with the poses of the trajectory file `trajectory` (camera to world), for
/// `sldepth fuse DIR --trajectory FILE`:
///
/// - a TUM-format trajectory (`timestamp tx ty tz qx qy qz qw`) by time: each frame takes the
///   pose nearest its timestamp within `max_dt_s`; a frame without a timestamp (7-Scenes, an
///   Open3D folder of numbered images) is stamped with its index, as `sldepth track` writes
///   such frames, and takes the pose of exactly that number;
/// - an Open3D `.log` by frame number: entry `i` for the folder's `i`-th frame.
///
/// A frame without a pose — one `sldepth track` lost or left to another fragment (comment
/// lines in its trajectory), or outside another system's trajectory — is left out and
/// counted. The trajectory of one of ICL-NUIM's TUM-format folders is in the data set's y-up
/// frame, as its ground truth is, and is read into sldepth's the same way
/// ([`sl_core::CameraToWorld::y_reflected`]).
///
/// # Errors
/// An unreadable folder or trajectory file, or a trajectory that gives none of the folder's
/// frames a pose (another recording's, or times in other units).
pub fn read_frames_along_trajectory(
    dir: impl AsRef<Path>,
    layout: SequenceLayout,
    trajectory: impl AsRef<Path>,
    max_dt_s: f64,
    limits: &Limits,
) -> Result<PosedFrames> {
    let (dir, trajectory) = (dir.as_ref(), trajectory.as_ref());
    let depth = read_depth_frames(dir, layout, limits)?;
    let poses = read_trajectory_with_limits(trajectory, limits)?;
    let by_number = is_open3d_log(trajectory);
    let y_up = layout == SequenceLayout::Tum && icl_nuim_tum_folder(dir);
    let mut frames = Vec::with_capacity(depth.len());
    for (i, f) in depth.iter().enumerate() {
        let (t, max_dt) = match f.timestamp {
            Some(t) if !by_number => (t, max_dt_s),
            _ => (i as f64, 0.0),
        };
        if let Some(p) = nearest_pose(&poses, t, max_dt) {
            frames.push(Frame {
                depth_path: f.depth_path.clone(),
                pose: if y_up { p.pose.y_reflected() } else { p.pose },
                timestamp: f.timestamp,
            });
        }
    }
    if frames.is_empty() && !depth.is_empty() {
        let how = match depth.first().and_then(|f| f.timestamp) {
            _ if by_number => "an Open3D .log numbers the folder's frames from 0".to_owned(),
            None => "the folder's frames have no timestamps: each is matched by its index \
                     (0, 1, ...), as `sldepth track` stamps them"
                .to_owned(),
            Some(t) => format!(
                "it is matched by time within {max_dt_s} s (the first frame's timestamp is {t})"
            ),
        };
        return Err(IoError::malformed(
            trajectory,
            format!(
                "the trajectory ({} poses) gives none of the {} depth frames of {} a pose: {how}",
                poses.len(),
                depth.len(),
                dir.display()
            ),
        ));
    }
    let without_pose = depth.len() - frames.len();
    Ok(PosedFrames {
        frames,
        without_pose,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pose line of a TUM trajectory at time `t`, translated by `(x, y, 0)`.
    fn line(t: &str, x: f64, y: f64) -> String {
        format!("{t} {x} {y} 0 0 0 0 1\n")
    }

    fn xy(f: &Frame) -> (f64, f64) {
        let m = f.pose.to_matrix();
        (m[(0, 3)], m[(1, 3)])
    }

    fn names(p: &PosedFrames) -> Vec<String> {
        p.frames
            .iter()
            .map(|f| {
                f.depth_path
                    .file_name()
                    .unwrap()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect()
    }

    /// A TUM folder by time within `max_dt_s`; a frame without a pose left out and counted;
    /// comment lines (frames `track` lost) give no pose.
    #[test]
    fn a_tum_folder_takes_the_poses_nearest_its_frames_times() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("depth.txt"),
            "# depth\n1.000 depth/a.png\n1.033 depth/b.png\n1.066 depth/c.png\n1.100 depth/d.png\n",
        )
        .unwrap();
        let traj = d.join("est.txt");
        let text = [
            "# sldepth track\n".to_owned(),
            line("1.000", 1.0, 0.0),
            line("1.040", 2.0, 0.0),
            "# 1.066 lost: no overlap\n".to_owned(),
            line("1.300", 4.0, 0.0),
        ]
        .concat();
        std::fs::write(&traj, text).unwrap();
        let limits = Limits::default();
        let p = read_frames_along_trajectory(d, SequenceLayout::Tum, &traj, 0.02, &limits).unwrap();
        assert_eq!(names(&p), ["a.png", "b.png"]);
        assert_eq!(p.without_pose, 2);
        assert_eq!(xy(&p.frames[1]), (2.0, 0.0));
        assert_eq!(p.frames[1].timestamp, Some(1.033));
        // Another recording's trajectory gives no frame a pose: an error that says how frames
        // are matched.
        std::fs::write(&traj, line("500.0", 1.0, 0.0)).unwrap();
        let e = read_frames_along_trajectory(d, SequenceLayout::Tum, &traj, 0.02, &limits)
            .unwrap_err()
            .to_string();
        assert!(e.contains("gives none of the 4 depth frames"), "{e}");
        assert!(e.contains("the first frame's timestamp is 1"), "{e}");
    }

    /// Frames without timestamps (7-Scenes) by their index, exactly, from a TUM file as
    /// `track` writes it, and by frame number from a `.log` (even in a timed folder).
    #[test]
    fn untimed_frames_by_index_and_logs_by_frame_number() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for i in 0..3 {
            std::fs::write(d.join(format!("frame-{i:06}.depth.png")), b"").unwrap();
        }
        let traj = d.join("t.txt");
        let text = [
            line("0", 0.5, 0.0),
            line("1.01", 1.5, 0.0),
            line("2", 2.5, 0.0),
        ]
        .concat();
        std::fs::write(&traj, text).unwrap();
        let limits = Limits::default();
        let p = read_frames_along_trajectory(d, SequenceLayout::SevenScenes, &traj, 0.02, &limits)
            .unwrap();
        assert_eq!(
            names(&p),
            ["frame-000000.depth.png", "frame-000002.depth.png"]
        );
        assert_eq!(xy(&p.frames[1]), (2.5, 0.0));
        let log = d.join("t.log");
        let entry = |i: usize, x: f64| format!("{i} {i} 3\n1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
        std::fs::write(&log, [entry(1, 7.0), entry(2, 8.0)].concat()).unwrap();
        let p = read_frames_along_trajectory(d, SequenceLayout::SevenScenes, &log, 0.02, &limits)
            .unwrap();
        assert_eq!(
            names(&p),
            ["frame-000001.depth.png", "frame-000002.depth.png"]
        );
        assert_eq!(p.without_pose, 1);
        assert_eq!(xy(&p.frames[0]), (7.0, 0.0));
        // A timed TUM folder with a .log: by frame number too.
        let tum = tempfile::tempdir().unwrap();
        std::fs::write(
            tum.path().join("depth.txt"),
            "100.0 depth/a.png\n100.1 depth/b.png\n100.2 depth/c.png\n",
        )
        .unwrap();
        let p = read_frames_along_trajectory(tum.path(), SequenceLayout::Tum, &log, 0.02, &limits)
            .unwrap();
        assert_eq!(names(&p), ["b.png", "c.png"]);
    }

    /// One of ICL-NUIM's TUM-format folders: the trajectory is in its y-up frame, as its ground
    /// truth and `track`'s output are, and is read into sldepth's (y mirrored).
    #[test]
    fn an_icl_nuim_folder_s_trajectory_is_read_out_of_its_y_up_frame() {
        let root = tempfile::tempdir().unwrap();
        let d = root.path().join("living_room_traj0_frei_png");
        std::fs::create_dir(&d).unwrap();
        std::fs::write(
            d.join("associations.txt"),
            "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n",
        )
        .unwrap();
        assert!(icl_nuim_tum_folder(&d));
        let traj = d.join("t.txt");
        std::fs::write(&traj, [line("0", 1.0, 2.0), line("1", 1.0, 3.0)].concat()).unwrap();
        let p =
            read_frames_along_trajectory(&d, SequenceLayout::Tum, &traj, 0.02, &Limits::default())
                .unwrap();
        assert_eq!(p.frames.len(), 2);
        assert_eq!(xy(&p.frames[1]), (1.0, -3.0));
    }
}

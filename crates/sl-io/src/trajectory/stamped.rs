//! A trajectory file of either kind read as timestamped poses: a TUM file by its timestamps, an
//! Open3D `.log` by its frame numbers.

use std::path::Path;

use super::{TimedPose, read_open3d_log_with_limits, read_tum_trajectory_with_limits};
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// Whether a file of another name holds an Open3D `.log`: its first line that is not blank or a
/// `#` comment is three whole numbers (an entry's `i j n`), where a TUM line has eight numbers
/// and its timestamp. The Redwood and Augmented ICL-NUIM data sets ship their trajectories so
/// (`livingroom1-traj.txt`). Only the first 4 KB are looked at; an unreadable file is not one
/// (the TUM reader then says why).
fn holds_a_log(path: &Path) -> bool {
    crate::text::first_data_fields(path)
        .is_some_and(|f| f.len() == 3 && f.iter().all(|t| crate::text::is_whole_number(t)))
}

/// Whether [`read_trajectory`] reads `path` as an Open3D `.log` (its extension, any case, or
/// its first data line `i j n` of three whole numbers), whose poses are stamped with frame
/// numbers, rather than as a TUM file of times.
pub fn is_open3d_log(path: impl AsRef<Path>) -> bool {
    let path = path.as_ref();
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("log"))
        || holds_a_log(path)
}

/// Reads a camera trajectory as timestamped camera-to-world poses: an Open3D `.log` (told by
/// its extension, any case, or by its content in a file of another name: the Redwood data
/// sets' `*-traj.txt`) with each entry `i i n` stamped with its frame number `i` — the
/// timestamp `sldepth track` gives the frames of a 7-Scenes or Open3D folder — else a TUM
/// file ([`read_tum_trajectory`](super::read_tum_trajectory)); sorted by timestamp either way.
/// A `.log` entry `i j n` with `j ≠ i` is a registration between two frames (a pose graph's
/// odometry), not a camera pose, and is an error that says so; so is a frame with two poses.
pub fn read_trajectory(path: impl AsRef<Path>) -> Result<Vec<TimedPose>> {
    read_trajectory_with_limits(path, &Limits::default())
}

/// [`read_trajectory`] within `limits`.
pub fn read_trajectory_with_limits(
    path: impl AsRef<Path>,
    limits: &Limits,
) -> Result<Vec<TimedPose>> {
    let path = path.as_ref();
    if !is_open3d_log(path) {
        return read_tum_trajectory_with_limits(path, limits);
    }
    let entries = read_open3d_log_with_limits(path, limits)?;
    if let Some(e) = entries.iter().find(|e| e.metadata[0] != e.metadata[1]) {
        let [i, j, n] = e.metadata;
        return Err(IoError::malformed(
            path,
            format!(
                "entry `{i} {j} {n}` relates two frames (a registration between frames, as a pose \
                 graph's odometry .log holds): a trajectory has one camera pose per frame, \
                 entries `i i n`"
            ),
        ));
    }
    let mut poses: Vec<TimedPose> = entries
        .into_iter()
        .map(|e| TimedPose {
            timestamp: e.metadata[0] as f64,
            pose: e.pose,
        })
        .collect();
    poses.sort_by(|a, b| a.timestamp.total_cmp(&b.timestamp));
    if let Some(w) = poses.windows(2).find(|w| w[0].timestamp == w[1].timestamp) {
        return Err(IoError::malformed(
            path,
            format!("frame {} has two poses", w[0].timestamp),
        ));
    }
    Ok(poses)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(i: u64, j: u64, x: f64) -> String {
        format!("{i} {j} 3\n1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    }

    /// A `.log` is stamped with its frame numbers and sorted by them; a TUM file is read as
    /// TUM; a pairwise entry or a frame given twice is refused by name.
    #[test]
    fn a_log_is_stamped_with_its_frame_numbers() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("traj.LOG");
        std::fs::write(
            &log,
            entry(2, 2, 0.5) + &entry(0, 0, 0.0) + &entry(1, 1, 0.25),
        )
        .unwrap();
        let poses = read_trajectory(&log).unwrap();
        let stamps: Vec<f64> = poses.iter().map(|p| p.timestamp).collect();
        assert_eq!(stamps, [0.0, 1.0, 2.0]);
        let x: Vec<f64> = poses
            .iter()
            .map(|p| p.pose.isometry().translation.vector.x)
            .collect();
        assert_eq!(x, [0.0, 0.25, 0.5]);

        let tum = dir.path().join("traj.txt");
        std::fs::write(&tum, "7.5 1 2 3 0 0 0 1\n").unwrap();
        assert_eq!(read_trajectory(&tum).unwrap()[0].timestamp, 7.5);
        // A .log's content in a .txt (Redwood's `livingroom1-traj.txt`) is read as a .log.
        let redwood = dir.path().join("livingroom1-traj.txt");
        std::fs::write(&redwood, entry(1, 1, 0.25) + &entry(0, 0, 0.0)).unwrap();
        let poses = read_trajectory(&redwood).unwrap();
        assert_eq!(poses.len(), 2);
        assert_eq!(poses[1].pose.isometry().translation.vector.x, 0.25);
        // A TUM file whose stamps are whole numbers is still TUM (eight fields).
        std::fs::write(&tum, "# t x y z qx qy qz qw\n3 1 2 3 0 0 0 1\n").unwrap();
        assert_eq!(read_trajectory(&tum).unwrap()[0].timestamp, 3.0);

        std::fs::write(&log, entry(0, 0, 0.0) + &entry(0, 1, 0.1)).unwrap();
        let e = read_trajectory(&log).unwrap_err().to_string();
        assert!(e.contains("`0 1 3` relates two frames"), "{e}");
        std::fs::write(&log, entry(1, 1, 0.0) + &entry(1, 1, 0.1)).unwrap();
        let e = read_trajectory(&log).unwrap_err().to_string();
        assert!(e.contains("frame 1 has two poses"), "{e}");
    }
}

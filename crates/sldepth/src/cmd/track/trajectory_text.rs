//! The trajectory files: one row per input frame (a pose in its fragment's world, or why there
//! is none), written per world frame as TUM text (`--output`) and an Open3D `.log`
//! (`--output-log`).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use sl_core::CameraToWorld;

use super::Args;
use super::fragments::{FragmentOut, fragment_path, world_of};

/// One output row: a pose or why there is none.
pub(super) enum Row {
    /// A pose in the world frame of the fragment.
    Pose(CameraToWorld, usize),
    Lost(String),
    Skipped(String),
}

/// One trajectory per world frame: fragment 0's, and each fragment's that rejoined none.
pub(super) fn write_trajectories(
    args: &Args,
    rows: &[(f64, Row)],
    fragments: &[FragmentOut],
) -> Result<()> {
    for (index, out) in fragments.iter().enumerate() {
        if out.joined.is_some() {
            continue;
        }
        if let Some(p) = &args.output {
            let text = tum_text(rows, index, fragments, args.data_y_up);
            write_text(&fragment_path(p, index), &text)?;
        }
        if let Some(p) = &args.output_log {
            let text = log_text(rows, index, fragments, args.data_y_up);
            write_text(&fragment_path(p, index), &text)?;
        }
    }
    Ok(())
}

/// The pose of a row of fragment `f` in the world of fragment `world`, if it belongs there;
/// reflected into the data set's frame when it renders with y up (`y_up`, ICL-NUIM).
fn pose_in(
    p: &CameraToWorld,
    f: usize,
    world: usize,
    fragments: &[FragmentOut],
    y_up: bool,
) -> Option<CameraToWorld> {
    match world_of(f, fragments) {
        (w, t) if w == world => {
            let p = t.map_or(*p, |t| t * *p);
            Some(if y_up { p.y_reflected() } else { p })
        }
        _ => None,
    }
}

/// The TUM trajectory in fragment `world`'s frame (reflected with `y_up`, see [`pose_in`]): its
/// poses and those of the fragments that rejoined it, the other frames as comments.
fn tum_text(rows: &[(f64, Row)], world: usize, fragments: &[FragmentOut], y_up: bool) -> String {
    let mut s = String::from("# sldepth track: timestamp tx ty tz qx qy qz qw (camera to world)\n");
    if y_up {
        s.push_str("# in the data set's y-up frame (ICL-NUIM), as its ground truth\n");
    }
    if world > 0 {
        let _ = writeln!(
            s,
            "# fragment {world}: its own world frame (its first camera); not registered to the other fragments"
        );
    }
    // Timestamps closer than a microsecond keep enough digits to stay distinct (the file is
    // read back by `eval-traj`, which refuses a repeated timestamp).
    let stamps: Vec<f64> = rows.iter().map(|(t, _)| *t).collect();
    let stamp = sl_io::trajectory::timestamp_printer(&stamps);
    for (t, row) in rows {
        let t = stamp(*t);
        match row {
            Row::Pose(p, f) => match pose_in(p, *f, world, fragments, y_up) {
                None => {
                    let _ = writeln!(s, "# {t} in fragment {f}");
                }
                Some(p) => {
                    let tr = p.translation();
                    let q = p.rotation();
                    let _ = writeln!(
                        s,
                        "{t} {:.6} {:.6} {:.6} {:.7} {:.7} {:.7} {:.7}",
                        tr.x, tr.y, tr.z, q.i, q.j, q.k, q.w
                    );
                }
            },
            Row::Lost(why) => {
                let _ = writeln!(s, "# {t} lost: {why}");
            }
            Row::Skipped(why) => {
                let _ = writeln!(s, "# {t} skipped: {why}");
            }
        }
    }
    s
}

/// The Open3D `.log` of the tracked frames in fragment `world`'s frame (reflected with `y_up`).
fn log_text(rows: &[(f64, Row)], world: usize, fragments: &[FragmentOut], y_up: bool) -> String {
    let n = rows.len();
    let mut s = String::new();
    for (i, (_, row)) in rows.iter().enumerate() {
        if let Row::Pose(p, f) = row
            && let Some(p) = pose_in(p, *f, world, fragments, y_up)
        {
            let m = p.to_matrix();
            let _ = writeln!(s, "{i} {i} {n}");
            for r in 0..4 {
                let _ = writeln!(
                    s,
                    "{:.9} {:.9} {:.9} {:.9}",
                    m[(r, 0)],
                    m[(r, 1)],
                    m[(r, 2)],
                    m[(r, 3)]
                );
            }
        }
    }
    s
}

/// Writes `text` to `path` through `sl_io::atomic::write_atomic`.
fn write_text(path: &Path, text: &str) -> Result<()> {
    sl_io::atomic::write_atomic(path, |w| w.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

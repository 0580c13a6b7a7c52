//! # sl-testkit — the real frames of `../shared/data`, for tests, benchmarks and xtask
//!
//! One place that knows where the shared real data lives and how each source is stored: the
//! directory is `$SLDEPTH_DATA` when set, else `../shared/data` beside the workspace; every
//! frame is read through `sl-io` (no hand-written decoders) and comes with the camera preset of
//! its dataset. A test calls [`data_dir_or_skip`] (or a loader, which returns nothing when the
//! data is absent) and returns early with one clear message instead of failing.
//!
//! Dev-only (`publish = false`): it prints skip messages, which library crates never do.
//!
//! ```
//! // Absent data is not an error: the loaders return nothing and say why once.
//! if let Some(person) = sl_testkit::person() {
//!     assert_eq!(person.depth.width(), 640);
//!     assert_eq!(person.camera, sl_core::Camera::preset("ros-default")?);
//! }
//! # Ok::<(), sl_core::CoreError>(())
//! ```

pub mod rosbag_writer;
pub mod sqlite_writer;

use std::path::{Path, PathBuf};

use sl_core::{Camera, DepthImage};
use sl_io::depth::{DepthFormat, ReadConfig};

/// Environment variable that overrides the data directory.
pub const DATA_ENV: &str = "SLDEPTH_DATA";

/// The shared data directory, or why there is none.
pub fn data_dir() -> Result<PathBuf, String> {
    if let Some(dir) = std::env::var_os(DATA_ENV) {
        let dir = PathBuf::from(dir);
        return if dir.is_dir() {
            Ok(dir)
        } else {
            Err(format!("{DATA_ENV}={} is not a directory", dir.display()))
        };
    }
    let dir = workspace_root().join("../shared/data");
    if dir.is_dir() {
        Ok(dir)
    } else {
        Err(format!(
            "../shared/data not found (looked in {}; set {DATA_ENV} to use another copy)",
            dir.display()
        ))
    }
}

/// The data directory, or `None` after printing `skipping <what>: <reason>` once.
pub fn data_dir_or_skip(what: &str) -> Option<PathBuf> {
    match data_dir() {
        Ok(d) => Some(d),
        Err(reason) => {
            eprintln!("skipping {what}: {reason}");
            None
        }
    }
}

/// The workspace root (two levels above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A real frame: where it is, its depth in metres and its dataset's camera.
#[derive(Debug, Clone, PartialEq)]
pub struct RealFrame {
    /// A short name: `source` or `source/index`.
    pub name: String,
    /// The file.
    pub path: PathBuf,
    /// Depth in metres, 0 = invalid.
    pub depth: DepthImage,
    /// The camera of the dataset (a preset of `sl_core::preset`).
    pub camera: Camera,
}

/// Reads a depth file with `units_per_m` (or its format's own conversion for NYU raw).
pub fn read_depth(path: &Path, units_per_m: Option<f64>) -> Result<DepthImage, sl_io::IoError> {
    let mut opts = ReadConfig::default();
    opts.scale_units_per_m = units_per_m;
    Ok(sl_io::read_depth(path, &opts)?.depth)
}

fn frame(name: String, path: PathBuf, units_per_m: Option<f64>, preset: &str) -> Option<RealFrame> {
    let depth = match read_depth(&path, units_per_m) {
        Ok(d) => d,
        Err(e) => {
            eprintln!("skipping {name}: {e}");
            return None;
        }
    };
    let camera = Camera::preset(preset).ok()?;
    Some(RealFrame {
        name,
        path,
        depth,
        camera,
    })
}

fn sorted_pngs(dir: &Path) -> Vec<PathBuf> {
    let mut files = sl_io::trajectory::list_depth_files(dir).unwrap_or_default();
    files.sort();
    files
}

fn indexed(source: &str, i: usize, count: usize) -> String {
    if count == 1 {
        source.to_string()
    } else {
        format!("{source}/{i:02}")
    }
}

/// `open3d-testdata/person-depth.png`: a person before a wall (millimetres, ROS default camera).
pub fn person() -> Option<RealFrame> {
    let dir = data_dir_or_skip("person-depth.png")?;
    frame(
        "person".into(),
        dir.join("open3d-testdata/person-depth.png"),
        Some(1000.0),
        "ros-default",
    )
}

/// `open3d-testdata/tum-depth.png`: Open3D's TUM desk frame (5000 units/m, ROS default camera).
pub fn open3d_tum() -> Option<RealFrame> {
    let dir = data_dir_or_skip("open3d tum-depth.png")?;
    frame(
        "open3d-tum".into(),
        dir.join("open3d-testdata/tum-depth.png"),
        Some(5000.0),
        "ros-default",
    )
}

/// `open3d-testdata/nyu-raw-disparity.pgm`: NYU Depth v2 raw Kinect disparity (NYU camera).
pub fn nyu_raw() -> Option<RealFrame> {
    let dir = data_dir_or_skip("nyu-raw-disparity.pgm")?;
    let path = dir.join("open3d-testdata/nyu-raw-disparity.pgm");
    let depth = match sl_io::read_depth(
        &path,
        &ReadConfig::default().with_format(DepthFormat::NyuRaw),
    ) {
        Ok(l) => l.depth,
        Err(e) => {
            eprintln!("skipping nyu-raw: {e}");
            return None;
        }
    };
    Some(RealFrame {
        name: "nyu-raw".into(),
        path,
        depth,
        camera: Camera::preset("nyu-v2").ok()?,
    })
}

/// The first `count` frames of the 30-frame TUM fr1/rpy set (5000 units/m, `tum-fr1` camera).
pub fn tum_rpy(count: usize) -> Vec<RealFrame> {
    tum_dir("tum-fr1-rpy", count)
}

/// The first `count` frames of the 200-frame TUM fr1/rpy sequence.
pub fn tum_rpy_200(count: usize) -> Vec<RealFrame> {
    tum_dir("tum-fr1-rpy-200", count)
}

fn tum_dir(source: &str, count: usize) -> Vec<RealFrame> {
    let Some(dir) = data_dir_or_skip(source) else {
        return Vec::new();
    };
    sorted_pngs(&dir.join(source).join("depth"))
        .into_iter()
        .take(count)
        .enumerate()
        .filter_map(|(i, p)| frame(indexed(source, i, count), p, Some(5000.0), "tum-fr1"))
        .collect()
}

/// The first `count` (≤ 50) 7-Scenes red-kitchen frames, from frame 150 (millimetres, 0 invalid).
pub fn seven_scenes(count: usize) -> Vec<RealFrame> {
    let Some(dir) = data_dir_or_skip("7-scenes") else {
        return Vec::new();
    };
    (0..count.min(50))
        .filter_map(|i| {
            let p = dir.join(format!("7scenes-redkitchen/frame-{:06}.depth.png", 150 + i));
            frame(indexed("7scenes", i, count), p, Some(1000.0), "7-scenes")
        })
        .collect()
}

/// The ICL-NUIM living-room frames (millimetres, `icl-nuim` camera).
pub fn icl(count: usize) -> Vec<RealFrame> {
    let Some(dir) = data_dir_or_skip("icl-livingroom") else {
        return Vec::new();
    };
    sorted_pngs(&dir.join("open3d-testdata/icl-livingroom/depth"))
        .into_iter()
        .take(count)
        .enumerate()
        .filter_map(|(i, p)| frame(indexed("icl", i, count), p, Some(1000.0), "icl-nuim"))
        .collect()
}

/// The PCL floor-and-box scan frames (16-bit TIFF millimetres, `pcl-openni` camera).
pub fn floor_scan(count: usize) -> Vec<RealFrame> {
    let Some(dir) = data_dir_or_skip("pcl-floor-box") else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir.join("pcl-floor-box"))
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.to_string_lossy().ends_with("_depth.tiff"))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
        .into_iter()
        .take(count)
        .enumerate()
        .filter_map(|(i, p)| {
            frame(
                indexed("pcl-floor-box", i, count),
                p,
                Some(1000.0),
                "pcl-openni",
            )
        })
        .collect()
}

/// Depth frames with their camera-to-world poses, for fusion and tracking.
#[derive(Debug, Clone, PartialEq)]
pub struct PosedSequence {
    /// `icl`, `7scenes` or `tum-fr1-rpy`.
    pub name: &'static str,
    /// The dataset's camera preset.
    pub camera: Camera,
    /// Depth (metres) and camera-to-world pose of each frame, in order.
    pub frames: Vec<(DepthImage, sl_core::CameraToWorld)>,
}

fn posed(
    name: &'static str,
    preset: &str,
    frames: Result<Vec<sl_io::Frame>, sl_io::IoError>,
    max_frames: usize,
) -> Option<PosedSequence> {
    let frames = match frames {
        Ok(f) => f,
        Err(e) => {
            eprintln!("skipping {name}: {e}");
            return None;
        }
    };
    let mut out = Vec::new();
    for f in frames.into_iter().take(max_frames) {
        match read_depth(&f.depth_path, None) {
            Ok(d) => out.push((d, f.pose)),
            Err(e) => {
                eprintln!("skipping {name}: {e}");
                return None;
            }
        }
    }
    Some(PosedSequence {
        name,
        camera: Camera::preset(preset).ok()?,
        frames: out,
    })
}

/// The ICL-NUIM living-room frames with their Open3D `.log` poses (at most `max_frames`).
pub fn icl_sequence(max_frames: usize) -> Option<PosedSequence> {
    let dir = data_dir_or_skip("icl-livingroom")?.join("open3d-testdata/icl-livingroom");
    let frames = sl_io::read_open3d_log_frames(dir.join("odometry.log"), dir.join("depth"));
    posed("icl", "icl-nuim", frames, max_frames)
}

/// The 7-Scenes red-kitchen frames with their poses (at most `max_frames`).
pub fn seven_scenes_sequence(max_frames: usize) -> Option<PosedSequence> {
    let dir = data_dir_or_skip("7-scenes")?.join("7scenes-redkitchen");
    posed(
        "7scenes",
        "7-scenes",
        sl_io::read_7scenes_sequence(&dir),
        max_frames,
    )
}

/// The 200 TUM fr1/rpy frames (`tum-fr1-rpy-200`: `depth.txt` + `groundtruth.txt`, depth
/// at 5000 units per metre) with their ground-truth poses associated within 0.02 s (at most
/// `max_frames`): the nearest pose, as the benchmark's tools associate them.
pub fn tum_rpy_200_sequence(max_frames: usize) -> Option<PosedSequence> {
    tum_rpy_200_posed(max_frames, None)
}

/// The clock offset of the `tum-fr1-rpy-200` depth frames against their motion capture,
/// seconds: the frames were taken about 20 ms before their stamps. Measured four ways that
/// share nothing but the frames (docs/bench/track.md, session 61): the offset that best
/// aligns the orientations of three trackers' trajectories with the ground truth (ours
/// −20 ms, Open3D's dense SLAM −28 ms, its frame-to-frame point-to-plane odometry −16 ms;
/// `sldepth eval-traj --estimate-offset`), and the one at which the frames fused at the
/// motion capture's own poses agree best with their frames (−20 ms).
pub const TUM_FR1_RPY_CLOCK_OFFSET_S: f64 = -0.020;

/// [`tum_rpy_200_sequence`] with each frame's pose interpolated at its stamp plus `offset_s`
/// ([`sl_io::trajectory::associate_interpolated`]; [`TUM_FR1_RPY_CLOCK_OFFSET_S`] undoes the
/// measured clock offset): for experiments that fuse the frames at these poses, where a
/// frame fused 20 ms away from where it was taken smears the surface.
pub fn tum_rpy_200_sequence_at_offset(max_frames: usize, offset_s: f64) -> Option<PosedSequence> {
    tum_rpy_200_posed(max_frames, Some(offset_s))
}

/// The `tum-fr1-rpy-200` folder and its `depth.txt` entries in order (`(stamp, file)` as
/// written, comment lines left out), for tests that build a sequence of their own from its frames
/// (every k-th, reordered, some turned); `None` after the skip message when the data is absent.
pub fn tum_rpy_200_depth_list(what: &str) -> Option<(PathBuf, Vec<(String, String)>)> {
    let dir = data_dir_or_skip(what)?.join("tum-fr1-rpy-200");
    let text = std::fs::read_to_string(dir.join("depth.txt")).ok()?;
    let entries = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .filter_map(|l| {
            let mut it = l.split_whitespace();
            Some((it.next()?.to_owned(), it.next()?.to_owned()))
        })
        .collect();
    Some((dir, entries))
}

fn tum_rpy_200_posed(max_frames: usize, offset_s: Option<f64>) -> Option<PosedSequence> {
    let dir = data_dir_or_skip("tum-fr1-rpy-200")?.join("tum-fr1-rpy-200");
    // `depth.txt` as TUM ships it (the folder has no `associations.txt`).
    let frames = match offset_s {
        None => sl_io::trajectory::read_tum_sequence(&dir, 0.02).map(|seq| seq.frames),
        Some(offset) => sl_io::trajectory::read_tum_sequence_at_offset(
            &dir,
            offset,
            0.02,
            &sl_io::Limits::default(),
        )
        .map(|seq| seq.frames),
    };
    let frames = match frames {
        Ok(frames) => frames,
        Err(e) => {
            eprintln!("skipping tum-fr1-rpy-200: {e}");
            return None;
        }
    };
    let mut out = Vec::new();
    for f in frames.into_iter().take(max_frames) {
        match read_depth(&f.depth_path, Some(5000.0)) {
            Ok(d) => out.push((d, f.pose)),
            Err(e) => {
                eprintln!("skipping tum-fr1-rpy-200: {e}");
                return None;
            }
        }
    }
    Some(PosedSequence {
        name: "tum-fr1-rpy",
        camera: Camera::preset("tum-fr1").ok()?,
        frames: out,
    })
}

/// Exact depth of the nearest of `planes` (camera coordinates) at every pixel, with labels
/// (1-based plane index); pixels beyond `max_z` are left invalid.
pub fn render_planes(
    k: &sl_core::Intrinsics,
    planes: &[sl_core::Plane],
    max_z: f64,
) -> (DepthImage, sl_core::Image<u16>) {
    let mut depth = vec![0f32; k.width * k.height];
    let mut labels = vec![0u16; k.width * k.height];
    for y in 0..k.height {
        for x in 0..k.width {
            let mut best = f64::INFINITY;
            for (i, p) in planes.iter().enumerate() {
                if let Some(z) = p.depth_at(k, x as f64, y as f64)
                    && z < best
                    && z <= max_z
                {
                    best = z;
                    labels[y * k.width + x] = i as u16 + 1;
                }
            }
            if best.is_finite() {
                depth[y * k.width + x] = best as f32;
            }
        }
    }
    (
        DepthImage::from_vec(k.width, k.height, depth)
            .unwrap_or_else(|_| DepthImage::invalid(k.width, k.height)),
        sl_core::Image::from_vec(k.width, k.height, labels)
            .unwrap_or_else(|_| sl_core::Image::filled(k.width, k.height, 0)),
    )
}

/// The `n × n` block means of `depth`'s disparity, as depth (a block with an invalid pixel is
/// invalid): the frame of a sensor that decimates by averaging, `width / n × height / n`, each
/// value at its block's centre as [`sl_core::Camera::resampled`]`(1/n)` places the pixels.
/// `n = 0` is taken as 1.
pub fn block_mean(depth: &DepthImage, n: usize) -> DepthImage {
    let n = n.max(1);
    let (w, h) = (depth.width() / n, depth.height() / n);
    let (src, sw) = (depth.data(), depth.width());
    let mut out = vec![0.0f32; w * h];
    for (y, row) in out.chunks_mut(w.max(1)).enumerate() {
        for (x, o) in row.iter_mut().enumerate() {
            let (mut s, mut ok) = (0.0f64, true);
            for dy in 0..n {
                for dx in 0..n {
                    let z = src[(n * y + dy) * sw + n * x + dx];
                    ok &= z > 0.0 && z.is_finite();
                    s += 1.0 / f64::from(z);
                }
            }
            *o = if ok { ((n * n) as f64 / s) as f32 } else { 0.0 };
        }
    }
    DepthImage::from_vec(w, h, out).unwrap_or_else(|_| DepthImage::invalid(w, h))
}

/// Every `n`-th pixel of every `n`-th row of `depth` (a driver's decimation, a QVGA mode of a
/// VGA sensor): `width / n × height / n`, the pixel at `(n·x, n·y)` for `(x, y)`. `n = 0` is
/// taken as 1.
pub fn decimate(depth: &DepthImage, n: usize) -> DepthImage {
    let n = n.max(1);
    let (w, h) = (depth.width() / n, depth.height() / n);
    let data = (0..w * h)
        .map(|j| depth.data()[(j / w) * n * depth.width() + (j % w) * n])
        .collect();
    DepthImage::from_vec(w, h, data).unwrap_or_else(|_| DepthImage::invalid(w, h))
}

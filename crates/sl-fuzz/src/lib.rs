//! Dev-only: the bodies of the cargo-fuzz targets of `fuzz/`, as plain functions over bytes.
//!
//! Each function takes arbitrary bytes and must return without panicking (errors are the
//! expected outcome for most inputs). [`TARGETS`] names them; `fuzz/fuzz_targets/*.rs` call
//! them from libFuzzer, and `tests/corpus.rs` replays the committed corpus on stable.
//!
//! Readers see the bytes as a file in a per-thread scratch directory (they take paths); every
//! call runs under [`fuzz_limits`] (64 MiB), so that an input can only be refused, never make
//! the fuzzer run out of memory. Algorithm targets decode the bytes into a tiny frame
//! ([`tiny_frame`]: at most 24×24 pixels; `track` enlarges them, [`enlarged`]) and parameters.
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use sl_core::{Camera, CameraToWorld, DepthImage, Intrinsics};
use sl_io::Limits;
use sl_io::depth::{DepthFormat, ReadConfig};

/// A fuzz target body.
pub type Target = fn(&[u8]);

/// Every target, by the name of its `fuzz/fuzz_targets/<name>.rs` and corpus directory.
pub const TARGETS: &[(&str, Target)] = &[
    ("depth_png", depth_png),
    ("depth_tiff", depth_tiff),
    ("depth_pgm", depth_pgm),
    ("depth_sun", depth_sun),
    ("camera_json", camera_json),
    ("rosbag", rosbag),
    ("intrinsics_txt", intrinsics_txt),
    ("tum_trajectory", tum_trajectory),
    ("tum_associations", tum_associations),
    ("open3d_log", open3d_log),
    ("frame_list", frame_list),
    ("tum_depth_list", tum_depth_list),
    ("ply", ply),
    ("filter", filter),
    ("planes", planes),
    ("motion", motion),
    ("tsdf", tsdf),
    ("multiscale", multiscale),
    ("track", track),
    ("noise_stats", noise_stats),
];

/// The limits every target runs under: a 64 MiB budget.
pub fn fuzz_limits() -> Limits {
    Limits::for_memory(64 << 20)
}

thread_local! {
    static SCRATCH: RefCell<Option<PathBuf>> = const { RefCell::new(None) };
}

/// A per-thread scratch directory (in `/dev/shm` where it exists, for speed).
fn scratch_dir() -> PathBuf {
    SCRATCH.with(|s| {
        s.borrow_mut()
            .get_or_insert_with(|| {
                let shm = Path::new("/dev/shm");
                let base = if shm.is_dir() {
                    shm.to_path_buf()
                } else {
                    std::env::temp_dir()
                };
                let dir = base.join(format!(
                    "sl-fuzz-{}-{:?}",
                    std::process::id(),
                    std::thread::current().id()
                ));
                let _ = std::fs::create_dir_all(&dir);
                dir
            })
            .clone()
    })
}

/// Writes `data` to the scratch file `name` and gives its path (`None` if the scratch space
/// cannot be written: nothing to test then).
fn with_file(name: &str, data: &[u8], f: impl FnOnce(&Path)) {
    let path = scratch_dir().join(name);
    if std::fs::write(&path, data).is_ok() {
        f(&path);
    }
}

fn read_depth_as(name: &str, data: &[u8], format: DepthFormat) {
    with_file(name, data, |p| {
        let opts = ReadConfig::default().with_format(format);
        let _ = sl_io::depth::read_depth_with_limits(p, &opts, &fuzz_limits());
        let _ = sl_io::depth::read_raw_depth_with_limits(p, &opts, &fuzz_limits());
    });
}

/// 16-bit PNG depth.
pub fn depth_png(data: &[u8]) {
    read_depth_as("d.png", data, DepthFormat::Png);
    with_file("c.png", data, |p| {
        let _ = sl_io::rgb::read_rgb_with_limits(p, &fuzz_limits());
    });
}

/// 16-bit TIFF depth.
pub fn depth_tiff(data: &[u8]) {
    read_depth_as("d.tif", data, DepthFormat::Tiff);
}

/// NYU raw disparity PGM (and PNM colour images).
pub fn depth_pgm(data: &[u8]) {
    read_depth_as("d.pgm", data, DepthFormat::NyuRaw);
    with_file("c.ppm", data, |p| {
        let _ = sl_io::rgb::read_rgb_with_limits(p, &fuzz_limits());
    });
}

/// SUN RGB-D bit-rotated PNG.
pub fn depth_sun(data: &[u8]) {
    read_depth_as("d.sun.png", data, DepthFormat::Sun);
}

/// Open3D camera JSON, and the same bytes as a ROS camera calibration YAML.
pub fn camera_json(data: &[u8]) {
    with_file("camera.json", data, |p| {
        let _ = sl_io::camera::read_camera_json_with_limits(p, &fuzz_limits());
    });
    // The same bytes as a ROS camera calibration / CameraInfo YAML.
    with_file("camera.yaml", data, |p| {
        let _ = sl_io::ros_camera::read_ros_camera(p, &fuzz_limits());
    });
}

/// A robot recording (a ROS 1 bag, MCAP or SQLite: the reader tells them by their first
/// bytes): its index, topics, transforms (looked up at a few times), depth topic, the first
/// frames of it and their frame, its camera and a RealSense recording's options and timestamps.
pub fn rosbag(data: &[u8]) {
    with_file("rec.bag", data, |p| {
        let Ok(mut bag) = sl_io::rosbag::RosBag::open(p, &fuzz_limits()) else {
            return;
        };
        let _ = bag.topics();
        for ns in bag
            .tf_namespaces()
            .into_iter()
            .filter(|n| !n.is_empty())
            .take(4)
        {
            let _ = bag.transforms_in(&ns);
        }
        if let Ok(tree) = bag.transforms() {
            let frames = tree.frames();
            for (f, t) in frames.iter().zip(&frames).take(8) {
                for time in [f.first_s, t.last_s, 0.5 * (f.first_s + t.last_s)] {
                    let _ = tree.lookup(&f.parent, &t.frame, time, 0.02);
                }
            }
        }
        let Ok(topic) = bag.depth_topic(None) else {
            return;
        };
        if let Ok(messages) = bag.messages(&topic) {
            for m in messages.iter().take(16) {
                let _ = bag.read_depth(m, 1000.0, 1.0);
                let _ = bag.image_frame_id(m);
            }
        }
        if let Some(info) = bag.camera_info_topic(&topic) {
            let _ = bag.camera(&info);
        }
        let _ = bag.depth_camera(&topic);
        let _ = bag.depth_units_per_m(&topic);
        if let Ok(messages) = bag.messages(&topic) {
            let _ = bag.realsense_frame_times(&topic, &messages);
        }
    });
}

/// 3×3 intrinsics text (7-Scenes) and 4×4 pose text.
pub fn intrinsics_txt(data: &[u8]) {
    with_file("camera-intrinsics.txt", data, |p| {
        let _ = sl_io::camera::read_7scenes_intrinsics(p);
        let _ = sl_io::trajectory::read_pose_txt(p);
    });
}

/// TUM `groundtruth.txt`.
pub fn tum_trajectory(data: &[u8]) {
    with_file("groundtruth.txt", data, |p| {
        let _ = sl_io::trajectory::read_tum_trajectory_with_limits(p, &fuzz_limits());
    });
}

/// TUM `associations.txt`.
pub fn tum_associations(data: &[u8]) {
    with_file("associations.txt", data, |p| {
        let _ = sl_io::trajectory::read_tum_associations_with_limits(p, &fuzz_limits());
    });
}

/// Open3D `.log` trajectory.
pub fn open3d_log(data: &[u8]) {
    with_file("trajectory.log", data, |p| {
        let _ = sl_io::trajectory::read_open3d_log_with_limits(p, &fuzz_limits());
    });
}

/// A TUM sequence folder's `depth.txt` (`sldepth track --tum`), read from a folder of its own
/// (so that no `associations.txt` of another target is preferred).
pub fn tum_depth_list(data: &[u8]) {
    let dir = scratch_dir().join("tum-sequence");
    if std::fs::create_dir_all(&dir).is_ok() && std::fs::write(dir.join("depth.txt"), data).is_ok()
    {
        let _ = sl_io::sequence::read_tum_depth_frames(&dir, &fuzz_limits());
    }
}

/// `sldepth fuse --frames` list.
pub fn frame_list(data: &[u8]) {
    with_file("frames.txt", data, |p| {
        let _ = sl_io::trajectory::read_frame_list(p, &fuzz_limits());
    });
}

/// PLY cloud or mesh.
pub fn ply(data: &[u8]) {
    with_file("m.ply", data, |p| {
        let _ = sl_io::ply::read_ply_with_limits(p, &fuzz_limits());
    });
}

/// Reads bytes as a little cursor (zeros past the end).
#[derive(Debug)]
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
}

/// A tiny frame from bytes: width and height 1..=24, then per pixel a 16-bit value in
/// millimetres, or (when the first byte is odd) raw `f32` metres, so NaN, infinities and
/// negative depths occur too. Returns the depth and a camera of its size.
pub fn tiny_frame(data: &[u8]) -> (DepthImage, Camera) {
    let mut b = Bytes(data);
    let mode = b.u8();
    let w = usize::from(b.u8() % 24) + 1;
    let h = usize::from(b.u8() % 24) + 1;
    let f = 0.5 + f64::from(b.u8()) * 2.0;
    let raw_f32 = mode & 1 == 1;
    let values: Vec<f32> = (0..w * h)
        .map(|_| {
            if raw_f32 {
                b.f32()
            } else {
                f32::from(b.u16()) / 1000.0
            }
        })
        .collect();
    let depth = DepthImage::from_vec(w, h, values).unwrap_or_else(|_| DepthImage::invalid(w, h));
    let camera = Intrinsics::new(w, h, f, f, (w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0)
        .and_then(|k| Camera::from_intrinsics(k, None, None))
        .unwrap_or_else(|_| Camera::kinect_v1());
    (depth, camera)
}

/// Every filter method with parameters from the first bytes, on a tiny frame.
pub fn filter(data: &[u8]) {
    let (head, rest) = data.split_at(data.len().min(6));
    let mut b = Bytes(head);
    let method = sl_filter::Method::ALL[usize::from(b.u8()) % sl_filter::Method::ALL.len()];
    let mut cfg = sl_filter::FilterConfig::new(method);
    cfg.radius_px = Some(usize::from(b.u8() % 6));
    let s = b.u8();
    cfg.sigma_s_px = (s != 0).then(|| f64::from(s) / 16.0);
    let k = b.u8();
    cfg.k_per_m = (k != 0).then(|| f64::from(k) / 1000.0);
    let (depth, camera) = tiny_frame(rest);
    if let Ok(filter) = cfg.build(&camera.sensor) {
        let _ = filter.apply(&depth);
    }
}

/// Plane extraction (disparity method, with and without the seam stage, and the metric RANSAC
/// baseline) on a tiny frame.
pub fn planes(data: &[u8]) {
    let (depth, camera) = tiny_frame(data);
    let mut cfg = sl_planes::PlaneConfig::default();
    cfg.min_pixels = 3;
    if let Ok(mut ex) = sl_planes::PlaneExtractor::new(cfg) {
        let _ = ex.extract_depth(&depth, &camera);
    }
    // The optional seam and taken-in stages (off by default) on the same frame.
    cfg.refine_seams = true;
    cfg.give_back_taken_in = true;
    if let Ok(mut ex) = sl_planes::PlaneExtractor::new(cfg) {
        let _ = ex.extract_depth(&depth, &camera);
    }
    // Fewer hypotheses than the default 500 per plane: the code paths are the same, and a
    // fuzzer needs many executions per second.
    let mut rcfg = sl_planes::RansacConfig::default();
    rcfg.min_pixels = 3;
    rcfg.iterations = 16;
    rcfg.max_planes = 4;
    rcfg.score_samples = 256;
    let _ = sl_planes::metric_ransac(&depth, &camera, &rcfg);
}

/// Motion between two tiny frames (the second half of the bytes is frame B, same size).
pub fn motion(data: &[u8]) {
    let (a_bytes, b_bytes) = data.split_at(data.len() / 2);
    let (a, camera) = tiny_frame(a_bytes);
    let (b_raw, _) = tiny_frame(b_bytes);
    let b = DepthImage::from_vec(
        a.width(),
        a.height(),
        (0..a.width() * a.height())
            .map(|i| b_raw.data().get(i).copied().unwrap_or(0.0))
            .collect(),
    )
    .unwrap_or_else(|_| a.clone());
    let mut cfg = sl_track::DepthMotionConfig::default();
    cfg.planes.min_pixels = 3;
    cfg.icp = data.first().is_some_and(|&m| m & 2 == 2);
    let _ = sl_track::motion_between_depths(&a, &b, &camera, &cfg);
}

/// TSDF integration (voxel, band and pose from the first bytes) and mesh extraction, within a
/// 1 MiB budget (small, so that the budget checks are hit often and an execution stays short).
pub fn tsdf(data: &[u8]) {
    let (head, rest) = data.split_at(data.len().min(16));
    let mut b = Bytes(head);
    let voxel = 0.001 + f64::from(b.u8()) * 0.002;
    let trunc = voxel * (1.0 + f64::from(b.u8() % 8));
    let t = [b.f32(), b.f32(), b.f32()].map(|v| {
        if v.is_finite() {
            f64::from(v) % 10.0
        } else {
            0.0
        }
    });
    let angle = f64::from(b.u8()) / 40.0;
    let pose = CameraToWorld::from_isometry(sl_core::nalgebra::Isometry3::from_parts(
        sl_core::nalgebra::Translation3::new(t[0], t[1], t[2]),
        sl_core::nalgebra::UnitQuaternion::from_euler_angles(angle, -angle / 2.0, angle / 3.0),
    ));
    let budget = 1 << 20;
    let mut params = sl_tsdf::TsdfConfig::default();
    params.voxel_m = voxel;
    params.trunc_m = trunc;
    params.memory_budget_bytes = budget;
    let (depth, camera) = tiny_frame(rest);
    let Ok(mut vol) = sl_tsdf::TsdfVolume::new(params) else {
        return;
    };
    let _ = vol.integrate(&depth, &camera.intrinsics, &pose);
    let _ = vol.integrate(&depth, &camera.intrinsics, &CameraToWorld::identity());
    let _ = vol.extract_mesh_within(&sl_tsdf::MeshConfig::default(), budget);
    // The model seen from both poses (what the tracker renders).
    let rc = sl_tsdf::RaycastConfig::default();
    let _ = vol.raycast(&CameraToWorld::identity(), &camera.intrinsics, &rc);
    let _ = vol.raycast(&pose, &camera.intrinsics, &rc);
}

/// The multi-scale filter (the default of `sldepth filter`) with dilations from the first
/// bytes (1–3 passes of 1..=8 px, or none), on a tiny frame.
pub fn multiscale(data: &[u8]) {
    let (head, rest) = data.split_at(data.len().min(4));
    let mut b = Bytes(head);
    let (depth, camera) = tiny_frame(rest);
    let mut ms = sl_filter::MultiScale::default_for(&camera.sensor);
    let n = usize::from(b.u8() % 4);
    ms.dilations = (0..n).map(|_| usize::from(b.u8() % 8) + 1).collect();
    let _ = ms.apply(&depth);
}

/// `depth` enlarged `s` times along each axis, interpolated bilinearly in disparity (`1/Z`,
/// so that a plane stays a plane), a pixel invalid where any of its four neighbours is (the
/// camera of that size: [`enlarged_camera`]).
pub fn enlarged(depth: &DepthImage, s: usize) -> DepthImage {
    let (w, h) = (depth.width(), depth.height());
    let (ws, hs) = (w * s, h * s);
    let z = depth.data();
    let inv = |x: usize, y: usize| {
        let v = z[y * w + x];
        (v > 0.0 && v.is_finite()).then(|| 1.0 / f64::from(v))
    };
    let mut out = Vec::with_capacity(ws * hs);
    for ys in 0..hs {
        // The source coordinate of this pixel's centre, clamped to the grid.
        let fy = ((ys as f64 + 0.5) / s as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (y0, ty) = (fy.floor() as usize, fy.fract());
        let y1 = (y0 + 1).min(h - 1);
        for xs in 0..ws {
            let fx = ((xs as f64 + 0.5) / s as f64 - 0.5).clamp(0.0, (w - 1) as f64);
            let (x0, tx) = (fx.floor() as usize, fx.fract());
            let x1 = (x0 + 1).min(w - 1);
            let v = match (inv(x0, y0), inv(x1, y0), inv(x0, y1), inv(x1, y1)) {
                (Some(a), Some(b), Some(c), Some(d)) => {
                    let top = a + (b - a) * tx;
                    let bottom = c + (d - c) * tx;
                    (1.0 / (top + (bottom - top) * ty)) as f32
                }
                _ => 0.0,
            };
            out.push(v);
        }
    }
    DepthImage::from_vec(ws, hs, out).unwrap_or_else(|_| depth.clone())
}

/// The camera of `w`×`h` frames [`enlarged`] `s` times (the same one when its intrinsics
/// cannot be).
pub fn enlarged_camera(camera: &Camera, w: usize, h: usize, s: usize) -> Camera {
    let k = &camera.intrinsics;
    let at = |c: f64| (c + 0.5) * s as f64 - 0.5;
    Intrinsics::new(
        w * s,
        h * s,
        k.fx * s as f64,
        k.fy * s as f64,
        at(k.cx),
        at(k.cy),
    )
    .and_then(|k| Camera::from_intrinsics(k, None, None))
    .unwrap_or(*camera)
}

/// Tracking and fusion of a short sequence (`sl_track::Reconstruction`): the bytes after the
/// head are cut into up to four tiny frames of the first frame's size, enlarged 1–8 times
/// ([`enlarged`]: a 24×24 frame becomes up to 192×192, enough for the tracker's checks to
/// find planes), with timestamps, the tracking mode and the rolling-shutter readout from the
/// head (timestamps may go backwards or be NaN), within a 1 MiB volume budget.
pub fn track(data: &[u8]) {
    let _ = track_steps(data);
}

/// The body of [`track`], returning the status of every step (`None` for a step that failed
/// with an error), so that tests can check that the seeds reach the tracker.
pub fn track_steps(data: &[u8]) -> Vec<Option<sl_track::TrackStatus>> {
    let (head, rest) = data.split_at(data.len().min(8));
    let mut b = Bytes(head);
    let mode = b.u8();
    let scale = usize::from(b.u8() % 8) + 1;
    let (first, camera) = tiny_frame(rest);
    let (w, h) = (first.width(), first.height());
    // The later frames: the bytes after the first frame's, `w·h` 16-bit millimetres each.
    let used = 4 + 2 * w * h;
    let mut frames = vec![first];
    for chunk in rest.get(used..).unwrap_or(&[]).chunks(2 * w * h).take(3) {
        let mut fb = Bytes(chunk);
        let values = (0..w * h).map(|_| f32::from(fb.u16()) / 1000.0).collect();
        if let Ok(d) = DepthImage::from_vec(w, h, values) {
            frames.push(d);
        }
    }
    let big_camera = enlarged_camera(&camera, w, h, scale);
    let frames: Vec<DepthImage> = frames.iter().map(|f| enlarged(f, scale)).collect();
    let mut cfg = sl_track::ReconstructionConfig::default_for(big_camera.sensor);
    cfg.frame_to_model = mode & 1 == 0;
    cfg.tsdf.memory_budget_bytes = 1 << 20;
    cfg.tracker.rolling_shutter_readout_s = if mode & 2 == 2 { 0.03 } else { 0.0 };
    let Ok(mut rec) = sl_track::Reconstruction::new(big_camera, cfg) else {
        return Vec::new();
    };
    frames
        .iter()
        .enumerate()
        .map(|(i, frame)| {
            let t = match b.u8() {
                0 => None,
                255 => Some(f64::NAN),
                v => Some(f64::from(v) / 30.0 + i as f64 * 0.01),
            };
            rec.step(frame, t).ok().map(|s| s.result.status)
        })
        .collect()
}

/// The real-noise statistics (`sldepth noise-stats`) of a tiny frame, on regions from the
/// plane extractor or (when the first byte is odd) labels from the bytes.
pub fn noise_stats(data: &[u8]) {
    let (head, rest) = data.split_at(data.len().min(4));
    let mut b = Bytes(head);
    let mode = b.u8();
    let (depth, camera) = tiny_frame(rest);
    let (w, h) = (depth.width(), depth.height());
    let labels = if mode & 1 == 1 {
        let ls: Vec<u16> = (0..w * h)
            .map(|i| u16::from(rest.get(i).copied().unwrap_or(0) % 4))
            .collect();
        sl_core::Image::from_vec(w, h, ls).ok()
    } else {
        let mut cfg = sl_planes::PlaneConfig::default();
        cfg.min_pixels = 3;
        sl_planes::extract_planes(&depth, &camera, &cfg)
            .ok()
            .map(|s| s.labels)
    };
    let Some(labels) = labels else {
        return;
    };
    let mut opts = sl_noise::stats::NoiseStatsConfig::default();
    opts.tile_px = usize::from(b.u8() % 16);
    opts.min_tile_pixels = usize::from(b.u8() % 32);
    let fb = camera.sensor.fb() * f64::from(b.u8().max(1)) / 64.0;
    let _ = sl_noise::stats::noise_stats(&depth, fb, &labels, &opts);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_and_small_inputs_do_not_panic() {
        for (_, t) in TARGETS {
            t(&[]);
            t(&[0xff; 7]);
            t(&[1; 64]);
        }
    }

    #[test]
    fn tiny_frame_has_the_declared_size() {
        let (d, c) = tiny_frame(&[0, 3, 1, 100, 0xe8, 0x03]);
        assert_eq!((d.width(), d.height()), (4, 2));
        assert_eq!(c.intrinsics.width, 4);
        assert_eq!(d.data()[0], 1.0);
    }
}

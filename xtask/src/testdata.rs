//! `cargo xtask gen-testdata`: the seeded synthetic frames committed under `testdata/`.
//!
//! Each frame is a named scene of `sl_noise::sim` rendered through the `kinect-v1` simulator with
//! a fixed seed, stored as three 16-bit PNGs: the noisy depth (millimetres, like a Kinect),
//! the noise-free depth (1/5000 m units, for sub-millimetre ground truth) and the surface labels.
//! `--check` regenerates every frame in memory and compares decoded pixel values with the
//! committed files (PNG compression may differ between encoder versions; the values may not).
//! The same check is a unit test of this crate, so `cargo test --workspace` runs it (CI has no
//! separate step for it: `cargo xtask` builds the dependencies again with the features of xtask
//! alone, minutes on a 2-core machine).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use sl_core::{DepthImage, Image};
use sl_io::depth::{DepthEncoding, ReadConfig};
use sl_noise::sim::{KinectSimulator, named_scene};

/// The committed frames: (scene, seed).
pub const FRAMES: &[(&str, u64)] = &[("floor", 1), ("figure-walls", 2), ("three-planes", 3)];

/// Units per metre of the noise-free depth files.
pub const TRUTH_UNITS_PER_M: f64 = 5000.0;

/// The three files of one frame.
pub fn frame_paths(dir: &Path, scene: &str, seed: u64) -> [PathBuf; 3] {
    let stem = format!("{scene}-seed{seed}");
    [
        dir.join(format!("{stem}-depth.png")),
        dir.join(format!("{stem}-truth.png")),
        dir.join(format!("{stem}-labels.png")),
    ]
}

struct Generated {
    depth: DepthImage,
    truth: DepthImage,
    labels: Image<u16>,
}

fn generate(scene: &str, seed: u64) -> Result<Generated> {
    let named = named_scene(scene)?;
    let sim = KinectSimulator::kinect_v1().white();
    let f = sim.simulate(&named.scene, &named.intrinsics, &named.pose, seed);
    Ok(Generated {
        depth: f.depth,
        truth: f.truth,
        labels: f.labels,
    })
}

/// Quantises depth the way writing it with `units_per_m` does, for comparison after reading.
fn quantised(d: &DepthImage, units_per_m: f64) -> Vec<u32> {
    d.data()
        .iter()
        .map(|&z| {
            if z > 0.0 {
                (f64::from(z) * units_per_m).round() as u32
            } else {
                0
            }
        })
        .collect()
}

/// Writes (or with `check`, verifies) every frame of [`FRAMES`] in `dir`.
pub fn run(dir: &Path, check: bool) -> Result<()> {
    if !check {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let mut mismatches = Vec::new();
    for &(scene, seed) in FRAMES {
        let g = generate(scene, seed)?;
        let [depth_p, truth_p, labels_p] = frame_paths(dir, scene, seed);
        let depth_enc = DepthEncoding::png(1000.0);
        let truth_enc = DepthEncoding::png(TRUTH_UNITS_PER_M);
        if check {
            for (path, img, enc) in [
                (&depth_p, &g.depth, depth_enc),
                (&truth_p, &g.truth, truth_enc),
            ] {
                let read = sl_io::depth::read_depth(
                    path,
                    &ReadConfig::default().with_scale(enc.units_per_m),
                )
                .with_context(|| format!("reading {}", path.display()))?;
                if quantised(&read.depth, enc.units_per_m) != quantised(img, enc.units_per_m) {
                    mismatches.push(path.display().to_string());
                }
            }
            let labels = sl_io::rgb::read_gray16(&labels_p)
                .with_context(|| format!("reading {}", labels_p.display()))?;
            if labels != g.labels {
                mismatches.push(labels_p.display().to_string());
            }
        } else {
            sl_io::depth::write_depth(&depth_p, &g.depth, &depth_enc)?;
            sl_io::depth::write_depth(&truth_p, &g.truth, &truth_enc)?;
            sl_io::rgb::write_gray16_png(&labels_p, &g.labels)?;
            eprintln!(
                "wrote {}, {}, {}",
                depth_p.display(),
                truth_p.display(),
                labels_p.display()
            );
        }
    }
    if !mismatches.is_empty() {
        bail!(
            "testdata differs from what the simulator generates now (run `cargo xtask gen-testdata` \
             if the change is intended): {}",
            mismatches.join(", ")
        );
    }
    if check {
        eprintln!("testdata/ matches the simulator ({} frames)", FRAMES.len());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn committed_testdata_equals_what_the_simulator_generates_now() {
        let dir = crate::workspace_root().join("testdata");
        if let Err(e) = run(&dir, true) {
            panic!("{e:#}");
        }
    }
}

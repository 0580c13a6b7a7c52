//! Times [`TsdfVolume::raycast_into`] on a real sequence: fuses the first frames with their
//! reference poses (the default `TsdfConfig`: 4 mm voxels, the sensor-adaptive band), then
//! renders 640×480 from the last frame's pose `reps` times and prints the median milliseconds.
//! Also the driver for instruction counts:
//!
//! `valgrind --tool=callgrind --toggle-collect='*raycast_into*' target/release/examples/raycast_timing icl 5 1`
//!
//! `cargo run --release -p sl-tsdf --example raycast_timing -- icl|tum|7scenes [frames] [reps]
//! [--dump FILE] [--compare FILE]`
//!
//! `--hint` starts the rays at the last frame's depth (`TsdfVolume::raycast_hinted_into`).
//!
//! `--dump` writes the maps (depth, points, normals, weights as little-endian f32) to `FILE`;
//! `--compare` reads such a file and prints how far this build's maps are from it (hits gained
//! and lost, depth and normal differences), to check a change of implementation.

use std::time::Instant;

use sl_tsdf::{Raycast, RaycastConfig, TsdfConfig, TsdfVolume};

fn maps(out: &Raycast) -> Vec<f32> {
    let mut v = Vec::with_capacity(out.weights.len() * 8);
    for i in 0..out.weights.len() {
        v.push(out.depth.data()[i]);
        v.extend_from_slice(out.points[i].coords.as_slice());
        v.extend_from_slice(out.normals[i].as_slice());
        v.push(out.weights[i]);
    }
    v
}

fn compare(a: &[f32], b: &[f32]) -> String {
    let (mut gained, mut lost, mut both) = (0usize, 0usize, 0usize);
    let (mut dz_max, mut dz_sum, mut far) = (0.0f64, 0.0f64, 0usize);
    let (mut dn_max, mut dn_sum) = (0.0f64, 0.0f64);
    for (p, q) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        match (p[0] > 0.0, q[0] > 0.0) {
            (true, false) => lost += 1,
            (false, true) => gained += 1,
            (true, true) => {
                both += 1;
                let dz = f64::from((p[0] - q[0]).abs());
                dz_max = dz_max.max(dz);
                dz_sum += dz;
                if dz > 0.004 {
                    far += 1;
                }
                let dot = f64::from(p[4] * q[4] + p[5] * q[5] + p[6] * q[6]).clamp(-1.0, 1.0);
                let ang = dot.acos().to_degrees();
                dn_max = dn_max.max(ang);
                dn_sum += ang;
            }
            (false, false) => {}
        }
    }
    let n = both.max(1) as f64;
    format!(
        "\"hits_both\": {both}, \"hits_lost\": {lost}, \"hits_gained\": {gained}, \
         \"depth_diff_mean_mm\": {:.5}, \"depth_diff_max_mm\": {:.3}, \"depth_diff_over_1_voxel\": {far}, \
         \"normal_diff_mean_deg\": {:.4}, \"normal_diff_max_deg\": {:.2}",
        dz_sum / n * 1e3,
        dz_max * 1e3,
        dn_sum / n,
        dn_max
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let pos: Vec<&String> = args
        .iter()
        .skip(1)
        .scan(false, |skip, a| {
            let keep = !*skip && !a.starts_with("--");
            *skip = a.starts_with("--");
            Some(keep.then_some(a))
        })
        .flatten()
        .collect();
    let which = pos.first().map_or("icl", |s| s.as_str());
    let max_frames: usize = pos.get(1).and_then(|s| s.parse().ok()).unwrap_or(20);
    let reps: usize = pos.get(2).and_then(|s| s.parse().ok()).unwrap_or(9);
    let seq = match which {
        "icl" => sl_testkit::icl_sequence(max_frames),
        "tum" => sl_testkit::tum_rpy_200_sequence(max_frames),
        _ => sl_testkit::seven_scenes_sequence(max_frames),
    };
    let Some(seq) = seq else {
        return Ok(());
    };
    let (frames, k) = (seq.frames, seq.camera.intrinsics);
    let mut vol = TsdfVolume::new(TsdfConfig::default())?;
    for (d, p) in &frames {
        vol.integrate(d, &k, p)?;
    }
    let (last_depth, pose) = frames.last().ok_or("no frames")?;
    let pose = *pose;
    let hint = std::env::args()
        .any(|a| a == "--hint")
        .then_some(last_depth);
    let config = RaycastConfig::default();
    let mut out = Raycast::default();
    let mut ms = Vec::new();
    for _ in 0..reps.max(1) {
        let t = Instant::now();
        vol.raycast_hinted_into(&pose, &k, &config, hint, &mut out)?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let mut sorted = ms.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let now = maps(&out);
    if let Some(p) = flag("--dump") {
        let bytes: Vec<u8> = now.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(p, bytes)?;
    }
    let cmp = match flag("--compare") {
        Some(p) => {
            let bytes = std::fs::read(p)?;
            let old: Vec<f32> = bytes
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            format!(", {}", compare(&old, &now))
        }
        None => String::new(),
    };
    println!(
        "{{\"sequence\": \"{which}\", \"frames\": {}, \"blocks\": {}, \"hits\": {}, \
         \"raycast_ms_median\": {median:.2}, \"raycast_ms\": {ms:.1?}{cmp}}}",
        frames.len(),
        vol.block_count(),
        out.hit_count()
    );
    Ok(())
}

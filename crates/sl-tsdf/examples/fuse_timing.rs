//! Times integration and marching cubes on a real sequence, the way `sldepth fuse --json` does
//! (per-frame integration without file I/O, then one extraction), for the Open3D comparison in
//! `docs/bench/open3d_tsdf.py`.
//!
//! `cargo run --release -p sl-tsdf --example fuse_timing -- icl|7scenes [weight] [frames]`
//!
//! The JSON also carries `mesh_checksum`, an order-sensitive hash of the mesh's bits, to check
//! that a change of implementation leaves the output unchanged.

use std::path::Path;
use std::time::Instant;

use sl_io::{ReadOptions, read_depth};
use sl_tsdf::{ExtractOptions, TsdfParams, TsdfVolume, WeightMode};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map(String::as_str).unwrap_or("icl");
    let weight = WeightMode::parse(args.get(2).map(String::as_str).unwrap_or("inv-z4"))?;
    let max_frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(50);
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !data.is_dir() {
        println!("skipping: ../shared/data not found");
        return Ok(());
    }
    let (frames, k) = if which == "icl" {
        let dir = data.join("open3d-testdata/icl-livingroom");
        let f =
            sl_io::trajectory::read_open3d_log_frames(dir.join("odometry.log"), dir.join("depth"))?;
        (
            f,
            sl_io::camera::read_camera_json(dir.join("camera.json"))?.intrinsics,
        )
    } else {
        let dir = data.join("7scenes-redkitchen");
        let f = sl_io::trajectory::read_7scenes_sequence(&dir)?;
        (
            f,
            sl_io::camera::read_7scenes_intrinsics(dir.join("camera-intrinsics.txt"))?,
        )
    };
    let frames: Vec<_> = frames
        .into_iter()
        .take(max_frames)
        .map(|f| {
            Ok((
                read_depth(&f.depth_path, &ReadOptions::default())?.depth,
                f.pose,
            ))
        })
        .collect::<Result<_, sl_io::IoError>>()?;
    let params = TsdfParams {
        voxel_m: 0.004,
        trunc_m: 0.02,
        max_depth_m: 4.0,
        weight,
        ..TsdfParams::default()
    };
    let mut vol = TsdfVolume::new(params)?;
    let mut ms = Vec::new();
    for (d, p) in &frames {
        let t0 = Instant::now();
        vol.integrate(d, &k, p)?;
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let t0 = Instant::now();
    let mesh = vol.extract_mesh(&ExtractOptions::default());
    let extract_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Order-sensitive FNV-1a checksum of the mesh (to compare implementations).
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |v: u32| {
        h ^= u64::from(v);
        h = h.wrapping_mul(0x0100_0000_01b3);
    };
    for p in mesh.positions.iter().chain(&mesh.normals) {
        p.iter().for_each(|c| eat(c.to_bits()));
    }
    mesh.confidence.iter().for_each(|c| eat(c.to_bits()));
    mesh.triangles.iter().flatten().for_each(|&i| eat(i));
    let mut sorted = ms.clone();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let med = if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    };
    println!(
        "{{\"tool\": \"sl-tsdf\", \"dataset\": \"{which}\", \"weight\": \"{}\", \"frames\": {n}, \"integrate_ms_median\": {med:.2}, \"integrate_ms\": {:?}, \"extract_ms\": {extract_ms:.1}, \"vertices\": {}, \"triangles\": {}, \"blocks\": {}, \"memory_bytes\": {}, \"mesh_checksum\": \"{h:016x}\"}}",
        weight.name(),
        ms.iter()
            .map(|x| (x * 100.0).round() / 100.0)
            .collect::<Vec<_>>(),
        mesh.vertex_count(),
        mesh.triangle_count(),
        vol.block_count(),
        vol.memory_bytes()
    );
    Ok(())
}

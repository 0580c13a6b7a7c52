//! Times integration and marching cubes on a real sequence, the way `sldepth fuse --json` does
//! (per-frame integration without file I/O, then one extraction), for the Open3D comparison in
//! `docs/bench/open3d_tsdf.py`.
//!
//! `cargo run --release -p sl-tsdf --example fuse_timing -- icl|7scenes [weight] [frames]`
//!
//! The JSON also carries `mesh_checksum`, an order-sensitive hash of the mesh's bits, to check
//! that a change of implementation leaves the output unchanged.

use std::time::Instant;

use sl_tsdf::{MeshConfig, TsdfConfig, TsdfVolume, WeightMode};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map(String::as_str).unwrap_or("icl");
    let weight = WeightMode::parse(args.get(2).map(String::as_str).unwrap_or("inv-z4"))?;
    let max_frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(50);
    let seq = if which == "icl" {
        sl_testkit::icl_sequence(max_frames)
    } else {
        sl_testkit::seven_scenes_sequence(max_frames)
    };
    let Some(seq) = seq else {
        return Ok(());
    };
    let (frames, k) = (seq.frames, seq.camera.intrinsics);
    let mut params = TsdfConfig::default();
    params.voxel_m = 0.004;
    params.trunc_m = 0.02;
    params.max_depth_m = 4.0;
    params.weight = weight;
    let mut vol = TsdfVolume::new(params)?;
    let mut ms = Vec::new();
    for (d, p) in &frames {
        let t0 = Instant::now();
        vol.integrate(d, &k, p)?;
        ms.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    let t0 = Instant::now();
    let mesh = vol.extract_mesh(&MeshConfig::default());
    let extract_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Order-sensitive FNV-1a checksum of the mesh (to compare implementations).
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |v: u32| {
        h ^= u64::from(v);
        h = h.wrapping_mul(0x0100_0000_01b3);
    };
    let coords = mesh.positions.iter().map(|p| &p.coords);
    for p in coords.chain(&mesh.normals) {
        p.iter().for_each(|c| eat(c.to_bits()));
    }
    let confidence = mesh.scalar_values(sl_tsdf::CONFIDENCE_PROPERTY);
    confidence
        .unwrap_or_default()
        .iter()
        .for_each(|c| eat(c.to_bits()));
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

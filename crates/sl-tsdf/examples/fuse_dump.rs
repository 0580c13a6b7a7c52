//! TEMPORARY (perf work): dumps the fused volume and mesh to raw files for before/after diffs.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
use std::io::Write;
use std::path::Path;

use sl_io::{ReadOptions, read_depth};
use sl_tsdf::{ExtractOptions, TsdfParams, TsdfVolume};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let which = args[1].as_str();
    let out = Path::new(&args[2]);
    let max_frames: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(50);
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let (frames, k) = if which == "icl" {
        let dir = data.join("open3d-testdata/icl-livingroom");
        let f =
            sl_io::trajectory::read_open3d_log_frames(dir.join("odometry.log"), dir.join("depth"))?;
        (f, sl_io::camera::read_camera_json(dir.join("camera.json"))?.intrinsics)
    } else {
        let dir = data.join("7scenes-redkitchen");
        let f = sl_io::trajectory::read_7scenes_sequence(&dir)?;
        (f, sl_io::camera::read_7scenes_intrinsics(dir.join("camera-intrinsics.txt"))?)
    };
    let params = TsdfParams { voxel_m: 0.004, trunc_m: 0.02, max_depth_m: 4.0, ..TsdfParams::default() };
    let mut vol = TsdfVolume::new(params)?;
    for f in frames.into_iter().take(max_frames) {
        let d = read_depth(&f.depth_path, &ReadOptions::default())?.depth;
        vol.integrate(&d, &k, &f.pose)?;
    }
    let mut coords: Vec<[i32; 3]> = vol.block_coords().collect();
    coords.sort();
    let mut w = std::io::BufWriter::new(std::fs::File::create(out.with_extension("vol"))?);
    for c in &coords {
        let b = vol.block(*c).unwrap();
        for x in c { w.write_all(&x.to_le_bytes())?; }
        for x in b.tsdf.iter().chain(b.weight.iter()) { w.write_all(&x.to_le_bytes())?; }
    }
    drop(w);
    let m = vol.extract_mesh(&ExtractOptions::default());
    let mut w = std::io::BufWriter::new(std::fs::File::create(out.with_extension("mesh"))?);
    w.write_all(&(m.positions.len() as u64).to_le_bytes())?;
    w.write_all(&(m.triangles.len() as u64).to_le_bytes())?;
    for p in m.positions.iter().chain(m.normals.iter()) { for x in p { w.write_all(&x.to_le_bytes())?; } }
    for x in &m.confidence { w.write_all(&x.to_le_bytes())?; }
    for t in &m.triangles { for x in t { w.write_all(&x.to_le_bytes())?; } }
    println!("blocks {} vertices {} triangles {}", coords.len(), m.positions.len(), m.triangles.len());
    Ok(())
}

//! Development probe: extract planes from a few real frames and print timing and planes.
#![allow(clippy::unwrap_used, missing_docs)]
use std::time::Instant;

use sl_core::{Camera, Intrinsics};
use sl_planes::{PlaneConfig, PlaneExtractor};

fn cpu_s() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap();
    let f: Vec<&str> = s.rsplit(')').next().unwrap().split_whitespace().collect();
    (f[11].parse::<f64>().unwrap() + f[12].parse::<f64>().unwrap()) / 100.0
}

fn main() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let args: Vec<String> = std::env::args().collect();
    let thr: f64 = args.get(1).map_or(0.3, |s| s.parse().unwrap());
    let lthr: f64 = args.get(2).map_or(0.1, |s| s.parse().unwrap());
    let mp: f64 = args.get(3).map_or(0.2, |s| s.parse().unwrap());
    let cfg = PlaneConfig { threshold_px: thr, log_threshold_px: lthr, merge_px: mp, ..Default::default() };
    let tum = Camera::from_intrinsics(Intrinsics::new(640, 480, 517.3, 516.5, 318.6, 255.3).unwrap(), None, None).unwrap();
    let o3d = Camera::from_intrinsics(Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap(), None, None).unwrap();
    let sev = Camera::from_intrinsics(Intrinsics::new(640, 480, 585.0, 585.0, 320.0, 240.0).unwrap(), None, None).unwrap();
    let mut frames = vec![];
    let tumdir = data.join("tum-fr1-rpy");
    let mut tums: Vec<_> = std::fs::read_dir(tumdir.join("depth")).unwrap().map(|e| e.unwrap().path()).collect();
    tums.sort();
    let opts = |s: f64| sl_io::ReadOptions::default().with_scale(s);
    frames.push(("tum", sl_io::read_depth(&tums[0], &opts(5000.0)).unwrap().depth, tum));
    frames.push(("o3d-tum", sl_io::read_depth(data.join("open3d-testdata/tum-depth.png"), &opts(5000.0)).unwrap().depth, o3d));
    frames.push(("7scenes", sl_io::read_depth(data.join("7scenes-redkitchen/frame-000150.depth.png"), &opts(1000.0)).unwrap().depth, sev));
    frames.push(("person", sl_io::read_depth(data.join("open3d-testdata/person-depth.png"), &opts(1000.0)).unwrap().depth, o3d));
    let mut ex = PlaneExtractor::new(cfg).unwrap();
    for (name, depth, cam) in &frames {
        let mut best = f64::MAX;
        let mut seg = None;
        let c0 = cpu_s();
        for _ in 0..5 {
            let t = Instant::now();
            let s = ex.extract_depth(depth, cam).unwrap();
            best = best.min(t.elapsed().as_secs_f64() * 1e3);
            seg = Some(s);
        }
        println!("cpu per frame {:.2} ms", (cpu_s() - c0) * 200.0);
        let seg = seg.unwrap();
        let lab: usize = seg.planes.iter().map(|p| p.pixels).sum();
        println!("{name}: {:.2} ms, {} planes, {:.1}% labelled of {} valid", best, seg.planes.len(), 100.0 * lab as f64 / depth.valid_count() as f64, depth.valid_count());
        for p in seg.planes.iter().take(8) {
            println!("   id {} px {} n [{:.3} {:.3} {:.3}] d {:.3} rms {:.3}px {:.1}mm c.z {:.2}", p.id, p.pixels, p.plane.normal.x, p.plane.normal.y, p.plane.normal.z, p.plane.offset_m, p.rms_px, p.rms_m * 1e3, p.centroid_m.z);
        }
        let rgb = sl_planes::overlay::depth_to_rgb(depth);
        let o = sl_planes::overlay::overlay_rgb(&seg.labels, &rgb, 0.6).unwrap();
        image::RgbImage::from_raw(640, 480, o).unwrap().save(format!("/tmp/planes_{name}.png")).unwrap();
    }
    let raw = sl_io::read_nyu_raw(data.join("open3d-testdata/nyu-raw-disparity.pgm")).unwrap();
    let disp = sl_io::depth::nyu_raw_to_disparity(&raw, sl_io::depth::NYU_DOFF);
    let cam = Camera { intrinsics: sl_io::depth::nyu_intrinsics(), sensor: sl_io::depth::nyu_sensor_model() };
    let mut best = f64::MAX;
    let mut seg = None;
    for _ in 0..20 {
        let t = Instant::now();
        let s = ex.extract_disparity(&disp, &cam).unwrap();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
        seg = Some(s);
    }
    let seg = seg.unwrap();
    println!("nyu: {:.2} ms, {} planes", best, seg.planes.len());
    for p in seg.planes.iter().take(8) {
        println!("   id {} px {} d {:.3} rms {:.3}px {:.1}mm", p.id, p.pixels, p.plane.offset_m, p.rms_px, p.rms_m * 1e3);
    }
    let depth = disp.to_depth(&cam.sensor);
    let o = sl_planes::overlay::overlay_rgb(&seg.labels, &sl_planes::overlay::depth_to_rgb(&depth), 0.6).unwrap();
    image::RgbImage::from_raw(640, 480, o).unwrap().save("/tmp/planes_nyu.png").unwrap();
}

//! Per-stage timing of the plane extractor on the real 640×480 frames, one thread, and a
//! regression check of its labels against a saved run.
//!
//! * `cargo run --release -p sl-planes --example planes_timing -- time [ITERATIONS] [FILTER]`:
//!   min and median milliseconds per frame and the median per stage (one frame per source; a
//!   `FILTER` with a `/`, such as `tum-fr1-rpy/04` or `tum-fr1-rpy-200/86`, picks among the
//!   frames of `sweep`, by the names it prints).
//! * `… -- sweep [ITERATIONS] [ROUNDS]`: min/median per frame over many frames of each source
//!   (all TUM and 7-Scenes frames, the 200 of TUM fr1/rpy-200 included, NYU raw, the Open3D and
//!   PCL frames, the simulated scenes),
//!   and the slowest frame; `ROUNDS` passes over all frames, `ITERATIONS` runs each.
//! * `… -- dump DIR` / `… -- compare DIR`: writes the labels and planes of those frames to `DIR`,
//!   or compares the current labels with them (pixel agreement after matching planes by
//!   overlap): a check that an optimisation did not change the segmentation.
//!   `compare` also checks that labels and every plane field are bit-identical.
//! * `… -- repeat N FILTER`: N extractions of one frame (a `FILTER` with a `/` as in `time`;
//!   for `valgrind --tool=callgrind --collect-atstart=no --toggle-collect='*repeat_extract*'`).
//! * `… -- view DIR OUT FILTER`: side-by-side overlays (saved | current) as PNGs in `OUT`.
//!
//! * `… -- time-pool [ITERATIONS] [FILTER]`: `time` run from a worker of the global pool.
//!
//! `PLANES_TIMING_OPTIONS=give_back_taken_in` (or `refine_seams`, comma-separated) switches
//! on optional stages.
//!
//! `RAYON_NUM_THREADS=1` times one thread (the final pass runs in bands on the rayon pool when
//! it has more than one thread; from the main thread the extraction then moves onto a worker
//! once per frame, see `PlaneExtractor::extract_depth`). Frames come from
//! `../shared/data` (simulated frames when absent), as in `benches/planes.rs`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

#[path = "../benches/support/frames.rs"]
mod frames;

use std::collections::HashMap;
use std::path::PathBuf;

use frames::{Input, frames, load};
use sl_core::Camera;
use sl_planes::{PlaneConfig, PlaneExtractor, PlaneSegmentation, Stage};

fn run(ex: &mut PlaneExtractor, input: &Input, cam: &Camera) -> PlaneSegmentation {
    match input {
        Input::Depth(d) => ex.extract_depth(d, cam).unwrap(),
        Input::Disparity(d) => ex.extract_disparity(d, cam).unwrap(),
    }
}

/// The default configuration, with the optional stages named in `PLANES_TIMING_OPTIONS`
/// (comma-separated: `refine_seams`, `give_back_taken_in`) switched on.
fn config() -> PlaneConfig {
    let mut cfg = PlaneConfig::default();
    let options = std::env::var("PLANES_TIMING_OPTIONS").unwrap_or_default();
    for o in options.split(',').filter(|o| !o.is_empty()) {
        match o {
            "refine_seams" => cfg.refine_seams = true,
            "give_back_taken_in" => cfg.give_back_taken_in = true,
            _ => {
                eprintln!("unknown option {o:?} in PLANES_TIMING_OPTIONS");
                std::process::exit(2);
            }
        }
    }
    cfg
}

fn median(v: &mut [u64]) -> f64 {
    v.sort_unstable();
    v[v.len() / 2] as f64 / 1e6
}

fn time(iters: usize, filter: &str) {
    let all = frames_for(filter, frames);
    for (name, input, cam) in all {
        if !name.contains(filter) {
            continue;
        }
        let mut ex = PlaneExtractor::new(config()).unwrap();
        let mut totals = Vec::with_capacity(iters);
        let mut stages: Vec<Vec<u64>> = vec![Vec::with_capacity(iters); Stage::ALL.len()];
        let mut nplanes = 0;
        for _ in 0..iters {
            let t = std::time::Instant::now();
            let seg = run(&mut ex, &input, &cam);
            totals.push(t.elapsed().as_nanos() as u64);
            nplanes = seg.planes.len();
            std::hint::black_box(seg);
            for (s, v) in Stage::ALL.iter().zip(stages.iter_mut()) {
                v.push(ex.stage_times().ns(*s));
            }
        }
        let min = *totals.iter().min().unwrap() as f64 / 1e6;
        println!(
            "{name}: {nplanes} planes, min {min:.3} ms, median {:.3} ms",
            median(&mut totals)
        );
        for (s, v) in Stage::ALL.iter().zip(stages.iter_mut()) {
            println!("  {:<16} {:>7.3} ms", s.name(), median(v));
        }
    }
}

/// The time of one `NoiseMeter::measure` (a frame's noise against its camera's model, as
/// `sldepth track` runs it on every raw frame) on the matching frames.
fn noise(iters: usize, filter: &str) {
    for (name, input, cam) in frames() {
        if !name.contains(filter) {
            continue;
        }
        let depth = match &input {
            Input::Depth(d) => d.clone(),
            Input::Disparity(d) => d.to_depth(&cam.sensor),
        };
        let mut meter = sl_planes::NoiseMeter::new(&PlaneConfig::default());
        let mut times = Vec::with_capacity(iters);
        let mut scale = 1.0;
        for _ in 0..iters {
            let t = std::time::Instant::now();
            scale = meter.measure(&depth, &cam).unwrap();
            times.push(t.elapsed().as_nanos() as u64);
        }
        println!(
            "{name}: noise ×{scale:.3}, median {:.3} ms",
            median(&mut times)
        );
    }
}

/// The sweep's frames: up to 50 of each source, and every frame of the 200-frame TUM sequence
/// (issue 12's budget is per real frame).
fn sweep_frames() -> Vec<(String, Input, Camera)> {
    let mut inputs = load(50);
    inputs.extend(
        sl_testkit::tum_rpy_200(200)
            .into_iter()
            .map(|f| (f.name, Input::Depth(f.depth), f.camera)),
    );
    inputs
}

/// The frames a `FILTER` picks from: the sweep's when it names a frame (it has a `/`, as in
/// `tum-fr1-rpy-200/86`), else `otherwise()`.
fn frames_for(
    filter: &str,
    otherwise: impl FnOnce() -> Vec<(String, Input, Camera)>,
) -> Vec<(String, Input, Camera)> {
    if filter.contains('/') {
        sweep_frames()
    } else {
        otherwise()
    }
}

fn sweep(iters: usize, rounds: usize) {
    let mut ex = PlaneExtractor::new(config()).unwrap();
    let inputs = sweep_frames();
    // Per frame: every run's time. Rounds visit all frames in turn, so a slow spell of a shared
    // machine falls on a few runs of many frames, not on every run of one frame.
    let mut times: Vec<Vec<u64>> = vec![Vec::with_capacity(iters * rounds); inputs.len()];
    for _ in 0..rounds.max(1) {
        for ((_, input, cam), t) in inputs.iter().zip(&mut times) {
            for _ in 0..iters {
                let t0 = std::time::Instant::now();
                std::hint::black_box(run(&mut ex, input, cam));
                t.push(t0.elapsed().as_nanos() as u64);
            }
        }
    }
    let mut by_source: HashMap<String, (Vec<u64>, Vec<u64>, String)> = HashMap::new();
    for ((name, _, _), t) in inputs.iter().zip(&mut times) {
        let source = name.split('/').next().unwrap().to_string();
        let e = by_source.entry(source).or_default();
        let min = *t.iter().min().unwrap();
        if e.0.iter().all(|&m| m < min) {
            e.2 = name.clone();
        }
        e.0.push(min);
        e.1.push((median(t) * 1e6) as u64);
    }
    let mut keys: Vec<_> = by_source.keys().cloned().collect();
    keys.sort();
    for k in keys {
        let (mins, meds, worst_name) = by_source.get_mut(&k).unwrap();
        let n = mins.len();
        let worst = *mins.iter().max().unwrap() as f64 / 1e6;
        println!(
            "{k:<14} {n:>3} frames: per-frame min: median {:.3} ms, worst {worst:.3} ms ({worst_name}); per-frame median: median {:.3} ms",
            median(mins),
            median(meds)
        );
    }
}

fn dump(dir: &std::path::Path) {
    std::fs::create_dir_all(dir).unwrap();
    let mut ex = PlaneExtractor::new(config()).unwrap();
    for (name, input, cam) in load(50) {
        let seg = run(&mut ex, &input, &cam);
        let file = dir.join(name.replace('/', "_"));
        let bytes: Vec<u8> = seg
            .labels
            .data()
            .iter()
            .flat_map(|l| l.to_le_bytes())
            .collect();
        std::fs::write(file.with_extension("labels"), bytes).unwrap();
        let mut txt = String::new();
        for p in &seg.planes {
            txt += &format!(
                "{} {} {:.6} {:.6} {:.6} {:.6} {:.4} {:.5}\n",
                p.id,
                p.pixels,
                p.plane.normal.x,
                p.plane.normal.y,
                p.plane.normal.z,
                p.plane.offset_m,
                p.rms_px,
                p.rms_m
            );
        }
        std::fs::write(file.with_extension("planes"), txt).unwrap();
        std::fs::write(file.with_extension("full"), full_planes(&seg)).unwrap();
    }
}

/// Every field of every plane at full precision (bit-exact comparison).
fn full_planes(seg: &PlaneSegmentation) -> String {
    let mut txt = String::new();
    for p in &seg.planes {
        txt += &format!(
            "{} {} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?}\n",
            p.id,
            p.pixels,
            p.plane.normal.x,
            p.plane.normal.y,
            p.plane.normal.z,
            p.plane.offset_m,
            p.affine.a,
            p.affine.b,
            p.affine.c,
            p.rms_px,
            p.rms_m,
            p.centroid_m.x,
            p.centroid_m.y,
            p.centroid_m.z
        );
    }
    txt
}

/// Runs the extraction `iters` times on the first frame matching `filter` (for callgrind:
/// `--toggle-collect` on `repeat_extract` counts the extraction alone).
fn repeat(iters: usize, filter: &str) {
    let (name, input, cam) = frames_for(filter, || load(1))
        .into_iter()
        .find(|(n, _, _)| n.contains(filter))
        .unwrap();
    let mut ex = PlaneExtractor::new(config()).unwrap();
    let n = repeat_extract(&mut ex, &input, &cam, iters);
    println!("{name}: {iters} runs, {n} planes");
}

#[inline(never)]
fn repeat_extract(ex: &mut PlaneExtractor, input: &Input, cam: &Camera, iters: usize) -> usize {
    let mut n = 0;
    for _ in 0..iters {
        n = std::hint::black_box(run(ex, input, cam)).planes.len();
    }
    n
}

fn compare(dir: &std::path::Path) {
    let mut ex = PlaneExtractor::new(config()).unwrap();
    let (mut worst, mut sum, mut n) = (1.0f64, 0.0f64, 0usize);
    let mut exact = true;
    for (name, input, cam) in load(50) {
        let seg = run(&mut ex, &input, &cam);
        let file = dir.join(name.replace('/', "_"));
        let Ok(bytes) = std::fs::read(file.with_extension("labels")) else {
            println!("{name}: no saved labels");
            continue;
        };
        let old: Vec<u16> = bytes
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        let old_planes = std::fs::read_to_string(file.with_extension("planes"))
            .unwrap()
            .lines()
            .count();
        let exact_labels = old.as_slice() == seg.labels.data();
        let exact_planes = std::fs::read_to_string(file.with_extension("full"))
            .is_ok_and(|t| t == full_planes(&seg));
        exact &= exact_labels && exact_planes;
        // Confusion counts, greedy one-to-one matching by overlap.
        let mut conf: HashMap<(u16, u16), usize> = HashMap::new();
        let mut either = 0usize;
        for (&a, &b) in old.iter().zip(seg.labels.data()) {
            if a != 0 || b != 0 {
                either += 1;
            }
            if a != 0 && b != 0 {
                *conf.entry((a, b)).or_default() += 1;
            }
        }
        let mut pairs: Vec<_> = conf.into_iter().collect();
        pairs.sort_by_key(|p| std::cmp::Reverse(p.1));
        let (mut ua, mut ub) = (vec![false; 65536], vec![false; 65536]);
        let mut agree = 0usize;
        for ((a, b), c) in pairs {
            if !ua[a as usize] && !ub[b as usize] {
                ua[a as usize] = true;
                ub[b as usize] = true;
                agree += c;
            }
        }
        let frac = if either == 0 {
            1.0
        } else {
            agree as f64 / either as f64
        };
        worst = worst.min(frac);
        sum += frac;
        n += 1;
        println!(
            "{name:<22} planes {old_planes:>3} -> {:>3}  agreement {:.2} %  labels {}  planes {}",
            seg.planes.len(),
            100.0 * frac,
            if exact_labels { "identical" } else { "DIFFER" },
            if exact_planes { "identical" } else { "DIFFER" },
        );
    }
    println!(
        "mean agreement {:.2} %, worst {:.2} % over {n} frames",
        100.0 * sum / n.max(1) as f64,
        100.0 * worst
    );
    println!(
        "bit-exact labels and planes on all frames: {}",
        if exact { "YES" } else { "NO" }
    );
}

/// Side-by-side overlays (saved labels | current labels) of the frames matching `filter`.
fn view(dir: &std::path::Path, out: &std::path::Path, filter: &str) {
    use sl_eval::planes::overlay::{depth_to_rgb, overlay_rgb};
    std::fs::create_dir_all(out).unwrap();
    let mut ex = PlaneExtractor::new(config()).unwrap();
    for (name, input, cam) in load(50) {
        if !name.contains(filter) {
            continue;
        }
        let seg = run(&mut ex, &input, &cam);
        let file = dir.join(name.replace('/', "_"));
        let Ok(bytes) = std::fs::read(file.with_extension("labels")) else {
            continue;
        };
        let old: Vec<u16> = bytes
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        let (w, h) = (seg.labels.width(), seg.labels.height());
        let depth = match &input {
            Input::Depth(d) => d.clone(),
            Input::Disparity(d) => d.to_depth(&cam.sensor),
        };
        let base = depth_to_rgb(&depth);
        let old = sl_core::Image::from_vec(w, h, old).unwrap();
        let a = overlay_rgb(&old, &base, 0.6).unwrap();
        let b = overlay_rgb(&seg.labels, &base, 0.6).unwrap();
        let mut img = image::RgbImage::new(2 * w as u32, h as u32);
        for y in 0..h {
            for x in 0..w {
                let i = 3 * (y * w + x);
                img.put_pixel(x as u32, y as u32, image::Rgb([a[i], a[i + 1], a[i + 2]]));
                img.put_pixel(
                    (x + w) as u32,
                    y as u32,
                    image::Rgb([b[i], b[i + 1], b[i + 2]]),
                );
            }
        }
        img.save(out.join(format!("{}.png", name.replace('/', "_"))))
            .unwrap();
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).cloned().unwrap_or_default();
    match arg(0).as_str() {
        "sweep" => sweep(arg(1).parse().unwrap_or(5), arg(2).parse().unwrap_or(1)),
        "dump" => dump(&PathBuf::from(arg(1))),
        "compare" => compare(&PathBuf::from(arg(1))),
        "view" => view(&PathBuf::from(arg(1)), &PathBuf::from(arg(2)), &arg(3)),
        "repeat" => repeat(arg(1).parse().unwrap_or(20), &arg(2)),
        "time" => time(arg(1).parse().unwrap_or(200), &arg(2)),
        "noise" => noise(arg(1).parse().unwrap_or(200), &arg(2)),
        "time-pool" => rayon::scope(|_| time(arg(1).parse().unwrap_or(200), &arg(2))),
        _ => time(arg(0).parse().unwrap_or(200), &arg(1)),
    }
}

//! Release timing of the filters on a real 640×480 frame (median and minimum of N runs), for
//! side-by-side comparison with `docs/bench/opencv_bilateral.py`:
//!
//! ```text
//! cargo run --release -p sl-filter --example time_filters -- [DEPTH.png] [REPS] [DEPTH_SCALE]
//! ```
//!
//! Environment: `METHODS=adaptive,gaussian` (default: all four), `RADII=2` (default: 2,3),
//! `ISA=portable|avx2` (default: the best this CPU supports), `WINDOW=square|disc` (default: the
//! filter's own default).

use std::time::Instant;

use sl_core::SensorModel;
use sl_filter::{DepthFilter, Isa, Method, Window, default_sigma_s_px};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).cloned().unwrap_or_else(|| {
        sl_testkit::data_dir()
            .unwrap_or_default()
            .join("open3d-testdata/person-depth.png")
            .to_string_lossy()
            .into_owned()
    });
    let reps: usize = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(100);
    let scale: f32 = args
        .get(3)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(1000.0);
    let depth = sl_testkit::read_depth(std::path::Path::new(&path), Some(f64::from(scale)))?;
    let (w, h) = (depth.width(), depth.height());
    let sensor = SensorModel::kinect_v1();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let methods: Vec<Method> = match std::env::var("METHODS") {
        Ok(s) => s.split(',').map(|m| m.parse()).collect::<Result<_, _>>()?,
        Err(_) => Method::ALL.to_vec(),
    };
    let isa = match std::env::var("ISA").as_deref() {
        Ok("portable") => Isa::Portable,
        Ok("avx2") => Isa::Avx2,
        _ => Isa::detect(),
    };
    println!(
        "frame {path} ({w}x{h}), isa {}, threads {}",
        isa.name(),
        rayon::current_num_threads()
    );
    let window: Option<Window> = std::env::var("WINDOW")
        .ok()
        .map(|s| s.parse())
        .transpose()?;
    let radii: Vec<usize> = match std::env::var("RADII") {
        Ok(s) => s.split(',').map(|r| r.parse()).collect::<Result<_, _>>()?,
        Err(_) => vec![2, 3],
    };
    for &r in &radii {
        for &m in &methods {
            let mut f = DepthFilter::default_for(m, &sensor)
                .with_radius(r)
                .with_sigma_s(default_sigma_s_px(r));
            if let Some(window) = window {
                f = f.with_window(window);
            }
            for threads in [1usize, rayon::current_num_threads()] {
                let run = || -> Result<Vec<f64>, sl_filter::FilterError> {
                    let mut t = Vec::with_capacity(reps);
                    f.apply_with_isa(&depth, isa)?;
                    for _ in 0..reps {
                        let t0 = Instant::now();
                        std::hint::black_box(f.apply_with_isa(std::hint::black_box(&depth), isa)?);
                        t.push(t0.elapsed().as_secs_f64() * 1e3);
                    }
                    Ok(t)
                };
                let mut t = if threads == 1 {
                    one.install(run)?
                } else {
                    run()?
                };
                t.sort_by(f64::total_cmp);
                println!(
                    "{m:>9} {}x{} threads={threads}: median {:.3} ms, min {:.3} ms",
                    2 * r + 1,
                    2 * r + 1,
                    t[t.len() / 2],
                    t[0]
                );
            }
        }
    }
    Ok(())
}

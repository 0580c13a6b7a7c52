//! Criterion benchmarks of the four filters on a 640×480 Kinect frame.
//!
//! The frame is `../shared/data/open3d-testdata/person-depth.png` (a person before a wall, the
//! paper's Figure 4 situation) when the shared data is present, otherwise a synthetic noisy
//! tilted plane of the same size. Radius 2 (5×5) and 3 (7×7), every method, with one thread (a
//! local rayon pool) and with all threads; the adaptive filter also with the portable (non-AVX)
//! kernel, and with the disc window (OpenCV's) on this CPU's best kernel and on AVX2. Compare with OpenCV using `docs/bench/opencv_bilateral.py`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::{DepthImage, SensorModel};
use sl_filter::{DepthFilter, Isa, Method, Window, default_sigma_s_px};

fn frame() -> DepthImage {
    if let Some(person) = sl_testkit::person() {
        eprintln!("benchmark frame: {}", person.path.display());
        return person.depth;
    }
    eprintln!("skipping real frame: ../shared/data not found; using a synthetic 640x480 plane");
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let data = (0..640 * 480)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let (x, y) = ((i % 640) as f32, (i / 640) as f32);
            let noise = ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.01;
            if state.is_multiple_of(50) {
                0.0
            } else {
                1.0 + 0.004 * y + 0.001 * x + noise
            }
        })
        .collect();
    DepthImage::from_vec(640, 480, data).unwrap_or_else(|_| DepthImage::invalid(640, 480))
}

fn bench(c: &mut Criterion) {
    let depth = frame();
    let sensor = SensorModel::kinect_v1();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let all_threads = rayon::current_num_threads();
    let mut g = c.benchmark_group("filter_640x480");
    g.sample_size(30);
    for r in [2usize, 3] {
        for m in Method::ALL {
            let f = DepthFilter::default_for(m, &sensor)
                .with_radius(r)
                .with_sigma_s(default_sigma_s_px(r));
            g.bench_function(format!("{m}/{}x{}/1thread", 2 * r + 1, 2 * r + 1), |b| {
                one.install(|| b.iter(|| f.apply(black_box(&depth)).unwrap()))
            });
            g.bench_function(
                format!("{m}/{}x{}/{all_threads}threads", 2 * r + 1, 2 * r + 1),
                |b| b.iter(|| f.apply(black_box(&depth)).unwrap()),
            );
        }
        let f = DepthFilter::default_for(Method::Adaptive, &sensor)
            .with_radius(r)
            .with_sigma_s(default_sigma_s_px(r));
        for isa in [Isa::Portable, Isa::Avx2] {
            g.bench_function(
                format!(
                    "adaptive-{}/{}x{}/1thread",
                    isa.name(),
                    2 * r + 1,
                    2 * r + 1
                ),
                |b| one.install(|| b.iter(|| f.apply_with_isa(black_box(&depth), isa).unwrap())),
            );
        }
        // The disc window (OpenCV's), with this CPU's best kernel and with the AVX2 one (once
        // where the best is AVX2: criterion refuses a benchmark name twice).
        let disc = f.with_window(Window::Disc);
        let best = Isa::detect();
        let disc_isas: &[Isa] = if best == Isa::Avx2 {
            &[Isa::Avx2]
        } else {
            &[best, Isa::Avx2]
        };
        for &isa in disc_isas {
            g.bench_function(
                format!(
                    "adaptive-disc-{}/{}x{}/1thread",
                    isa.name(),
                    2 * r + 1,
                    2 * r + 1
                ),
                |b| one.install(|| b.iter(|| disc.apply_with_isa(black_box(&depth), isa).unwrap())),
            );
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Plane extraction on 640×480 frames, one thread (target ≤ 3 ms per frame, issue 12).
//!
//! Real frames from `../shared/data` (TUM fr1/rpy, 7-Scenes, NYU raw disparity, Open3D's TUM
//! sample); when that directory is absent, simulated Kinect frames (`sl-noise`) instead; and
//! two scenes of the randomised room benchmark (a room and a corridor, realistic noise). The
//! global rayon pool is limited to one thread, and the extractor itself is sequential.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

#[path = "support/frames.rs"]
mod frames;

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use frames::{Input, frames};
use sl_planes::{PlaneConfig, PlaneExtractor};

fn bench(c: &mut Criterion) {
    // One worker thread for anything that would use rayon (the extractor is sequential).
    let _ = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global();
    let mut g = c.benchmark_group("planes-1-thread");
    g.sample_size(40);
    for (name, input, cam) in frames() {
        let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
        g.bench_function(&name, |b| {
            b.iter(|| match &input {
                Input::Depth(d) => black_box(ex.extract_depth(black_box(d), &cam).unwrap()),
                Input::Disparity(d) => black_box(ex.extract_disparity(black_box(d), &cam).unwrap()),
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! I/O benchmarks: a 640×480 depth PNG (write, read) and a 1M-vertex / 2M-face PLY mesh write.
//!
//! Run with `cargo bench -p sl-io`.
// A benchmark that cannot write its temp files has nothing to measure: abort loudly.
#![allow(clippy::expect_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use sl_core::{DepthImage, Image};
use sl_io::ply::{PlyData, PlyFormat, encode_ply};
use sl_io::{DepthEncoding, ReadConfig, read_depth, write_depth, write_ply};

/// A Kinect-like 640×480 frame: a tilted plane with a bump, in millimetres, some holes.
fn frame() -> DepthImage {
    DepthImage::from_image(Image::from_fn(640, 480, |x, y| {
        if (x / 40 + y / 30) % 11 == 0 {
            0.0
        } else {
            let (u, v) = (x as f32 / 640.0, y as f32 / 480.0);
            ((0.8 + 1.5 * v + 0.3 * (6.0 * u).sin()) * 1000.0).round() / 1000.0
        }
    }))
}

/// A grid mesh of `side`² vertices and 2·(side−1)² triangles.
fn grid_mesh(side: usize) -> PlyData {
    let positions: Vec<[f32; 3]> = (0..side * side)
        .map(|i| {
            let (x, y) = ((i % side) as f32, (i / side) as f32);
            [x * 0.001, y * 0.001, 1.0 + 0.01 * (x * 0.05).sin()]
        })
        .collect();
    let normals = vec![[0.0, 0.0, -1.0]; side * side];
    let mut faces = Vec::with_capacity(2 * (side - 1) * (side - 1));
    for y in 0..side - 1 {
        for x in 0..side - 1 {
            let i = (y * side + x) as u32;
            let s = side as u32;
            faces.push([i, i + s, i + 1]);
            faces.push([i + 1, i + s, i + s + 1]);
        }
    }
    PlyData::mesh(positions, faces).with_normals(normals)
}

fn bench_depth_png(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("depth.png");
    let depth = frame();
    let enc = DepthEncoding::default();
    c.bench_function("write_depth_png_640x480", |b| {
        b.iter(|| write_depth(&path, black_box(&depth), &enc).expect("write"))
    });
    write_depth(&path, &depth, &enc).expect("write");
    c.bench_function("read_depth_png_640x480", |b| {
        b.iter(|| read_depth(black_box(&path), &ReadConfig::default()).expect("read"))
    });
}

fn bench_ply(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("mesh.ply");
    let mesh = grid_mesh(1000); // 1M vertices, ~2M faces
    let mut g = c.benchmark_group("ply");
    g.sample_size(10);
    g.bench_function("write_ply_binary_1M_vertices_2M_faces", |b| {
        b.iter(|| write_ply(&path, black_box(&mesh), PlyFormat::BinaryLittleEndian).expect("write"))
    });
    // The same mesh encoded into memory: ply-rs's per-property cost without the file system.
    let mut buf = Vec::with_capacity(64 << 20);
    g.bench_function("encode_ply_binary_1M_vertices_2M_faces_to_memory", |b| {
        b.iter(|| {
            buf.clear();
            encode_ply(&mut buf, black_box(&mesh), PlyFormat::BinaryLittleEndian).expect("encode");
        })
    });
    // Baseline: the same payload bytes copied by hand (what a hand-rolled writer would cost).
    g.bench_function("baseline_raw_payload_to_memory", |b| {
        b.iter(|| {
            buf.clear();
            for (p, n) in mesh.positions.iter().zip(mesh.normals.iter().flatten()) {
                for v in p.iter().chain(n) {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
            }
            for f in &mesh.faces {
                buf.push(3);
                for i in f {
                    buf.extend_from_slice(&(*i as i32).to_le_bytes());
                }
            }
            black_box(buf.len())
        })
    });
    g.finish();
}

criterion_group!(benches, bench_depth_png, bench_ply);
criterion_main!(benches);

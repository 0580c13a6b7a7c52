//! Tests of the pyramid: the branch-free downsampling and the batched normals against their
//! per-pixel references, levels built on a grid and completed.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use super::normals::{Select, normals, point_aux};
use super::*;
use sl_core::Camera;

/// A slanted wall with a box in front and holes: depth edges, invalid pixels, borders.
fn scene(k: &Intrinsics) -> Vec<f32> {
    let mut d = vec![0.0f32; k.width * k.height];
    for y in 0..k.height {
        for x in 0..k.width {
            let (xf, yf) = (x as f32, y as f32);
            let mut z = 2.0 + 0.002 * xf + 0.001 * yf;
            if (200..400).contains(&x) && (150..300).contains(&y) {
                z = 1.2 + 0.0005 * (xf - 300.0).abs();
            }
            if (x * 7 + y * 13) % 97 == 0 {
                z = 0.0;
            }
            d[y * k.width + x] = z;
        }
    }
    d
}

fn bits(v: &[Vector3<f32>]) -> Vec<[u32; 3]> {
    v.iter()
        .map(|n| [n.x.to_bits(), n.y.to_bits(), n.z.to_bits()])
        .collect()
}

fn aux_bits(v: &[PointAux]) -> Vec<[u32; 3]> {
    v.iter()
        .map(|a| [a.ray_len.to_bits(), a.cz2.to_bits(), a.cos_gate.to_bits()])
        .collect()
}

/// The depth-aware 2×2 downsampling as it was written before it was made branch-free:
/// the minimum of the valid depths, then the sums of those within the edge gate of it.
fn downsample_with_branches(
    src: &[f32],
    sw: usize,
    dw: usize,
    dh: usize,
    c: f32,
    fx: f32,
) -> Vec<f32> {
    let mut out = vec![f32::NAN; dw * dh];
    for y in 0..dh {
        for x in 0..dw {
            let i = 2 * y * sw + 2 * x;
            let zs = [src[i], src[i + 1], src[i + sw], src[i + sw + 1]];
            let zmin = zs
                .iter()
                .copied()
                .filter(|z| *z > 0.0)
                .fold(f32::INFINITY, f32::min);
            out[y * dw + x] = if zmin.is_finite() {
                let gate = edge_jump_m(std::f32::consts::SQRT_2, zmin, fx, c);
                let (mut s, mut n) = (0.0f32, 0.0f32);
                for z in zs {
                    if z > 0.0 && z - zmin <= gate {
                        s += z;
                        n += 1.0;
                    }
                }
                s / n
            } else {
                0.0
            };
        }
    }
    out
}

/// The branch-free downsampling gives the filtered minimum and conditional sums bit for
/// bit, on blocks with every mix of valid, zero, negative, NaN and infinite depths and
/// with depth edges inside them, on an odd-sized source (its last column and row unused).
#[test]
fn branch_free_downsampling_is_the_filtered_one() {
    let (sw, sh) = (67usize, 41usize);
    let odd = [0.0, -0.5, f32::NAN, f32::INFINITY];
    let src: Vec<f32> = (0..sw * sh)
        .map(|i| {
            let (x, y) = (i % sw, i / sw);
            let h = (x * 31 + y * 17) % 11;
            if (10..14).contains(&x) && (6..10).contains(&y) {
                odd[(x + y) % 4]
            } else if h < 4 {
                odd[h]
            } else if (x / 5 + y / 3) % 2 == 0 {
                1.1 + 0.001 * (x + y) as f32
            } else {
                2.9 + 0.0007 * (x * y) as f32
            }
        })
        .collect();
    let sensor = Camera::kinect_v1().sensor;
    let (dw, dh) = (sw / 2, sh / 2);
    for fx in [580.0f64, 145.0] {
        let mut dst = vec![f32::NAN; dw * dh];
        downsample(&src, sw, &mut dst, dw, &sensor, fx);
        let c = (sensor.sigma_d_px / sensor.fb()) as f32;
        let want = downsample_with_branches(&src, sw, dw, dh, c, fx as f32);
        let to_bits = |v: &[f32]| v.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
        assert_eq!(to_bits(&dst), to_bits(&want), "fx {fx}");
        // Every kind of block is there: empty ones, averaged ones and edges.
        assert!(dst.contains(&0.0));
        assert!(dst.iter().any(|&z| z > 2.0) && dst.iter().any(|&z| z > 0.0 && z < 2.0));
    }
}

#[test]
fn a_level_built_on_a_grid_and_completed_equals_one_built_on_every_pixel() {
    let cam = Camera::kinect_v1();
    let (k, sensor) = (cam.intrinsics, cam.sensor);
    let depth = scene(&k);
    let mut full = Pyramid::default();
    full.build(&depth, &k, &sensor, 3, 1).unwrap();
    for stride in [2, 3] {
        let mut grid = Pyramid::default();
        grid.build(&depth, &k, &sensor, 3, stride).unwrap();
        let (g0, f0) = (&grid.levels[0], &full.levels[0]);
        let mut on_grid = 0;
        for (i, (g, f)) in g0.normals.iter().zip(&f0.normals).enumerate() {
            let (x, y) = (i % k.width, i / k.width);
            if x % stride == 0 && y % stride == 0 {
                assert_eq!(bits(&[*g]), bits(&[*f]), "pixel ({x}, {y})");
                on_grid += usize::from(f.x.is_finite());
            } else {
                assert!(g.x.is_nan(), "pixel ({x}, {y}) is off the grid");
            }
        }
        assert!(on_grid > 1000, "{on_grid} grid normals");
        // The coarser levels do not depend on the grid.
        for l in 1..3 {
            assert_eq!(bits(&grid.levels[l].normals), bits(&full.levels[l].normals));
        }
        let mut done = grid.levels[0].clone();
        done.complete_normals(&sensor, k.fx as f32, normal_radius(0));
        assert_eq!(done.normal_stride, 1);
        assert_eq!(bits(&done.normals), bits(&f0.normals));
        assert_eq!(aux_bits(&done.aux), aux_bits(&f0.aux));
    }
}

/// A corridor's side wall (0.4 m to the camera's right, along the line of sight, 0.7–2.2 m
/// away: seen at up to 80° from its normal) through a camera at half its sensor's
/// resolution: from one pixel to the next its depth changes by more than 3σ_Z. The points
/// of every coarser level must still lie on the wall. With the noise alone as the
/// downsampling's edge gate each block kept its nearer column only: the points moved
/// towards the camera, 0.9–2.3 mm off the wall at level 1 and 2.7–6.6 mm at level 2 (10th
/// to 90th percentile), and the wall turned.
#[test]
fn coarser_levels_of_an_oblique_wall_stay_on_the_wall() {
    let cam = Camera::preset("oak-d").unwrap().resampled(0.5).unwrap();
    let (k, sensor) = (cam.intrinsics, cam.sensor);
    let wall_x = 0.4;
    let mut depth = vec![0.0f32; k.width * k.height];
    for y in 0..k.height {
        for x in 0..k.width {
            let dx = (x as f64 - k.cx) / k.fx;
            let z = wall_x / dx;
            if dx > 0.0 && (0.7..2.2).contains(&z) {
                depth[y * k.width + x] = z as f32;
            }
        }
    }
    // The premise: neighbouring pixels differ by more than 3σ_Z over most of the wall.
    let (z0, z1) = (depth[k.width * 100 + 500], depth[k.width * 100 + 501]);
    assert!(z0 - z1 > 3.0 * sensor.sigma_z(f64::from(z0)) as f32);
    let mut pyramid = Pyramid::default();
    pyramid.build(&depth, &k, &sensor, 3, 1).unwrap();
    for (l, level) in pyramid.levels.iter().enumerate().skip(1) {
        let mut off: Vec<f32> = level
            .points
            .iter()
            .filter(|p| p.z > 0.0)
            .map(|p| p.x - wall_x as f32)
            .collect();
        let points = off.len();
        off.sort_by(f32::total_cmp);
        assert!(points > 1000, "level {l}: {points} points");
        // Four in five points within half a millimetre (the mean of a block's depths is a
        // little behind a curved 1/u, and blocks at the wall's ends are partial).
        let (p10, p90) = (off[points / 10], off[points * 9 / 10]);
        assert!(
            p10 > -5e-4 && p90 < 5e-4,
            "level {l}: off the wall by {p10} to {p90} m (10th to 90th percentile)"
        );
    }
}

/// The batched normals and `PointAux` are the per-pixel reference's, bit for bit: every
/// level, on every pixel and on a grid, and completing a grid.
#[test]
fn batched_normals_are_the_per_pixel_ones() {
    let cam = Camera::kinect_v1();
    let (k0, sensor) = (cam.intrinsics, cam.sensor);
    let mut depth = scene(&k0);
    // Invalid and non-finite depths as well.
    depth[5000] = f32::NAN;
    depth[7000] = f32::INFINITY;
    depth[9000] = -1.0;
    let fl = k0.fx as f32;
    for stride in [1, 2, 3] {
        let mut pyramid = Pyramid::default();
        pyramid.build(&depth, &k0, &sensor, 3, stride).unwrap();
        for (l, level) in pyramid.levels.iter().enumerate() {
            let k = level.k.unwrap();
            let sel = Select {
                stride: if l == 0 { stride } else { 1 },
                off_grid: false,
            };
            let mut reference = level.clone();
            normals(&mut reference, &k, &sensor, normal_radius(l), sel);
            point_aux(&mut reference, &sensor, fl, k.width, sel);
            assert_eq!(bits(&level.normals), bits(&reference.normals), "level {l}");
            assert_eq!(aux_bits(&level.aux), aux_bits(&reference.aux), "level {l}");
            let finite = level.normals.iter().filter(|n| n.x.is_finite()).count();
            assert!(
                finite > 1000 / (1 << (2 * l)),
                "level {l}: {finite} normals"
            );
            if l == 0 && stride > 1 {
                let mut done = level.clone();
                done.complete_normals(&sensor, fl, normal_radius(0));
                let off = Select {
                    stride,
                    off_grid: true,
                };
                normals(&mut reference, &k, &sensor, normal_radius(0), off);
                point_aux(&mut reference, &sensor, fl, k.width, off);
                assert_eq!(bits(&done.normals), bits(&reference.normals));
                assert_eq!(aux_bits(&done.aux), aux_bits(&reference.aux));
            }
        }
    }
}

/// Narrow images: fewer interior pixels than a batch (one pixel at a time), and rows
/// whose last batch overlaps the one before.
#[test]
fn narrow_levels_get_the_per_pixel_normals() {
    let sensor = Camera::kinect_v1().sensor;
    for w in [5, 11, 13, 20, 27] {
        let h = 9;
        let k = Intrinsics::new(w, h, 12.0, 12.0, w as f64 / 2.0, 4.0).unwrap();
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if i % 17 == 3 {
                    0.0
                } else {
                    1.5 + 0.01 * x - 0.02 * y + 0.003 * x * y
                }
            })
            .collect();
        for stride in [1, 2] {
            let mut pyramid = Pyramid::default();
            pyramid.build(&depth, &k, &sensor, 1, stride).unwrap();
            let level = &pyramid.levels[0];
            let sel = Select {
                stride,
                off_grid: false,
            };
            let mut reference = level.clone();
            normals(&mut reference, &k, &sensor, normal_radius(0), sel);
            point_aux(&mut reference, &sensor, k.fx as f32, w, sel);
            assert_eq!(bits(&level.normals), bits(&reference.normals), "width {w}");
            assert_eq!(aux_bits(&level.aux), aux_bits(&reference.aux), "width {w}");
            if w > 5 {
                assert!(level.normals.iter().any(|n| n.x.is_finite()), "width {w}");
            }
        }
    }
}

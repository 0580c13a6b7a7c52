//! Unit tests of the extractor.

use super::*;
use sl_core::{Camera, Intrinsics, SensorModel};

/// A standard normal deviate from a small deterministic generator (Box–Muller on a 64-bit
/// LCG), for the stages' tests.
pub(super) fn gauss(state: &mut u64) -> f64 {
    let mut uni = || {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    let (a, b) = (uni(), uni());
    (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
}

/// The depth rows converted for the final pass and the per-pixel conversion of the
/// disambiguation agree bit for bit, invalid depths (0, negative, NaN, ∞) included.
#[test]
fn depth_rows_and_pixels_agree() {
    let (w, h, fb) = (13usize, 3usize, 43.5f32);
    let specials = [0.0, -1.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
    let z: Vec<f32> = (0..w * h)
        .map(|i| {
            if i % 5 == 0 {
                specials[(i / 5) % specials.len()]
            } else {
                0.3 + 0.0173 * i as f32
            }
        })
        .collect();
    let full = FullDisparity::Depth { z: &z, fb };
    let mut scratch = vec![0.0; w];
    for y in 0..h {
        let row = full.row(y, w, &mut scratch).to_vec();
        for (x, &d) in row.iter().enumerate() {
            let i = y * w + x;
            assert_eq!(d.to_bits(), full.at(i).to_bits(), "pixel {i}");
            let ok = z[i] > 0.0 && z[i].is_finite();
            assert_eq!(d > 0.0, ok, "pixel {i}");
        }
    }
}

/// Two tilted planes with a depth step between them, on frames whose sizes are not
/// multiples of the cell (tail columns and rows), through both entry points.
#[test]
fn odd_sizes_and_disparity_input() {
    for (w, h) in [(163usize, 125usize), (160, 120), (97, 61)] {
        let k = Intrinsics::new(w, h, 150.0, 150.0, w as f64 / 2.0, h as f64 / 2.0).unwrap();
        let cam = Camera {
            intrinsics: k,
            sensor: SensorModel::kinect_v1(),
        };
        let left = Plane::new(nalgebra::Vector3::new(0.3, 0.0, -1.0), 1.5)
            .unwrap()
            .facing_origin();
        let right = Plane::new(nalgebra::Vector3::new(-0.3, 0.1, -1.0), 2.5)
            .unwrap()
            .facing_origin();
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let p = if x < w as f64 / 2.0 { &left } else { &right };
                p.depth_at(&k, x, y).unwrap_or(0.0) as f32
            })
            .collect();
        let depth = DepthImage::from_vec(w, h, depth).unwrap();
        let cfg = PlaneConfig {
            min_pixels: 200,
            min_piece_pixels: 64,
            ..PlaneConfig::default()
        };
        let mut ex = PlaneExtractor::new(cfg).unwrap();
        let seg = ex.extract_depth(&depth, &cam).unwrap();
        assert_eq!(seg.planes.len(), 2, "{w}x{h}: {:?}", seg.planes);
        let labelled = seg.labels.data().iter().filter(|&&l| l != 0).count();
        assert!(
            labelled as f64 > 0.9 * (w * h) as f64,
            "{w}x{h}: {labelled}"
        );
        // Sorted by size, ids 1.., the label counts match.
        for (i, p) in seg.planes.iter().enumerate() {
            assert_eq!(p.id as usize, i + 1);
            let n = seg.labels.data().iter().filter(|&&l| l == p.id).count();
            assert_eq!(n, p.pixels);
            let truth = if p.plane.normal.x > 0.0 {
                &left
            } else {
                &right
            };
            assert!(p.plane.angle_to_deg(truth) < 0.1, "{:?}", p.plane);
        }
        // The same through the disparity entry point, also with garbage where invalid.
        let disp = depth.to_disparity(&cam.sensor);
        let seg2 = ex.extract_disparity(&disp, &cam).unwrap();
        assert_eq!(seg2.planes.len(), 2);
        assert_eq!(seg2.labels, seg.labels);
        if w < 160 {
            continue;
        }
        // (A hole of 8×8 pixels and a few isolated pixels.)
        let is_bad = |i: usize| {
            let (x, y) = (i % w, i / w);
            (20..28).contains(&x) && (30..38).contains(&y) || i % 997 == 3
        };
        let mut bad = disp.data().to_vec();
        for (i, v) in bad.iter_mut().enumerate().filter(|(i, _)| is_bad(*i)) {
            *v = [f32::NAN, f32::INFINITY, -4.0, f32::NEG_INFINITY][i % 4];
        }
        let bad = DisparityImage::from_vec(w, h, bad).unwrap();
        let seg3 = ex.extract_disparity(&bad, &cam).unwrap();
        // (The isolated invalid pixels break the LoG support around them: fewer seeds,
        // but never an invalid pixel labelled or a non-finite statistic.)
        assert!(!seg3.planes.is_empty());
        for (i, &l) in seg3.labels.data().iter().enumerate() {
            if is_bad(i) {
                assert_eq!(l, 0, "invalid pixel {i} labelled");
            }
        }
        assert!(seg3.planes.iter().all(|p| p.rms_px.is_finite()
            && p.rms_m.is_finite()
            && p.centroid_m.iter().all(|c| c.is_finite())));
    }
}

#[test]
fn empty_and_tiny_frames() {
    let cam = Camera::kinect_v1();
    let k = cam.intrinsics;
    let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
    let seg = ex
        .extract_depth(&DepthImage::invalid(k.width, k.height), &cam)
        .unwrap();
    assert!(seg.planes.is_empty());
    assert!(seg.labels.data().iter().all(|&l| l == 0));
    assert!(ex.stage_times().total_ns() > 0);
    // Too small for the cell grid: no planes, no panic.
    let tiny = Intrinsics::new(20, 12, 30.0, 30.0, 10.0, 6.0).unwrap();
    let cam = Camera {
        intrinsics: tiny,
        sensor: SensorModel::kinect_v1(),
    };
    let seg = ex
        .extract_depth(&DepthImage::from_vec(20, 12, vec![1.0; 240]).unwrap(), &cam)
        .unwrap();
    assert!(seg.planes.is_empty());
    // A size mismatch is an error.
    assert!(
        ex.extract_depth(&DepthImage::invalid(10, 10), &cam)
            .is_err()
    );
}

/// A wall with a bumpy square in the middle: the square is on no plane and `explain` says the
/// LoG turned it down; a frame of one clean wall leaves nothing to explain.
#[test]
fn explain_names_the_bumpy_region() {
    let cam = Camera::kinect_v1();
    let k = cam.intrinsics;
    let z: Vec<f32> = (0..k.width * k.height)
        .map(|i| {
            let (x, y) = ((i % k.width) as f32, (i / k.width) as f32);
            if (200.0..400.0).contains(&x) && (150.0..330.0).contains(&y) {
                2.0 + 0.3 * (x * 0.4).sin() * (y * 0.4).cos()
            } else {
                2.0
            }
        })
        .collect();
    let depth = DepthImage::from_vec(k.width, k.height, z).unwrap();
    let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
    let seg = ex.extract_depth(&depth, &cam).unwrap();
    let regions = ex.explain_unlabelled(&seg, 1000);
    assert!(!regions.is_empty(), "{} planes", seg.planes.len());
    let r = &regions[0];
    assert!(r.pixels > 20_000, "{r:?}");
    assert!(r.bbox_px[0] >= 190 && r.bbox_px[2] <= 410, "{r:?}");
    assert_eq!(r.reason, RejectReason::NotPlanarLog, "{r:?}");
    let flat = DepthImage::from_vec(k.width, k.height, vec![2.0; k.width * k.height]).unwrap();
    let seg = ex.extract_depth(&flat, &cam).unwrap();
    assert!(ex.explain_unlabelled(&seg, 1000).is_empty());
}

/// `plane_borders` against its definition: a labelled cell with a cell of another plane among
/// its 8 neighbours (rows of any length, missing rows at the grid's edges).
#[test]
fn plane_borders_match_definition() {
    let mut state = 12345u32;
    let mut next = || {
        state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
        (state >> 16) % 4
    };
    for n in [0usize, 1, 2, 3, 7, 16, 33] {
        for _ in 0..50 {
            let row: Vec<u16> = (0..n).map(|_| next() as u16).collect();
            let up: Vec<u16> = (0..n).map(|_| next() as u16).collect();
            let dn: Vec<u16> = if next() == 0 {
                Vec::new()
            } else {
                (0..n).map(|_| next() as u16).collect()
            };
            let mut out = vec![7u8; n];
            plane_borders(&row, &up, &dn, &mut out);
            for i in 0..n {
                let l = row[i];
                let mut want = false;
                for k in i.saturating_sub(1)..=(i + 1).min(n - 1) {
                    for (r, skip) in [(&up, false), (&row, true), (&dn, false)] {
                        if let Some(&m) = r.get(k)
                            && !(skip && k == i)
                        {
                            want |= l != 0 && m != 0 && m != l;
                        }
                    }
                }
                assert_eq!(out[i], u8::from(want), "{row:?} {up:?} {dn:?} at {i}");
            }
        }
    }
}

/// A surface seen only as a strip along the image border (a box face cut by the frame, 28 px
/// tall) and one seen between two wide holes (24 px wide) are found: the LoG reads the map
/// extended across holes and the border, so their pixels keep planar cells. Without the
/// extension every pixel within 8 px of the border or a hole failed the LoG and neither strip
/// had a seed.
#[test]
fn strips_along_the_border_and_between_holes_are_planes() {
    let cam = Camera::kinect_v1();
    let k = cam.intrinsics;
    let (w, h) = (k.width, k.height);
    let wall = Plane::new(nalgebra::Vector3::new(0.1, -0.05, -1.0), 3.0)
        .unwrap()
        .facing_origin();
    let strip = Plane::new(nalgebra::Vector3::new(-0.2, 0.6, -1.0), 1.6)
        .unwrap()
        .facing_origin();
    let column = Plane::new(nalgebra::Vector3::new(0.5, 0.1, -1.0), 2.0)
        .unwrap()
        .facing_origin();
    let depth: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let p = if y >= h - 28 {
                &strip
            } else if (300..324).contains(&x) {
                &column
            } else if (260..300).contains(&x) || (324..364).contains(&x) {
                return 0.0;
            } else {
                &wall
            };
            p.depth_at(&k, x as f64, y as f64).unwrap_or(0.0) as f32
        })
        .collect();
    let depth = DepthImage::from_vec(w, h, depth).unwrap();
    let seg = extract_planes(&depth, &cam, &PlaneConfig::default()).unwrap();
    for (name, truth, pixels) in [
        ("border strip", &strip, 28 * w),
        ("column between holes", &column, 24 * (h - 28)),
    ] {
        let found = seg
            .planes
            .iter()
            .find(|p| p.plane.angle_to_deg(truth) < 1.0)
            .unwrap_or_else(|| panic!("{name} not found: {:?}", seg.planes));
        assert!(
            found.pixels as f64 > 0.9 * pixels as f64,
            "{name}: {} of {pixels} px",
            found.pixels
        );
    }
}

/// `relabel` against its definition (`lut[l]`, 0 beyond the table) on runs, mixed chunks,
/// labels beyond the table and lengths that are not a whole number of chunks.
#[test]
fn relabel_matches_a_lookup_per_label() {
    let mut state = 777u32;
    let mut next = |m: u32| {
        state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
        (state >> 16) % m
    };
    for n in [0usize, 1, 7, 8, 9, 64, 203] {
        for _ in 0..40 {
            let lut: Vec<u16> = (0..next(20) as usize).map(|_| next(20) as u16).collect();
            // Runs of random length, so that chunks repeat, are uniform or mixed.
            let mut labels = Vec::with_capacity(n);
            while labels.len() < n {
                let (l, len) = (next(24) as u16, 1 + next(20) as usize);
                labels.extend(std::iter::repeat_n(l, len.min(n - labels.len())));
            }
            let want: Vec<u16> = labels
                .iter()
                .map(|&l| lut.get(l as usize).copied().unwrap_or(0))
                .collect();
            relabel(&mut labels, &lut);
            assert_eq!(labels, want);
        }
    }
}

//! Geometric invariants on synthetic planes (proptest).

use proptest::prelude::*;
use sl_core::{DepthImage, Intrinsics, SensorModel};
use sl_filter::{DepthFilter, RangeKernel};

use super::common::{filters, interior, isas, plane_depth, random_image};

const W: usize = 48;
const H: usize = 36;

fn small_camera() -> Intrinsics {
    // A 48x36 crop with the Kinect's focal length scaled like a 160x120 image.
    Intrinsics::new(W, H, 145.0, 145.0, 23.5, 17.5).unwrap()
}

fn unit(n: [f64; 3]) -> [f64; 3] {
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    [n[0] / l, n[1] / l, n[2] / l]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// A fronto-parallel plane is unchanged everywhere (all values equal, holes or not).
    #[test]
    fn fronto_parallel_plane_is_unchanged(z in 0.5f32..6.0, r in 1usize..5, seed in 0u64..1000) {
        let sensor = SensorModel::kinect_v1();
        let holes = random_image(W, H, 1.0, 2.0, 0.2, seed);
        let data: Vec<f32> = holes.data().iter().map(|&v| if v > 0.0 { z } else { 0.0 }).collect();
        let depth = DepthImage::from_vec(W, H, data).unwrap();
        for f in filters(r, r as f64 / 2.0 + 0.3, &sensor) {
            for isa in isas() {
                let out = f.apply_with_isa(&depth, isa).unwrap();
                for (&a, &b) in out.data().iter().zip(depth.data()) {
                    prop_assert!((a - b).abs() <= 2e-6 * z, "{:?}: {} vs {}", f, a, b);
                }
            }
        }
    }

    /// A linear depth ramp Z = a + b·x + c·y is unchanged in the interior by the depth-domain
    /// filters: the kernels are symmetric and Z(p+δ) − Z(p) is odd in δ, so the ±δ terms cancel.
    #[test]
    fn linear_ramp_is_unchanged_in_the_interior(
        a in 1.0f64..3.0, b in -0.01f64..0.01, c in -0.01f64..0.01, r in 1usize..5,
    ) {
        let sensor = SensorModel::kinect_v1();
        let data: Vec<f32> = (0..W * H).map(|i| (a + b * (i % W) as f64 + c * (i / W) as f64) as f32).collect();
        let depth = DepthImage::from_vec(W, H, data).unwrap();
        for f in filters(r, r as f64 / 2.0 + 0.3, &sensor).into_iter().filter(|f| !matches!(f.range, RangeKernel::Disparity { .. })) {
            for isa in isas() {
                let out = f.apply_with_isa(&depth, isa).unwrap();
                for y in 0..H {
                    for x in 0..W {
                        if interior(x, y, W, H, r) {
                            let (o, z) = (out.data()[y * W + x], depth.data()[y * W + x]);
                            prop_assert!((o - z).abs() <= 2e-6 * z, "{:?} at ({},{}): {} vs {}", f, x, y, o, z);
                        }
                    }
                }
            }
        }
    }

    /// The disparity variant leaves any 3D plane unchanged in the interior: D = fB/Z is affine
    /// in the pixel coordinates for a plane, so its symmetric kernel cancels exactly.
    #[test]
    fn disparity_variant_keeps_any_plane(
        nx in -0.6f64..0.6, ny in -0.6f64..0.6, dist in 0.8f64..3.5, sigma in 0.05f64..2.0, r in 1usize..5,
    ) {
        let sensor = SensorModel::kinect_v1();
        let k = small_camera();
        let n = unit([nx, ny, 1.0]);
        let truth = plane_depth(&k, n, dist);
        prop_assume!(truth.iter().all(|&z| z > 0.3 && z < 8.0));
        let depth = DepthImage::from_vec(W, H, truth.iter().map(|&z| z as f32).collect()).unwrap();
        let f = DepthFilter::disparity(r, r as f64 / 2.0 + 0.3, sigma, &sensor);
        for isa in isas() {
            let out = f.apply_with_isa(&depth, isa).unwrap();
            for y in 0..H {
                for x in 0..W {
                    if interior(x, y, W, H, r) {
                        let (o, z) = (f64::from(out.data()[y * W + x]), truth[y * W + x]);
                        prop_assert!((o - z).abs() <= 2e-6 * z, "({},{}): {} vs {}", x, y, o, z);
                    }
                }
            }
        }
    }

    /// On a tilted 3D plane the depth-domain filters are biased (Z is convex in the pixel
    /// coordinates), but never by more than the bound derived in the crate docs:
    /// `|Ẑ − Z| ≤ Z·Σ ŵ_q t_q²/(1 − t_q²) / r_min` with `Z(q) = Z/(1 + t_q)`; for the Gaussian
    /// the bias equals that sum (and is positive).
    #[test]
    fn tilted_plane_bias_obeys_the_second_order_bound(
        nx in -0.7f64..0.7, ny in -0.7f64..0.7, dist in 0.8f64..3.5, r in 1usize..5, sigma_d in 0.005f64..0.1, k_per_m in 0.002f64..0.02,
    ) {
        let kk = small_camera();
        let n = unit([nx, ny, 1.0]);
        let truth = plane_depth(&kk, n, dist);
        prop_assume!(truth.iter().all(|&z| z > 0.3 && z < 10.0));
        let depth = DepthImage::from_vec(W, H, truth.iter().map(|&z| z as f32).collect()).unwrap();
        let ss = r as f64 / 2.0 + 0.3;
        let cases = [
            DepthFilter::gaussian(r, ss),
            DepthFilter::bilateral(r, ss, sigma_d),
            DepthFilter::adaptive(r, ss, k_per_m),
        ];
        for f in cases {
            let ws = f.spatial_weights();
            let out = f.apply(&depth).unwrap();
            let ri = r as i64;
            let mut worst_ratio = 0.0f64;
            for y in 0..H {
                for x in 0..W {
                    if !interior(x, y, W, H, r) {
                        continue;
                    }
                    let z = truth[y * W + x];
                    let z_in = f64::from(depth.data()[y * W + x]);
                    let sigma_range = match f.range {
                        RangeKernel::Fixed { sigma_d_m } => Some(sigma_d_m),
                        RangeKernel::Adaptive { k_per_m } => Some(k_per_m * z_in * z_in),
                        _ => None,
                    };
                    let (mut sum, mut max_dev, mut i) = (0.0f64, 0.0f64, 0usize);
                    for dy in -ri..=ri {
                        for dx in -ri..=ri {
                            let zq = truth[((y as i64 + dy) as usize) * W + (x as i64 + dx) as usize];
                            let t = z / zq - 1.0;
                            prop_assume!(t.abs() < 0.5);
                            sum += ws[i] * t * t / (1.0 - t * t);
                            max_dev = max_dev.max((zq - z).abs());
                            i += 1;
                        }
                    }
                    let r_min = sigma_range.map_or(1.0, |s| (-max_dev * max_dev / (2.0 * s * s)).exp());
                    let bound = z * sum / r_min;
                    let bias = f64::from(out.data()[y * W + x]) - z;
                    // f32 input rounding (~6e-8·Z per value) and the fast exp (4e-6 relative on
                    // each weight, times the depth spread of the window).
                    let tol = 1e-6 * z + 1e-5 * max_dev;
                    prop_assert!(bias.abs() <= bound + tol, "{:?} at ({},{}): bias {} > bound {}", f, x, y, bias, bound);
                    if f.range == RangeKernel::None {
                        // The Gaussian's bias is exactly the sum (to first order in rounding).
                        prop_assert!((bias - z * sum).abs() <= tol, "gaussian bias {} vs predicted {}", bias, z * sum);
                    }
                    if bound > 0.0 {
                        worst_ratio = worst_ratio.max(bias.abs() / bound);
                    }
                }
            }
            prop_assert!(worst_ratio.is_finite());
        }
    }

    /// Invalid pixels stay invalid and valid ones stay valid, for every method and radius.
    #[test]
    fn invalid_masks_are_preserved(seed in 0u64..10_000, holes in 0.0f64..0.9, r in 1usize..6) {
        let sensor = SensorModel::kinect_v1();
        let depth = random_image(W, H, 0.4, 5.0, holes, seed);
        for f in filters(r, 1.2, &sensor) {
            for isa in isas() {
                let out = f.apply_with_isa(&depth, isa).unwrap();
                for (&o, &i) in out.data().iter().zip(depth.data()) {
                    let valid_in = i > 0.0 && i.is_finite();
                    prop_assert_eq!(o > 0.0 && o.is_finite(), valid_in);
                    if !valid_in {
                        prop_assert_eq!(o, 0.0);
                    }
                }
            }
        }
    }

    /// Where k·Z(p)² equals σ, the adaptive filter reproduces the fixed bilateral with that σ
    /// (the adaptive filter is the bilateral with a per-pixel σ and nothing else).
    #[test]
    fn adaptive_with_constant_k_z2_is_the_fixed_bilateral(seed in 0u64..1000, k_per_m in 0.003f64..0.03) {
        let depth = random_image(24, 18, 0.6, 3.5, 0.1, seed);
        let adaptive = DepthFilter::adaptive(2, 1.0, k_per_m).apply(&depth).unwrap();
        for (i, &z) in depth.data().iter().enumerate().step_by(7) {
            if !(z > 0.0 && z.is_finite()) {
                continue;
            }
            let sigma = k_per_m * f64::from(z) * f64::from(z);
            let fixed = DepthFilter::bilateral(2, 1.0, sigma).apply(&depth).unwrap();
            let (a, b) = (adaptive.data()[i], fixed.data()[i]);
            prop_assert!((a - b).abs() <= 2e-6 * z, "pixel {}: adaptive {} vs bilateral {}", i, a, b);
        }
        // And on a constant-depth image (k·Z² constant everywhere) the whole images agree.
        let flat = DepthImage::from_vec(24, 18, depth.data().iter().map(|&v| if v > 0.0 { 2.0 } else { 0.0 }).collect()).unwrap();
        let a = DepthFilter::adaptive(2, 1.0, k_per_m).apply(&flat).unwrap();
        let b = DepthFilter::bilateral(2, 1.0, 4.0 * k_per_m).apply(&flat).unwrap();
        for (&x, &y) in a.data().iter().zip(b.data()) {
            prop_assert!((x - y).abs() <= 4e-6, "{} vs {}", x, y);
        }
    }
}

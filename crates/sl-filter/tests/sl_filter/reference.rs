//! The fast kernel (every method, every fast path, every instruction set) against the slow
//! reference implementation, on random images with holes and depth edges.

use sl_core::SensorModel;
use sl_filter::reference::filter_reference;

use super::common::{filters, isas, random_image};

#[test]
fn fast_kernel_matches_reference_on_random_images_with_holes() {
    let sensor = SensorModel::kinect_v1();
    let mut checked = 0;
    // Radii 1-3 are the const-radius fast paths, 4 and 6 the runtime-radius path; widths that
    // are and are not multiples of the lane counts (8, 16, 32).
    for (case, &(w, h, r, s)) in [
        (37, 23, 1, 0.8),
        (64, 40, 2, 1.0),
        (33, 17, 3, 1.5),
        (50, 31, 4, 2.0),
        (19, 29, 6, 3.0),
        (5, 4, 3, 1.5),
    ]
    .iter()
    .enumerate()
    {
        let depth = random_image(w, h, 0.5, 4.0, 0.15, 100 + case as u64);
        for f in filters(r, s, &sensor) {
            let want = filter_reference(&f, &depth).unwrap();
            for isa in isas() {
                let got = f.apply_with_isa(&depth, isa).unwrap();
                for (i, (&a, &b)) in got.data().iter().zip(want.data()).enumerate() {
                    let input = depth.data()[i];
                    let valid_in = input > 0.0 && input.is_finite();
                    assert_eq!(a > 0.0, valid_in, "{f:?} {isa:?}: mask differs at {i}");
                    assert_eq!(b > 0.0, valid_in);
                    // Weights carry the fast exp's relative error (4e-6) and f32 rounding: the
                    // output error is at most ~1e-5 of the depth differences in the window
                    // (< 4 m here) plus a few ulp of the depth.
                    let tol = 4.0e-6 * b.abs() + 2.0e-5;
                    assert!(
                        (a - b).abs() <= tol,
                        "{f:?} {isa:?} at ({}, {}): fast {a} vs reference {b}",
                        i % w,
                        i / w
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 10_000);
}

#[test]
fn every_instruction_set_gives_nearly_identical_results() {
    let sensor = SensorModel::kinect_v1();
    let depth = random_image(97, 41, 0.6, 3.5, 0.1, 7);
    for f in filters(3, 1.5, &sensor) {
        let base = f.apply_with_isa(&depth, sl_filter::Isa::Portable).unwrap();
        for isa in isas() {
            let other = f.apply_with_isa(&depth, isa).unwrap();
            for (&a, &b) in base.data().iter().zip(other.data()) {
                assert!((a - b).abs() <= 1e-5, "{isa:?}: {a} vs {b}");
            }
        }
    }
}

#[test]
fn large_holes_and_image_borders_match_the_reference() {
    // Holes wider than the kernel's 32-pixel groups (whose output is skipped as a whole) and
    // than a window, next to valid pixels, on an image wider than one 128-pixel chunk.
    let sensor = SensorModel::kinect_v1();
    let (w, h) = (171, 23);
    let mut depth = random_image(w, h, 0.5, 4.0, 0.05, 42);
    for y in 3..15 {
        for x in 20..95 {
            depth.data_mut()[y * w + x] = 0.0;
        }
    }
    for x in 100..171 {
        depth.data_mut()[20 * w + x] = f32::NAN;
    }
    for r in 1..=3 {
        for f in filters(r, 0.5 * r as f64, &sensor) {
            let want = filter_reference(&f, &depth).unwrap();
            for isa in isas() {
                let got = f.apply_with_isa(&depth, isa).unwrap();
                for (i, (&a, &b)) in got.data().iter().zip(want.data()).enumerate() {
                    let input = depth.data()[i];
                    assert_eq!(
                        a > 0.0,
                        input > 0.0 && input.is_finite(),
                        "{f:?} {isa:?} at {i}"
                    );
                    assert!(
                        (a - b).abs() <= 4.0e-6 * b.abs() + 2.0e-5,
                        "{f:?} {isa:?} at ({}, {}): fast {a} vs reference {b}",
                        i % w,
                        i / w
                    );
                }
            }
        }
    }
}

#[test]
fn the_disc_window_skips_the_corners_and_the_square_does_not() {
    // A flat 1 m frame with one pixel 1 cm deeper at offset (2, 2) (corner of the 5x5 square,
    // outside the radius-2 disc) and one at (0, 2) (inside both) of the centre (10, 10).
    let sensor = SensorModel::kinect_v1();
    let (w, h) = (21, 21);
    let mut depth = sl_core::DepthImage::from_vec(w, h, vec![1.0; w * h]).unwrap();
    depth.data_mut()[12 * w + 12] = 1.01;
    for f in filters(2, 1.0, &sensor) {
        for isa in isas() {
            let out = f.apply_with_isa(&depth, isa).unwrap();
            let centre = out.data()[10 * w + 10];
            match f.window {
                sl_filter::Window::Disc => assert_eq!(centre, 1.0, "{f:?} {isa:?}"),
                sl_filter::Window::Square => assert!(centre > 1.0, "{f:?} {isa:?}: {centre}"),
            }
        }
    }
    depth.data_mut()[12 * w + 12] = 1.0;
    depth.data_mut()[12 * w + 10] = 1.01;
    for f in filters(2, 1.0, &sensor) {
        for isa in isas() {
            let centre = f.apply_with_isa(&depth, isa).unwrap().data()[10 * w + 10];
            assert!(centre > 1.0, "{f:?} {isa:?}: {centre}");
        }
    }
}

//! Property tests of sl-core's geometry.

// Test code: a panic is a failed test.
#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use nalgebra::{Isometry3, Point3, Vector3};
use proptest::prelude::*;
use sl_core::{Camera, DepthImage, Intrinsics, SensorModel, pose_from_matrix, pose_to_matrix};

fn camera() -> impl Strategy<Value = (Intrinsics, SensorModel)> {
    (
        400.0f64..700.0,
        0.9f64..1.1,
        -20.0f64..20.0,
        -20.0f64..20.0,
        0.05f64..0.12,
    )
        .prop_map(|(f, aspect, dcx, dcy, b)| {
            let k = Intrinsics {
                width: 64,
                height: 48,
                fx: f,
                fy: f * aspect,
                cx: 31.5 + dcx,
                cy: 23.5 + dcy,
            };
            (
                k,
                SensorModel::new(f, b, 8, 0.07).unwrap_or_else(|e| panic!("{e}")),
            )
        })
}

/// A plane n·X = d in front of the camera, with its normal within 60° of the optical axis so
/// that it covers the image at positive depth.
fn plane() -> impl Strategy<Value = (Vector3<f64>, f64)> {
    (-0.8f64..0.8, -0.8f64..0.8, 0.6f64..4.0)
        .prop_map(|(a, b, d)| (Vector3::new(a, b, 1.0).normalize(), d))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Paper eq. 14: on a 3D plane the disparity is affine in the pixel coordinates. We render
    /// a plane by ray casting, convert it to disparity and check that an affine function fitted
    /// to three corners predicts every pixel to float precision.
    #[test]
    fn disparity_of_a_plane_is_affine_in_pixels((k, s) in camera(), (n, d) in plane()) {
        let depth: Vec<f32> = (0..k.height)
            .flat_map(|y| (0..k.width).map(move |x| (x, y)))
            .map(|(x, y)| {
                let r = k.ray(x as f64, y as f64);
                let t = d / n.dot(&r);
                if t > 0.0 { t as f32 } else { 0.0 }
            })
            .collect();
        prop_assume!(depth.iter().all(|&z| z > 0.1 && z < 50.0));
        let img = DepthImage::from_vec(k.width, k.height, depth).unwrap_or_else(|e| panic!("{e}"));
        let disp = img.to_disparity(&s);
        // Analytic coefficients: D = fB/Z and 1/Z = n·ray/d, so
        // D = (fB/d)·(n_x (x−cx)/fx + n_y (y−cy)/fy + n_z).
        let fb = s.fb();
        let ax = fb / d * n.x / k.fx;
        let ay = fb / d * n.y / k.fy;
        let c = fb / d * (n.z - n.x * k.cx / k.fx - n.y * k.cy / k.fy);
        let max_d = disp.data().iter().copied().fold(0.0f32, f32::max) as f64;
        for y in 0..k.height {
            for x in 0..k.width {
                let got = f64::from(disp.get(x, y).unwrap_or(0.0));
                let want = ax * x as f64 + ay * y as f64 + c;
                prop_assert!((got - want).abs() <= 1e-5 * max_d.max(1.0), "({x},{y}): {got} vs {want}");
            }
        }
    }

    #[test]
    fn project_inverts_back_project(
        (k, _s) in camera(),
        x in 0.0f64..64.0,
        y in 0.0f64..48.0,
        z in 0.3f64..10.0,
    ) {
        let p = k.back_project(x, y, z);
        let (u, v) = k.project(&p).unwrap_or((f64::NAN, f64::NAN));
        prop_assert!((u - x).abs() < 1e-9 && (v - y).abs() < 1e-9);
        prop_assert!((k.ray(x, y) * z - p.coords).norm() < 1e-9);
    }

    #[test]
    fn depth_disparity_round_trip((_k, s) in camera(), z in 0.3f64..10.0) {
        let d = s.depth_to_disparity(z);
        prop_assert!((s.disparity_to_depth(d) - z).abs() < 1e-9 * z);
        // σ_Z is the magnitude of ∂Z/∂D times σ_D.
        prop_assert!((s.sigma_z(z) - s.dz_dd(z).abs() * s.sigma_d_px).abs() < 1e-12);
    }

    #[test]
    fn pose_matrix_round_trip(
        t in prop::array::uniform3(-5.0f64..5.0),
        r in prop::array::uniform3(-3.0f64..3.0),
        p in prop::array::uniform3(-2.0f64..2.0),
    ) {
        let pose = Isometry3::new(Vector3::from(t), Vector3::from(r));
        let back = pose_from_matrix(&pose_to_matrix(&pose)).unwrap_or_else(|e| panic!("{e}"));
        let q = Point3::from(p);
        prop_assert!((pose * q - back * q).norm() < 1e-9);
    }
}

/// A camera resampled from its sensor keeps the sensor's noise model and says how its pixels
/// relate to the sensor's.
#[test]
fn a_resampled_camera_keeps_its_sensor() {
    let cam = Camera::kinect_v1();
    assert_eq!(cam.pixels_per_sensor_pixel(), 1.0);
    let half = cam.resampled(0.5).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((half.intrinsics.width, half.intrinsics.height), (320, 240));
    assert_eq!(half.intrinsics.fx, cam.intrinsics.fx / 2.0);
    assert_eq!(half.sensor, cam.sensor);
    assert_eq!(half.pixels_per_sensor_pixel(), 0.5);
    assert_eq!(half.sensor.sigma_z(2.0), cam.sensor.sigma_z(2.0));
    assert!(cam.resampled(0.0).is_err());
    assert!(cam.resampled(f64::NAN).is_err());
}

//! The realistic sensor's drop-out of weak returns (`RealisticNoise::min_return`): dark and far
//! surfaces lose their depth where `ρ·cos θ / r²` falls below the bound, and nothing changes
//! while the bound is 0.

use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{CameraToWorld, Intrinsics};
use sl_noise::sim::{KinectSimulator, NoiseModel, Plane, Quad, RealisticNoise, Scene};

/// The Kinect with the realistic model and a weak-return bound of `min_return`.
fn sensor(min_return: f64) -> KinectSimulator {
    let mut noise = RealisticNoise::default();
    noise.min_return = min_return;
    KinectSimulator::kinect_v1().with_noise(NoiseModel::Realistic(noise))
}

/// A white wall facing the camera at `z_wall` and a board `z_board` away, 60 × 60 cm, of
/// reflectance `rho` (labels: wall 1, board 2).
fn dark_board(z_wall: f64, z_board: f64, rho: f64) -> Scene {
    let mut scene = Scene::new();
    scene.add(Plane::new(Point3::new(0.0, 0.0, z_wall), Vector3::z()).unwrap());
    let board = scene.add(
        Quad::new(
            Point3::new(0.0, 0.0, z_board),
            Vector3::new(0.3, 0.0, 0.0),
            Vector3::new(0.0, 0.3, 0.0),
        )
        .unwrap(),
    );
    scene.set_reflectance(board, rho).unwrap();
    scene
}

/// Shares of the pixels of surface `label` that have depth.
fn valid_share(sim: &KinectSimulator, scene: &Scene, label: u16) -> f64 {
    let k = Intrinsics::kinect_v1();
    let f = sim.simulate(scene, &k, &CameraToWorld::identity(), 3);
    let (mut n, mut valid) = (0usize, 0usize);
    for (l, z) in f.labels.data().iter().zip(f.depth.data()) {
        if *l == label {
            n += 1;
            valid += usize::from(*z > 0.0);
        }
    }
    assert!(n > 1000, "surface {label} covers {n} pixels");
    valid as f64 / n as f64
}

#[test]
fn a_dark_board_drops_out_beyond_the_distance_its_reflectance_allows() {
    // ρ = 0.1 and a bound of 0.04: the board returns enough up to √(0.1 / 0.04) = 1.58 m.
    let sim = sensor(0.04);
    let near = dark_board(3.0, 1.3, 0.1);
    let far = dark_board(3.0, 1.9, 0.1);
    assert!(valid_share(&sim, &near, 2) > 0.95);
    assert_eq!(valid_share(&sim, &far, 2), 0.0);
    // The white wall behind it (1 / 3² = 0.11) keeps its depth, as without the bound (the
    // board's projector shadow aside).
    let wall = valid_share(&sim, &far, 1);
    assert_eq!(wall, valid_share(&sensor(0.0), &far, 1));
    assert!(wall > 0.9);
    // A white board at the same distance keeps its depth.
    assert!(valid_share(&sim, &dark_board(3.0, 1.9, 1.0), 2) > 0.95);
}

#[test]
fn the_valid_disc_on_a_wall_follows_cos_cubed_over_depth_squared() {
    // A white wall facing the camera at Z: a pixel θ off the axis sees it at r = Z / cos θ
    // under the incidence θ, so it returns cos³θ / Z². With the bound m it keeps its depth
    // while cos θ ≥ (m·Z²)^(1/3): at Z = 3.8 m and m = 0.0625, θ ≤ 15.2°, a disc of about
    // 585·tan 15.2° = 159 px around the principal point.
    let (z, m) = (3.8, 0.0625);
    let mut scene = Scene::new();
    scene.add(Plane::new(Point3::new(0.0, 0.0, z), Vector3::z()).unwrap());
    let k = Intrinsics::kinect_v1();
    let f = sensor(m).simulate(&scene, &k, &CameraToWorld::identity(), 5);
    let theta = (m * z * z).cbrt().acos();
    let (w, h) = (f.depth.width(), f.depth.height());
    let (mut inside, mut outside) = ((0usize, 0usize), (0usize, 0usize));
    for y in 0..h {
        for x in 0..w {
            let ray = k.ray(x as f64, y as f64);
            let off_axis = (ray.x * ray.x + ray.y * ray.y).sqrt().atan();
            let valid = f.depth.data()[y * w + x] > 0.0;
            if off_axis < theta - 0.01 {
                inside.0 += 1;
                inside.1 += usize::from(valid);
            } else if off_axis > theta + 0.01 {
                outside.0 += 1;
                outside.1 += usize::from(valid);
            }
        }
    }
    assert!(inside.0 > 10_000 && outside.0 > 10_000);
    assert_eq!(
        inside.1, inside.0,
        "every pixel inside the disc keeps its depth"
    );
    assert_eq!(outside.1, 0, "no pixel outside the disc keeps its depth");
}

#[test]
fn without_the_bound_reflectance_changes_nothing() {
    let k = Intrinsics::kinect_v1();
    let sim = sensor(0.0);
    let dark = dark_board(3.0, 1.9, 0.05);
    let white = dark_board(3.0, 1.9, 1.0);
    let pose = CameraToWorld::identity();
    assert_eq!(
        sim.simulate(&dark, &k, &pose, 9).depth,
        sim.simulate(&white, &k, &pose, 9).depth
    );
    // And the default model has no bound.
    assert_eq!(RealisticNoise::default().min_return, 0.0);
}

#[test]
fn bad_bounds_and_reflectances_are_errors() {
    for bad in [-0.1, f64::NAN, f64::INFINITY] {
        let mut noise = RealisticNoise::default();
        noise.min_return = bad;
        assert!(noise.validate().is_err(), "min_return {bad}");
    }
    let mut scene = dark_board(3.0, 1.9, 0.5);
    assert_eq!(scene.reflectance(2), 0.5);
    assert_eq!(scene.reflectance(0), 1.0);
    assert_eq!(scene.reflectance(7), 1.0);
    for bad in [-0.01, 1.01, f64::NAN] {
        assert!(scene.set_reflectance(2, bad).is_err(), "reflectance {bad}");
    }
    assert!(scene.set_reflectance(0, 0.5).is_err());
    assert!(scene.set_reflectance(3, 0.5).is_err());
    assert_eq!(scene.reflectance(2), 0.5);
    // Absurd numbers are printed compactly, not as 300-digit decimals.
    let mut noise = RealisticNoise::default();
    noise.min_return = -1e300;
    let err = noise.validate().unwrap_err().to_string();
    assert!(err.contains("min_return -1e300 must be"), "{err}");
    let err = scene.set_reflectance(2, 1e300).unwrap_err().to_string();
    assert!(err.contains("reflectance 1e300 of surface 2"), "{err}");
    let err = scene.set_reflectance(2, 1.5).unwrap_err().to_string();
    assert!(err.contains("reflectance 1.5 of surface 2"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 24,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("proptest-regressions/sl_noise.txt"))),
        ..ProptestConfig::default()
    })]

    /// On a wall of reflectance `ρ` facing the camera at `Z`, a pixel `θ` off the axis keeps its
    /// depth exactly when `ρ·cos³θ ≥ m·Z²` (pixels within 0.1 % of the boundary not judged).
    #[test]
    fn a_pixel_keeps_its_depth_exactly_when_its_return_reaches_the_bound(
        z in 1.0f64..4.5,
        rho in 0.05f64..1.0,
        m in 0.005f64..0.2,
    ) {
        let mut scene = Scene::new();
        let wall = scene.add(Plane::new(Point3::new(0.0, 0.0, z), Vector3::z()).unwrap());
        scene.set_reflectance(wall, rho).unwrap();
        let k = Intrinsics::kinect_v1().scaled(0.25).unwrap();
        let f = sensor(m).simulate(&scene, &k, &CameraToWorld::identity(), 11);
        let w = f.depth.width();
        for (i, d) in f.depth.data().iter().enumerate() {
            let ray = k.ray((i % w) as f64, (i / w) as f64);
            let cos = 1.0 / ray.norm();
            let (signal, bound) = (rho * cos.powi(3), m * z * z);
            if (signal - bound).abs() <= 1e-3 * bound {
                continue;
            }
            prop_assert_eq!(*d > 0.0, signal >= bound, "pixel {} of {}", i, w);
        }
    }
}

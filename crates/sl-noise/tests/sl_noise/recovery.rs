//! Simulate → analyze: the analysis recovers the simulator's f·B within 1 % and its sub-pixel
//! steps exactly, on named scenes, several seeds, and random planes (proptest).

use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{Intrinsics, SensorModel};
use sl_noise::analysis::{AnalysisConfig, analyze, analyze_with};
use sl_noise::sim::{KinectSimulator, Plane, Scene, look_at, named_scene};

fn check_recovery(sim: &KinectSimulator, depth: &sl_core::DepthImage, what: &str) {
    let a = analyze(depth, &sim.sensor).unwrap();
    let fb = a.fb_px_m.unwrap();
    let rel = fb / sim.sensor.fb() - 1.0;
    eprintln!(
        "{what}: unique {} slope {:.4} robust {:.4} fB {fb:.4} ({:+.4} %) sub-pixel {:?} nominal {:?}",
        a.unique_depths,
        a.slope,
        a.slope_robust,
        100.0 * rel,
        a.subpixel_steps,
        a.subpixel_steps_nominal
    );
    assert!(rel.abs() < 0.01, "{what}: fB {fb} vs {}", sim.sensor.fb());
    assert_eq!(a.subpixel_steps, Some(sim.sensor.subpixel_steps), "{what}");
    assert_eq!(
        a.subpixel_steps_nominal,
        Some(sim.sensor.subpixel_steps),
        "{what}"
    );
    assert!((1.8..=2.2).contains(&a.slope), "{what}: slope {}", a.slope);
}

#[test]
fn named_scenes_recover_fb_and_steps() {
    for (name, seed) in [
        ("floor", 1),
        ("floor", 2),
        ("corridor", 3),
        ("boxes", 4),
        ("figure-walls", 5),
    ] {
        let ns = named_scene(name).unwrap();
        let k = ns.intrinsics.scaled(0.5).unwrap();
        for sim in [
            KinectSimulator::kinect_v1().white(),
            KinectSimulator::paper_kinect().white(),
        ] {
            let f = sim.simulate(&ns.scene, &k, &ns.pose, seed);
            check_recovery(
                &sim,
                &f.depth,
                &format!("{name} seed {seed} f {}", sim.sensor.focal_px),
            );
        }
    }
}

#[test]
fn other_sensors_are_recovered_too() {
    // A wider baseline and finer sub-pixel steps: the count follows the simulator.
    let ns = named_scene("floor").unwrap();
    let k = ns.intrinsics.scaled(0.5).unwrap();
    for (baseline_m, steps) in [(0.1, 8), (0.075, 4), (0.05, 16)] {
        let sim = KinectSimulator::with_sensor(SensorModel {
            baseline_m,
            subpixel_steps: steps,
            ..SensorModel::kinect_v1()
        })
        .white();
        let f = sim.simulate(&ns.scene, &k, &ns.pose, 11);
        check_recovery(&sim, &f.depth, &format!("B {baseline_m} q {steps}"));
    }
}

#[test]
fn dropout_and_small_frames() {
    let ns = named_scene("floor").unwrap();
    let k = ns.intrinsics.scaled(0.25).unwrap();
    let sim = KinectSimulator {
        dropout: 0.05,
        ..KinectSimulator::kinect_v1().white()
    };
    let f = sim.simulate(&ns.scene, &k, &ns.pose, 9);
    check_recovery(&sim, &f.depth, "floor 160x120 dropout 5 %");
    // Without q the analysis falls back to the nominal f·B for the count.
    let mut opts = AnalysisConfig::for_sensor(&sim.sensor);
    opts.subpixel_steps = None;
    let a = analyze_with(&f.depth, &opts).unwrap();
    assert_eq!(a.fb_used_px_m, Some(sim.sensor.fb()));
    assert_eq!(a.subpixel_steps, Some(8));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 16,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("proptest-regressions/sl_noise.txt"))),
        ..ProptestConfig::default()
    })]

    /// Random tilted planes seen by random cameras: simulate → analyze recovers f·B within 1 %
    /// and the sub-pixel steps exactly.
    #[test]
    fn random_planes_recover_fb(
        height in 0.5f64..1.2,
        pitch_deg in 25.0f64..40.0,
        roll in -0.3f64..0.3,
        focal in 540.0f64..600.0,
        baseline in 0.06f64..0.1,
        seed in 0u64..1_000_000,
    ) {
        let mut scene = Scene::new();
        scene.add(Plane::new(Point3::origin(), Vector3::new(roll, 0.0, 1.0)).unwrap());
        let pitch = pitch_deg.to_radians();
        let eye = Point3::new(0.0, 0.0, height);
        let pose = look_at(eye, eye + Vector3::new(0.0, pitch.cos(), -pitch.sin()), Vector3::z()).unwrap();
        let k = Intrinsics::new(160, 120, focal / 4.0, focal / 4.0, 79.5, 59.5).unwrap();
        let sim = KinectSimulator::with_sensor(SensorModel {
            focal_px: focal,
            baseline_m: baseline,
            ..SensorModel::kinect_v1()
        }).white();
        let f = sim.simulate(&scene, &k, &pose, seed);
        let a = analyze(&f.depth, &sim.sensor).unwrap();
        let fb = a.fb_px_m.unwrap();
        prop_assert!((fb / sim.sensor.fb() - 1.0).abs() < 0.01, "fB {} vs {}", fb, sim.sensor.fb());
        prop_assert_eq!(a.subpixel_steps, Some(8));
    }
}

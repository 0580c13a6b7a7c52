//! Geometry invariants of every primitive (proptest): hits lie on the surface, normals are unit
//! and face the ray, distances are 1-Lipschitz and zero on the surface, the scene's nearest hit
//! is the minimum over its surfaces.

use proptest::prelude::*;
use proptest::test_runner::FileFailurePersistence;
use sl_core::nalgebra::{Point3, Rotation3, Vector3};
use sl_noise::sim::{Cuboid, Cylinder, Plane, Quad, ReliefPlate, Scene, Sphere, Surface};

fn v3() -> impl Strategy<Value = Vector3<f64>> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

/// All primitives, built around a random centre with random orientation.
fn primitives(
    c: Vector3<f64>,
    axis: Vector3<f64>,
    angle: f64,
) -> Vec<(&'static str, Box<dyn Surface>)> {
    let centre = Point3::from(c) + Vector3::new(0.0, 0.0, 3.0);
    let rot = Rotation3::from_scaled_axis(axis * angle);
    let (u, v) = (
        rot * Vector3::new(0.4, 0.0, 0.0),
        rot * Vector3::new(0.0, 0.3, 0.0),
    );
    vec![
        (
            "plane",
            Box::new(Plane::new(centre, rot * Vector3::z()).unwrap()),
        ),
        ("quad", Box::new(Quad::new(centre, u, v).unwrap())),
        ("sphere", Box::new(Sphere::new(centre, 0.35).unwrap())),
        (
            "cuboid",
            Box::new(Cuboid::new(centre, Vector3::new(0.3, 0.2, 0.4), rot).unwrap()),
        ),
        (
            "cylinder",
            Box::new(Cylinder::new(centre, rot * Vector3::y(), 0.2, 0.3, true).unwrap()),
        ),
        (
            "open cylinder",
            Box::new(Cylinder::new(centre, rot * Vector3::x(), 0.25, 0.2, false).unwrap()),
        ),
        (
            "relief",
            Box::new(ReliefPlate::new(centre, u, v, 0.004, 0.05).unwrap()),
        ),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 32,
        failure_persistence: Some(Box::new(FileFailurePersistence::Direct("proptest-regressions/sl_noise.txt"))),
        ..ProptestConfig::default()
    })]

    #[test]
    fn hits_lie_on_surfaces(c in v3(), axis in v3(), angle in 0.0f64..3.0, target in v3(), origin in v3()) {
        let o = Point3::from(origin * 0.5);
        for (name, s) in primitives(c * 0.3, axis, angle) {
            let dir = Point3::from(c * 0.3 + target * 0.4) + Vector3::new(0.0, 0.0, 3.0) - o;
            if let Some(hit) = s.intersect(&o, &dir) {
                let p = o + dir * hit.t;
                prop_assert!(hit.t > 0.0, "{}", name);
                prop_assert!(s.distance(&p) < 1e-7, "{}: distance {} at the hit", name, s.distance(&p));
                prop_assert!((hit.normal.norm() - 1.0).abs() < 1e-9, "{}", name);
                prop_assert!(hit.normal.dot(&dir) <= 1e-12, "{}: normal faces away", name);
                // Nothing in front of the hit: the distance along the ray before it is positive.
                let before = o + dir * (hit.t * 0.5);
                prop_assert!(s.distance(&before) > 0.0, "{}", name);
            }
        }
    }

    #[test]
    fn distances_are_lipschitz(c in v3(), axis in v3(), angle in 0.0f64..3.0, p in v3(), q in v3()) {
        let shift = Vector3::new(0.0, 0.0, 3.0);
        let (p, q) = (Point3::from(p + shift), Point3::from(q + shift));
        for (name, s) in primitives(c * 0.3, axis, angle) {
            let (dp, dq) = (s.distance(&p), s.distance(&q));
            prop_assert!(dp >= 0.0 && dq >= 0.0, "{}", name);
            // The relief's distance is an upper bound from a local search: allow its tolerance.
            let tol = if name == "relief" { 0.008 } else { 1e-9 };
            prop_assert!((dp - dq).abs() <= (p - q).norm() + tol, "{}: |{} - {}| > {}", name, dp, dq, (p - q).norm());
        }
    }

    #[test]
    fn scene_trace_is_the_nearest_hit(c in v3(), axis in v3(), angle in 0.0f64..3.0, target in v3()) {
        let mut scene = Scene::new();
        let prims = primitives(c * 0.3, axis, angle);
        for (_, s) in primitives(c * 0.3, axis, angle) {
            scene.add(s);
        }
        let o = Point3::origin();
        let dir = Point3::from(target * 0.5) + Vector3::new(0.0, 0.0, 3.0) - o;
        let best = prims
            .iter()
            .enumerate()
            .filter_map(|(i, (_, s))| s.intersect(&o, &dir).map(|h| (i + 1, h.t)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match (scene.trace(&o, &dir), best) {
            (Some((label, hit)), Some((i, t))) => {
                prop_assert_eq!(usize::from(label), i);
                prop_assert_eq!(hit.t, t);
            }
            (None, None) => {}
            (a, b) => prop_assert!(false, "trace {:?} vs {:?}", a.map(|x| x.0), b),
        }
    }
}

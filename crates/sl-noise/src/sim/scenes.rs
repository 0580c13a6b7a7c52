//! Named ground-truth scenes (for `sldepth simulate --scene NAME`, validation and tests).
//!
//! The world frame of every named scene is Z-up (x east, y north, z up, metres), with the floor,
//! where there is one, at z = 0. The camera is a `kinect-v1` (640×480, f = 580 px) placed with
//! [`look_at`].

use nalgebra::{Point3, Rotation3, UnitQuaternion, Vector3};
use sl_core::{CameraToWorld, Intrinsics};

use crate::error::{NoiseError, Result};
use crate::sim::primitives::{Cylinder, Plane, Quad, Sphere};
use crate::sim::relief::ReliefPlate;
use crate::sim::scene::{Scene, look_at};

/// Names accepted by [`named_scene`].
pub const SCENE_NAMES: &[&str] = &[
    "floor",
    "wall",
    "figure-walls",
    "three-planes",
    "corridor",
    "relief",
    "boxes",
];

/// A named scene with its camera.
#[derive(Debug)]
pub struct NamedScene {
    /// The scene name (one of [`SCENE_NAMES`]).
    pub name: &'static str,
    /// One-line description.
    pub description: &'static str,
    /// The surfaces.
    pub scene: Scene,
    /// Camera-to-world pose of the camera.
    pub pose: CameraToWorld,
    /// The camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Human-readable names of the labels (e.g. `(2, "plane B (book)")`).
    pub label_names: Vec<(u16, String)>,
}

impl NamedScene {
    /// The name given to `label`, if any.
    pub fn label_name(&self, label: u16) -> Option<&str> {
        self.label_names
            .iter()
            .find(|(l, _)| *l == label)
            .map(|(_, n)| n.as_str())
    }
}

/// Builds the scene `name` (see [`SCENE_NAMES`]):
///
/// * `floor` — a floor seen from 0.70 m height with the camera pitched 32° down: depths from
///   about 0.8 m (bottom rows) to 3.9 m (top rows), like the paper's Figure 1 floor scan.
/// * `wall` — a fronto-parallel wall at exactly 2 m.
/// * `figure-walls` — a standing figure (head, torso, arms) about 1 m away before two walls
///   meeting at 90° in a corner 3 m ahead, on a floor (the paper's Figure 4).
/// * `three-planes` — a table top (plane A) about 0.6 m away, a book on it whose top (plane B)
///   is 1 cm above the table, and a wall (plane C) about 3 m away (the paper's Figure 8).
/// * `corridor` — a model corridor 0.8 m wide and 0.6 m high: floor, ceiling and two walls
///   from 0.6 to 4.5 m, closed by an end wall at 4.5 m (visible depths ≈ 0.72–4.5 m).
/// * `relief` — a 0.6 m plate with 3 mm sinusoidal relief (wavelength 5 cm) 1 m away, tilted
///   20°, before a wall at 1.6 m.
/// * `boxes` — three boxes, a sphere and a cylinder on a floor, 1.3–2.8 m away, before a
///   back wall 3.6 m ahead.
pub fn named_scene(name: &str) -> Result<NamedScene> {
    let k = Intrinsics::kinect_v1();
    let mut names = Vec::new();
    let mut scene = Scene::new();
    let mut label = |l: u16, n: &str| names.push((l, n.to_string()));
    let up = Vector3::z();
    let (description, pose): (&'static str, CameraToWorld) = match name {
        "floor" => {
            let l = scene.add(Plane::new(Point3::origin(), up)?);
            label(l, "floor");
            let pitch = 32f64.to_radians();
            let eye = Point3::new(0.0, 0.0, 0.70);
            let target = eye + Vector3::new(0.0, pitch.cos(), -pitch.sin());
            (
                "tilted floor, depths ~0.8-3.9 m (paper Fig. 1)",
                look_at(eye, target, up)?,
            )
        }
        "wall" => {
            let l = scene.add(Plane::new(Point3::new(0.0, 2.0, 0.0), Vector3::y())?);
            label(l, "wall");
            let eye = Point3::new(0.0, 0.0, 1.0);
            (
                "fronto-parallel wall at 2 m",
                look_at(eye, eye + Vector3::y(), up)?,
            )
        }
        "figure-walls" => {
            // Walls meeting at 90° in a corner 3 m straight ahead, each at 45° to the view.
            let corner = Point3::new(0.0, 3.0, 0.0);
            let l = scene.add(Plane::new(corner, Vector3::new(1.0, -1.0, 0.0))?);
            label(l, "left wall");
            let l = scene.add(Plane::new(corner, Vector3::new(-1.0, -1.0, 0.0))?);
            label(l, "right wall");
            let l = scene.add(Plane::new(Point3::origin(), up)?);
            label(l, "floor");
            // The figure, 1.1 m ahead of a camera at 1.3 m height and 0.3 m left of the view
            // axis, so that the corner stays visible beside it.
            let (fx, fy) = (-0.3, 1.1);
            let l = scene.add(Sphere::new(Point3::new(fx, fy, 1.62), 0.11)?);
            label(l, "head");
            let torso = scene.add_cuboid(
                Point3::new(fx, fy, 1.2),
                Vector3::new(0.2, 0.1, 0.3),
                UnitQuaternion::identity(),
            );
            for (i, t) in torso.iter().enumerate() {
                label(*t, &format!("torso face {i}"));
            }
            for (side, name) in [(-1.0, "left arm"), (1.0, "right arm")] {
                let l = scene.add(Cylinder::new(
                    Point3::new(fx + side * 0.27, fy, 1.15),
                    up,
                    0.05,
                    0.3,
                    true,
                )?);
                label(l, name);
            }
            let eye = Point3::new(0.0, 0.0, 1.3);
            let target = Point3::new(0.0, 3.0, 1.25);
            (
                "a figure ~1 m away before two walls meeting at 90° at ~3 m (paper Fig. 4)",
                look_at(eye, target, up)?,
            )
        }
        "three-planes" => {
            // Table top (z = 0) spanning y ∈ [0.1, 0.9]; the book's top 1 cm above it.
            let l = scene.add(Quad::new(
                Point3::new(0.0, 0.5, 0.0),
                Vector3::new(0.6, 0.0, 0.0),
                Vector3::new(0.0, 0.4, 0.0),
            )?);
            label(l, "plane A (table)");
            let book = scene.add_cuboid(
                Point3::new(0.05, 0.36, 0.005),
                Vector3::new(0.12, 0.09, 0.005),
                Rotation3::from_axis_angle(&Vector3::z_axis(), 0.2),
            );
            for (i, b) in book.iter().enumerate() {
                let n = if i == 4 {
                    "plane B (book top)".to_string()
                } else {
                    format!("book face {i}")
                };
                label(*b, &n);
            }
            let l = scene.add(Plane::new(Point3::new(0.0, 3.2, 0.0), Vector3::y())?);
            label(l, "plane C (wall)");
            // 0.52 m above the table, pitched 45° down: the book (≈0.6 m away) sits just below
            // the image centre and the table ends before the top rows, which see the wall.
            let eye = Point3::new(0.0, 0.0, 0.52);
            let target = Point3::new(0.0, 0.52, 0.0);
            (
                "table (A) and book (B) 1 cm apart ~0.6 m away, wall (C) ~3 m away (paper Fig. 8)",
                look_at(eye, target, up)?,
            )
        }
        "corridor" => {
            let (y0, y1, half_w, height) = (0.6, 4.5, 0.4, 0.6);
            let (yc, hy) = ((y0 + y1) / 2.0, (y1 - y0) / 2.0);
            let along = Vector3::new(0.0, hy, 0.0);
            let across = Vector3::new(half_w, 0.0, 0.0);
            let vertical = Vector3::new(0.0, 0.0, height / 2.0);
            let parts = [
                (
                    "floor",
                    Quad::new(Point3::new(0.0, yc, 0.0), across, along)?,
                ),
                (
                    "ceiling",
                    Quad::new(Point3::new(0.0, yc, height), across, along)?,
                ),
                (
                    "left wall",
                    Quad::new(Point3::new(-half_w, yc, height / 2.0), along, vertical)?,
                ),
                (
                    "right wall",
                    Quad::new(Point3::new(half_w, yc, height / 2.0), along, vertical)?,
                ),
                (
                    "end wall",
                    Quad::new(Point3::new(0.0, y1, height / 2.0), across, vertical)?,
                ),
            ];
            for (n, q) in parts {
                let l = scene.add(q);
                label(l, n);
            }
            let eye = Point3::new(0.0, 0.0, height / 2.0);
            (
                "model corridor: floor, ceiling, two walls from 0.6 to 4.5 m, end wall",
                look_at(eye, eye + Vector3::y(), up)?,
            )
        }
        "relief" => {
            let tilt = 20f64.to_radians();
            let centre = Point3::new(0.0, 1.0, 1.0);
            // Turned 20° about the vertical; normal u × v = (sin 20°, −cos 20°, 0)·0.09 faces the
            // camera (−y).
            let hu = Vector3::new(0.3 * tilt.cos(), 0.3 * tilt.sin(), 0.0);
            let hv = Vector3::new(0.0, 0.0, 0.3);
            let plate = ReliefPlate::new(centre, hu, hv, 0.003, 0.05)?;
            let l = scene.add(plate);
            label(l, "relief plate");
            let l = scene.add(Plane::new(Point3::new(0.0, 1.6, 0.0), Vector3::y())?);
            label(l, "wall");
            let eye = Point3::new(0.0, 0.0, 1.0);
            (
                "plate with 3 mm relief (λ 5 cm) at 1 m, tilted 20°, wall at 1.6 m",
                look_at(eye, eye + Vector3::y(), up)?,
            )
        }
        "boxes" => {
            let l = scene.add(Plane::new(Point3::origin(), up)?);
            label(l, "floor");
            let l = scene.add(Plane::new(Point3::new(0.0, 3.6, 0.0), Vector3::y())?);
            label(l, "back wall");
            let boxes = [
                (
                    Point3::new(-0.4, 1.8, 0.2),
                    Vector3::new(0.2, 0.15, 0.2),
                    0.3,
                ),
                (
                    Point3::new(0.35, 2.2, 0.15),
                    Vector3::new(0.25, 0.2, 0.15),
                    -0.5,
                ),
                (
                    Point3::new(0.0, 2.9, 0.35),
                    Vector3::new(0.3, 0.3, 0.35),
                    0.1,
                ),
            ];
            for (i, (c, h, yaw)) in boxes.into_iter().enumerate() {
                let faces =
                    scene.add_cuboid(c, h, Rotation3::from_axis_angle(&Vector3::z_axis(), yaw));
                for (j, f) in faces.iter().enumerate() {
                    label(*f, &format!("box {i} face {j}"));
                }
            }
            let l = scene.add(Sphere::new(Point3::new(0.1, 1.5, 0.12), 0.12)?);
            label(l, "sphere");
            let l = scene.add(Cylinder::new(
                Point3::new(-0.55, 2.6, 0.25),
                up,
                0.08,
                0.25,
                true,
            )?);
            label(l, "cylinder");
            let eye = Point3::new(0.0, 0.0, 1.0);
            (
                "three boxes, a sphere and a cylinder on a floor, 1.3-2.8 m away",
                look_at(eye, Point3::new(0.0, 2.2, 0.1), up)?,
            )
        }
        _ => {
            return Err(NoiseError::UnknownScene {
                name: name.to_string(),
                known: SCENE_NAMES.join(", "),
            });
        }
    };
    let name = SCENE_NAMES
        .iter()
        .copied()
        .find(|n| *n == name)
        .unwrap_or("unknown");
    Ok(NamedScene {
        name,
        description,
        scene,
        pose,
        intrinsics: k,
        label_names: names,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::KinectSimulator;

    #[test]
    fn every_named_scene_renders_in_range() {
        let sim = KinectSimulator::kinect_v1().white();
        for name in SCENE_NAMES {
            let ns = named_scene(name).unwrap();
            assert_eq!(ns.name, *name);
            // Quarter resolution keeps the test fast; same field of view.
            let k = ns.intrinsics.scaled(0.25).unwrap();
            let f = sim.simulate(&ns.scene, &k, &ns.pose, 1);
            let stats = f.truth.stats().unwrap();
            assert!(
                stats.valid_pixels as f64 > 0.9 * k.pixel_count() as f64,
                "{name}: {stats:?}"
            );
            assert!(
                f64::from(stats.min) >= 0.5 && f64::from(stats.max) <= 5.0,
                "{name}: {stats:?}"
            );
            for l in f.labels.data() {
                assert!(
                    *l == 0 || ns.label_name(*l).is_some(),
                    "{name}: unnamed label {l}"
                );
            }
        }
        assert!(matches!(
            named_scene("nope"),
            Err(NoiseError::UnknownScene { .. })
        ));
    }

    #[test]
    fn floor_spans_paper_range_and_wall_is_at_two_metres() {
        let ns = named_scene("floor").unwrap();
        let r = ns.scene.render(&ns.intrinsics, &ns.pose);
        let s = r.depth.stats().unwrap();
        assert!(
            (0.75..0.85).contains(&s.min) && (3.7..4.1).contains(&s.max),
            "{s:?}"
        );
        let ns = named_scene("wall").unwrap();
        let r = ns.scene.render(&ns.intrinsics, &ns.pose);
        assert!(r.depth.data().iter().all(|z| (*z - 2.0).abs() < 1e-6));
    }

    #[test]
    fn three_planes_geometry() {
        let ns = named_scene("three-planes").unwrap();
        let r = ns.scene.render(&ns.intrinsics, &ns.pose);
        let find = |n: &str| {
            ns.label_names
                .iter()
                .find(|(_, s)| s.starts_with(n))
                .unwrap()
                .0
        };
        let (a, b, c) = (find("plane A"), find("plane B"), find("plane C"));
        let count = |l: u16| r.labels.data().iter().filter(|x| **x == l).count();
        assert!(count(a) > 10_000 && count(b) > 5_000 && count(c) > 5_000);
        let mean_z = |l: u16| {
            let v: Vec<f64> = r
                .labels
                .data()
                .iter()
                .zip(r.depth.data())
                .filter(|(x, _)| **x == l)
                .map(|(_, z)| f64::from(*z))
                .collect();
            v.iter().sum::<f64>() / v.len() as f64
        };
        assert!((0.45..0.75).contains(&mean_z(a)), "A at {}", mean_z(a));
        assert!((0.45..0.75).contains(&mean_z(b)), "B at {}", mean_z(b));
        assert!((2.5..3.5).contains(&mean_z(c)), "C at {}", mean_z(c));
        // A and B are parallel planes 1 cm apart.
        let pa = ns.scene.surface(a).unwrap();
        let top_of_book = Point3::new(0.05, 0.36, 0.01);
        assert!((pa.distance(&top_of_book) - 0.01).abs() < 1e-12);
        assert!(ns.scene.surface(b).unwrap().distance(&top_of_book) < 1e-12);
    }
}

//! The randomised room benchmark (issue 12): seeded rooms and corridors with floor, ceiling,
//! walls and boxes, seen by a camera of random height, pitch, roll, yaw and focal length.
//!
//! Each scene is a convex box (floor at z = 0, ceiling, four walls, as infinite planes: inside
//! the box the nearest hit is always the right surface) with up to three boxes standing on the
//! floor (one label per face). Rooms are 3–6 m wide and 3.5–7 m long; corridors 1.4–2.2 m wide
//! and 8–14 m long, looked along within ±35°. The camera stands 0.6–1.8 m high, at least 0.5 m
//! from every wall, pitched −35°…+10°, rolled ±15°, with a focal length of 520–600 px and the
//! principal point within 10 px of the centre of a 640×480 image. The simulator's range limit
//! (5 m by default) cuts what lies farther. Everything follows from the seed
//! ([`room_scene`]`(seed)`), so the benchmark is reproducible: [`ROOM_BENCHMARK_SEEDS`] scenes.

use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sl_core::{Camera, CameraToWorld, Intrinsics, SensorModel};

use crate::error::Result;
use crate::sim::kinect::{KinectSimulator, NoiseModel};
use crate::sim::primitives::{Cuboid, Plane};
use crate::sim::realistic::RealisticNoise;
use crate::sim::scene::{Scene, look_at};

/// Number of scenes of the room benchmark (seeds `0..ROOM_BENCHMARK_SEEDS`).
pub const ROOM_BENCHMARK_SEEDS: u64 = 60;

/// What kind of space a [`RoomScene`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoomKind {
    /// A room, 3–6 m by 3.5–7 m, camera looking anywhere.
    Room,
    /// A corridor, 1.4–2.2 m wide and 8–14 m long, camera looking along it.
    Corridor,
}

/// One randomised scene of the room benchmark.
#[derive(Debug)]
pub struct RoomScene {
    /// The seed it was built from.
    pub seed: u64,
    /// Room or corridor.
    pub kind: RoomKind,
    /// The surfaces (floor, ceiling, four walls, then the box faces).
    pub scene: Scene,
    /// Camera-to-world pose.
    pub pose: CameraToWorld,
    /// The camera (640×480, random focal length).
    pub intrinsics: Intrinsics,
    /// Human-readable label names (`floor`, `ceiling`, `wall +x`, `box 1 face 4`, …).
    pub label_names: Vec<(u16, String)>,
    /// Width (x), length (y) and height (z) of the space, metres.
    pub size_m: [f64; 3],
}

impl RoomScene {
    /// The camera that sees the scene and the simulator that renders it: the scene's own
    /// Kinect-class camera ([`RoomScene::intrinsics`], the Kinect v1 sensor model and
    /// simulator), or with `preset` a camera of `sl_core::preset` (its resolution, focal
    /// length, baseline, sub-pixel step and noise) through the realistic model for that camera
    /// ([`RealisticNoise::for_camera`]).
    ///
    /// # Errors
    /// A `preset` that `sl_core::Camera::preset` does not know.
    pub fn camera_and_simulator(&self, preset: Option<&str>) -> Result<(Camera, KinectSimulator)> {
        Ok(match preset {
            Some(name) => {
                let cam = Camera::preset(name)?;
                let noise = NoiseModel::Realistic(RealisticNoise::for_camera(name));
                (
                    cam,
                    KinectSimulator::with_sensor(cam.sensor).with_noise(noise),
                )
            }
            None => (
                Camera {
                    intrinsics: self.intrinsics,
                    sensor: SensorModel::kinect_v1(),
                },
                KinectSimulator::kinect_v1(),
            ),
        })
    }
}

/// Builds the benchmark scene of `seed` (every third seed a corridor, the others rooms).
pub fn room_scene(seed: u64) -> Result<RoomScene> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0012 ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    let kind = if seed % 3 == 2 {
        RoomKind::Corridor
    } else {
        RoomKind::Room
    };
    let (wx, ly, hz) = match kind {
        RoomKind::Room => (
            rng.random_range(3.0..6.0),
            rng.random_range(3.5..7.0),
            rng.random_range(2.4..3.0),
        ),
        RoomKind::Corridor => (
            rng.random_range(1.4..2.2),
            rng.random_range(8.0..14.0),
            rng.random_range(2.3..2.8),
        ),
    };
    let (hx, hy) = (wx / 2.0, ly / 2.0);
    let mut scene = Scene::new();
    let mut names = Vec::new();
    let walls = [
        ("floor", Point3::new(0.0, 0.0, 0.0), Vector3::z()),
        ("ceiling", Point3::new(0.0, 0.0, hz), -Vector3::z()),
        ("wall -x", Point3::new(-hx, 0.0, 0.0), Vector3::x()),
        ("wall +x", Point3::new(hx, 0.0, 0.0), -Vector3::x()),
        ("wall -y", Point3::new(0.0, -hy, 0.0), Vector3::y()),
        ("wall +y", Point3::new(0.0, hy, 0.0), -Vector3::y()),
    ];
    for (name, p, n) in walls {
        let l = scene.try_add(Plane::new(p, n)?)?;
        names.push((l, name.to_string()));
    }
    // The camera: in a room anywhere 0.5 m from the walls, in a corridor near one end.
    let margin = 0.5;
    let height = rng.random_range(0.6..1.8);
    let (eye, yaw) = match kind {
        RoomKind::Room => (
            Point3::new(
                rng.random_range(-hx + margin..hx - margin),
                rng.random_range(-hy + margin..hy - margin),
                height,
            ),
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        ),
        RoomKind::Corridor => (
            Point3::new(
                rng.random_range(-hx + margin..hx - margin),
                -hy + rng.random_range(0.6..2.0),
                height,
            ),
            std::f64::consts::FRAC_PI_2 + rng.random_range(-35f64..35.0).to_radians(),
        ),
    };
    let pitch = rng.random_range(-35f64..10.0).to_radians();
    let roll = rng.random_range(-15f64..15.0).to_radians();
    let f = rng.random_range(520.0..600.0);
    let cx = 319.5 + rng.random_range(-10.0..10.0);
    let cy = 239.5 + rng.random_range(-10.0..10.0);
    let intrinsics = Intrinsics::new(640, 480, f, f, cx, cy)?;
    let dir = Vector3::new(
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    );
    let mut pose = look_at(eye, eye + dir, Vector3::z())?.into_isometry();
    pose.rotation *= UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
    let pose = CameraToWorld::from_isometry(pose);
    // Boxes on the floor, clear of the camera and inside the walls.
    let n_boxes = match kind {
        RoomKind::Room => rng.random_range(1..=3),
        RoomKind::Corridor => rng.random_range(0..=2),
    };
    let mut placed = 0;
    let mut tries = 0;
    while placed < n_boxes && tries < 50 {
        tries += 1;
        let half: Vector3<f64> = Vector3::new(
            rng.random_range(0.15..0.5),
            rng.random_range(0.15..0.5),
            rng.random_range(0.15..0.6),
        );
        let r = half.x.hypot(half.y);
        if 2.0 * r + 0.2 >= wx.min(ly) {
            continue;
        }
        let c = Point3::new(
            rng.random_range(-hx + r + 0.05..hx - r - 0.05),
            rng.random_range(-hy + r + 0.05..hy - r - 0.05),
            half.z,
        );
        if (c.x - eye.x).hypot(c.y - eye.y) < r + 0.8 {
            continue;
        }
        let rot = UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            rng.random_range(0.0..std::f64::consts::PI),
        );
        placed += 1;
        for (i, face) in Cuboid::new(c, half, rot)?.faces().into_iter().enumerate() {
            let l = scene.try_add(face)?;
            names.push((l, format!("box {placed} face {i}")));
        }
    }
    Ok(RoomScene {
        seed,
        kind,
        scene,
        pose,
        intrinsics,
        label_names: names,
        size_m: [wx, ly, hz],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_room_is_seen_through_its_own_camera_or_a_preset() {
        let room = room_scene(7).unwrap();
        let (own, _) = room.camera_and_simulator(None).unwrap();
        assert_eq!(own.intrinsics, room.intrinsics);
        assert_eq!(own.sensor, SensorModel::kinect_v1());
        let (d435, sim) = room.camera_and_simulator(Some("d435")).unwrap();
        assert_eq!(d435, Camera::preset("d435").unwrap());
        // The preset's own sensor renders it: its frames have the preset's size.
        let frame = sim.simulate(&room.scene, &d435.intrinsics, &room.pose, 1);
        assert_eq!(
            (frame.depth.width(), frame.depth.height()),
            (d435.intrinsics.width, d435.intrinsics.height)
        );
        assert!(room.camera_and_simulator(Some("no-such-camera")).is_err());
    }

    #[test]
    fn scenes_are_reproducible_and_varied() {
        let a = room_scene(4).unwrap();
        let b = room_scene(4).unwrap();
        assert_eq!(a.pose, b.pose);
        assert_eq!(a.intrinsics, b.intrinsics);
        assert_eq!(a.label_names, b.label_names);
        let c = room_scene(5).unwrap();
        assert_ne!(a.pose, c.pose);
        assert_eq!(room_scene(2).unwrap().kind, RoomKind::Corridor);
        for seed in 0..ROOM_BENCHMARK_SEEDS {
            let s = room_scene(seed).unwrap();
            let f = s.intrinsics.fx;
            assert!((520.0..600.0).contains(&f), "seed {seed}: f = {f}");
            // The camera is inside the space, below the ceiling.
            let t = s.pose.translation();
            assert!(t.x.abs() < s.size_m[0] / 2.0 && t.y.abs() < s.size_m[1] / 2.0);
            assert!(t.z > 0.5 && t.z < s.size_m[2]);
        }
    }

    #[test]
    fn render_sees_only_inside_surfaces() {
        let s = room_scene(0).unwrap();
        let k = s.intrinsics.scaled(0.25).unwrap();
        let r = s.scene.render(&k, &s.pose);
        // A closed room: every pixel hits a surface.
        assert!(r.labels.data().iter().all(|&l| l != 0));
        let floor_or_wall = r.labels.data().iter().filter(|&&l| l <= 6).count();
        assert!(floor_or_wall > r.labels.data().len() / 2);
    }
}

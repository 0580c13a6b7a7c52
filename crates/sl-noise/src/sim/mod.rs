//! The seeded Kinect simulator: analytic ground-truth scenes rendered through a pinhole camera,
//! then passed through the structured-light sensor model.
//!
//! * Geometry: the [`Surface`] trait (ray intersection + unsigned distance) and the primitives
//!   [`Plane`], [`Quad`], [`Sphere`], [`Cuboid`], [`Cylinder`] and [`ReliefPlate`]; implement
//!   [`Surface`] for anything else.
//! * [`Scene`]: labelled surfaces (label = 1-based insertion index, 0 = background;
//!   [`Scene::add_cuboid`] labels each face), [`Scene::render`] to exact depth `Z`, labels and
//!   camera-frame normals (rows in parallel), [`Scene::distance`] for ground-truth
//!   point-to-surface errors (e.g. of a fused mesh), [`look_at`] for camera poses.
//! * [`KinectSimulator`]: disparity noise, `1/q` quantisation, 1 mm rounding, range limits,
//!   dropout; by default the [`realistic`] model ([`NoiseModel::Realistic`] with
//!   [`RealisticNoise`]: block-matching-correlated error, occlusion bands, drop-outs), or the
//!   paper's white noise ([`NoiseModel::White`], [`KinectSimulator::white`], optionally with
//!   projector shadows: [`KinectSimulator::simulate_with_shadows`]); seeded per row so results
//!   do not depend on threads.
//! * [`named_scene`]: the scenes of the paper's figures by name ([`SCENE_NAMES`]);
//!   [`room_scene`]: the seeded random rooms and corridors of the room benchmark
//!   ([`ROOM_BENCHMARK_SEEDS`] of them, issue 12).
//!
//! ```
//! use sl_noise::sim::{KinectSimulator, Plane, Scene, Sphere};
//! use sl_core::{CameraToWorld, Intrinsics, nalgebra::{Point3, Vector3}};
//!
//! let mut scene = Scene::new();
//! let wall = scene.add(Plane::new(Point3::new(0.0, 0.0, 3.0), Vector3::z())?);
//! let ball = scene.add(Sphere::new(Point3::new(0.0, 0.0, 1.5), 0.2)?);
//! let k = Intrinsics::kinect_v1().scaled(0.25)?;
//! let frame = KinectSimulator::kinect_v1().simulate(&scene, &k, &CameraToWorld::identity(), 42);
//! assert_eq!(frame.labels.get(80, 60), Some(&ball));
//! assert_eq!(frame.labels.get(0, 0), Some(&wall));
//! // The sensor output is the truth plus quantised disparity noise, on a 1 mm grid.
//! let z = frame.depth.get(80, 60).unwrap_or(0.0);
//! assert!((z - frame.truth.get(80, 60).unwrap_or(0.0)).abs() < 0.03);
//! # Ok::<(), sl_noise::NoiseError>(())
//! ```

mod hand_held;
mod kinect;
mod primitives;
pub mod realistic;
mod relief;
mod rooms;
mod scene;
mod scenes;

pub use hand_held::HandHeldPath;
pub use kinect::{
    KINECT_MAX_DEPTH_M, KINECT_MIN_DEPTH_M, KinectSimulator, NoiseModel, SimulatedFrame,
};
pub use primitives::{Cuboid, Cylinder, Hit, Plane, Quad, Sphere, Surface, T_MIN};
pub use realistic::RealisticNoise;
pub use relief::ReliefPlate;
pub use rooms::{ROOM_BENCHMARK_SEEDS, RoomKind, RoomScene, room_scene};
pub use scene::{MAX_RENDER_PIXELS, MAX_SURFACES, Render, Scene, look_at};
pub use scenes::{NamedScene, SCENE_NAMES, named_scene};

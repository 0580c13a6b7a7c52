//! The camera path of the room benchmark's tracking runs: a hand-held camera moving 1.2 cm and
//! turning 1.2° per frame, optionally shaken by a seeded random extra motion per step (so that
//! a tracker's constant-velocity prediction misses).

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use sl_core::{CameraToCamera, CameraToWorld};

/// A hand-held path through a [`crate::sim::RoomScene`]: each [`HandHeldPath::advance`] moves
/// the camera by the constant step (1.2 cm, 1.2° about a mostly vertical axis) and then by a
/// shake of up to `shake` cm along and `shake`° about each camera axis, uniform and seeded (a
/// xorshift generator, so the same seed gives the same path on every machine).
///
/// ```
/// use sl_noise::sim::{HandHeldPath, room_scene};
///
/// let room = room_scene(3004).unwrap();
/// let mut path = HandHeldPath::new(3004, 1.0);
/// let next = path.advance(&room.pose);
/// let moved = (room.pose.isometry().inverse() * next.isometry()).translation.vector.norm();
/// assert!(moved > 0.0 && moved < 0.04);
/// ```
#[derive(Debug, Clone)]
pub struct HandHeldPath {
    step: CameraToCamera,
    shake: f64,
    state: u64,
}

impl HandHeldPath {
    /// The path of room `seed`, shaken by up to `shake` cm and degrees per axis and step
    /// (0: the constant step alone).
    pub fn new(seed: u64, shake: f64) -> Self {
        Self {
            step: CameraToCamera::from_isometry(Isometry3::from_parts(
                Translation3::new(0.005, 0.002, 0.012),
                UnitQuaternion::from_scaled_axis(
                    Vector3::new(0.3, 1.0, 0.1).normalize() * 1.2f64.to_radians(),
                ),
            )),
            shake,
            state: seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
        }
    }

    /// The constant step alone.
    pub fn step(&self) -> CameraToCamera {
        self.step
    }

    /// The pose one frame after `pose`.
    pub fn advance(&mut self, pose: &CameraToWorld) -> CameraToWorld {
        let s = self.shake;
        let (tx, ty, tz) = (self.uniform(), self.uniform(), self.uniform());
        let (rx, ry, rz) = (self.uniform(), self.uniform(), self.uniform());
        let shaken = CameraToCamera::from_isometry(Isometry3::from_parts(
            Translation3::new(0.01 * s * tx, 0.01 * s * ty, 0.01 * s * tz),
            UnitQuaternion::from_scaled_axis(Vector3::new(rx, ry, rz) * s.to_radians()),
        ));
        *pose * self.step * shaken
    }

    /// The next xorshift draw, uniform in [−1, 1).
    fn uniform(&mut self) -> f64 {
        let s = &mut self.state;
        *s ^= *s << 13;
        *s ^= *s >> 7;
        *s ^= *s << 17;
        (*s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

//! The planes of the last good frame, for its reference maps: a pixel on one of the frame's
//! planes gets the plane's normal as its reference normal instead of its own.
//!
//! **Why.** A structured-light frame's depth error is fixed to the camera: quantisation
//! terraces lie at fixed disparities, i.e. at fixed depths in the camera frame, and the bands
//! of the block-matching window sit in the image. On a wall seen at a grazing angle (a
//! corridor's side walls, a floor), the terraces tilt the per-pixel normals (central
//! differences over a few pixels) towards the optical axis. Aligned point-to-plane against
//! those normals, the next frame — whose own terraces lie at the same camera depths — fits best
//! where the camera has not moved along the axis: a pull towards standing still that is not in
//! the pose's uncertainty. Simulated corridors through the D415 and OAK-D presets, tracked
//! against the last frame: every step recovered about 6 of the camera's 10 mm along the axis,
//! reported tracked. A plane's normal, fitted to thousands of pixels, carries none of it; the
//! structure check ([`super::structure`]) already counts the frame's information with these
//! normals, so the alignment now sees what the check counted. Frame to frame on the real
//! sequences: TUM fr1/rpy-200 ATE 3.35 → 3.03 cm, 7-Scenes 0.73 → 0.51 cm
//! (docs/bench/track.md, session 33).
//!
//! A pixel keeps its own normal off the planes, more than 3 σ_Z from its plane along its ray
//! (labels come from half resolution, where a pixel by a depth edge averages two surfaces), and
//! where its own normal is further from the plane's than the normal noise allows (the
//! association's gate, [`super::pyramid::normal_gate_cos`]: by a crease).
//!
//! Only the last frame's maps change. A model's normals come from a field fused over many
//! views, whose terraces average out; given the last frame's planes too, the model reference
//! tracked worse (TUM 2.93 → 3.07 cm, 7-Scenes 0.60 → 0.66 cm).

use nalgebra::{Isometry3, Point3, Vector3};
use rayon::prelude::*;
use sl_core::{Intrinsics, Plane, SensorModel};

use super::pyramid::normal_gate_cos;
use super::reference::ReferenceMaps;

/// A level-0 pixel takes its plane's normal only when its depth lies within this many of the
/// sensor's σ_Z of the plane along its ray: the label comes from the half-resolution level,
/// where a pixel at a depth edge averages two surfaces.
const ON_PLANE_SIGMAS: f32 = 3.0;

/// One frame's plane segmentation: labels on a pyramid level, planes in the camera frame.
#[derive(Debug, Default)]
pub(crate) struct FramePlanes {
    /// Plane label per pixel of the segmented level (0: on no plane), row-major.
    pub(crate) labels: Vec<u16>,
    /// Width and height of the segmented level.
    pub(crate) width: usize,
    pub(crate) height: usize,
    /// The segmented level's index (its pixel is `2^level` level-0 pixels wide).
    pub(crate) level: usize,
    /// Plane `l` (camera frame) at index `l − 1`.
    pub(crate) planes: Vec<Plane>,
}

impl FramePlanes {
    /// Empties the segmentation (no pixel is on a plane).
    pub(crate) fn clear(&mut self) {
        self.labels.clear();
        self.planes.clear();
        self.width = 0;
        self.height = 0;
    }

    /// The plane of level-0 pixel `(u, v)`, if it has one.
    fn plane_at(&self, u: usize, v: usize) -> Option<&Plane> {
        let shift = self.level.min(16);
        let (x, y) = (u >> shift, v >> shift);
        if x >= self.width || y >= self.height {
            return None;
        }
        let label = *self.labels.get(y * self.width + x)?;
        self.planes.get(usize::from(label).checked_sub(1)?)
    }

    /// Replaces the normals of `maps` (the frame's own, seen from `pose`) by the planes' where a
    /// map point lies on the plane of the pixel it projects to in this frame (`k`: the frame's
    /// level-0 intrinsics, `pose`: its camera-to-world pose), facing the camera, and the
    /// point's variance along the normal by the sensor's for that normal: `(σ_Z(z)·cos)²`,
    /// `cos` between the normal and the pixel's ray.
    pub(crate) fn apply(
        &self,
        maps: &mut ReferenceMaps,
        k: &Intrinsics,
        pose: &Isometry3<f64>,
        sensor: &SensorModel,
    ) {
        if self.planes.is_empty() {
            return;
        }
        let rot = pose
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        let inv = pose.inverse().cast::<f32>();
        let c = (sensor.sigma_d_px / sensor.fb()) as f32;
        let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
        let (w, h) = (k.width as f32, k.height as f32);
        let on_plane = |x: &Point3<f32>, nrm: &mut Vector3<f32>, var: &mut f32| {
            if !(x.x.is_finite() && nrm.x.is_finite()) {
                return;
            }
            let p = inv * x;
            if p.z <= 0.0 {
                return;
            }
            // The nearest pixel centre (pixel `(u, v)` is centred on integer coordinates).
            let (u, v) = (fx * p.x / p.z + cx + 0.5, fy * p.y / p.z + cy + 0.5);
            if !(u >= 0.0 && v >= 0.0 && u < w && v < h) {
                return;
            }
            let Some(plane) = self.plane_at(u as usize, v as usize) else {
                return;
            };
            let n: Vector3<f32> = plane.normal.cast::<f32>();
            let np = n.dot(&p.coords);
            // The plane's depth along the point's ray: X = s·p with n·X + offset = 0.
            let s = -(plane.offset_m as f32) / np;
            let sigma_z = c * p.z * p.z;
            if !(s.is_finite() && (p.z * (1.0 - s)).abs() <= ON_PLANE_SIGMAS * sigma_z) {
                return;
            }
            let n = if np > 0.0 { -n } else { n };
            let n_world = rot * n;
            if n_world.dot(nrm) < normal_gate_cos(c, p.z, fx) {
                return;
            }
            *nrm = n_world;
            let sd = sigma_z * n.dot(&p.coords) / p.coords.norm();
            *var = sd * sd;
        };
        (
            maps.points.par_iter(),
            maps.normals.par_iter_mut(),
            maps.variance_m2.par_iter_mut(),
        )
            .into_par_iter()
            .for_each(|(x, nrm, var)| on_plane(x, nrm, var));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_core::CameraToWorld;

    /// A wall `z = 2 m` seen head-on by a 64×48 camera at `pose`, whose per-pixel normals are
    /// tilted (as a single frame's terraces tilt them), with one pixel 10 cm in front of it.
    fn wall_maps(k: &Intrinsics, pose: &Isometry3<f64>) -> ReferenceMaps {
        let mut maps = ReferenceMaps::empty(k);
        maps.pose = CameraToWorld::from_isometry(*pose);
        let iso = pose.cast::<f32>();
        for v in 0..k.height {
            for u in 0..k.width {
                let i = v * k.width + u;
                let z = if (u, v) == (10, 10) { 1.9 } else { 2.0 };
                let p = Point3::new(
                    (u as f32 - k.cx as f32) * z / k.fx as f32,
                    (v as f32 - k.cy as f32) * z / k.fy as f32,
                    z,
                );
                maps.points[i] = iso * p;
                maps.normals[i] = iso.rotation * Vector3::new(0.2, 0.0, -1.0).normalize();
                maps.variance_m2[i] = 1.0;
            }
        }
        maps
    }

    #[test]
    fn points_on_a_plane_take_its_normal_facing_the_camera() {
        let k = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap();
        let sensor = SensorModel::kinect_v1();
        let pose = Isometry3::new(
            nalgebra::Vector3::new(0.3, -0.2, 1.0),
            nalgebra::Vector3::new(0.1, 0.2, -0.05),
        );
        // Labelled on half-resolution pixels, all on plane 1: the wall, its normal pointing
        // away from the camera (the extractor imposes no orientation).
        let planes = FramePlanes {
            labels: vec![1; 32 * 24],
            width: 32,
            height: 24,
            level: 1,
            planes: vec![Plane::new(Vector3::new(0.0, 0.0, 1.0), -2.0).unwrap()],
        };
        let mut maps = wall_maps(&k, &pose);
        planes.apply(&mut maps, &k, &pose, &sensor);
        let facing = pose.rotation.cast::<f32>() * Vector3::new(0.0, 0.0, -1.0);
        let sigma_z = sensor.sigma_z(2.0) as f32;
        for v in 0..k.height {
            for u in 0..k.width {
                let i = v * k.width + u;
                if (u, v) == (10, 10) {
                    // 10 cm off the plane, far beyond 3 σ_Z: its own normal stays.
                    assert!((maps.normals[i] - facing).norm() > 0.1);
                    assert_eq!(maps.variance_m2[i], 1.0);
                    continue;
                }
                assert!((maps.normals[i] - facing).norm() < 1e-5, "pixel ({u}, {v})");
                // σ_Z along the ray, projected on the normal.
                let ray = (maps.points[i] - pose.translation.vector.cast::<f32>()).coords;
                let cos = facing.dot(&ray) / ray.norm();
                let expected = (sigma_z * cos).powi(2);
                assert!((maps.variance_m2[i] - expected).abs() < 1e-3 * expected);
            }
        }
    }

    #[test]
    fn no_planes_change_nothing() {
        let k = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap();
        let pose = Isometry3::identity();
        let mut maps = wall_maps(&k, &pose);
        let before = maps.normals.clone();
        FramePlanes::default().apply(&mut maps, &k, &pose, &SensorModel::kinect_v1());
        assert_eq!(maps.normals, before);
    }
}

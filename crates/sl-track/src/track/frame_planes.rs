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
//! association's gate, the level's `PointAux::cos_gate`: by a crease).
//!
//! Only the last frame's maps change. A model's normals come from a field fused over many
//! views, whose terraces average out; given the last frame's planes too, the model reference
//! tracked worse (TUM 2.93 → 3.07 cm, 7-Scenes 0.60 → 0.66 cm).

use nalgebra::Vector3;
use rayon::prelude::*;
use sl_core::Plane;

use super::pyramid::Level;
use super::reference::{ReferenceMaps, variance_along_normal};

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

    /// Replaces the normals of `maps` — the maps of the frame itself, built from `level0` (its
    /// level 0: camera-frame points, and their `aux` complete) and seen from `maps.pose` — by
    /// the planes' where a pixel's point lies on the plane of its pixel, facing the camera, and
    /// the point's variance along the normal by the sensor's for that normal: `(σ_Z(z)·cos)²`,
    /// `cos` between the normal and the pixel's ray.
    pub(crate) fn apply(&self, maps: &mut ReferenceMaps, level0: &Level) {
        let Some(k) = level0.k else {
            return;
        };
        let n = k.width * k.height;
        if self.planes.is_empty()
            || level0.points.len() != n
            || level0.aux.len() != n
            || maps.normals.len() != n
            || maps.variance_m2.len() != n
            || maps.own_normals.len() != n
        {
            return;
        }
        let rot = maps
            .pose
            .isometry()
            .rotation
            .to_rotation_matrix()
            .into_inner()
            .cast::<f32>();
        // Each plane facing the camera: on it `n·p = −offset`, one sign for all its points, so
        // `offset > 0` after the flip; and its normal in world coordinates.
        let faced: Vec<(Vector3<f32>, f32, Vector3<f32>)> = self
            .planes
            .iter()
            .map(|pl| {
                let (nc, off) = (pl.normal.cast::<f32>(), pl.offset_m as f32);
                let (nc, off) = if off < 0.0 { (-nc, -off) } else { (nc, off) };
                (nc, off, rot * nc)
            })
            .collect();
        let shift = self.level.min(16);
        let w = k.width;
        let lateral = maps.lateral_sigma_per_m;
        maps.normals
            .par_chunks_mut(w)
            .zip(maps.variance_m2.par_chunks_mut(w))
            .zip(maps.own_normals.par_chunks_mut(w))
            .zip(level0.points.par_chunks(w))
            .zip(level0.aux.par_chunks(w))
            .enumerate()
            .for_each(|(v, ((((normals, variances), own), points), aux))| {
                let y = v >> shift;
                if y >= self.height {
                    return;
                }
                let labels = &self.labels[y * self.width..(y + 1) * self.width];
                for (u, ((((nrm, var), own), p), a)) in normals
                    .iter_mut()
                    .zip(variances.iter_mut())
                    .zip(own.iter_mut())
                    .zip(points)
                    .zip(aux)
                    .enumerate()
                {
                    let Some(&(nc, off, nw)) = labels
                        .get(u >> shift)
                        .and_then(|&l| usize::from(l).checked_sub(1))
                        .and_then(|l| faced.get(l))
                    else {
                        continue;
                    };
                    if !(p.z > 0.0 && nrm.x.is_finite()) {
                        continue;
                    }
                    // Within 3 σ_Z of the plane along the pixel's ray: the ray meets the plane
                    // at depth z·s with s = −offset/(n·p), and z·|1 − s| ≤ 3·σ_Z becomes
                    // z·|n·p + offset| ≤ 3·σ_Z·|n·p| (no division).
                    let np = nc.dot(&p.coords);
                    let on_plane = p.z * (np + off).abs() <= ON_PLANE_SIGMAS * a.cz2 * np.abs();
                    // The own normal within the association's normal gate of the plane's.
                    if !on_plane || nw.dot(nrm) < a.cos_gate {
                        continue;
                    }
                    *nrm = nw;
                    *own = false;
                    *var = variance_along_normal(a.cz2, lateral * p.z, np / a.ray_len);
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::track::pyramid::{PointAux, normal_gate_cos};
    use nalgebra::{Isometry3, Point3};
    use sl_core::{CameraToWorld, Intrinsics, SensorModel};

    /// A wall `z = 2 m` seen head-on by a 64×48 Kinect-like camera at `pose` (its level 0, and
    /// reference maps whose normals are tilted as a single frame's terraces tilt them), with
    /// one pixel 10 cm in front of it.
    fn wall(k: &Intrinsics, pose: &Isometry3<f64>, sensor: &SensorModel) -> (Level, ReferenceMaps) {
        let mut maps = ReferenceMaps::empty(k);
        maps.pose = CameraToWorld::from_isometry(*pose);
        let mut level = Level {
            k: Some(*k),
            ..Level::default()
        };
        let c = (sensor.sigma_d_px / sensor.fb()) as f32;
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
                level.points.push(p);
                level.aux.push(PointAux {
                    ray_len: p.coords.norm(),
                    cz2: c * z * z,
                    cos_gate: normal_gate_cos(c, z, k.fx as f32),
                });
                maps.points[i] = iso * p;
                maps.normals[i] = iso.rotation * Vector3::new(0.2, 0.0, -1.0).normalize();
                maps.variance_m2[i] = 1.0;
            }
        }
        (level, maps)
    }

    /// Every half-resolution pixel of a 64×48 frame on `plane`.
    fn everywhere(plane: Plane) -> FramePlanes {
        FramePlanes {
            labels: vec![1; 32 * 24],
            width: 32,
            height: 24,
            level: 1,
            planes: vec![plane],
        }
    }

    #[test]
    fn points_on_a_plane_take_its_normal_facing_the_camera() {
        let k = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap();
        let sensor = SensorModel::kinect_v1();
        let pose = Isometry3::new(
            nalgebra::Vector3::new(0.3, -0.2, 1.0),
            nalgebra::Vector3::new(0.1, 0.2, -0.05),
        );
        // The wall, its normal pointing away from the camera (the extractor imposes no
        // orientation).
        let planes = everywhere(Plane::new(Vector3::new(0.0, 0.0, 1.0), -2.0).unwrap());
        let (level, mut maps) = wall(&k, &pose, &sensor);
        planes.apply(&mut maps, &level);
        let facing = pose.rotation.cast::<f32>() * Vector3::new(0.0, 0.0, -1.0);
        let sigma_z = sensor.sigma_z(2.0) as f32;
        for v in 0..k.height {
            for u in 0..k.width {
                let i = v * k.width + u;
                if (u, v) == (10, 10) {
                    // 10 cm off the plane, far beyond 3 σ_Z: its own normal stays.
                    assert!((maps.normals[i] - facing).norm() > 0.1);
                    assert_eq!(maps.variance_m2[i], 1.0);
                    assert!(maps.own_normals[i]);
                    continue;
                }
                assert!((maps.normals[i] - facing).norm() < 1e-5, "pixel ({u}, {v})");
                assert!(!maps.own_normals[i], "pixel ({u}, {v})");
                // σ_Z along the ray, projected on the normal.
                let ray = level.points[i].coords;
                let cos = ray.z / ray.norm();
                let expected = (sigma_z * cos).powi(2);
                assert!((maps.variance_m2[i] - expected).abs() < 1e-3 * expected);
            }
        }
    }

    #[test]
    fn a_normal_beyond_the_gate_or_no_planes_change_nothing() {
        let k = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap();
        let sensor = SensorModel::kinect_v1();
        let pose = Isometry3::identity();
        let (level, mut maps) = wall(&k, &pose, &sensor);
        let before = maps.normals.clone();
        FramePlanes::default().apply(&mut maps, &level);
        assert_eq!(maps.normals, before);
        // A plane at 45° to the wall: every own normal is further from it than the gate.
        let planes = everywhere(Plane::new(Vector3::new(1.0, 0.0, 1.0), -2.0).unwrap());
        planes.apply(&mut maps, &level);
        let on_it = maps.normals[24 * 64 + 32] != before[24 * 64 + 32];
        let elsewhere = maps
            .normals
            .iter()
            .zip(&before)
            .filter(|(a, b)| a != b)
            .count();
        assert!(!on_it && elsewhere == 0, "{elsewhere} normals replaced");
        assert!(maps.own_normals.iter().all(|&own| own));
    }
}

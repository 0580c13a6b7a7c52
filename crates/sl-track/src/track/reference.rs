//! What a frame is tracked against: world-frame point and normal maps seen from one pose, with
//! the variance of each reference point along its normal.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::{CameraToWorld, Intrinsics, SensorModel};

use super::pyramid::Level;

/// Reference maps for projective data association: what the model (a raycast of the fused
/// volume) or the previous frame shows from [`ReferenceMaps::pose`].
///
/// Pixel `i` (row-major, `intrinsics`' size) holds a world point, its unit normal and the
/// variance of the point along the normal (m²); NaN points/normals mark pixels without a
/// surface. Build it with [`ReferenceMaps::from_depth`] (the previous frame) or from a model
/// raycast with [`ReferenceMaps::from_model`]; [`crate::Tracker::track`] reuses one across frames.
#[derive(Debug, Clone)]
pub struct ReferenceMaps {
    /// The camera the maps are seen from.
    pub pose: CameraToWorld,
    /// Its intrinsics (sets the maps' size).
    pub intrinsics: Intrinsics,
    /// World points (NaN = none).
    pub points: Vec<Point3<f32>>,
    /// World unit normals (NaN = none).
    pub normals: Vec<Vector3<f32>>,
    /// Variance of each point along its normal, m².
    pub variance_m2: Vec<f32>,
    /// Whether each normal is the pixel's own (central differences on one frame: as noisy as
    /// that frame's normals) rather than a plane's fitted to the frame's pixels or a fused
    /// model's; the tracker's structure check credits a sample by how it faces the reference
    /// only where the reference's normal is not the pixel's own.
    pub own_normals: Vec<bool>,
}

impl ReferenceMaps {
    /// Empty maps of `k`'s size (every pixel without a surface).
    pub fn empty(k: &Intrinsics) -> Self {
        let n = k.width * k.height;
        Self {
            pose: CameraToWorld::identity(),
            intrinsics: *k,
            points: vec![Point3::new(f32::NAN, f32::NAN, f32::NAN); n],
            normals: vec![Vector3::new(f32::NAN, f32::NAN, f32::NAN); n],
            variance_m2: vec![0.0; n],
            own_normals: vec![true; n],
        }
    }

    /// Number of pixels with a surface.
    pub fn valid_count(&self) -> usize {
        self.normals.iter().filter(|n| n.x.is_finite()).count()
    }

    /// Maps of one depth frame (the previous frame in frame-to-frame tracking) seen from
    /// `pose`: its points and normals in world coordinates, and the sensor's variance along
    /// the normal: the depth noise acts along the ray, so `σ_Z(z)²·(n·r)²` with `r` the unit
    /// ray of the pixel.
    pub fn from_depth(
        depth: &[f32],
        k: &Intrinsics,
        sensor: &SensorModel,
        pose: &CameraToWorld,
    ) -> crate::Result<Self> {
        let mut pyr = super::pyramid::Pyramid::default();
        pyr.build(depth, k, sensor, 1, 1)?;
        let mut out = Self::empty(k);
        if let Some(level) = pyr.levels.first() {
            out.set_from_level(level, k, sensor, pose);
        }
        Ok(out)
    }

    /// Replaces the maps by those of a pyramid level (level 0 of the tracked frame), reusing
    /// the buffers.
    pub(crate) fn set_from_level(
        &mut self,
        level: &Level,
        k: &Intrinsics,
        sensor: &SensorModel,
        pose: &CameraToWorld,
    ) {
        let n = k.width * k.height;
        self.pose = *pose;
        self.intrinsics = *k;
        self.points.resize(n, Point3::origin());
        self.normals.resize(n, Vector3::zeros());
        self.variance_m2.resize(n, 0.0);
        self.own_normals.clear();
        self.own_normals.resize(n, true);
        let iso = pose.isometry();
        let r = iso.rotation.to_rotation_matrix().matrix().cast::<f32>();
        let t = iso.translation.vector.cast::<f32>();
        let c = (sensor.sigma_d_px / sensor.fb()) as f32;
        let nan_p = Point3::new(f32::NAN, f32::NAN, f32::NAN);
        let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
        (
            self.points.par_iter_mut(),
            self.normals.par_iter_mut(),
            self.variance_m2.par_iter_mut(),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(i, (p, nrm, var))| {
                let pc = level.points[i];
                let nc = level.normals[i];
                if pc.z.is_finite() && nc.x.is_finite() {
                    *p = Point3::from(r * pc.coords + t);
                    *nrm = r * nc;
                    let z = pc.z;
                    let cos = nc.dot(&pc.coords) / pc.coords.norm();
                    let s = c * z * z * cos;
                    *var = s * s;
                } else {
                    *p = nan_p;
                    *nrm = nan_n;
                    *var = 0.0;
                }
            });
    }

    /// Maps of a raycast of the fused model ([`sl_tsdf::TsdfVolume::raycast`]) seen from
    /// `pose` with intrinsics `k`: the raycast's world points and normals, and for the variance
    /// [`ReferenceMaps::model_variance_m2`] of the fused weight at the hit (the volume's
    /// weights must be `inv-z4` normalised at `z_ref_m`).
    pub fn from_model(
        raycast: &sl_tsdf::Raycast,
        pose: &CameraToWorld,
        k: &Intrinsics,
        sensor: &SensorModel,
        z_ref_m: f64,
    ) -> crate::Result<Self> {
        let mut out = Self::empty(k);
        out.set_from_model(raycast, pose, k, sensor, z_ref_m)?;
        Ok(out)
    }

    /// [`ReferenceMaps::from_model`] into these maps, reusing the buffers.
    pub fn set_from_model(
        &mut self,
        raycast: &sl_tsdf::Raycast,
        pose: &CameraToWorld,
        k: &Intrinsics,
        sensor: &SensorModel,
        z_ref_m: f64,
    ) -> crate::Result<()> {
        let n = k.width * k.height;
        if raycast.width != k.width
            || raycast.height != k.height
            || raycast.points.len() != n
            || raycast.normals.len() != n
            || raycast.weights.len() != n
        {
            return Err(crate::TrackError::SizeMismatch {
                expected_width: k.width,
                expected_height: k.height,
                width: raycast.width,
                height: raycast.height,
            });
        }
        self.pose = *pose;
        self.intrinsics = *k;
        self.points.clear();
        self.points.extend_from_slice(&raycast.points);
        self.normals.clear();
        self.normals.extend_from_slice(&raycast.normals);
        self.variance_m2.resize(n, 0.0);
        self.own_normals.clear();
        self.own_normals.resize(n, false);
        let s2 = sensor.sigma_z(z_ref_m) as f32;
        let s2 = s2 * s2;
        self.variance_m2
            .par_iter_mut()
            .zip(raycast.weights.par_iter())
            .zip(self.normals.par_iter_mut())
            .for_each(|((v, w), nrm)| {
                if *w > 0.0 && nrm.x.is_finite() {
                    *v = s2 / *w;
                } else {
                    *v = 0.0;
                    *nrm = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
                }
            });
        Ok(())
    }

    /// The model's variance along the normal for a fused TSDF weight `weight` under 1/Z⁴
    /// weights normalised at `z_ref_m`: one observation at depth `Z` weighs
    /// `w = (z_ref/Z)⁴` and has variance `σ_Z(Z)² = σ_Z(z_ref)²·(Z/z_ref)⁴ = σ_Z(z_ref)²/w`,
    /// so the weights are inverse variances in units of `σ_Z(z_ref)²`, and the weighted mean of
    /// observations with total weight `W` has variance `σ_Z(z_ref)²/W` (along the rays, which
    /// for a surface seen head-on is the normal). Returns `f32::INFINITY` for `W ≤ 0`.
    pub fn model_variance_m2(sensor: &SensorModel, z_ref_m: f64, weight: f32) -> f32 {
        if weight > 0.0 {
            let s = sensor.sigma_z(z_ref_m) as f32;
            s * s / weight
        } else {
            f32::INFINITY
        }
    }
}

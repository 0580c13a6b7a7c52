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
    /// The sensor's lateral error per metre of depth, `σ_L/f` ([`TrackerConfig::lateral_sigma_px`]
    /// over the sensor's focal length), when the reference is a depth frame: its points'
    /// variances include `(σ_L·z/f)²·(1 − (n·r)²)`, and the tracked frame's points get the same
    /// term. 0 for a fused model's raycast (see [`TrackerConfig::lateral_sigma_px`] for why).
    ///
    /// [`TrackerConfig::lateral_sigma_px`]: crate::TrackerConfig::lateral_sigma_px
    pub lateral_sigma_per_m: f32,
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
            lateral_sigma_per_m: 0.0,
        }
    }

    /// Number of pixels with a surface.
    pub fn valid_count(&self) -> usize {
        self.normals.iter().filter(|n| n.x.is_finite()).count()
    }

    /// Maps of one depth frame (the previous frame in frame-to-frame tracking) seen from
    /// `pose`: its points and normals in world coordinates, and the sensor's variance along
    /// the normal: the depth noise acts along the ray, so `σ_Z(z)²·(n·r)²` with `r` the unit
    /// ray of the pixel, plus the lateral error across it,
    /// `(σ_L·z/f)²·(1 − (n·r)²)` with [`crate::DEFAULT_LATERAL_SIGMA_PX`].
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
            out.set_from_level(level, k, sensor, pose, crate::DEFAULT_LATERAL_SIGMA_PX);
        }
        Ok(out)
    }

    /// Replaces the maps by those of a pyramid level (level 0 of the tracked frame), reusing
    /// the buffers; `lateral_sigma_px` is the sensor's lateral error in its own pixels.
    pub(crate) fn set_from_level(
        &mut self,
        level: &Level,
        k: &Intrinsics,
        sensor: &SensorModel,
        pose: &CameraToWorld,
        lateral_sigma_px: f64,
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
        let lateral = lateral_sigma_per_m(lateral_sigma_px, sensor);
        self.lateral_sigma_per_m = lateral;
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
                    *var = variance_along_normal(c * z * z, lateral * z, cos);
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
        self.lateral_sigma_per_m = 0.0;
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

/// `σ_L/f` of a sensor: its lateral error (`lateral_sigma_px`, pixels of the sensor) per metre
/// of depth; 0 for a non-positive or non-finite result.
pub(crate) fn lateral_sigma_per_m(lateral_sigma_px: f64, sensor: &SensorModel) -> f32 {
    let s = lateral_sigma_px / sensor.focal_px;
    if s.is_finite() && s > 0.0 {
        s as f32
    } else {
        0.0
    }
}

/// The variance along a surface's unit normal `n` of a point measured along the unit ray `r`
/// with depth error `sigma_z` (m, along the ray) and lateral error `sigma_lat` (m, across it),
/// for `cos = n·r`: `σ_Z²·cos² + σ_lat²·(1 − cos²)`.
#[inline(always)]
pub(crate) fn variance_along_normal(sigma_z: f32, sigma_lat: f32, cos: f32) -> f32 {
    let axial = sigma_z * cos;
    let across = sigma_lat * sigma_lat * (1.0 - cos * cos).max(0.0);
    axial * axial + across
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// A floor 1 m below a Kinect looking along it: its far rows are seen at a grazing angle,
    /// where the depth error along the normal (`σ_Z·cos θ`) nearly vanishes and the lateral
    /// error across the ray (`σ_L·z/f·sin θ`) is what is left.
    #[test]
    fn a_grazing_floor_keeps_the_lateral_error_along_its_normal() {
        let k = Intrinsics::kinect_v1();
        let sensor = SensorModel::kinect_v1();
        let mut depth = vec![0.0f32; k.width * k.height];
        for v in 0..k.height {
            let dv = v as f64 - k.cy;
            if dv > 4.0 {
                for u in 0..k.width {
                    depth[v * k.width + u] = (k.fy / dv) as f32;
                }
            }
        }
        let pose = CameraToWorld::identity();
        let maps = ReferenceMaps::from_depth(&depth, &k, &sensor, &pose).unwrap();
        let lateral = crate::DEFAULT_LATERAL_SIGMA_PX / sensor.focal_px;
        assert!((f64::from(maps.lateral_sigma_per_m) - lateral).abs() < 1e-9);
        // Rows 20.5, 100.5 and 230.5 below the centre: 28 m (past the sensor's range; the maps
        // do not care), 5.8 m and 2.5 m away. Each pixel's variance is the sum of both terms,
        // and at these slants the lateral one is the larger.
        let mut checked = 0;
        for v in [260usize, 340, 470] {
            let i = v * k.width + 320;
            let (p, n, var) = (
                maps.points[i],
                maps.normals[i],
                f64::from(maps.variance_m2[i]),
            );
            assert!(n.x.is_finite(), "row {v}");
            let z = f64::from(p.z);
            let cos = f64::from(n.dot(&p.coords) / p.coords.norm());
            let axial = sensor.sigma_z(z) * cos;
            let across = lateral * z * (1.0 - cos * cos).sqrt();
            let want = axial * axial + across * across;
            assert!(
                (var / want - 1.0).abs() < 1e-3,
                "row {v}: {var} against {want}"
            );
            assert!(across > axial, "row {v}: lateral {across} axial {axial}");
            checked += 1;
        }
        assert_eq!(checked, 3);
        // Head-on and edge-on.
        assert_eq!(variance_along_normal(0.01, 0.002, 1.0), 1e-4);
        assert!((variance_along_normal(0.01, 0.002, 0.0) - 4e-6).abs() < 1e-12);
    }
}

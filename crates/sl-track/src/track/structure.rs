//! Whether a frame's geometry pins the pose down at all: the standard deviation of the pose
//! along its least-constrained direction that point-to-plane alignment of the frame could
//! reach, from the sensor model — with the normals of the frame's planes where it has them.
//!
//! **Why planes.** The normal equations of the alignment itself cannot tell a single wall from
//! a room: the noise of per-pixel normals (several degrees at 2 m, central differences over a
//! few pixels) spreads them over all directions and fills the null space of a wall or a floor
//! with fake constraints (session 10 measured the conditioning of a wall at 1.7·10⁻², within
//! the range of well-constrained real frames). A plane's normal comes from thousands of pixels,
//! so on a wall every sample gets the same normal and the directions along the wall get no
//! information, as the geometry says. Pixels on no plane (objects, curved surfaces, edges)
//! keep their own normal.
//!
//! **The rule.** Each sample (every [`STEP`]-th pixel in both directions) contributes the
//! point-to-plane Jacobian `[p × n; n]` with the information of its `STEP²` pixels: one
//! independent measurement per correlation window of the sensor's error
//! ([`TrackerConfig::correlated_pixels`]) of variance `σ_Z²` at its depth. Rotations are
//! expressed as displacements at the mean depth of the samples. The result is
//! `1/√λ_min` of that information matrix, metres. [`super::Tracker`] reports a frame lost when
//! this exceeds the σ of its own motion prior (`max_acceleration_m_s2 · frame_interval_s²`):
//! along such a direction the data say less than the constant-velocity guess, so the pose
//! there would be the guess, not a measurement.

use nalgebra::{Matrix6, SymmetricEigen, Vector6};
use sl_core::{Camera, DepthView, SensorModel};
use sl_planes::{PlaneConfig, PlaneExtractor};

use super::TrackerConfig;
use super::pyramid::Level;
use super::solve::rotations_at_depth;
use crate::error::Result;

/// Pixels between samples, in both directions.
pub(crate) const STEP: usize = 4;

/// The plane extractor kept between frames (its buffers are reused).
#[derive(Debug, Default)]
pub(crate) struct StructureCheck {
    extractor: Option<PlaneExtractor>,
}

impl StructureCheck {
    /// The pose's standard deviation along its least-constrained direction, metres
    /// (`f64::INFINITY` when a direction gets no information at all: a single plane), from
    /// pyramid level `index` of the frame (points, normals and depth; level 1, half
    /// resolution, is where [`super::Tracker`] runs it: a plane's normal needs no more, and
    /// the extraction costs a quarter).
    pub(crate) fn weakest_sigma_m(
        &mut self,
        level: &Level,
        index: usize,
        sensor: &SensorModel,
        cfg: &TrackerConfig,
    ) -> Result<f64> {
        let Some(k) = level.k else {
            return Ok(f64::INFINITY);
        };
        let scale = f64::from(1u32 << index.min(16));
        let extractor = match &mut self.extractor {
            Some(e) => e,
            None => {
                // The correlation window of the sensor's error in this level's pixels.
                let mut pc = PlaneConfig::default();
                pc.noise_window_x_px = (cfg.noise_window_x_px / scale).max(1.0);
                pc.noise_window_y_px = (cfg.noise_window_y_px / scale).max(1.0);
                self.extractor.insert(PlaneExtractor::new(pc)?)
            }
        };
        let camera = Camera {
            intrinsics: k,
            sensor: SensorModel {
                focal_px: k.fx,
                ..*sensor
            },
        };
        let seg =
            extractor.extract_depth(DepthView::new(k.width, k.height, &level.depth)?, &camera)?;
        let labels = seg.labels.data();
        let step = (STEP as f64 / scale).max(1.0) as usize;
        let share = (step * step) as f64 / cfg.correlated_pixels(index);
        let mut info = Matrix6::<f64>::zeros();
        let (mut z_sum, mut count) = (0.0f64, 0.0f64);
        for v in (step / 2..k.height).step_by(step) {
            for u in (step / 2..k.width).step_by(step) {
                let i = v * k.width + u;
                let (Some(p), Some(n_own)) = (level.points.get(i), level.normals.get(i)) else {
                    continue;
                };
                if p.z.is_nan() || p.z <= 0.0 || !n_own.x.is_finite() {
                    continue;
                }
                let p = p.cast::<f64>().coords;
                let n = match labels.get(i).map(|&l| l as usize) {
                    Some(l) if l > 0 => match seg.planes.get(l - 1) {
                        Some(pl) if pl.plane.normal.dot(&p) > 0.0 => -pl.plane.normal,
                        Some(pl) => pl.plane.normal,
                        None => n_own.cast::<f64>(),
                    },
                    _ => n_own.cast::<f64>(),
                };
                let sigma_z = sensor.sigma_z(p.z);
                if sigma_z.is_nan() || sigma_z <= 0.0 {
                    continue;
                }
                let r = p.cross(&n);
                let j = Vector6::new(r.x, r.y, r.z, n.x, n.y, n.z);
                info += j * j.transpose() * (share / (sigma_z * sigma_z));
                z_sum += p.z;
                count += 1.0;
            }
        }
        if count < 6.0 {
            return Ok(f64::INFINITY);
        }
        // Rotations as displacements at the mean depth.
        rotations_at_depth(&mut info, z_sum / count);
        let min = SymmetricEigen::new(info)
            .eigenvalues
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let largest = info.diagonal().max();
        // Round-off of a rank-deficient sum leaves |λ_min| ~ 1e-12 of the largest.
        Ok(if min > largest * 1e-9 {
            1.0 / min.sqrt()
        } else {
            f64::INFINITY
        })
    }
}

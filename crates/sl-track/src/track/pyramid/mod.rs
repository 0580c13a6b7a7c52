//! The depth pyramid of the frame being tracked: depth-aware 2×2 downsampling, and per level the
//! camera-frame vertex and normal maps. Buffers are kept and reused from frame to frame.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::{Intrinsics, SensorModel};

use crate::error::{Result, TrackError};
use crate::rolling_shutter::{motion_power, row_offset};
use normals::{Select, normals_and_aux};

mod normals;
#[cfg(test)]
mod tests;

/// The largest angle between a surface and the line of sight for which a normal is computed
/// (tan 80° ≈ 5.7): neighbouring pixels one pixel apart at depth `z` differ by up to
/// `z/f·tan(80°)` on such a surface, plus the sensor noise; larger jumps are depth edges.
pub(crate) const MAX_SLANT_TAN: f32 = 5.67;

/// The largest depth difference, metres, between two pixels `distance_px` apart at depth `z`
/// on one surface: a surface at 80° to the line of sight ([`MAX_SLANT_TAN`]), plus 3σ_Z
/// (`c = σ_D/(f·B)`, so σ_Z = c·z²). A larger jump is a depth edge. `fx`: the image's focal
/// length, pixels.
#[inline(always)]
fn edge_jump_m(distance_px: f32, z: f32, fx: f32, c: f32) -> f32 {
    distance_px * z / fx * MAX_SLANT_TAN + 3.0 * c * z * z
}

/// One level of the pyramid.
#[derive(Debug, Clone, Default)]
pub(crate) struct Level {
    /// Intrinsics of this level.
    pub k: Option<Intrinsics>,
    /// Depth, metres (0 = invalid).
    pub depth: Vec<f32>,
    /// Camera-frame points (NaN where invalid).
    pub points: Vec<Point3<f32>>,
    /// Camera-frame unit normals facing the camera (NaN where not computable).
    pub normals: Vec<Vector3<f32>>,
    /// Per-pixel constants of the association pass (valid where the normal is).
    pub aux: Vec<PointAux>,
    /// Normals (and `aux`) are computed on the pixels whose column and row are multiples of
    /// this (1: every pixel); elsewhere they are NaN until [`Level::complete_normals`].
    pub normal_stride: usize,
}

/// What the association pass needs of a frame point besides its position and normal, and
/// does not depend on the pose: computed once per frame instead of once per iteration.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct PointAux {
    /// `‖p‖`, the distance from the camera, metres.
    pub ray_len: f32,
    /// `c·z²` with `c = σ_D/(f·B)`: the point's depth σ, metres.
    pub cz2: f32,
    /// Cosine of the normal gate at the point's depth (see [`normal_gate_cos`]).
    pub cos_gate: f32,
}

/// Cosine of the widest angle between the frame's and the reference's normals at depth `z`:
/// central differences over ±2 pixels at depth z have an angular error of about
/// `σ_Z(z)·f/(2·2·z)` each (√2 for two normals), gated at 3σ (`c = σ_D/(f·B)`, `fl` the
/// full-resolution focal length, pixels). The caller caps it at the configured angle.
#[inline]
pub(crate) fn normal_gate_cos(c: f32, z: f32, fl: f32) -> f32 {
    let tan_g = 3.0 * std::f32::consts::SQRT_2 * c * z * fl / 4.0;
    1.0 / (1.0 + tan_g * tan_g).sqrt()
}

impl Level {
    /// Moves the level's points and normals to where the camera would have measured them at
    /// the middle of a rolling-shutter readout (see [`crate::rolling_shutter`]): row `y` of its
    /// `height` rows is exposed `s = ((y + ½)/height − ½)·
    /// readout_fraction` frame intervals after the middle, and a point measured then is
    /// `motionˢ·p` in the camera at the middle (`motion`: the camera's motion over one frame
    /// interval, camera frame). `aux` (the measurement's σ) is left as measured.
    pub fn undo_rolling_shutter(
        &mut self,
        motion: &nalgebra::Isometry3<f64>,
        readout_fraction: f64,
    ) {
        let Some(k) = self.k else { return };
        let (w, h) = (k.width.max(1), k.height);
        self.points
            .par_chunks_mut(w)
            .zip(self.normals.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (prow, nrow))| {
                let m = motion_power(motion, row_offset(y, h, readout_fraction)).cast::<f32>();
                // Branch-free (every point moved, the valid ones kept), so that the loops
                // vectorise; the kept values are the same.
                for p in prow.iter_mut() {
                    let q = m * *p;
                    *p = if p.z.is_finite() { q } else { *p };
                }
                for n in nrow.iter_mut() {
                    let r = m.rotation * *n;
                    *n = if n.x.is_finite() { r } else { *n };
                }
            });
    }

    /// Intrinsics of this level (set by [`Pyramid::build`]).
    pub fn intrinsics(&self) -> Option<&Intrinsics> {
        self.k.as_ref()
    }

    /// Computes the normals (and `aux`) a level built on a grid ([`Pyramid::build`]'s
    /// `stride0`) left out, so that every pixel has them: the same values a build on every
    /// pixel gives. `fl`: the full-resolution focal length, pixels; `r`: the level's normal
    /// baseline (2 at full resolution).
    pub fn complete_normals(&mut self, sensor: &SensorModel, fl: f32, r: usize) {
        if self.normal_stride <= 1 {
            return;
        }
        let Some(k) = self.k else {
            return;
        };
        let sel = Select {
            stride: self.normal_stride,
            off_grid: true,
        };
        normals_and_aux(self, &k, sensor, r, fl, sel);
        self.normal_stride = 1;
    }
}

/// The pyramid: level 0 is the input resolution, each further level half the previous one.
#[derive(Debug, Clone, Default)]
pub(crate) struct Pyramid {
    pub levels: Vec<Level>,
}

/// The baseline of level `l`'s central-difference normals, pixels (see `normals`).
pub(crate) fn normal_radius(l: usize) -> usize {
    if l == 0 { 2 } else { 1 }
}

/// Checks that a camera can be halved `levels − 1` times: the error names the camera and the
/// pyramid instead of the coarsest level's intrinsics.
pub(crate) fn check_levels(k: &Intrinsics, levels: usize) -> Result<()> {
    let mut kl = *k;
    for _ in 1..levels {
        kl = half(&kl).map_err(|e| {
            TrackError::InvalidConfig(format!(
                "a {}x{} camera with fx = {} px is too small for a pyramid of {levels} levels, \
                 each half the previous one ({e}): fewer levels or a larger camera",
                k.width, k.height, k.fx
            ))
        })?;
    }
    Ok(())
}

/// Intrinsics of a 2×2-downsampled image (pixel-centre convention of `Intrinsics::scaled`).
fn half(k: &Intrinsics) -> Result<Intrinsics> {
    Ok(Intrinsics::new(
        k.width / 2,
        k.height / 2,
        k.fx * 0.5,
        k.fy * 0.5,
        (k.cx + 0.5) * 0.5 - 0.5,
        (k.cy + 0.5) * 0.5 - 0.5,
    )?)
}

/// Depth-aware 2×2 downsampling: the mean of the block's valid depths on the nearest one's
/// surface, 0 when the block has no valid depth. A block straddling a depth edge keeps the
/// front surface instead of a point in the air between the two; the edge is the normals'
/// ([`edge_jump_m`] across the block's diagonal). `fx` is the source image's focal length,
/// pixels.
///
/// The slant term matters: with the noise alone as the gate, a surface seen obliquely (a
/// corridor's walls, whose depth changes by more than 3σ_Z from one pixel to the next once the
/// image is coarser than the sensor) lost the far pixels of every block, and its points moved
/// half a pixel's depth step towards the camera. The walls of a corridor then converged (by
/// 1/(2f) rad each), and their planes claimed information along the corridor's axis that the
/// geometry does not give (docs/bench/track.md, session 25).
fn downsample(src: &[f32], sw: usize, dst: &mut [f32], dw: usize, sensor: &SensorModel, fx: f64) {
    let (c, fx) = ((sensor.sigma_d_px / sensor.fb()) as f32, fx as f32);
    // Branch-free per pixel, so that the loop vectorises: an invalid depth (not positive, or
    // NaN) takes part as +∞ in the minimum and as 0 in the sums. The minimum of values that
    // are never NaN is exact in any order, and adding 0 to a non-negative sum leaves its bits,
    // so every output equals the filtered minimum and conditional sums bit for bit.
    let lowest = |a: f32, b: f32| if b < a { b } else { a };
    dst.par_chunks_mut(dw.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let top = src.get(2 * y * sw..(2 * y + 1) * sw).unwrap_or(&[]);
            let bottom = src.get((2 * y + 1) * sw..(2 * y + 2) * sw).unwrap_or(&[]);
            let blocks = top.chunks_exact(2).zip(bottom.chunks_exact(2));
            for (out, (t, b)) in row.iter_mut().zip(blocks) {
                let zs = [t[0], t[1], b[0], b[1]];
                let low = zs.map(|z| if z > 0.0 { z } else { f32::INFINITY });
                let zmin = lowest(lowest(lowest(low[0], low[1]), low[2]), low[3]);
                let gate = edge_jump_m(std::f32::consts::SQRT_2, zmin, fx, c);
                let (mut s, mut n) = (0.0f32, 0.0f32);
                for z in zs {
                    let take = z > 0.0 && z - zmin <= gate;
                    s += if take { z } else { 0.0 };
                    n += if take { 1.0 } else { 0.0 };
                }
                *out = if zmin.is_finite() { s / n } else { 0.0 };
            }
        });
}

/// The vertex map of one level from its depth.
fn vertices(level: &mut Level, k: &Intrinsics) {
    let (w, h) = (k.width, k.height);
    let nan_p = Point3::new(f32::NAN, f32::NAN, f32::NAN);
    level.points.resize(w * h, nan_p);
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let depth = &level.depth;
    level
        .points
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            let zs = depth.get(y * w..(y + 1) * w).unwrap_or(&[]);
            let yc = y as f32 - cy;
            // Branch-free (both sides computed, one kept), so that the loop vectorises; the
            // kept point is computed as before, bit for bit.
            for (x, (p, &z)) in row.iter_mut().zip(zs).enumerate() {
                let q = Point3::new((x as f32 - cx) * z / fx, yc * z / fy, z);
                *p = if z > 0.0 { q } else { nan_p };
            }
        });
}

impl Pyramid {
    /// Builds `levels` levels from a depth map of `k`'s size (checked by the caller). Level 0
    /// gets normals on the grid of every `stride0`-th column and row only (the pixels the
    /// association pass samples there, [`crate::TrackerConfig::sample_stride`]; 1: all); see
    /// [`Level::complete_normals`].
    pub fn build(
        &mut self,
        depth: &[f32],
        k: &Intrinsics,
        sensor: &SensorModel,
        levels: usize,
        stride0: usize,
    ) -> Result<()> {
        self.levels.resize_with(levels, Level::default);
        let mut kl = *k;
        for l in 0..levels {
            if l == 0 {
                let lv = &mut self.levels[0];
                lv.depth.clear();
                lv.depth.extend_from_slice(depth);
            } else {
                let kh = half(&kl)?;
                let (prev, rest) = self.levels.split_at_mut(l);
                let src = &prev[l - 1].depth;
                let lv = &mut rest[0];
                lv.depth.resize(kh.width * kh.height, 0.0);
                downsample(src, kl.width, &mut lv.depth, kh.width, sensor, kl.fx);
                kl = kh;
            }
            let lv = &mut self.levels[l];
            lv.k = Some(kl);
            let sel = Select {
                stride: if l == 0 { stride0.max(1) } else { 1 },
                off_grid: false,
            };
            lv.normal_stride = sel.stride;
            vertices(lv, &kl);
            normals_and_aux(lv, &kl, sensor, normal_radius(l), k.fx as f32, sel);
        }
        Ok(())
    }
}

//! The depth pyramid of the frame being tracked: depth-aware 2×2 downsampling, and per level the
//! camera-frame vertex and normal maps. Buffers are kept and reused from frame to frame.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::{Intrinsics, SensorModel};

use crate::error::Result;

/// The largest angle between a surface and the line of sight for which a normal is computed
/// (tan 80° ≈ 5.7): neighbouring pixels one pixel apart at depth `z` differ by up to
/// `z/f·tan(80°)` on such a surface, plus the sensor noise; larger jumps are depth edges.
const MAX_SLANT_TAN: f32 = 5.67;

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

/// Fills `level.aux` from its points and normals.
fn point_aux(level: &mut Level, sensor: &SensorModel, fl: f32) {
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let n = level.points.len();
    level.aux.resize(n, PointAux::default());
    level
        .aux
        .par_iter_mut()
        .zip(level.points.par_iter())
        .zip(level.normals.par_iter())
        .for_each(|((a, pc), nc)| {
            *a = if nc.x.is_finite() {
                let z = pc.z;
                PointAux {
                    ray_len: pc.coords.norm(),
                    cz2: c * z * z,
                    cos_gate: normal_gate_cos(c, z, fl),
                }
            } else {
                PointAux::default()
            };
        });
}

impl Level {
    /// Intrinsics of this level (set by [`Pyramid::build`]).
    pub fn intrinsics(&self) -> Option<&Intrinsics> {
        self.k.as_ref()
    }
}

/// The pyramid: level 0 is the input resolution, each further level half the previous one.
#[derive(Debug, Clone, Default)]
pub(crate) struct Pyramid {
    pub levels: Vec<Level>,
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

/// Depth-aware 2×2 downsampling: the mean of the block's valid depths within 3·σ_Z of the
/// nearest one (a block straddling a depth edge keeps the front surface instead of a point in
/// the air between the two), 0 when the block has no valid depth.
fn downsample(src: &[f32], sw: usize, dst: &mut [f32], dw: usize, sensor: &SensorModel) {
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    dst.par_chunks_mut(dw.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                let i = 2 * y * sw + 2 * x;
                let zs = [src[i], src[i + 1], src[i + sw], src[i + sw + 1]];
                let zmin = zs
                    .iter()
                    .copied()
                    .filter(|z| *z > 0.0)
                    .fold(f32::INFINITY, f32::min);
                if !zmin.is_finite() {
                    *out = 0.0;
                    continue;
                }
                let gate = 3.0 * c * zmin * zmin;
                let (mut s, mut n) = (0.0f32, 0.0f32);
                for z in zs {
                    if z > 0.0 && z - zmin <= gate {
                        s += z;
                        n += 1.0;
                    }
                }
                *out = s / n;
            }
        });
}

/// Vertex and normal maps of one level from its depth. Normals are central differences over
/// `±r` pixels: Kinect depth is quantised into terraces (1 cm steps at 2 m) and one-pixel
/// differences give normals tens of degrees off; at full resolution `r = 2` (the coarser levels
/// are already averaged, `r = 1`).
fn vertices_normals(level: &mut Level, k: &Intrinsics, sensor: &SensorModel, r: usize) {
    let (w, h) = (k.width, k.height);
    let nan_p = Point3::new(f32::NAN, f32::NAN, f32::NAN);
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    level.points.resize(w * h, nan_p);
    level.normals.resize(w * h, nan_n);
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    let depth = &level.depth;
    level
        .points
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, p) in row.iter_mut().enumerate() {
                let z = depth[y * w + x];
                *p = if z > 0.0 {
                    Point3::new((x as f32 - cx) * z / fx, (y as f32 - cy) * z / fy, z)
                } else {
                    nan_p
                };
            }
        });
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let points = &level.points;
    level
        .normals
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, n) in row.iter_mut().enumerate() {
                *n = nan_n;
                if x < r || y < r || x + r >= w || y + r >= h {
                    continue;
                }
                let i = y * w + x;
                let z = depth[i];
                if z <= 0.0 {
                    continue;
                }
                // A jump larger than a surface at 80° to the line of sight plus 3σ of noise is
                // a depth edge.
                let gate = r as f32 * z / fx * MAX_SLANT_TAN + 3.0 * c * z * z;
                let nb = [i - r, i + r, i - r * w, i + r * w];
                if nb
                    .iter()
                    .any(|&j| depth[j] <= 0.0 || depth[j].is_nan() || (depth[j] - z).abs() > gate)
                {
                    continue;
                }
                let dx = points[i + r] - points[i - r];
                let dy = points[i + r * w] - points[i - r * w];
                let m = dx.cross(&dy);
                let len = m.norm();
                if len <= 0.0 || len.is_nan() {
                    continue;
                }
                let mut m = m / len;
                if m.dot(&points[i].coords) > 0.0 {
                    m = -m;
                }
                *n = m;
            }
        });
}

impl Pyramid {
    /// Builds `levels` levels from a depth map of `k`'s size (checked by the caller).
    pub fn build(
        &mut self,
        depth: &[f32],
        k: &Intrinsics,
        sensor: &SensorModel,
        levels: usize,
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
                downsample(src, kl.width, &mut lv.depth, kh.width, sensor);
                kl = kh;
            }
            let lv = &mut self.levels[l];
            lv.k = Some(kl);
            vertices_normals(lv, &kl, sensor, if l == 0 { 2 } else { 1 });
            point_aux(lv, sensor, k.fx as f32);
        }
        Ok(())
    }
}

//! The depth pyramid of the frame being tracked: depth-aware 2×2 downsampling, and per level the
//! camera-frame vertex and normal maps. Buffers are kept and reused from frame to frame.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::{Intrinsics, SensorModel};

use crate::error::{Result, TrackError};
use crate::rolling_shutter::{motion_power, row_offset};

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

/// Which pixels of a level get a normal: those on the grid of every `stride`-th column and
/// row (`off_grid = false`; `stride = 1`: all), or the others (`off_grid = true`, completing a
/// level built on the grid).
#[derive(Debug, Clone, Copy)]
struct Select {
    stride: usize,
    off_grid: bool,
}

impl Select {
    /// Sets the selected entries of image row `y` to `f(x)`; the others to `unset` when
    /// selecting the grid, unchanged when completing it.
    #[inline(always)]
    #[cfg(test)]
    fn apply<T: Copy>(&self, row: &mut [T], y: usize, unset: T, f: impl Fn(usize) -> T) {
        let s = self.stride.max(1);
        let row_on_grid = y.is_multiple_of(s);
        match (self.off_grid, row_on_grid) {
            (false, false) => row.fill(unset),
            (false, true) => {
                if s > 1 {
                    row.fill(unset);
                }
                for (x, v) in row.iter_mut().enumerate().step_by(s) {
                    *v = f(x);
                }
            }
            (true, false) => {
                for (x, v) in row.iter_mut().enumerate() {
                    *v = f(x);
                }
            }
            (true, true) => {
                for (x, v) in row.iter_mut().enumerate() {
                    if !x.is_multiple_of(s) {
                        *v = f(x);
                    }
                }
            }
        }
    }
}

/// Fills `level.aux` from its points and normals on the selected pixels (the others: the
/// default when selecting the grid, unchanged when completing it). The reference of
/// [`normals_and_aux`], which computes the same bits in batches.
#[cfg(test)]
fn point_aux(level: &mut Level, sensor: &SensorModel, fl: f32, w: usize, sel: Select) {
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let n = level.points.len();
    level.aux.resize(n, PointAux::default());
    level
        .aux
        .par_chunks_mut(w.max(1))
        .zip(level.points.par_chunks(w.max(1)))
        .zip(level.normals.par_chunks(w.max(1)))
        .enumerate()
        .for_each(|(y, ((arow, prow), nrow))| {
            sel.apply(arow, y, PointAux::default(), |x| {
                let (pc, nc) = (&prow[x], &nrow[x]);
                if nc.x.is_finite() {
                    let z = pc.z;
                    PointAux {
                        ray_len: pc.coords.norm(),
                        cz2: c * z * z,
                        cos_gate: normal_gate_cos(c, z, fl),
                    }
                } else {
                    PointAux::default()
                }
            })
        });
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

/// The normal map of one level (on the pixels `sel` selects; NaN on the others when selecting
/// a grid, unchanged when completing one) from its depth and vertices. Normals are central
/// differences over `±r` pixels: Kinect depth is quantised into terraces (1 cm steps at 2 m)
/// and one-pixel differences give normals tens of degrees off; at full resolution `r = 2` (the
/// coarser levels are already averaged, `r = 1`). The reference of [`normals_and_aux`], which
/// computes the same bits in batches.
#[cfg(test)]
fn normals(level: &mut Level, k: &Intrinsics, sensor: &SensorModel, r: usize, sel: Select) {
    let (w, h) = (k.width, k.height);
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    level.normals.resize(w * h, nan_n);
    let fx = k.fx as f32;
    let depth = &level.depth;
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let points = &level.points;
    let normal_at = |x: usize, y: usize| -> Vector3<f32> {
        if x < r || y < r || x + r >= w || y + r >= h {
            return nan_n;
        }
        let i = y * w + x;
        let z = depth[i];
        if z <= 0.0 {
            return nan_n;
        }
        let gate = edge_jump_m(r as f32, z, fx, c);
        let nb = [i - r, i + r, i - r * w, i + r * w];
        if nb
            .iter()
            .any(|&j| depth[j] <= 0.0 || depth[j].is_nan() || (depth[j] - z).abs() > gate)
        {
            return nan_n;
        }
        let dx = points[i + r] - points[i - r];
        let dy = points[i + r * w] - points[i - r * w];
        let m = dx.cross(&dy);
        let len = m.norm();
        if len <= 0.0 || len.is_nan() {
            return nan_n;
        }
        let m = m / len;
        if m.dot(&points[i].coords) > 0.0 {
            -m
        } else {
            m
        }
    };
    level
        .normals
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| sel.apply(row, y, nan_n, |x| normal_at(x, y)));
}

/// Pixels per batch of [`normals_and_aux`]: one AVX2 register of `f32`, two SSE2 registers.
const LANES: usize = 8;

/// The normals of a level's selected pixels and their [`PointAux`] (see `normals` and
/// `point_aux` in the tests: the same operations in the same order, so the same bits), in
/// batches of [`LANES`] pixels of a row — consecutive, or a grid row's pixels `stride` apart —:
/// the depths around them loaded, the points recomputed from them as [`vertices`] computes
/// them, the arithmetic in branch-free structure-of-arrays loops the compiler vectorises, and
/// the selected pixels' results written back (completing a grid, a batch computes the grid's
/// pixels too and drops them). A per-pixel closure with early returns cost about 150
/// instructions a normal, most of the pyramid's time (session 34).
fn normals_and_aux(
    level: &mut Level,
    k: &Intrinsics,
    sensor: &SensorModel,
    r: usize,
    fl: f32,
    sel: Select,
) {
    let (w, h) = (k.width, k.height);
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    level.normals.resize(w * h, nan_n);
    level.aux.resize(w * h, PointAux::default());
    let consts = NormalConsts {
        w,
        r,
        fx: k.fx as f32,
        fy: k.fy as f32,
        cx: k.cx as f32,
        cy: k.cy as f32,
        c: (sensor.sigma_d_px / sensor.fb()) as f32,
        fl,
    };
    let depth = &level.depth;
    level
        .normals
        .par_chunks_mut(w.max(1))
        .zip(level.aux.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(y, (nrow, arow))| {
            let s = sel.stride.max(1);
            let row_on_grid = y.is_multiple_of(s);
            if !sel.off_grid && (!row_on_grid || s > 1) {
                nrow.fill(nan_n);
                arow.fill(PointAux::default());
            }
            if !sel.off_grid && !row_on_grid {
                return;
            }
            let selected = |x: usize| match (sel.off_grid, row_on_grid) {
                (false, _) => x.is_multiple_of(s),
                (true, false) => true,
                (true, true) => !x.is_multiple_of(s),
            };
            // Pixels whose neighbours `r` away leave the image get no normal.
            let interior = y >= r && y + r < h && w > 2 * r;
            let (lo, hi) = if interior { (r, w - r) } else { (0, 0) };
            for x in (0..lo).chain(hi..w).filter(|&x| selected(x)) {
                nrow[x] = nan_n;
                arow[x] = PointAux::default();
            }
            if hi < lo + LANES {
                // Fewer interior pixels than a batch: one batch over the clamped range.
                for x in (lo..hi).filter(|&x| selected(x)) {
                    let (n, a) = normal_one(&consts, depth, x, y);
                    nrow[x] = n;
                    arow[x] = a;
                }
                return;
            }
            if !sel.off_grid && s > 1 {
                // A grid row: batches of `LANES` grid pixels `s` apart, the rest one by one.
                let mut x0 = lo.next_multiple_of(s);
                while x0 + (LANES - 1) * s < hi {
                    let (normals, aux) = normal_batch(&consts, depth, x0, s, y);
                    for l in 0..LANES {
                        nrow[x0 + l * s] = normals[l];
                        arow[x0 + l * s] = aux[l];
                    }
                    x0 += LANES * s;
                }
                for x in (x0..hi).step_by(s) {
                    let (n, a) = normal_one(&consts, depth, x, y);
                    nrow[x] = n;
                    arow[x] = a;
                }
                return;
            }
            let mut x0 = lo;
            while x0 < hi {
                // The last batch ends at `hi` (it recomputes some pixels: the same values).
                let start = x0.min(hi - LANES);
                let (normals, aux) = normal_batch(&consts, depth, start, 1, y);
                for l in 0..LANES {
                    let x = start + l;
                    if x >= x0 && selected(x) {
                        nrow[x] = normals[l];
                        arow[x] = aux[l];
                    }
                }
                x0 = start + LANES;
            }
        });
}

/// The constants of [`normal_batch`].
struct NormalConsts {
    w: usize,
    /// The central differences' baseline, pixels.
    r: usize,
    /// The level's intrinsics.
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    /// `σ_D/(f·B)`: σ_Z = c·z².
    c: f32,
    /// The full-resolution focal length, pixels (the normal gate).
    fl: f32,
}

/// `LANES` values of `v`, `step` apart from `i` on.
#[inline(always)]
fn lanes(v: &[f32], i: usize, step: usize) -> [f32; LANES] {
    let mut out = [0f32; LANES];
    if step == 1 {
        out.copy_from_slice(&v[i..i + LANES]);
    } else {
        let span = &v[i..=i + (LANES - 1) * step];
        for (o, x) in out.iter_mut().zip(span.iter().step_by(step)) {
            *o = *x;
        }
    }
    out
}

/// The normal and [`PointAux`] of interior pixel `(x, y)` (its neighbours `r` away inside the
/// image): [`normal_batch`]'s arithmetic with the pixel in every lane, lane 0 kept.
fn normal_one(k: &NormalConsts, depth: &[f32], x: usize, y: usize) -> (Vector3<f32>, PointAux) {
    let (w, r) = (k.w, k.r);
    let i = y * w + x;
    let at = |j: usize| [depth[j]; LANES];
    let (n, a) = normal_lanes(
        k,
        [at(i), at(i - r), at(i + r), at(i - r * w), at(i + r * w)],
        x,
        0,
        y,
    );
    (n[0], a[0])
}

/// The normals and [`PointAux`] of the interior pixels `x0 + l·step` (`l < LANES`) of row `y`.
#[inline(always)]
fn normal_batch(
    k: &NormalConsts,
    depth: &[f32],
    x0: usize,
    step: usize,
    y: usize,
) -> ([Vector3<f32>; LANES], [PointAux; LANES]) {
    let (w, r) = (k.w, k.r);
    let i = y * w + x0;
    normal_lanes(
        k,
        [
            lanes(depth, i, step),
            lanes(depth, i - r, step),
            lanes(depth, i + r, step),
            lanes(depth, i - r * w, step),
            lanes(depth, i + r * w, step),
        ],
        x0,
        step,
        y,
    )
}

/// The arithmetic of [`normal_batch`] on the depths `[centre, left, right, up, down]` of the
/// pixels `x0 + l·step` of row `y` (lane `l`; [`normal_one`] passes one pixel in every lane,
/// `step` 0).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn normal_lanes(
    k: &NormalConsts,
    d: [[f32; LANES]; 5],
    x0: usize,
    step: usize,
    y: usize,
) -> ([Vector3<f32>; LANES], [PointAux; LANES]) {
    let r = k.r;
    let [z, zl, zr, zu, zd] = d;
    // Pixel coordinates as `f32` (exact: images are far narrower than 2²⁴ pixels), built from
    // lane offsets so that the conversions vectorise.
    const OFFSETS: [f32; LANES] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    let (x0f, rf, stepf) = (x0 as f32, r as f32, step as f32);
    let (yf, yu, yd) = (y as f32, (y - r) as f32, (y + r) as f32);
    let point = |xf: f32, yf: f32, z: f32| {
        // As `vertices`: ((x − cx)·z/fx, (y − cy)·z/fy, z).
        ((xf - k.cx) * z / k.fx, (yf - k.cy) * z / k.fy)
    };
    let mut out = [[0f32; LANES]; 3];
    let mut valid = [false; LANES];
    let mut aux = [[0f32; LANES]; 3];
    for l in 0..LANES {
        let xf = x0f + OFFSETS[l] * stepf;
        let zc = z[l];
        let gate = edge_jump_m(r as f32, zc, k.fx, k.c);
        let mut edge = false;
        for dj in [zl[l], zr[l], zu[l], zd[l]] {
            // (Non-short-circuit: branch-free, so that the loop vectorises.)
            edge |= (dj <= 0.0) | dj.is_nan() | ((dj - zc).abs() > gate);
        }
        let (plx, ply) = point(xf - rf, yf, zl[l]);
        let (prx, pry) = point(xf + rf, yf, zr[l]);
        let (pux, puy) = point(xf, yu, zu[l]);
        let (pdx, pdy) = point(xf, yd, zd[l]);
        let dx = [prx - plx, pry - ply, zr[l] - zl[l]];
        let dy = [pdx - pux, pdy - puy, zd[l] - zu[l]];
        // `dx.cross(&dy)`, its norm and the unit normal, as nalgebra computes them.
        let m = [
            dx[1] * dy[2] - dx[2] * dy[1],
            dx[2] * dy[0] - dx[0] * dy[2],
            dx[0] * dy[1] - dx[1] * dy[0],
        ];
        let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
        let u = [m[0] / len, m[1] / len, m[2] / len];
        let (pcx, pcy) = point(xf, yf, zc);
        let facing = u[0] * pcx + u[1] * pcy + u[2] * zc;
        let flip = facing > 0.0;
        // (`z <= 0` is the invalid depth; a NaN centre is not rejected here, as in `normals`.)
        valid[l] = ((zc > 0.0) | zc.is_nan()) & !edge & (len > 0.0);
        for a in 0..3 {
            out[a][l] = if flip { -u[a] } else { u[a] };
        }
        aux[0][l] = (pcx * pcx + pcy * pcy + zc * zc).sqrt();
        aux[1][l] = k.c * zc * zc;
        aux[2][l] = normal_gate_cos(k.c, zc, k.fl);
    }
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    let mut normals = [nan_n; LANES];
    let mut auxes = [PointAux::default(); LANES];
    for l in 0..LANES {
        if valid[l] {
            normals[l] = Vector3::new(out[0][l], out[1][l], out[2][l]);
        }
        // Where the normal is finite, as `point_aux` decides from the stored normal.
        if normals[l].x.is_finite() {
            auxes[l] = PointAux {
                ray_len: aux[0][l],
                cz2: aux[1][l],
                cos_gate: aux[2][l],
            };
        }
    }
    (normals, auxes)
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

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use sl_core::Camera;

    /// A slanted wall with a box in front and holes: depth edges, invalid pixels, borders.
    fn scene(k: &Intrinsics) -> Vec<f32> {
        let mut d = vec![0.0f32; k.width * k.height];
        for y in 0..k.height {
            for x in 0..k.width {
                let (xf, yf) = (x as f32, y as f32);
                let mut z = 2.0 + 0.002 * xf + 0.001 * yf;
                if (200..400).contains(&x) && (150..300).contains(&y) {
                    z = 1.2 + 0.0005 * (xf - 300.0).abs();
                }
                if (x * 7 + y * 13) % 97 == 0 {
                    z = 0.0;
                }
                d[y * k.width + x] = z;
            }
        }
        d
    }

    fn bits(v: &[Vector3<f32>]) -> Vec<[u32; 3]> {
        v.iter()
            .map(|n| [n.x.to_bits(), n.y.to_bits(), n.z.to_bits()])
            .collect()
    }

    fn aux_bits(v: &[PointAux]) -> Vec<[u32; 3]> {
        v.iter()
            .map(|a| [a.ray_len.to_bits(), a.cz2.to_bits(), a.cos_gate.to_bits()])
            .collect()
    }

    /// The depth-aware 2×2 downsampling as it was written before it was made branch-free:
    /// the minimum of the valid depths, then the sums of those within the edge gate of it.
    fn downsample_with_branches(
        src: &[f32],
        sw: usize,
        dw: usize,
        dh: usize,
        c: f32,
        fx: f32,
    ) -> Vec<f32> {
        let mut out = vec![f32::NAN; dw * dh];
        for y in 0..dh {
            for x in 0..dw {
                let i = 2 * y * sw + 2 * x;
                let zs = [src[i], src[i + 1], src[i + sw], src[i + sw + 1]];
                let zmin = zs
                    .iter()
                    .copied()
                    .filter(|z| *z > 0.0)
                    .fold(f32::INFINITY, f32::min);
                out[y * dw + x] = if zmin.is_finite() {
                    let gate = edge_jump_m(std::f32::consts::SQRT_2, zmin, fx, c);
                    let (mut s, mut n) = (0.0f32, 0.0f32);
                    for z in zs {
                        if z > 0.0 && z - zmin <= gate {
                            s += z;
                            n += 1.0;
                        }
                    }
                    s / n
                } else {
                    0.0
                };
            }
        }
        out
    }

    /// The branch-free downsampling gives the filtered minimum and conditional sums bit for
    /// bit, on blocks with every mix of valid, zero, negative, NaN and infinite depths and
    /// with depth edges inside them, on an odd-sized source (its last column and row unused).
    #[test]
    fn branch_free_downsampling_is_the_filtered_one() {
        let (sw, sh) = (67usize, 41usize);
        let odd = [0.0, -0.5, f32::NAN, f32::INFINITY];
        let src: Vec<f32> = (0..sw * sh)
            .map(|i| {
                let (x, y) = (i % sw, i / sw);
                let h = (x * 31 + y * 17) % 11;
                if (10..14).contains(&x) && (6..10).contains(&y) {
                    odd[(x + y) % 4]
                } else if h < 4 {
                    odd[h]
                } else if (x / 5 + y / 3) % 2 == 0 {
                    1.1 + 0.001 * (x + y) as f32
                } else {
                    2.9 + 0.0007 * (x * y) as f32
                }
            })
            .collect();
        let sensor = Camera::kinect_v1().sensor;
        let (dw, dh) = (sw / 2, sh / 2);
        for fx in [580.0f64, 145.0] {
            let mut dst = vec![f32::NAN; dw * dh];
            downsample(&src, sw, &mut dst, dw, &sensor, fx);
            let c = (sensor.sigma_d_px / sensor.fb()) as f32;
            let want = downsample_with_branches(&src, sw, dw, dh, c, fx as f32);
            let to_bits = |v: &[f32]| v.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
            assert_eq!(to_bits(&dst), to_bits(&want), "fx {fx}");
            // Every kind of block is there: empty ones, averaged ones and edges.
            assert!(dst.contains(&0.0));
            assert!(dst.iter().any(|&z| z > 2.0) && dst.iter().any(|&z| z > 0.0 && z < 2.0));
        }
    }

    #[test]
    fn a_level_built_on_a_grid_and_completed_equals_one_built_on_every_pixel() {
        let cam = Camera::kinect_v1();
        let (k, sensor) = (cam.intrinsics, cam.sensor);
        let depth = scene(&k);
        let mut full = Pyramid::default();
        full.build(&depth, &k, &sensor, 3, 1).unwrap();
        for stride in [2, 3] {
            let mut grid = Pyramid::default();
            grid.build(&depth, &k, &sensor, 3, stride).unwrap();
            let (g0, f0) = (&grid.levels[0], &full.levels[0]);
            let mut on_grid = 0;
            for (i, (g, f)) in g0.normals.iter().zip(&f0.normals).enumerate() {
                let (x, y) = (i % k.width, i / k.width);
                if x % stride == 0 && y % stride == 0 {
                    assert_eq!(bits(&[*g]), bits(&[*f]), "pixel ({x}, {y})");
                    on_grid += usize::from(f.x.is_finite());
                } else {
                    assert!(g.x.is_nan(), "pixel ({x}, {y}) is off the grid");
                }
            }
            assert!(on_grid > 1000, "{on_grid} grid normals");
            // The coarser levels do not depend on the grid.
            for l in 1..3 {
                assert_eq!(bits(&grid.levels[l].normals), bits(&full.levels[l].normals));
            }
            let mut done = grid.levels[0].clone();
            done.complete_normals(&sensor, k.fx as f32, normal_radius(0));
            assert_eq!(done.normal_stride, 1);
            assert_eq!(bits(&done.normals), bits(&f0.normals));
            assert_eq!(aux_bits(&done.aux), aux_bits(&f0.aux));
        }
    }

    /// A corridor's side wall (0.4 m to the camera's right, along the line of sight, 0.7–2.2 m
    /// away: seen at up to 80° from its normal) through a camera at half its sensor's
    /// resolution: from one pixel to the next its depth changes by more than 3σ_Z. The points
    /// of every coarser level must still lie on the wall. With the noise alone as the
    /// downsampling's edge gate each block kept its nearer column only: the points moved
    /// towards the camera, 0.9–2.3 mm off the wall at level 1 and 2.7–6.6 mm at level 2 (10th
    /// to 90th percentile), and the wall turned.
    #[test]
    fn coarser_levels_of_an_oblique_wall_stay_on_the_wall() {
        let cam = Camera::preset("oak-d").unwrap().resampled(0.5).unwrap();
        let (k, sensor) = (cam.intrinsics, cam.sensor);
        let wall_x = 0.4;
        let mut depth = vec![0.0f32; k.width * k.height];
        for y in 0..k.height {
            for x in 0..k.width {
                let dx = (x as f64 - k.cx) / k.fx;
                let z = wall_x / dx;
                if dx > 0.0 && (0.7..2.2).contains(&z) {
                    depth[y * k.width + x] = z as f32;
                }
            }
        }
        // The premise: neighbouring pixels differ by more than 3σ_Z over most of the wall.
        let (z0, z1) = (depth[k.width * 100 + 500], depth[k.width * 100 + 501]);
        assert!(z0 - z1 > 3.0 * sensor.sigma_z(f64::from(z0)) as f32);
        let mut pyramid = Pyramid::default();
        pyramid.build(&depth, &k, &sensor, 3, 1).unwrap();
        for (l, level) in pyramid.levels.iter().enumerate().skip(1) {
            let mut off: Vec<f32> = level
                .points
                .iter()
                .filter(|p| p.z > 0.0)
                .map(|p| p.x - wall_x as f32)
                .collect();
            let points = off.len();
            off.sort_by(f32::total_cmp);
            assert!(points > 1000, "level {l}: {points} points");
            // Four in five points within half a millimetre (the mean of a block's depths is a
            // little behind a curved 1/u, and blocks at the wall's ends are partial).
            let (p10, p90) = (off[points / 10], off[points * 9 / 10]);
            assert!(
                p10 > -5e-4 && p90 < 5e-4,
                "level {l}: off the wall by {p10} to {p90} m (10th to 90th percentile)"
            );
        }
    }

    /// The batched normals and `PointAux` are the per-pixel reference's, bit for bit: every
    /// level, on every pixel and on a grid, and completing a grid.
    #[test]
    fn batched_normals_are_the_per_pixel_ones() {
        let cam = Camera::kinect_v1();
        let (k0, sensor) = (cam.intrinsics, cam.sensor);
        let mut depth = scene(&k0);
        // Invalid and non-finite depths as well.
        depth[5000] = f32::NAN;
        depth[7000] = f32::INFINITY;
        depth[9000] = -1.0;
        let fl = k0.fx as f32;
        for stride in [1, 2, 3] {
            let mut pyramid = Pyramid::default();
            pyramid.build(&depth, &k0, &sensor, 3, stride).unwrap();
            for (l, level) in pyramid.levels.iter().enumerate() {
                let k = level.k.unwrap();
                let sel = Select {
                    stride: if l == 0 { stride } else { 1 },
                    off_grid: false,
                };
                let mut reference = level.clone();
                normals(&mut reference, &k, &sensor, normal_radius(l), sel);
                point_aux(&mut reference, &sensor, fl, k.width, sel);
                assert_eq!(bits(&level.normals), bits(&reference.normals), "level {l}");
                assert_eq!(aux_bits(&level.aux), aux_bits(&reference.aux), "level {l}");
                let finite = level.normals.iter().filter(|n| n.x.is_finite()).count();
                assert!(
                    finite > 1000 / (1 << (2 * l)),
                    "level {l}: {finite} normals"
                );
                if l == 0 && stride > 1 {
                    let mut done = level.clone();
                    done.complete_normals(&sensor, fl, normal_radius(0));
                    let off = Select {
                        stride,
                        off_grid: true,
                    };
                    normals(&mut reference, &k, &sensor, normal_radius(0), off);
                    point_aux(&mut reference, &sensor, fl, k.width, off);
                    assert_eq!(bits(&done.normals), bits(&reference.normals));
                    assert_eq!(aux_bits(&done.aux), aux_bits(&reference.aux));
                }
            }
        }
    }

    /// Narrow images: fewer interior pixels than a batch (one pixel at a time), and rows
    /// whose last batch overlaps the one before.
    #[test]
    fn narrow_levels_get_the_per_pixel_normals() {
        let sensor = Camera::kinect_v1().sensor;
        for w in [5, 11, 13, 20, 27] {
            let h = 9;
            let k = Intrinsics::new(w, h, 12.0, 12.0, w as f64 / 2.0, 4.0).unwrap();
            let depth: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32, (i / w) as f32);
                    if i % 17 == 3 {
                        0.0
                    } else {
                        1.5 + 0.01 * x - 0.02 * y + 0.003 * x * y
                    }
                })
                .collect();
            for stride in [1, 2] {
                let mut pyramid = Pyramid::default();
                pyramid.build(&depth, &k, &sensor, 1, stride).unwrap();
                let level = &pyramid.levels[0];
                let sel = Select {
                    stride,
                    off_grid: false,
                };
                let mut reference = level.clone();
                normals(&mut reference, &k, &sensor, normal_radius(0), sel);
                point_aux(&mut reference, &sensor, k.fx as f32, w, sel);
                assert_eq!(bits(&level.normals), bits(&reference.normals), "width {w}");
                assert_eq!(aux_bits(&level.aux), aux_bits(&reference.aux), "width {w}");
                if w > 5 {
                    assert!(level.normals.iter().any(|n| n.x.is_finite()), "width {w}");
                }
            }
        }
    }
}

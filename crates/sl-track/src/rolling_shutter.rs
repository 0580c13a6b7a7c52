//! A rolling-shutter frame moved to one instant: [`Rectifier`] (or [`rectify_depth`])
//! resamples a depth map whose rows were exposed one after the other by a moving camera into
//! the depth map the camera would have measured at the middle of the readout, so that it can
//! be fused at the frame's pose. The tracker aligns such frames row by row
//! ([`crate::TrackerConfig::rolling_shutter_readout_s`]); this is the same motion model
//! (constant velocity over the frame) applied to the image.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use sl_core::whole::floor_i32;
use sl_core::{DepthImage, Intrinsics, Isa, IsaKernel};

/// When row `y` of a frame of `height` rows was exposed, in frame intervals after the middle
/// of the readout: `s = ((y + ½)/height − ½)·readout_fraction`.
pub(crate) fn row_offset(y: usize, height: usize, readout_fraction: f64) -> f64 {
    ((y as f64 + 0.5) / height.max(1) as f64 - 0.5) * readout_fraction
}

/// `motionˢ`, the camera's motion over `s` frame intervals at constant velocity (`motion`:
/// over one interval; rotation and translation scaled).
pub(crate) fn motion_power(motion: &Isometry3<f64>, s: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(motion.translation.vector * s),
        UnitQuaternion::from_scaled_axis(motion.rotation.scaled_axis() * s),
    )
}

/// Writes into `out` (the size of `depth`) the depth map of a rolling-shutter frame moved to
/// the middle of its readout (see [`Rectifier::rectify`]; this allocates the rectifier's
/// buffers on every call).
pub fn rectify_depth(
    depth: &DepthImage,
    k: &Intrinsics,
    motion: &Isometry3<f64>,
    readout_fraction: f64,
    out: &mut DepthImage,
) {
    Rectifier::default().rectify(depth, k, motion, readout_fraction, out);
}

/// Moves rolling-shutter frames to the middle of their readout, keeping its buffers (a
/// displacement and a depth per pixel, 12 bytes) from frame to frame.
#[derive(Debug)]
pub struct Rectifier {
    /// Instruction set of the two passes (every one gives the same bits).
    isa: Isa,
    /// Per input pixel: where its point moves, `(Δx, Δy)` in pixels, and its depth there; NaN
    /// where the pixel is invalid or its point moves behind the camera. Three planes, so that
    /// both passes vectorise.
    dx: Vec<f32>,
    dy: Vec<f32>,
    z: Vec<f32>,
}

impl Default for Rectifier {
    /// A rectifier running on the best instruction set this CPU supports ([`Isa::detect`]).
    fn default() -> Self {
        Self::with_isa(Isa::detect())
    }
}

impl Rectifier {
    /// A rectifier running on `isa` (one this CPU does not support runs the portable code);
    /// the output is the same on every instruction set.
    pub fn with_isa(isa: Isa) -> Self {
        Self {
            isa,
            dx: Vec::new(),
            dy: Vec::new(),
            z: Vec::new(),
        }
    }

    /// Writes into `out` (the size of `depth`) the depth map of a rolling-shutter frame moved
    /// to the middle of its readout: `motion` is the camera's motion over one frame interval
    /// (camera frame, `T(t + Δ) = T(t)·motion`), `readout_fraction` the readout time over the
    /// frame interval. Each output pixel takes the nearest input pixel that lands on it: the
    /// input pixel at the output position minus the displacement of the point seen there (one
    /// refinement with the displacement of the pixel found), its point moved by its row's
    /// motion. Within a frame the displacement changes by a small fraction of a pixel per
    /// pixel, so this gather matches a forward projection except on the pixels next to depth
    /// edges; pixels with no valid source stay 0.
    ///
    /// Two passes, both compiled for the rectifier's instruction set: every pixel's
    /// displacement and moved depth (one division a pixel; vectorised), then the gathers from
    /// them (each pixel's first sample vectorised, the second gather scalar).
    pub fn rectify(
        &mut self,
        depth: &DepthImage,
        k: &Intrinsics,
        motion: &Isometry3<f64>,
        readout_fraction: f64,
        out: &mut DepthImage,
    ) {
        let (w, h) = (depth.width(), depth.height());
        if out.width() != w || out.height() != h || w == 0 {
            return;
        }
        let isa = self.isa;
        let cam = [k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32];
        for plane in [&mut self.dx, &mut self.dy, &mut self.z] {
            plane.resize(w * h, f32::NAN);
        }
        self.dx
            .par_chunks_mut(w)
            .zip(self.dy.par_chunks_mut(w))
            .zip(self.z.par_chunks_mut(w))
            .zip(depth.data().par_chunks(w))
            .enumerate()
            .for_each(|(y, (((dx, dy), z), zs))| {
                let map = RowMap::new(
                    &motion_power(motion, row_offset(y, h, readout_fraction)),
                    k,
                    y,
                );
                isa.run(MoveRow {
                    map: &map,
                    cam,
                    yf: y as f32,
                    zs,
                    dx,
                    dy,
                    z,
                });
            });
        let moved = Moved {
            dx: &self.dx,
            dy: &self.dy,
            z: &self.z,
            w,
            wl: w as f32 - 0.5,
            hl: h as f32 - 0.5,
        };
        out.data_mut()
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| {
                isa.run(GatherRow {
                    moved: &moved,
                    y,
                    row,
                })
            });
    }
}

/// Pass 1 over one row: each pixel's displacement and depth after its row's motion.
struct MoveRow<'a> {
    map: &'a RowMap,
    /// `fx, fy, cx, cy`.
    cam: [f32; 4],
    yf: f32,
    zs: &'a [f32],
    dx: &'a mut [f32],
    dy: &'a mut [f32],
    z: &'a mut [f32],
}

impl IsaKernel for MoveRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let [fx, fy, cx, cy] = self.cam;
        let n = self
            .zs
            .len()
            .min(self.dx.len())
            .min(self.dy.len())
            .min(self.z.len());
        let (zs, dxo, dyo, zo) = (
            &self.zs[..n],
            &mut self.dx[..n],
            &mut self.dy[..n],
            &mut self.z[..n],
        );
        // Two loops, so that both vectorise: the moved point of every pixel, then NaN where
        // the pixel is invalid or its point is behind the camera (one loop with the test made
        // LLVM branch per pixel around the arithmetic).
        for x in 0..n {
            // Through `i32`: a conversion that vectorises (`x` < 2^24, so the same value).
            let xf = x as i32 as f32;
            let q = self.map.point(xf, zs[x]);
            let inv = q[2].recip();
            dxo[x] = q[0] * inv * fx + cx - xf;
            dyo[x] = q[1] * inv * fy + cy - self.yf;
            zo[x] = q[2];
        }
        for x in 0..n {
            let zv = zs[x];
            let ok = (zv > 0.0) & (zv.abs() < f32::INFINITY) & (zo[x] > 0.0);
            dxo[x] = if ok { dxo[x] } else { f32::NAN };
            dyo[x] = if ok { dyo[x] } else { f32::NAN };
            zo[x] = if ok { zo[x] } else { f32::NAN };
        }
    }
}

/// The planes of pass 1 and the image bounds for pass 2.
struct Moved<'a> {
    dx: &'a [f32],
    dy: &'a [f32],
    z: &'a [f32],
    w: usize,
    /// `width − ½`, `height − ½`: a position is in the image when it is at least `−½` and
    /// below these.
    wl: f32,
    hl: f32,
}

impl Moved<'_> {
    /// Whether the position `(x, y)` lies in the image, and its nearest pixel's index (`x + ½`
    /// and `y + ½` rounded down, which is their truncation there); outside it and for NaN the
    /// index is meaningless (the callers discard it).
    #[inline(always)]
    fn sample(&self, x: f32, y: f32) -> (bool, usize) {
        let inside = (x >= -0.5) & (y >= -0.5) & (x < self.wl) & (y < self.hl);
        let i = (floor_i32(y + 0.5) as usize)
            .wrapping_mul(self.w)
            .wrapping_add(floor_i32(x + 0.5) as usize);
        (inside, i)
    }
}

/// Pixels of a row whose first samples are computed together in pass 2.
const GATHER_CHUNK: usize = 64;

/// Pass 2 over one output row: the displacement at the output pixel, then at the input pixel
/// it points to; the depth of the point found there.
struct GatherRow<'a> {
    moved: &'a Moved<'a>,
    y: usize,
    row: &'a mut [f32],
}

impl IsaKernel for GatherRow<'_> {
    type Output = ();

    #[inline(always)]
    fn run(self) {
        let m = self.moved;
        let w = m.w;
        let n = m.dx.len().min(m.dy.len()).min(m.z.len());
        if n == 0 || (self.y + 1) * w > n {
            return;
        }
        let (dx, dy, z) = (&m.dx[..n], &m.dy[..n], &m.z[..n]);
        let first = self.y * w;
        let yf = self.y as f32;
        let len = self.row.len().min(w);
        let (row, dx_row, dy_row) = (
            &mut self.row[..len],
            &dx[first..first + len],
            &dy[first..first + len],
        );
        // Per chunk of the row: the first sample of every pixel (a loop that vectorises),
        // then the gathers of the pixels whose first sample is in the image.
        let mut first_at = [0usize; GATHER_CHUNK];
        for x0 in (0..len).step_by(GATHER_CHUNK) {
            let m_len = GATHER_CHUNK.min(len - x0);
            for (j, f) in first_at[..m_len].iter_mut().enumerate() {
                let x = x0 + j;
                let xf = x as i32 as f32;
                let (inside, s) = m.sample(xf - dx_row[x], yf - dy_row[x]);
                *f = if inside { s } else { usize::MAX };
            }
            // With branches: scalar either way (written without them, LLVM does not use the
            // instruction sets' gathers here, and the count rose by 9 %).
            for (j, &s) in first_at[..m_len].iter().enumerate() {
                let x = x0 + j;
                let xf = x as i32 as f32;
                row[x] = match (dx.get(s), dy.get(s)) {
                    (Some(&dx2), Some(&dy2)) => match m.sample(xf - dx2, yf - dy2) {
                        (true, t) => z.get(t).copied().filter(|v| !v.is_nan()).unwrap_or(0.0),
                        (false, _) => 0.0,
                    },
                    _ => 0.0,
                };
            }
        }
    }
}

/// One row's motion applied to its pixels' rays: pixel `x` of the row at depth `z` moves to
/// `z·(a + x·b) + t` (`a + x·b` is the rotated ray, linear in `x` along a row), so a pixel costs
/// six multiply-adds instead of a rotation.
struct RowMap {
    a: [f32; 3],
    b: [f32; 3],
    t: [f32; 3],
}

impl RowMap {
    fn new(motion: &Isometry3<f64>, k: &Intrinsics, y: usize) -> Self {
        let r = motion.rotation;
        let a = r * Vector3::new(-k.cx / k.fx, (y as f64 - k.cy) / k.fy, 1.0);
        let b = r * Vector3::new(1.0 / k.fx, 0.0, 0.0);
        let t = motion.translation.vector;
        let f = |v: Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        Self {
            a: f(a),
            b: f(b),
            t: f(t),
        }
    }

    #[inline(always)]
    fn point(&self, x: f32, z: f32) -> [f32; 3] {
        std::array::from_fn(|i| z * (self.a[i] + x * self.b[i]) + self.t[i])
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::Point3;

    /// Without motion the frame is unchanged; with a pure rotation about the vertical axis
    /// (a pan), a fronto-parallel wall's rows are shifted by the rotation of their row's time,
    /// the middle row not at all.
    #[test]
    fn a_pan_shifts_each_row_by_its_share_of_the_rotation() {
        let k = Intrinsics::new(64, 48, 50.0, 50.0, 31.5, 23.5).unwrap();
        let mut data = vec![2.0f32; 64 * 48];
        // A vertical stripe of another depth marks column 32.
        for y in 0..48 {
            data[y * 64 + 32] = 1.5;
        }
        let depth = DepthImage::from_vec(64, 48, data).unwrap();
        let mut out = DepthImage::invalid(64, 48);
        rectify_depth(&depth, &k, &Isometry3::identity(), 0.9, &mut out);
        assert_eq!(out.data(), depth.data());
        // 8 px of pan per frame interval at the image centre: rows ±0.45·8 px at the ends.
        let angle = (8.0f64 / 50.0).atan();
        let pan = Isometry3::rotation(Vector3::y() * angle);
        rectify_depth(&depth, &k, &pan, 0.9, &mut out);
        let stripe = |y: usize| (0..64).find(|&x| (out.data()[y * 64 + x] - 1.5).abs() < 0.05);
        let (top, middle, bottom) = (stripe(0).unwrap(), stripe(24).unwrap(), stripe(47).unwrap());
        assert!((middle as i64 - 32).abs() <= 1, "middle {middle}");
        assert!(
            top < middle && middle < bottom || top > middle && middle > bottom,
            "{top} {middle} {bottom}"
        );
        assert!((top as i64 - bottom as i64).abs() >= 6, "{top} {bottom}");
    }

    /// The two passes as they were written before they were split into planes and compiled
    /// per instruction set (array of structures, `Option`s and saturating conversions): the
    /// definition the kernels must reproduce bit for bit.
    fn scalar_two_passes(
        depth: &DepthImage,
        k: &Intrinsics,
        motion: &Isometry3<f64>,
        readout_fraction: f64,
    ) -> Vec<f32> {
        let (w, h) = (depth.width(), depth.height());
        let src = depth.data();
        let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
        let mut moved = vec![[f32::NAN; 3]; w * h];
        for (y, (row, zs)) in moved.chunks_mut(w).zip(src.chunks(w)).enumerate() {
            let r = RowMap::new(
                &motion_power(motion, row_offset(y, h, readout_fraction)),
                k,
                y,
            );
            let yf = y as f32;
            for (x, (m, &z)) in row.iter_mut().zip(zs).enumerate() {
                let xf = x as f32;
                let q = r.point(xf, z);
                let inv = q[2].recip();
                let u = q[0] * inv * fx + cx;
                let v = q[1] * inv * fy + cy;
                let ok = z > 0.0 && z.is_finite() && q[2] > 0.0;
                *m = if ok {
                    [u - xf, v - yf, q[2]]
                } else {
                    [f32::NAN; 3]
                };
            }
        }
        let (wl, hl) = (w as f32 - 0.5, h as f32 - 0.5);
        let sample = |x: f32, y: f32| -> Option<usize> {
            (x >= -0.5 && y >= -0.5 && x < wl && y < hl)
                .then(|| (y + 0.5) as i32 as usize * w + (x + 0.5) as i32 as usize)
        };
        let mut out = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32, y as f32);
                let [dx, dy, _] = moved[y * w + x];
                out[y * w + x] = sample(xf - dx, yf - dy)
                    .and_then(|s| {
                        let [dx2, dy2, _] = moved[s];
                        sample(xf - dx2, yf - dy2)
                    })
                    .map_or(0.0, |t| {
                        let z = moved[t][2];
                        if z.is_nan() { 0.0 } else { z }
                    });
            }
        }
        out
    }

    /// Every instruction set gives the scalar definition's bits: on frames with holes, NaN,
    /// infinite and negative depths, widths that are not a multiple of any vector, and motions
    /// from none to one that moves much of the frame out of the image or behind the camera.
    #[test]
    fn every_instruction_set_gives_the_scalar_passes_bits() {
        let motions = [
            Isometry3::identity(),
            Isometry3::from_parts(
                Translation3::new(0.01, -0.004, 0.006),
                UnitQuaternion::from_scaled_axis(Vector3::new(0.02, 0.05, -0.01)),
            ),
            Isometry3::from_parts(
                Translation3::new(-0.3, 0.2, -1.6),
                UnitQuaternion::from_scaled_axis(Vector3::new(-0.4, 0.9, 0.3)),
            ),
        ];
        let mut compared = 0;
        for (w, h) in [(83usize, 61usize), (64, 48), (17, 5)] {
            let k =
                Intrinsics::new(w, h, 70.0, 68.0, w as f64 / 2.0 - 0.3, h as f64 / 2.0).unwrap();
            let data: Vec<f32> = (0..w * h)
                .map(|i| {
                    let (x, y) = (i % w, i / w);
                    match (x * 7 + y * 3) % 29 {
                        0 => 0.0,
                        1 => f32::NAN,
                        2 => f32::INFINITY,
                        3 => -1.0,
                        _ if (20..40).contains(&x) && (15..35).contains(&y) => {
                            1.2 + 0.002 * x as f32
                        }
                        _ => 2.5 + 0.01 * y as f32 + 0.003 * ((x * 13) % 7) as f32,
                    }
                })
                .collect();
            let depth = DepthImage::from_vec(w, h, data).unwrap();
            for motion in &motions {
                for readout in [0.0, 0.9] {
                    let want = scalar_two_passes(&depth, &k, motion, readout);
                    assert!(want.iter().any(|&z| z > 0.0));
                    for isa in Isa::ALL {
                        let mut out = DepthImage::invalid(w, h);
                        Rectifier::with_isa(isa).rectify(&depth, &k, motion, readout, &mut out);
                        let differ = out
                            .data()
                            .iter()
                            .zip(&want)
                            .filter(|(a, b)| a.to_bits() != b.to_bits())
                            .count();
                        assert_eq!(differ, 0, "{isa} {w}x{h} readout {readout}");
                        compared += 1;
                    }
                }
            }
        }
        assert_eq!(compared, 3 * 3 * 2 * Isa::ALL.len());
        // Sources exactly half a pixel off: a wall at 2 m seen with f = 64 px, c = 32 px (all
        // exact in binary) by a camera moving 4 m per interval sideways over a half-interval
        // readout shifts row `y` by exactly `y − 31.5` px, so every source lies on a tie.
        let k = Intrinsics::new(64, 64, 64.0, 64.0, 32.0, 32.0).unwrap();
        let data: Vec<f32> = (0..64 * 64)
            .map(|i| if i % 37 == 5 { 0.0 } else { 2.0 })
            .collect();
        let depth = DepthImage::from_vec(64, 64, data).unwrap();
        let motion = Isometry3::translation(4.0, 0.0, 0.0);
        let want = scalar_two_passes(&depth, &k, &motion, 0.5);
        assert!(want.iter().filter(|&&z| z > 0.0).count() > 100);
        for isa in Isa::ALL {
            let mut out = DepthImage::invalid(64, 64);
            Rectifier::with_isa(isa).rectify(&depth, &k, &motion, 0.5, &mut out);
            let bits = |v: &[f32]| v.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(out.data()), bits(&want), "{isa}: the ties");
        }
    }

    /// The two passes give what the gather computes pixel by pixel with each row's pose as an
    /// isometry (the direct formulation), on a scene with depth edges and holes, a pan-tilt
    /// and a translation: the same pixels except where `f32` rounding moves a source across a
    /// half-pixel boundary.
    #[test]
    fn the_two_passes_match_the_direct_gather() {
        let (w, h) = (80usize, 60usize);
        let k = Intrinsics::new(w, h, 70.0, 70.0, 39.5, 29.5).unwrap();
        let data: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x * 7 + y * 3) % 23 == 0 {
                    0.0
                } else if (20..40).contains(&x) && (15..35).contains(&y) {
                    1.2 + 0.002 * x as f32
                } else {
                    2.5 + 0.01 * y as f32
                }
            })
            .collect();
        let depth = DepthImage::from_vec(w, h, data).unwrap();
        let motion = Isometry3::from_parts(
            Translation3::new(0.01, -0.004, 0.006),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.02, 0.05, -0.01)),
        );
        let mut out = DepthImage::invalid(w, h);
        let mut r = Rectifier::default();
        r.rectify(&depth, &k, &motion, 0.9, &mut out);
        // The direct formulation.
        let rows: Vec<Isometry3<f64>> = (0..h)
            .map(|y| motion_power(&motion, row_offset(y, h, 0.9)))
            .collect();
        let src = depth.data();
        let moved = |x: usize, y: usize| -> Option<(f64, f64, f64)> {
            let z = f64::from(src[y * w + x]);
            (z > 0.0).then_some(())?;
            let p = Point3::new(
                (x as f64 - k.cx) * z / k.fx,
                (y as f64 - k.cy) * z / k.fy,
                z,
            );
            let q = rows[y] * p;
            (q.z > 0.0).then(|| (q.x / q.z * k.fx + k.cx, q.y / q.z * k.fy + k.cy, q.z))
        };
        let sample = |x: f64, y: f64| -> Option<(usize, usize)> {
            let (xr, yr) = (x.round(), y.round());
            (xr >= 0.0 && yr >= 0.0 && xr < w as f64 && yr < h as f64)
                .then_some((xr as usize, yr as usize))
        };
        let mut differ = 0;
        let mut valid = 0;
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f64, y as f64);
                let z = moved(x, y)
                    .and_then(|(u, v, _)| sample(2.0 * xf - u, 2.0 * yf - v))
                    .and_then(|(sx, sy)| {
                        let (u2, v2, _) = moved(sx, sy)?;
                        sample(xf - (u2 - sx as f64), yf - (v2 - sy as f64))
                    })
                    .and_then(|(tx, ty)| moved(tx, ty))
                    .map_or(0.0, |m| m.2);
                let got = f64::from(out.data()[y * w + x]);
                valid += usize::from(got > 0.0);
                if (got - z).abs() > 1e-4 {
                    differ += 1;
                }
            }
        }
        assert!(valid > w * h / 2, "{valid}");
        assert!(differ * 100 <= w * h, "{differ} of {} pixels differ", w * h);
        // The buffer is reused: a second frame gives the same output.
        let first = out.data().to_vec();
        r.rectify(&depth, &k, &motion, 0.9, &mut out);
        assert_eq!(out.data(), &first[..]);
    }
}

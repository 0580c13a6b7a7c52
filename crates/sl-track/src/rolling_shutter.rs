//! A rolling-shutter frame moved to one instant: [`Rectifier`] (or [`rectify_depth`])
//! resamples a depth map whose rows were exposed one after the other by a moving camera into
//! the depth map the camera would have measured at the middle of the readout, so that it can
//! be fused at the frame's pose. The tracker aligns such frames row by row
//! ([`crate::TrackerConfig::rolling_shutter_readout_s`]); this is the same motion model
//! (constant velocity over the frame) applied to the image.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use sl_core::{DepthImage, Intrinsics};

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
/// buffer on every call).
pub fn rectify_depth(
    depth: &DepthImage,
    k: &Intrinsics,
    motion: &Isometry3<f64>,
    readout_fraction: f64,
    out: &mut DepthImage,
) {
    Rectifier::default().rectify(depth, k, motion, readout_fraction, out);
}

/// Moves rolling-shutter frames to the middle of their readout, keeping its buffer (a
/// displacement per pixel, 12 bytes) from frame to frame.
#[derive(Debug, Default)]
pub struct Rectifier {
    /// Per input pixel: where its point moves, as `(Δx, Δy)` in pixels, and its depth there;
    /// NaN where the pixel is invalid or its point moves behind the camera.
    moved: Vec<[f32; 3]>,
}

impl Rectifier {
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
    /// Two passes: every pixel's displacement and moved depth (one division a pixel), then the
    /// gathers from them.
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
        let src = depth.data();
        let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
        self.moved.resize(w * h, [f32::NAN; 3]);
        self.moved
            .par_chunks_mut(w)
            .zip(src.par_chunks(w))
            .enumerate()
            .for_each(|(y, (moved, zs))| {
                let r = RowMap::new(
                    &motion_power(motion, row_offset(y, h, readout_fraction)),
                    k,
                    y,
                );
                let yf = y as f32;
                for (x, (m, &z)) in moved.iter_mut().zip(zs).enumerate() {
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
            });
        let moved = &self.moved[..];
        // The nearest pixel (`x + ½` truncated: `f32::round` is a library call on baseline
        // x86-64); `None` outside the image or for NaN. Inside, `x + ½` lies in `[0, w)`, so the
        // truncation through `i32` (one instruction) equals the saturating cast to `usize`
        // (several); a frame's sides are far below `i32::MAX`.
        let (wl, hl) = (w as f32 - 0.5, h as f32 - 0.5);
        let sample = |x: f32, y: f32| -> Option<usize> {
            (x >= -0.5 && y >= -0.5 && x < wl && y < hl)
                .then(|| (y + 0.5) as i32 as usize * w + (x + 0.5) as i32 as usize)
        };
        out.data_mut()
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| {
                let yf = y as f32;
                for (x, o) in row.iter_mut().enumerate() {
                    let xf = x as f32;
                    // The displacement at the output pixel, then at the input pixel it points
                    // to; the depth of the point found there.
                    let [dx, dy, _] = moved[y * w + x];
                    *o = sample(xf - dx, yf - dy)
                        .and_then(|s| {
                            let [dx2, dy2, _] = moved[s];
                            sample(xf - dx2, yf - dy2)
                        })
                        .map_or(0.0, |t| {
                            let z = moved[t][2];
                            if z.is_nan() { 0.0 } else { z }
                        });
                }
            });
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

    #[inline]
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

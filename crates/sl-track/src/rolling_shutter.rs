//! A rolling-shutter frame moved to one instant: [`rectify_depth`] resamples a depth map whose
//! rows were exposed one after the other by a moving camera into the depth map the camera
//! would have measured at the middle of the readout, so that it can be fused at the frame's
//! pose. The tracker aligns such frames row by row ([`crate::TrackerConfig::rolling_shutter_readout_s`]);
//! this is the same motion model (constant velocity over the frame) applied to the image.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};
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
/// the middle of its readout: `motion` is the camera's motion over one frame interval
/// (camera frame, `T(t + Δ) = T(t)·motion`), `readout_fraction` the readout time over the
/// frame interval. Each output pixel takes the nearest input pixel that lands on it: the
/// input pixel at the output position minus the displacement of the point seen there (one
/// refinement with the displacement of the pixel found), its point moved by its row's motion.
/// Within a frame the displacement changes by a small fraction of a pixel per pixel, so this
/// gather matches a forward projection except on the pixels next to depth edges; pixels with
/// no valid source stay 0.
pub fn rectify_depth(
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
    let rows: Vec<Isometry3<f32>> = (0..h)
        .map(|y| motion_power(motion, row_offset(y, h, readout_fraction)).cast::<f32>())
        .collect();
    let (fx, fy, cx, cy) = (k.fx as f32, k.fy as f32, k.cx as f32, k.cy as f32);
    // The pixel a valid input pixel moves to, and its depth there.
    let moved = |x: usize, y: usize| -> Option<(f32, f32, f32)> {
        let z = src[y * w + x];
        if !(z > 0.0 && z.is_finite()) {
            return None;
        }
        let p = Point3::new((x as f32 - cx) * z / fx, (y as f32 - cy) * z / fy, z);
        let q = rows[y] * p;
        (q.z > 0.0).then(|| (q.x / q.z * fx + cx, q.y / q.z * fy + cy, q.z))
    };
    let sample = |x: f32, y: f32| -> Option<(usize, usize)> {
        let (xr, yr) = (x.round(), y.round());
        (xr >= 0.0 && yr >= 0.0 && xr < w as f32 && yr < h as f32)
            .then_some((xr as usize, yr as usize))
    };
    out.data_mut()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                *o = 0.0;
                // The displacement at the output pixel, then at the input pixel it points to.
                let Some((u, v, _)) = moved(x, y) else {
                    continue;
                };
                let (dx, dy) = (u - x as f32, v - y as f32);
                let Some((sx, sy)) = sample(x as f32 - dx, y as f32 - dy) else {
                    continue;
                };
                let Some((u2, v2, _)) = moved(sx, sy) else {
                    continue;
                };
                let (dx2, dy2) = (u2 - sx as f32, v2 - sy as f32);
                let Some((tx, ty)) = sample(x as f32 - dx2, y as f32 - dy2) else {
                    continue;
                };
                if let Some((_, _, z)) = moved(tx, ty) {
                    *o = z;
                }
            }
        });
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

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
}

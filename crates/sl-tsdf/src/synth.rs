//! Exact synthetic depth frames of analytic scenes (planes, spheres) for tests, examples and
//! benchmarks that must run without the real data.

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;
use sl_core::{DepthImage, Intrinsics, Pose};

/// A scene made of planes `n·x = d` (unit `n`) and spheres, rendered by ray casting.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnalyticScene {
    /// Planes as (unit normal, offset): points with `n·x = d`.
    pub planes: Vec<(Vector3<f64>, f64)>,
    /// Spheres as (centre, radius).
    pub spheres: Vec<(Point3<f64>, f64)>,
}

impl AnalyticScene {
    /// Distance along the unit ray `o + t·r` to the first surface, if any (t > 0).
    pub fn intersect(&self, o: &Point3<f64>, r: &Vector3<f64>) -> Option<f64> {
        let mut best = f64::INFINITY;
        for (n, d) in &self.planes {
            let den = n.dot(r);
            if den.abs() > 1e-12 {
                let t = (d - n.dot(&o.coords)) / den;
                if t > 0.0 {
                    best = best.min(t);
                }
            }
        }
        for (c, rad) in &self.spheres {
            let oc = o - c;
            let b = oc.dot(r);
            let disc = b * b - (oc.norm_squared() - rad * rad);
            if disc >= 0.0 {
                let s = disc.sqrt();
                for t in [-b - s, -b + s] {
                    if t > 0.0 {
                        best = best.min(t);
                        break;
                    }
                }
            }
        }
        best.is_finite().then_some(best)
    }

    /// Unsigned distance from a point to the nearest surface.
    pub fn distance(&self, p: &Point3<f64>) -> f64 {
        let dp = self
            .planes
            .iter()
            .map(|(n, d)| (n.dot(&p.coords) - d).abs());
        let ds = self.spheres.iter().map(|(c, r)| ((p - c).norm() - r).abs());
        dp.chain(ds).fold(f64::INFINITY, f64::min)
    }

    /// The exact depth image (Z along the optical axis, 0 where nothing is hit) seen by camera
    /// `k` at camera-to-world `pose`.
    pub fn render(&self, k: &Intrinsics, pose: &Pose) -> DepthImage {
        let o = Point3::from(pose.translation.vector);
        let mut data = vec![0.0f32; k.width * k.height];
        data.par_chunks_mut(k.width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, px) in row.iter_mut().enumerate() {
                    let rc = k.ray(x as f64, y as f64);
                    let n = rc.norm();
                    let r = pose.rotation * (rc / n);
                    if let Some(t) = self.intersect(&o, &r) {
                        *px = (t / n) as f32;
                    }
                }
            });
        // `data` has exactly width*height entries.
        match DepthImage::from_vec(k.width, k.height, data) {
            Ok(d) => d,
            Err(_) => DepthImage::invalid(k.width, k.height),
        }
    }
}

//! Accuracy of fused meshes: distances from the vertices of an `sl-tsdf` mesh to a reference
//! surface, and their summary statistics.

use rayon::prelude::*;
use sl_core::Mesh;
use sl_core::nalgebra::Point3;

/// Summary of unsigned distances, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DistanceStats {
    /// Number of samples.
    pub count: usize,
    /// Mean distance.
    pub mean_m: f64,
    /// Root mean square distance.
    pub rms_m: f64,
    /// 95th percentile (nearest-rank).
    pub p95_m: f64,
    /// Largest distance.
    pub max_m: f64,
}

impl DistanceStats {
    /// Statistics of the finite values of `d` (absolute values are taken); `None` if none.
    pub fn from_distances(d: &[f64]) -> Option<Self> {
        let mut v: Vec<f64> = d
            .iter()
            .filter(|x| x.is_finite())
            .map(|x| x.abs())
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_unstable_by(f64::total_cmp);
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let rms = (v.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
        let rank = ((0.95 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Some(Self {
            count: n,
            mean_m: mean,
            rms_m: rms,
            p95_m: v[rank],
            max_m: v[n - 1],
        })
    }
}

/// Distances from the mesh vertices accepted by `keep` to a reference surface given by its
/// unsigned distance function `dist` (e.g. `sl_noise::sim::Scene::distance`).
pub fn vertex_distances(
    mesh: &Mesh,
    keep: impl Fn(&Point3<f64>) -> bool + Sync,
    dist: impl Fn(&Point3<f64>) -> f64 + Sync,
) -> Vec<f64> {
    mesh.positions
        .par_iter()
        .filter_map(|p| {
            let q = Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
            keep(&q).then(|| dist(&q))
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_known_values() {
        let d: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = DistanceStats::from_distances(&d).unwrap();
        assert_eq!(s.count, 100);
        assert!((s.mean_m - 50.5).abs() < 1e-12);
        assert_eq!(s.p95_m, 95.0);
        assert_eq!(s.max_m, 100.0);
        let rms = ((1..=100).map(|x| f64::from(x * x)).sum::<f64>() / 100.0).sqrt();
        assert!((s.rms_m - rms).abs() < 1e-12);
        assert!(DistanceStats::from_distances(&[f64::NAN]).is_none());
        let s = DistanceStats::from_distances(&[-2.0]).unwrap();
        assert_eq!((s.mean_m, s.p95_m), (2.0, 2.0));
    }
}

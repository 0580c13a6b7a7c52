//! Integration tests of `sl-eval` on real `sl-tsdf` meshes: the software renderer and the
//! mesh-to-surface distances.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use sl_core::nalgebra::{Point3, Vector3};
use sl_eval::render::{BACKGROUND_RGB, framing_camera, render_mesh};
use sl_eval::{DistanceStats, vertex_distances};
use sl_tsdf::{Mesh, MeshConfig, TsdfConfig, TsdfVolume, WeightMode};

/// The marching-cubes mesh of an exact sphere distance field.
fn sphere_mesh(voxel: f64, r: f64, centre: Point3<f64>) -> Mesh {
    let lo = [0, 1, 2].map(|a| centre[a] - r - 3.0 * voxel);
    let hi = [0, 1, 2].map(|a| centre[a] + r + 3.0 * voxel);
    let mut config = TsdfConfig::default();
    config.voxel_m = voxel;
    config.trunc_m = 4.0 * voxel;
    config.weight = WeightMode::Uniform;
    TsdfVolume::from_field(config, lo, hi, |p| Some(((p - centre).norm() - r) as f32))
        .unwrap()
        .extract_mesh(&MeshConfig::default())
}

#[test]
fn render_shows_the_sphere() {
    let mesh = sphere_mesh(0.02, 0.2, Point3::origin());
    let (k, pose) = framing_camera(&mesh, Vector3::z(), -Vector3::y(), 80, 60).unwrap();
    let img = render_mesh(&mesh, &k, &pose).unwrap();
    assert_ne!(*img.get(40, 30).unwrap(), BACKGROUND_RGB);
    assert_eq!(*img.get(0, 0).unwrap(), BACKGROUND_RGB);
    // Seen from outside, the centre is a front face (grey, not the blue back-face tint).
    let c = img.get(40, 30).unwrap();
    assert!(c[2] < c[0] + 20, "{c:?}");
}

#[test]
fn framing_rejects_empty_meshes_and_degenerate_views() {
    let mesh = sphere_mesh(0.02, 0.2, Point3::origin());
    assert!(framing_camera(&Mesh::default(), Vector3::z(), -Vector3::y(), 80, 60).is_err());
    assert!(framing_camera(&mesh, Vector3::zeros(), -Vector3::y(), 80, 60).is_err());
    assert!(framing_camera(&mesh, Vector3::y(), -Vector3::y(), 80, 60).is_err());
}

#[test]
fn sphere_vertices_are_within_a_tenth_of_a_voxel() {
    let (voxel, r, c) = (0.01, 0.123, Point3::new(-0.0137, 0.0412, 0.0051));
    let mesh = sphere_mesh(voxel, r, c);
    let keep_upper = |p: &Point3<f64>| p.y >= c.y;
    let all = vertex_distances(&mesh, |_| true, |p| ((p - c).norm() - r).abs());
    let upper = vertex_distances(&mesh, keep_upper, |p| ((p - c).norm() - r).abs());
    assert_eq!(all.len(), mesh.vertex_count());
    assert!(!upper.is_empty() && upper.len() < all.len());
    let s = DistanceStats::from_distances(&all).unwrap();
    assert_eq!(s.count, all.len());
    assert!(
        s.max_m < voxel / 10.0 && s.mean_m <= s.rms_m && s.rms_m <= s.max_m,
        "{s:?}"
    );
}

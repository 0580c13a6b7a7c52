//! Unit tests of motion estimation.

use super::*;

#[test]
fn rotation_angle_is_finite_at_180_degrees() {
    let a = Rotation3::from_scaled_axis(Vector3::new(0.1, 0.2, -0.3));
    let b = a * Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
    let d = rotation_between(&a, &b);
    assert!((d - std::f64::consts::PI).abs() < 1e-6, "{d}");
    assert!(rotation_between(&a, &a).abs() < 1e-6);
}

#[test]
fn icp_config_ranges_are_checked() {
    assert!(IcpConfig::default().validate().is_ok());
    assert!(IcpConfig::refinement().validate().is_ok());
    assert!(IcpConfig::refinement().max_dist_m < IcpConfig::default().max_dist_m);
    for bad in [
        IcpConfig {
            iterations: 0,
            ..IcpConfig::default()
        },
        IcpConfig {
            min_dist_m: 0.0,
            ..IcpConfig::default()
        },
        IcpConfig {
            max_dist_m: 0.01,
            ..IcpConfig::default()
        },
    ] {
        assert!(bad.validate().is_err(), "{bad:?}");
    }
}

#[test]
fn icp_rejection_names() {
    assert_eq!(IcpRejection::LostInliers.as_str(), "lost-inliers");
    assert_eq!(IcpRejection::Failed("x".into()).as_str(), "icp-failed");
}

#[test]
fn kabsch_recovers_rotation() {
    let r = Rotation3::from_scaled_axis(Vector3::new(0.2, -0.4, 0.1));
    let bs = [
        Vector3::new(0.0, 0.0, -1.0),
        Vector3::new(0.0, -1.0, 0.1).normalize(),
    ];
    let pairs: Vec<_> = bs.iter().map(|b| (r * b, *b, 1.0)).collect();
    let est = weighted_kabsch(&pairs).unwrap();
    assert!(est.angle_to(&r) < 1e-9);
    // Parallel normals do not determine a rotation.
    let par = [(bs[0], bs[0], 1.0), (bs[0] * 2.0, bs[0] * 2.0, 1.0)];
    assert!(weighted_kabsch(&par).is_none());
}

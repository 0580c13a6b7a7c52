//! Tracking in a map built beforehand (`track_in_map`, `track_in_map_with_noise`): the poses
//! it was built from recovered, the map left as it was, a given noise scale reaching the
//! tracker.

use super::*;

/// `n` frames of [`sequence`] (seed 3), a configuration with 10 mm voxels and the map they
/// make fused at their true poses.
struct FixedMap {
    cam: Camera,
    truth: Vec<CameraToWorld>,
    frames: Vec<DepthImage>,
    cfg: ReconstructionConfig,
    map: TsdfVolume,
}

fn fixed_map(n: usize) -> FixedMap {
    let (cam, truth, frames) = sequence(n, 3);
    let mut cfg = ReconstructionConfig::default_for(cam.sensor);
    cfg.tsdf.voxel_m = 0.01;
    cfg.tsdf.trunc_m = 0.05;
    let mut map = TsdfVolume::new(cfg.tsdf).unwrap();
    for (d, p) in frames.iter().zip(&truth) {
        map.integrate(d, &cam.intrinsics, p).unwrap();
    }
    FixedMap {
        cam,
        truth,
        frames,
        cfg,
        map,
    }
}

/// Tracking in a map built beforehand (`track_in_map`): the frames fused at their true poses,
/// then tracked against that map from the first true pose. Every frame is tracked, each pose
/// within a few millimetres of the truth, without the drift of a map built along the way
/// (every pose is aligned to the same fixed map; 10 mm voxels); and the map is left as it was.
/// A frame of another size is an error.
#[test]
fn tracking_in_a_fixed_map_recovers_the_poses_it_was_built_from() {
    let FixedMap {
        cam,
        truth,
        frames,
        cfg,
        map,
    } = fixed_map(12);
    let blocks = map.block_count();
    let results = sl_track::track_in_map(cam, &cfg, &map, truth[0], &frames).unwrap();
    assert_eq!(results.len(), frames.len());
    assert_eq!(results[0].status, TrackStatus::Initialised);
    assert_eq!(map.block_count(), blocks);
    for (i, (r, t)) in results.iter().zip(&truth).enumerate().skip(1) {
        assert!(r.status.is_tracked(), "frame {i}: {:?}", r.status);
        let d = t.isometry().inverse() * r.pose.isometry();
        let (dt, dr) = (d.translation.vector.norm(), d.rotation.angle().to_degrees());
        assert!(dt < 0.005 && dr < 0.3, "frame {i}: {dt} m {dr}°");
    }
    let small = DepthImage::invalid(10, 10);
    assert!(sl_track::track_in_map(cam, &cfg, &map, truth[0], &[small]).is_err());
}

/// `track_in_map_with_noise`: a noise scale the caller measured on the raw frames reaches the
/// tracker. The same frames given as 6.7 times noisier than the model (σ_D 0.2 px behind the
/// Kinect's 0.07) are still tracked, with every σ of the frame raised: the pose's
/// weakest-direction σ grows by about √6.7 ≈ 2.6 (the variance of every residual scaled by 6.7,
/// the gates widened with it).
#[test]
fn a_noise_scale_given_with_the_frames_reaches_the_tracker_in_a_fixed_map() {
    let m = fixed_map(6);
    let run = |scale: f64| {
        sl_track::track_in_map_with_noise(
            m.cam,
            &m.cfg,
            &m.map,
            m.truth[0],
            m.frames.iter().map(|d| (d, Some(scale))),
        )
        .unwrap()
    };
    let (nominal, noisier) = (run(1.0), run(6.7));
    let plain = sl_track::track_in_map(m.cam, &m.cfg, &m.map, m.truth[0], &m.frames).unwrap();
    for (i, ((a, b), c)) in nominal.iter().zip(&noisier).zip(&plain).enumerate().skip(1) {
        assert!(a.status.is_tracked() && b.status.is_tracked(), "frame {i}");
        // The simulated frames are at the model's noise: measured, they scale nothing.
        assert_eq!(a.pose, c.pose, "frame {i}");
        let ratio = b.weakest_sigma_m / a.weakest_sigma_m;
        assert!((2.2..3.0).contains(&ratio), "frame {i}: σ ratio {ratio}");
    }
}

//! Frames with fewer pixels than the sensor's grid: a frame decimated by 2 (read on the
//! sensor's grid) and a frame with scattered pixels missing give the whole frame's planes.

use super::*;

/// A frame of the Kinect decimated by 2 (every second pixel of every second row: a 320×240
/// stream) read with the camera resampled from the sensor (`Camera::resampled`) gives the
/// planes of the full frame: the extractor runs on the sensor's grid, where its scales and
/// `min_pixels` were validated. On the decimated pixels themselves (the camera taken as a
/// sensor of its own) the LoG rejects most of a real frame (TUM's desk: 4 planes instead of 16).
#[test]
fn a_decimated_frame_gives_the_planes_of_the_full_one() {
    let large = 5000;
    let (mut matched, mut total) = (0, 0);
    for seed in [0u64, 1, 2, 4] {
        let (depth, cam) = simulated_room(seed);
        let half_cam = cam.resampled(0.5).unwrap();
        let (w2, h2) = (half_cam.intrinsics.width, half_cam.intrinsics.height);
        let half = sl_testkit::decimate(&depth, 2);
        let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
        let full = ex.extract_depth(&depth, &cam).unwrap();
        let dec = ex.extract_depth(&half, &half_cam).unwrap();
        assert_eq!(dec.labels.dimensions(), (w2, h2));
        // Ids are 1.. in order of decreasing size, pixel counts exact in the frame's pixels.
        for (i, p) in dec.planes.iter().enumerate() {
            assert_eq!(usize::from(p.id), i + 1);
            let n = dec.labels.data().iter().filter(|&&l| l == p.id).count();
            assert_eq!(p.pixels, n);
            assert!(i == 0 || dec.planes[i - 1].pixels >= p.pixels);
        }
        // Every large plane of the full frame is found in the decimated one (normal within
        // 2°, offset within 2 cm) with about a quarter of its pixels, and vice versa.
        let same = |a: &sl_planes::PlaneInfo, b: &sl_planes::PlaneInfo| {
            a.plane.angle_to_deg(&b.plane) < 2.0
                && (a.plane.offset_m - b.plane.offset_m).abs() < 0.02
        };
        for p in full.planes.iter().filter(|p| p.pixels >= large) {
            total += 1;
            let found = dec
                .planes
                .iter()
                .find(|q| same(p, q) && (q.pixels * 4).abs_diff(p.pixels) * 5 < p.pixels);
            matched += usize::from(found.is_some());
        }
        for q in dec.planes.iter().filter(|q| q.pixels * 4 >= large) {
            assert!(
                full.planes.iter().any(|p| same(p, q)),
                "seed {seed}: decimated plane {q:?} is in no plane of the full frame"
            );
        }
    }
    assert!(total >= 10, "{total}");
    assert_eq!(
        matched, total,
        "{matched} of {total} large planes found again"
    );
}

/// Scattered invalid pixels (a stereo camera's dropped matches, a depth map aligned to a larger
/// colour image, a confidence mask) do not hide the planes: the coarse stages take a 2×2
/// block's value from a complete diagonal when a pixel is missing, exact for a plane. Rooms
/// 0–5 with 10 % of their pixels removed at random keep every plane of at least 2,000 pixels
/// that the whole frame gives (SegComp at 80 %, each frame against its own valid pixels). Before
/// this, a 4×4 cell with one missing pixel was no cell: 81 % of the cells were lost, and the
/// rooms gave no plane at all (a real 7-Scenes frame: 18 planes whole, 6 with 3 % of its pixels
/// removed, 0 with 10 %).
#[test]
fn scattered_missing_pixels_keep_the_planes() {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for seed in 0..6 {
        let (frame, whole) = extract_room(seed);
        let room = sl_noise::sim::room_scene(seed).unwrap();
        let cam = room_camera(room.intrinsics);
        let mut holed = frame.depth.clone();
        for z in holed.data_mut() {
            if uniform() < 0.1 {
                *z = 0.0;
            }
        }
        let seg = PlaneExtractor::new(PlaneConfig::default())
            .unwrap()
            .extract_depth(&holed, &cam)
            .unwrap();
        let valid = |d: &DepthImage| -> Vec<bool> { d.data().iter().map(|&z| z > 0.0).collect() };
        let a = segcomp(
            &frame.labels,
            &whole.labels,
            Some(&valid(&frame.depth)),
            0.8,
            2000,
        )
        .unwrap();
        let b = segcomp(&frame.labels, &seg.labels, Some(&valid(&holed)), 0.8, 2000).unwrap();
        assert!(a.correct > 0, "room {seed}: {a:?}");
        assert!(
            b.correct >= a.correct,
            "room {seed}: whole frame {a:?}, 10 % missing {b:?}"
        );
    }
}

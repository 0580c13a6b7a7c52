//! The segmentation does not depend on how it runs: the same on any number of threads, and
//! frames extracted in parallel match one by one.

use super::*;

/// The final pass runs in bands of rows on the caller's rayon pool: the labels and every plane
/// field are the same bit for bit on 1, 2 and 3 threads and from a thread outside every pool,
/// on simulated rooms (many planes, creases, pixels two planes explain) and on frames whose
/// height is not a whole number of bands (120 rows: 3 bands of 32 and one of 24; 118 rows).
#[test]
fn the_segmentation_does_not_depend_on_the_number_of_threads() {
    let mut frames = Vec::new();
    for seed in [0u64, 3] {
        let (depth, cam) = simulated_room(seed);
        frames.push((depth, cam, PlaneConfig::default()));
    }
    let cam = small_camera(150.0);
    let walls = [
        Plane::new(Vector3::new(0.6, 0.0, -0.8), 1.6).unwrap(),
        Plane::new(Vector3::new(-0.6, 0.0, -0.8), 1.6).unwrap(),
        Plane::new(Vector3::new(0.0, -0.7, -0.7), 1.2).unwrap(),
    ];
    let (truth, _) = render(&cam.intrinsics, &walls, 8.0);
    frames.push((noisy(&truth, 7), cam, cfg_small()));
    // 118 rows: an odd number of half-resolution rows (59), the last one without a cell row.
    let odd = Camera {
        intrinsics: Intrinsics::new(160, 118, 150.0, 150.0, 79.5, 58.5).unwrap(),
        sensor: SensorModel::kinect_v1(),
    };
    let (truth, _) = render(&odd.intrinsics, &walls, 8.0);
    frames.push((noisy(&truth, 8), odd, cfg_small()));
    for (depth, cam, cfg) in &frames {
        let run = || {
            let seg = PlaneExtractor::new(*cfg)
                .unwrap()
                .extract_depth(depth, cam)
                .unwrap();
            (seg.labels.data().to_vec(), format!("{:?}", seg.planes))
        };
        let outside = std::thread::scope(|s| s.spawn(run).join().unwrap());
        assert!(outside.1.contains("PlaneInfo"), "no plane found");
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let inside = pool.install(run);
            assert!(inside.0 == outside.0, "{threads} threads: labels differ");
            assert_eq!(inside.1, outside.1, "{threads} threads: planes differ");
        }
    }
}

/// Frames extracted in parallel (one extractor per task, `par_iter` over the frames), each
/// extraction splitting its own final pass on the same pool: the same segmentations as one
/// after the other, and no deadlock.
#[test]
fn frames_extracted_in_parallel_match_one_by_one() {
    use rayon::prelude::*;
    let frames: Vec<(DepthImage, Camera)> = (0..6u64).map(simulated_room).collect();
    let run = |(depth, cam): &(DepthImage, Camera)| {
        let seg = PlaneExtractor::new(PlaneConfig::default())
            .unwrap()
            .extract_depth(depth, cam)
            .unwrap();
        (seg.labels.data().to_vec(), format!("{:?}", seg.planes))
    };
    let one_by_one: Vec<_> = frames.iter().map(run).collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let parallel: Vec<_> = pool.install(|| frames.par_iter().map(run).collect());
    for (i, (a, b)) in one_by_one.iter().zip(&parallel).enumerate() {
        assert!(a.0 == b.0, "frame {i}: labels differ");
        assert_eq!(a.1, b.1, "frame {i}: planes differ");
    }
}

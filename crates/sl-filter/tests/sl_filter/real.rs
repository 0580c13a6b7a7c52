//! A real Kinect-class frame (skipped when ../shared/data is absent).

use std::path::PathBuf;

use sl_core::{Camera, DepthImage, Intrinsics};
use sl_filter::eval::{dominant_plane_region, plane_residual_by_band};
use sl_filter::{DEFAULT_RADIUS_PX, DepthFilter, Method};

fn person_depth() -> Option<DepthImage> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/open3d-testdata/person-depth.png");
    if !path.exists() {
        eprintln!("skipping: ../shared/data not found");
        return None;
    }
    let img = image::ImageReader::open(&path)
        .unwrap()
        .decode()
        .unwrap()
        .to_luma16();
    let (w, h) = img.dimensions();
    let data = img
        .as_raw()
        .iter()
        .map(|&v| f32::from(v) / 1000.0)
        .collect();
    Some(DepthImage::from_vec(w as usize, h as usize, data).unwrap())
}

/// On the wall behind the person, every filter keeps the valid mask and lowers the plane-fit
/// residual; the adaptive default lowers it by at least 10 %.
#[test]
fn filters_flatten_the_wall_of_person_depth() {
    let Some(depth) = person_depth() else {
        return;
    };
    let k = Intrinsics::new(640, 480, 525.0, 525.0, 319.5, 239.5).unwrap();
    let cam = Camera::from_intrinsics(k, None, None).unwrap();
    let region = dominant_plane_region(&depth, &k, &cam.sensor, DEFAULT_RADIUS_PX + 1, 200, 3)
        .unwrap()
        .unwrap();
    let all = [(0.0f32, f32::INFINITY)];
    let raw = plane_residual_by_band(&depth, &k, &region.mask, &all).unwrap()[0].rmse_m;
    for m in Method::ALL {
        let out = DepthFilter::default_for(m, &cam.sensor)
            .apply(&depth)
            .unwrap();
        for (&o, &i) in out.data().iter().zip(depth.data()) {
            assert_eq!(o > 0.0, i > 0.0);
        }
        let res = plane_residual_by_band(&out, &k, &region.mask, &all).unwrap()[0].rmse_m;
        assert!(res < raw, "{m}: {res} vs raw {raw}");
        if m == Method::Adaptive {
            assert!(res < 0.9 * raw, "adaptive: {res} vs raw {raw}");
        }
    }
}

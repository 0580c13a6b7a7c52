//! A real Kinect-class frame (skipped when ../shared/data is absent).

use sl_eval::filter::{dominant_plane_region, plane_residual_by_band};
use sl_filter::{DEFAULT_RADIUS_PX, DepthFilter, Method};

/// On the wall behind the person, every filter keeps the valid mask and lowers the plane-fit
/// residual; the adaptive default lowers it by at least 10 %.
#[test]
fn filters_flatten_the_wall_of_person_depth() {
    let Some(person) = sl_testkit::person() else {
        return;
    };
    let (depth, cam) = (person.depth, person.camera);
    let k = cam.intrinsics;
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

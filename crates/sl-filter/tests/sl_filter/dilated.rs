//! A dilated pass (the taps `s` pixels apart, the multi-scale filter's coarse passes) is, bit
//! for bit, its definition: the filter applied to each polyphase sub-image (every `s`-th pixel
//! of every `s`-th row) and interleaved back — for every method, window, radius, spacing, image
//! size and kernel, the fast paths (5×5 at 2, 4, 8 px) and the runtime-radius loop alike.

use proptest::prelude::*;
use sl_core::{DepthImage, DepthView, SensorModel};
use sl_filter::multiscale::apply_dilated_with_isa;

use super::common::{filters, isas, random_image};

/// The dilated pass by its definition.
fn by_sub_images(
    f: &sl_filter::DepthFilter,
    img: &DepthImage,
    s: usize,
    isa: sl_filter::Isa,
) -> Vec<f32> {
    let (w, h) = (img.width(), img.height());
    let mut out = vec![f32::NAN; w * h];
    for py in 0..s.min(h) {
        for px in 0..s.min(w) {
            let (sw, sh) = ((w - px).div_ceil(s), (h - py).div_ceil(s));
            let sub: Vec<f32> = (0..sw * sh)
                .map(|k| img.data()[(py + k / sw * s) * w + px + k % sw * s])
                .collect();
            let got = f
                .apply_with_isa(DepthView::new(sw, sh, &sub).unwrap(), isa)
                .unwrap();
            for (k, &v) in got.data().iter().enumerate() {
                out[(py + k / sw * s) * w + px + k % sw * s] = v;
            }
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, .. ProptestConfig::default() })]

    #[test]
    fn a_dilated_pass_is_its_polyphase_definition(
        w in 1usize..90,
        h in 1usize..60,
        s in prop_oneof![Just(2usize), Just(4), Just(8), 1usize..20],
        r in 1usize..5,
        seed in 0u64..10_000,
    ) {
        let sensor = SensorModel::kinect_v1();
        let img = random_image(w, h, 0.6, 4.0, 0.15, seed);
        for f in filters(r, r as f64 / 2.0, &sensor) {
            for isa in isas() {
                let got = apply_dilated_with_isa(&f, &img, s, isa).unwrap();
                let want = by_sub_images(&f, &img, s, isa);
                for (i, (a, b)) in got.data().iter().zip(&want).enumerate() {
                    prop_assert_eq!(
                        a.to_bits(), b.to_bits(),
                        "{:?} {:?} r {} step {} {}x{} at ({}, {}): {} vs {}",
                        isa, f.method(), r, s, w, h, i % w, i / w, a, b
                    );
                }
            }
        }
    }
}

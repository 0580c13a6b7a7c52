//! Tests of the noise statistics on frames with known answers.

use super::*;
use crate::error::NoiseError;

/// A fronto-parallel plane at disparity `d0` with a checkerboard residual `±a` px.
fn checker(w: usize, h: usize, fb: f64, d0: f64, a: f64) -> DepthImage {
    let data = (0..w * h)
        .map(|i| {
            let s = if (i % w + i / w).is_multiple_of(2) {
                a
            } else {
                -a
            };
            (fb / (d0 + s)) as f32
        })
        .collect();
    DepthImage::from_vec(w, h, data).unwrap()
}

#[test]
fn checkerboard_residual_sigma_and_correlation() {
    let (w, h, fb) = (128, 128, 43.5);
    let depth = checker(w, h, fb, 20.0, 0.05);
    let labels = Image::filled(w, h, 1u16);
    let s = noise_stats(&depth, fb, &labels, &NoiseStatsConfig::default()).unwrap();
    assert!((s.sigma_d_px - 0.05).abs() < 1e-4, "{}", s.sigma_d_px);
    let (x1, y1) = s.acf_at(1).unwrap();
    let (x2, y2) = s.acf_at(2).unwrap();
    assert!(x1 < -0.99 && y1 < -0.99, "{x1} {y1}");
    assert!(x2 > 0.99 && y2 > 0.99, "{x2} {y2}");
    // Depth ≈ 2.175 m: the band 2.0–2.5 m holds every tile.
    let band = s.bands.iter().find(|b| b.z_lo_m == 2.0).unwrap();
    assert_eq!(band.tiles, 4);
    assert_eq!(band.pixels, w * h);
    // Every pixel differs from its neighbours: all terraces are 1 px wide.
    assert_eq!(s.terraces.widths.median_px, 1.0);
    assert_eq!(s.terraces.fractions[0], 1.0);
    // The open last bin has no upper edge (it printed as 2⁶⁴ − 1 in JSON and Python).
    assert_eq!(s.terraces.bin_upper_px.last(), Some(&None));
    assert_eq!(s.terraces.bin_upper_px[..2], [Some(1), Some(2)]);
}

/// A noise-free plane has no noise to correlate: no autocorrelation (NaN), where the float
/// rounding of its residual used to report 0.97–1.00.
#[test]
fn a_noise_free_plane_has_no_autocorrelation() {
    let (w, h, fb) = (128, 128, 43.5);
    // A tilted plane: its residual is the rounding of `f32` depths, not zero.
    let data = (0..w * h)
        .map(|i| (fb / (20.0 + 0.01 * (i % w) as f64 + 0.003 * (i / w) as f64)) as f32)
        .collect();
    let depth = DepthImage::from_vec(w, h, data).unwrap();
    let labels = Image::filled(w, h, 1u16);
    let s = noise_stats(&depth, fb, &labels, &NoiseStatsConfig::default()).unwrap();
    assert!(
        s.sigma_d_px > 0.0 && s.sigma_d_px < 1e-4,
        "{}",
        s.sigma_d_px
    );
    let (x1, y1) = s.acf_at(1).unwrap();
    assert!(x1.is_nan() && y1.is_nan(), "{x1} {y1}");
}

#[test]
fn occlusion_bands_by_side() {
    // A board at 1 m over x in 30..50, a wall at 2 m; 6 invalid pixels left of the board,
    // 2 on its right, in every row.
    let (w, h) = (80, 10);
    let mut data = vec![2.0f32; w * h];
    for y in 0..h {
        for x in 30..50 {
            data[y * w + x] = 1.0;
        }
        for x in 24..30 {
            data[y * w + x] = 0.0;
        }
        for x in 50..52 {
            data[y * w + x] = 0.0;
        }
    }
    let depth = DepthImage::from_vec(w, h, data).unwrap();
    let b = occlusion_bands(&depth, 43.5, 0.15, 64);
    assert_eq!(b.left.widths.count, h);
    assert_eq!(b.left.widths.median_px, 6.0);
    assert_eq!(b.right.widths.median_px, 2.0);
    assert!((b.left.median_shadow_px - 21.75).abs() < 1e-9);
    assert_eq!((b.left.median_fg_m, b.left.median_bg_m), (1.0, 2.0));
    assert_eq!(b.left.direct_edges + b.right.direct_edges, 0);
    // Every edge predicts a 21.75-px shadow: all in the open bin, all with a band.
    for side in [&b.left, &b.right] {
        let bins: Vec<(usize, usize)> = side
            .by_shadow
            .iter()
            .map(|b| (b.edges, b.with_band))
            .collect();
        assert_eq!(bins, vec![(0, 0), (0, 0), (0, 0), (h, h)]);
    }
    assert_eq!(b.left.by_shadow[3].share(), 1.0);
    assert!(b.left.by_shadow[0].share().is_nan());
    // A far, small jump (2.0 / 2.3 m: a 2.8-px shadow) with no band in half the rows: the
    // second bin, half of its edges with a band.
    let mut far = vec![2.3f32; w * h];
    for y in 0..h {
        for x in 30..50 {
            far[y * w + x] = 2.0;
        }
        if y % 2 == 0 {
            far[y * w + 29] = 0.0;
        }
    }
    let f = occlusion_bands(&DepthImage::from_vec(w, h, far).unwrap(), 43.5, 0.15, 64);
    assert_eq!(
        (f.left.by_shadow[1].edges, f.left.by_shadow[1].with_band),
        (h, h / 2)
    );
    assert_eq!(f.left.direct_edges, h / 2);
    assert_eq!(
        (f.right.by_shadow[1].edges, f.right.by_shadow[1].with_band),
        (h, 0)
    );
    // A smaller jump than the threshold is no occlusion edge.
    let none = occlusion_bands(&depth, 43.5, 1.5, 64);
    assert_eq!(none.left.widths.count + none.right.widths.count, 0);
    // The same frame read as the sensor decimated by 2: the predicted shadow (a disparity
    // in sensor pixels) is reported in the image's pixels, as the widths are.
    let labels = Image::filled(w, h, 0u16);
    let mut opts = NoiseStatsConfig {
        pixels_per_sensor_pixel: 0.5,
        ..NoiseStatsConfig::default()
    };
    let s = noise_stats(&depth, 43.5, &labels, &opts).unwrap();
    assert!((s.occlusion.left.median_shadow_px - 21.75 / 2.0).abs() < 1e-9);
    assert_eq!(s.occlusion.left.widths.median_px, 6.0);
    opts.pixels_per_sensor_pixel = 0.0;
    assert!(noise_stats(&depth, 43.5, &labels, &opts).is_err());
}

#[test]
fn bad_inputs_are_errors() {
    let depth = checker(16, 16, 43.5, 20.0, 0.0);
    let wrong = Image::filled(8, 8, 1u16);
    assert!(noise_stats(&depth, 43.5, &wrong, &NoiseStatsConfig::default()).is_err());
    let labels = Image::filled(16, 16, 1u16);
    assert!(noise_stats(&depth, -1.0, &labels, &NoiseStatsConfig::default()).is_err());
    let o = NoiseStatsConfig {
        tile_px: 0,
        ..NoiseStatsConfig::default()
    };
    assert!(noise_stats(&depth, 43.5, &labels, &o).is_err());
    assert!(matches!(o.validate(), Err(NoiseError::InvalidParameter(_))));
    assert!(NoiseStatsConfig::default().validate().is_ok());
    // Too small to fit: no tiles, NaN statistics, no panic.
    let s = noise_stats(&depth, 43.5, &labels, &NoiseStatsConfig::default()).unwrap();
    assert_eq!(s.regions, 0);
    assert!(s.sigma_d_px.is_nan());
}

//! Colour overlays of plane labels (for the CLI's `sldepth planes --overlay` and the validation
//! report). No I/O.

use sl_core::{DepthImage, Image};

/// A distinct colour for plane `id` (golden-angle hues); grey for 0.
pub fn label_color(id: u16) -> [u8; 3] {
    if id == 0 {
        return [128, 128, 128];
    }
    let h = (f64::from(id) * 137.507_764) % 360.0;
    let (s, v) = (0.85, 0.95);
    let c = v * s;
    let x = c * (1.0 - ((h / 60.0) % 2.0 - 1.0).abs());
    let m = v - c;
    let (r, g, b) = match (h / 60.0) as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let q = |v: f64| ((v + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    [q(r), q(g), q(b)]
}

/// A grey RGB rendering of a depth image (near = bright, invalid = black), interleaved RGB.
pub fn depth_to_rgb(depth: &DepthImage) -> Vec<u8> {
    let (lo, hi) = depth.stats().map_or((0.0, 1.0), |s| (s.min, s.max));
    let span = (hi - lo).max(1e-6);
    let mut out = Vec::with_capacity(depth.data().len() * 3);
    for &z in depth.data() {
        let g = if z > 0.0 && z.is_finite() {
            (255.0 - 200.0 * (z - lo) / span) as u8
        } else {
            0
        };
        out.extend_from_slice(&[g, g, g]);
    }
    out
}

/// Blends plane colours over an interleaved RGB base image (`alpha` = weight of the plane
/// colour); non-planar pixels are darkened. Returns interleaved RGB, or `None` when the base
/// does not have `3·w·h` bytes.
pub fn overlay_rgb(labels: &Image<u16>, base_rgb: &[u8], alpha: f32) -> Option<Vec<u8>> {
    if base_rgb.len() != labels.data().len() * 3 {
        return None;
    }
    let a = alpha.clamp(0.0, 1.0);
    let mut out = Vec::with_capacity(base_rgb.len());
    for (i, &l) in labels.data().iter().enumerate() {
        let px = &base_rgb[3 * i..3 * i + 3];
        if l == 0 {
            out.extend(px.iter().map(|&v| (f32::from(v) * 0.5) as u8));
        } else {
            let c = label_color(l);
            out.extend(
                px.iter()
                    .zip(c)
                    .map(|(&v, c)| (f32::from(v) * (1.0 - a) + f32::from(c) * a) as u8),
            );
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_are_distinct_and_overlay_sized() {
        let cols: Vec<_> = (1..=12).map(label_color).collect();
        for i in 0..cols.len() {
            for j in i + 1..cols.len() {
                assert_ne!(cols[i], cols[j]);
            }
        }
        let labels = Image::from_fn(4, 2, |x, _| x as u16);
        let base = vec![200u8; 24];
        let o = overlay_rgb(&labels, &base, 0.6).unwrap();
        assert_eq!(o.len(), 24);
        assert_eq!(o[0], 100);
        assert!(overlay_rgb(&labels, &base[..3], 0.5).is_none());
    }
}

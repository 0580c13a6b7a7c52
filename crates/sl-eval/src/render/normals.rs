//! Shaded-normal renderings of depth maps (the CLI's `sldepth filter --normals` and the filter
//! report): depth noise is far easier to see in surface normals
//! (which differentiate the depth) than in the depth itself.

use rayon::prelude::*;
use sl_core::{DepthImage, Image, Intrinsics};

use crate::error::Result;

/// Relative depth jump above which a neighbour is treated as across an edge (not used for the
/// normal).
const EDGE_JUMP: f32 = 0.05;

/// Renders per-pixel surface normals of `depth` as colours, shaded by a head light.
///
/// The normal at a pixel is the cross product of the horizontal and vertical tangents of the
/// back-projected surface (central differences, one-sided where a neighbour is invalid or more
/// than 5 % away in depth). The colour is the normal map (`x, y, −z` of the camera-frame normal,
/// mapped from `[−1, 1]` to `[0, 255]`, so a fronto-parallel surface is light blue) times a
/// Lambertian shade `0.25 + 0.75·max(0, n·l)` for a light at the camera, slightly above and to
/// the left, which makes small bumps stand out. Invalid pixels and pixels without a valid
/// neighbour in both directions are black.
pub fn shaded_normals(depth: &DepthImage, k: &Intrinsics) -> Result<Image<[u8; 3]>> {
    depth.as_image().check_size(k)?;
    let (w, h) = (depth.width(), depth.height());
    let z = depth.data();
    let valid = |v: f32| v > 0.0 && v.is_finite();
    let point = |x: usize, y: usize| -> [f32; 3] {
        let d = z[y * w + x];
        [
            ((x as f64 - k.cx) / k.fx) as f32 * d,
            ((y as f64 - k.cy) / k.fy) as f32 * d,
            d,
        ]
    };
    let light = {
        let l = [-0.35f32, -0.5, -1.0];
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        [l[0] / n, l[1] / n, l[2] / n]
    };
    let mut out = vec![[0u8; 3]; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.iter_mut().enumerate() {
                let c = z[y * w + x];
                if !valid(c) {
                    continue;
                }
                let near = |xx: usize, yy: usize| {
                    let v = z[yy * w + xx];
                    valid(v) && (v - c).abs() <= EDGE_JUMP * c
                };
                // Tangent along one axis from the usable neighbours.
                let tangent =
                    |a: Option<(usize, usize)>, b: Option<(usize, usize)>| -> Option<[f32; 3]> {
                        let a = a.filter(|&(xx, yy)| near(xx, yy));
                        let b = b.filter(|&(xx, yy)| near(xx, yy));
                        let (p, q) = match (a, b) {
                            (Some(a), Some(b)) => (point(a.0, a.1), point(b.0, b.1)),
                            (Some(a), None) => (point(a.0, a.1), point(x, y)),
                            (None, Some(b)) => (point(x, y), point(b.0, b.1)),
                            (None, None) => return None,
                        };
                        Some([q[0] - p[0], q[1] - p[1], q[2] - p[2]])
                    };
                let tx = tangent(
                    x.checked_sub(1).map(|xx| (xx, y)),
                    (x + 1 < w).then_some((x + 1, y)),
                );
                let ty = tangent(
                    y.checked_sub(1).map(|yy| (x, yy)),
                    (y + 1 < h).then_some((x, y + 1)),
                );
                let (Some(u), Some(v)) = (tx, ty) else {
                    continue;
                };
                let mut n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if !(len > 0.0 && len.is_finite()) {
                    continue;
                }
                // Face the camera: the normal points against the viewing ray (towards −z).
                let p = point(x, y);
                let s = if n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0.0 {
                    -1.0 / len
                } else {
                    1.0 / len
                };
                for v in &mut n {
                    *v *= s;
                }
                let shade =
                    0.25 + 0.75 * (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]).max(0.0);
                let to_u8 =
                    |v: f32| ((0.5 + 0.5 * v) * shade * 255.0).round().clamp(0.0, 255.0) as u8;
                *px = [to_u8(n[0]), to_u8(n[1]), to_u8(-n[2])];
            }
        });
    Ok(Image::from_vec(w, h, out)?)
}

/// Places images of equal height side by side (with a 4-pixel black gap), e.g. raw and filtered
/// renderings for a report.
pub fn side_by_side(images: &[&Image<[u8; 3]>]) -> Result<Image<[u8; 3]>> {
    const GAP: usize = 4;
    let h = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let w = images.iter().map(|i| i.width()).sum::<usize>() + GAP * images.len().saturating_sub(1);
    let mut out = vec![[0u8; 3]; w * h];
    let mut x0 = 0;
    for img in images {
        for (y, row) in img.rows().enumerate() {
            out[y * w + x0..y * w + x0 + row.len()].copy_from_slice(row);
        }
        x0 += img.width() + GAP;
    }
    Ok(Image::from_vec(w, h, out)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fronto_parallel_wall_is_uniform_light_blue() {
        let k = Intrinsics::new(32, 24, 30.0, 30.0, 15.5, 11.5).unwrap();
        let d = DepthImage::from_vec(32, 24, vec![2.0; 32 * 24]).unwrap();
        let img = shaded_normals(&d, &k).unwrap();
        let c = *img.get(16, 12).unwrap();
        assert_eq!(c, *img.get(3, 20).unwrap());
        assert!(c[2] > c[0] && c[2] > c[1], "{c:?}");
        assert_eq!(c[0], c[1]);
    }

    #[test]
    fn invalid_pixels_are_black_and_tilts_change_colour() {
        let k = Intrinsics::new(32, 24, 30.0, 30.0, 15.5, 11.5).unwrap();
        let mut data: Vec<f32> = (0..32 * 24).map(|i| 1.0 + 0.02 * (i % 32) as f32).collect();
        data[5 * 32 + 5] = 0.0;
        let d = DepthImage::from_vec(32, 24, data).unwrap();
        let img = shaded_normals(&d, &k).unwrap();
        assert_eq!(*img.get(5, 5).unwrap(), [0, 0, 0]);
        let flat = shaded_normals(
            &DepthImage::from_vec(32, 24, vec![1.0; 32 * 24]).unwrap(),
            &k,
        )
        .unwrap();
        assert_ne!(img.get(16, 12), flat.get(16, 12));
        assert!(shaded_normals(&d, &Intrinsics::kinect_v1()).is_err());
    }

    #[test]
    fn side_by_side_concatenates() {
        let a = Image::filled(3, 2, [1u8, 2, 3]);
        let b = Image::filled(2, 2, [9u8, 9, 9]);
        let c = side_by_side(&[&a, &b]).unwrap();
        assert_eq!((c.width(), c.height()), (3 + 4 + 2, 2));
        assert_eq!(*c.get(8, 1).unwrap(), [9, 9, 9]);
        assert_eq!(*c.get(4, 0).unwrap(), [0, 0, 0]);
    }
}

//! Cross-sections of the fused function `F` on axis-aligned planes (the paper's Figure 7).

use sl_core::Image;

use crate::error::{Result, TsdfError};
use crate::volume::TsdfVolume;

/// A world axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// Parses `x`, `y` or `z`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "x" | "X" => Ok(Self::X),
            "y" | "Y" => Ok(Self::Y),
            "z" | "Z" => Ok(Self::Z),
            o => Err(TsdfError::InvalidParameter(format!(
                "axis '{o}' is not x, y or z"
            ))),
        }
    }

    /// Index 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
            Self::Z => 2,
        }
    }

    /// The two in-plane axes `(u, v)` of a slice normal to this axis: image columns follow
    /// `u` (increasing to the right), rows follow `v` (increasing upwards).
    pub fn plane_axes(self) -> (usize, usize) {
        match self {
            Self::X => (1, 2),
            Self::Y => (0, 2),
            Self::Z => (0, 1),
        }
    }
}

/// What to cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SliceSpec {
    /// Normal axis of the plane.
    pub axis: Axis,
    /// Plane coordinate along `axis`, metres (snapped to the nearest voxel plane).
    pub coord_m: f64,
    /// Output pixels per voxel (bilinear interpolation in the plane), 1..=16.
    pub pixels_per_voxel: usize,
    /// In-plane window `([u_min, u_max], [v_min, v_max])` in metres; `None` = the extent of the
    /// allocated blocks crossing the plane.
    pub window_m: Option<([f64; 2], [f64; 2])>,
}

impl SliceSpec {
    /// A slice over the whole allocated extent at 2 pixels per voxel.
    pub fn new(axis: Axis, coord_m: f64) -> Self {
        Self {
            axis,
            coord_m,
            pixels_per_voxel: 2,
            window_m: None,
        }
    }
}

/// Largest slice side, pixels.
pub const MAX_SLICE_PX: usize = 8192;

/// Sampled values of `F` on a plane.
#[derive(Debug, Clone, PartialEq)]
pub struct Slice {
    /// `F` in metres, NaN where unobserved; row 0 is the top (largest `v`).
    pub values: Image<f32>,
    /// `(u, v)` world coordinates of the centre of the bottom-left pixel, metres.
    pub origin_m: [f64; 2],
    /// Pixel size, metres.
    pub pixel_m: f64,
    /// The truncation of the volume, metres (colour scale).
    pub trunc_m: f64,
}

impl TsdfVolume {
    /// Samples `F` on an axis-aligned plane.
    pub fn slice(&self, spec: &SliceSpec) -> Result<Slice> {
        if !(1..=16).contains(&spec.pixels_per_voxel) || !spec.coord_m.is_finite() {
            return Err(TsdfError::InvalidParameter(format!(
                "slice needs 1..=16 pixels per voxel and a finite coordinate, got {} / {}",
                spec.pixels_per_voxel,
                sl_core::Compact(spec.coord_m)
            )));
        }
        let vm = self.params().voxel_m;
        let a = spec.axis.index();
        let (ua, va) = spec.axis.plane_axes();
        let plane = (spec.coord_m / vm).round() as i64;
        let window = match spec.window_m {
            Some(w) => w,
            None => {
                let bs = crate::volume::BLOCK_SIDE as i64;
                let pb = plane.div_euclid(bs) as i32;
                let mut lo = [f64::INFINITY; 2];
                let mut hi = [f64::NEG_INFINITY; 2];
                for b in self.block_coords().filter(|b| b[a] == pb) {
                    for (i, ax) in [ua, va].into_iter().enumerate() {
                        lo[i] = lo[i].min(f64::from(b[ax]) * bs as f64 * vm);
                        hi[i] = hi[i].max((f64::from(b[ax]) + 1.0) * bs as f64 * vm - vm);
                    }
                }
                if !lo[0].is_finite() {
                    // Where the blocks are along the axis, to pick a plane that crosses them.
                    let span = self.block_coords().map(|b| b[a]).fold(
                        None,
                        |acc: Option<(i32, i32)>, c| {
                            Some(acc.map_or((c, c), |(l, h)| (l.min(c), h.max(c))))
                        },
                    );
                    let name = ["x", "y", "z"][a];
                    let extent = match span {
                        Some((l, h)) => format!(
                            "the allocated blocks span {name} from {} to {} m",
                            sl_core::Compact(f64::from(l) * bs as f64 * vm),
                            sl_core::Compact((f64::from(h) + 1.0) * bs as f64 * vm)
                        ),
                        None => "no block is allocated: nothing was fused".into(),
                    };
                    return Err(TsdfError::InvalidParameter(format!(
                        "no allocated block crosses the plane {name} = {} m ({extent})",
                        sl_core::Compact(spec.coord_m)
                    )));
                }
                ([lo[0], hi[0]], [lo[1], hi[1]])
            }
        };
        let pixel_m = vm / spec.pixels_per_voxel as f64;
        let size = |r: [f64; 2]| ((r[1] - r[0]) / pixel_m).floor() + 1.0;
        let (wf, hf) = (size(window.0), size(window.1));
        if !(wf >= 1.0 && hf >= 1.0 && wf <= MAX_SLICE_PX as f64 && hf <= MAX_SLICE_PX as f64) {
            return Err(TsdfError::InvalidParameter(format!(
                "slice window {window:?} gives {}x{} pixels (max {MAX_SLICE_PX} per side)",
                sl_core::Compact(wf),
                sl_core::Compact(hf)
            )));
        }
        let (w, h) = (wf as usize, hf as usize);
        let values = Image::from_fn(w, h, |x, y| {
            let u = window.0[0] + x as f64 * pixel_m;
            let v = window.1[0] + (h - 1 - y) as f64 * pixel_m;
            let (gu, gv) = (u / vm, v / vm);
            let (iu, iv) = (gu.floor(), gv.floor());
            let (fu, fv) = ((gu - iu) as f32, (gv - iv) as f32);
            let mut acc = 0.0f32;
            for (du, dv, wt) in [
                (0, 0, (1.0 - fu) * (1.0 - fv)),
                (1, 0, fu * (1.0 - fv)),
                (0, 1, (1.0 - fu) * fv),
                (1, 1, fu * fv),
            ] {
                let mut idx = [0i64; 3];
                idx[a] = plane;
                idx[ua] = iu as i64 + du;
                idx[va] = iv as i64 + dv;
                match self.voxel(idx) {
                    Some(vx) if vx.weight > 0.0 => acc += wt * vx.tsdf,
                    _ if wt == 0.0 => {}
                    _ => return f32::NAN,
                }
            }
            acc
        });
        Ok(Slice {
            values,
            origin_m: [window.0[0], window.1[0]],
            pixel_m,
            trunc_m: self.params().trunc_m,
        })
    }

    /// The RGB cross-section of [`TsdfVolume::slice`] with its zero crossing in black.
    pub fn slice_rgb(&self, spec: &SliceSpec) -> Result<Image<[u8; 3]>> {
        Ok(self.slice(spec)?.to_rgb([0, 0, 0]))
    }
}

/// Colour of unobserved pixels.
pub const UNOBSERVED_RGB: [u8; 3] = [60, 60, 60];

impl Slice {
    /// Diverging colour map of `F / trunc` (blue behind the surface, red in front, white at
    /// zero, grey unobserved) with the zero crossing drawn in `line`.
    pub fn to_rgb(&self, line: [u8; 3]) -> Image<[u8; 3]> {
        let t = self.trunc_m as f32;
        let mut img = self.values.map(|&f| {
            if f.is_nan() {
                return UNOBSERVED_RGB;
            }
            let s = (f / t).clamp(-1.0, 1.0);
            let fade = |x: f32| (255.0 * (1.0 - 0.85 * x.abs())) as u8;
            if s >= 0.0 {
                [255, fade(s), fade(s)]
            } else {
                [fade(s), fade(s), 255]
            }
        });
        self.draw_zero_crossing(&mut img, line);
        img
    }

    /// Pixels where `F` changes sign towards the right or lower neighbour.
    pub fn zero_crossing_mask(&self) -> Image<bool> {
        let (w, h) = (self.values.width(), self.values.height());
        let d = self.values.data();
        Image::from_fn(w, h, |x, y| {
            let f = d[y * w + x];
            if f.is_nan() {
                return false;
            }
            let differs = |g: f32| !g.is_nan() && ((f < 0.0) != (g < 0.0));
            (x + 1 < w && differs(d[y * w + x + 1])) || (y + 1 < h && differs(d[(y + 1) * w + x]))
        })
    }

    /// Paints the zero crossing of this slice over an image of the same size.
    pub fn draw_zero_crossing(&self, img: &mut Image<[u8; 3]>, line: [u8; 3]) {
        let mask = self.zero_crossing_mask();
        if img.width() != mask.width() || img.height() != mask.height() {
            return;
        }
        for (p, &m) in img.data_mut().iter_mut().zip(mask.data()) {
            if m {
                *p = line;
            }
        }
    }
}

/// Places images side by side (top-aligned, `gap` grey pixels between them).
pub fn hconcat(images: &[&Image<[u8; 3]>], gap: usize) -> Image<[u8; 3]> {
    let h = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let w = images.iter().map(|i| i.width()).sum::<usize>() + gap * images.len().saturating_sub(1);
    let mut out = Image::filled(w, h, [200u8, 200, 200]);
    let mut x0 = 0;
    for img in images {
        for y in 0..img.height() {
            let src = img.row(y);
            let dst = &mut out.data_mut()[y * w + x0..y * w + x0 + img.width()];
            dst.copy_from_slice(src);
        }
        x0 += img.width() + gap;
    }
    out
}

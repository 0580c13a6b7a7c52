//! The streamed input of the extractor: depth or disparity rows, the full-resolution disparity
//! rebuilt row by row for the final pass, and the 2×2 half-resolution rows fed to the LoG.

use super::*;

/// The full-resolution input of [`PlaneExtractor::run`].
pub(super) enum Source<'a> {
    /// Disparity (pixels; non-positive or non-finite = invalid), used in place.
    Disparity(&'a [f32]),
    /// Depth (metres), converted row pair by row pair into `d` (two rows).
    Depth {
        z: &'a [f32],
        d: &'a mut [f32],
        fb: f32,
    },
}

/// The full-resolution disparity for the final pass: the input disparity, or the depth, whose
/// rows are converted again where they are used (the same conversion, so the same bits, without
/// writing and re-reading a full-resolution disparity image).
#[derive(Clone, Copy)]
pub(super) enum FullDisparity<'a> {
    /// Disparity (pixels; non-positive or non-finite = invalid).
    Disparity(&'a [f32]),
    /// Depth (metres) and `f·B`.
    Depth { z: &'a [f32], fb: f32 },
}

impl<'a> FullDisparity<'a> {
    /// Row `y` (width `w`) of the disparity, converted into `scratch` (length `w`) for depth.
    #[inline]
    pub(super) fn row<'s>(self, y: usize, w: usize, scratch: &'s mut [f32]) -> &'s [f32]
    where
        'a: 's,
    {
        match self {
            FullDisparity::Disparity(d) => &d[y * w..(y + 1) * w],
            FullDisparity::Depth { z, fb } => {
                depth_to_disparity_row(&z[y * w..(y + 1) * w], scratch, fb);
                scratch
            }
        }
    }

    /// The disparity of pixel `i` (the scalar form of `depth_to_disparity_row` for depth).
    #[inline]
    pub(super) fn at(self, i: usize) -> f32 {
        match self {
            FullDisparity::Disparity(d) => d[i],
            FullDisparity::Depth { z, fb } => {
                let zv = z[i];
                if zv > 0.0 && zv < f32::INFINITY {
                    fb / zv
                } else {
                    0.0
                }
            }
        }
    }
}

/// The half-resolution disparity (2×2 means, NaN = invalid) produced row by row for the LoG,
/// from the full-resolution rows (converted from depth on the way) while they are in L1; after
/// each odd row, the row of the cells `cell_disparity` (2×2 means of the half-resolution map).
pub(super) struct HalfRows<'a, 'b> {
    pub(super) src: Source<'a>,
    /// The last two half-resolution rows.
    pub(super) half_res_rows: &'b mut [f32],
    pub(super) cell_disparity: &'b mut [f32],
    /// Full-resolution width.
    pub(super) w: usize,
    /// Next half-resolution row.
    pub(super) next: usize,
}

impl<'a> HalfRows<'a, '_> {
    /// Produces the next half-resolution row (and cell row) and returns its index.
    pub(super) fn produce(&mut self) -> usize {
        let (w, y2) = (self.w, self.next);
        self.next += 1;
        let pair = 2 * y2 * w..(2 * y2 + 2) * w;
        let r2: &[f32] = match &mut self.src {
            Source::Disparity(d) => &d[pair],
            Source::Depth { z, d, fb } => {
                let (zp, dp) = (&z[pair], &mut d[..2 * w]);
                for (zr, dr) in zp.chunks_exact(w).zip(dp.chunks_exact_mut(w)) {
                    depth_to_disparity_row(zr, dr, *fb);
                }
                dp
            }
        };
        let (r0, r1) = r2.split_at(w);
        let w2 = w / 2;
        let (q0, q1) = self.half_res_rows.split_at_mut(w2);
        let out = if y2.is_multiple_of(2) { q0 } else { q1 };
        downsample_rows(r0, r1, out);
        if !y2.is_multiple_of(2) {
            let (q0, q1) = self.half_res_rows.split_at(w2);
            let (wq, j) = (w2 / 2, y2 / 2);
            let out = &mut self.cell_disparity[j * wq..(j + 1) * wq];
            for ((o, p), q) in out
                .iter_mut()
                .zip(q0.chunks_exact(2))
                .zip(q1.chunks_exact(2))
            {
                *o = 0.25 * ((p[0] + p[1]) + (q[0] + q[1]));
            }
        }
        y2
    }

    /// Produces the rows the LoG left (all of `half_res_rows` and `cell_disparity` are then done) and returns the
    /// full-resolution disparity.
    pub(super) fn finish(mut self, h: usize) -> FullDisparity<'a> {
        while self.next < h / 2 {
            self.produce();
        }
        match self.src {
            Source::Disparity(d) => FullDisparity::Disparity(d),
            Source::Depth { z, fb, .. } => FullDisparity::Depth { z, fb },
        }
    }
}

impl RowSource for HalfRows<'_, '_> {
    fn next_row(&mut self) -> &[f32] {
        let y2 = self.produce();
        let w2 = self.w / 2;
        &self.half_res_rows[(y2 % 2) * w2..(y2 % 2 + 1) * w2]
    }
}

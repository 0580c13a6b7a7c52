//! The input of the extractor: the full-resolution disparity (the depth converted row by row
//! where it is used), and the 2×2 half-resolution map and the 4×4 cells computed from it.

use rayon::prelude::*;

use super::*;

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

    /// Row `y` (width `w`) of the disparity written into `out` (length `w`).
    #[inline]
    pub(super) fn row_into(self, y: usize, w: usize, out: &mut [f32]) {
        match self {
            FullDisparity::Disparity(d) => out.copy_from_slice(&d[y * w..(y + 1) * w]),
            FullDisparity::Depth { z, fb } => {
                depth_to_disparity_row(&z[y * w..(y + 1) * w], out, fb)
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

/// Cell rows per piece of [`half_resolution`] (a constant, so the pieces do not depend on the
/// number of threads; each piece computes every value as the whole frame would).
const HALF_RES_PIECE_CELL_ROWS: usize = 8;

/// The half-resolution disparity (2×2 means, NaN = invalid) of the `w × h` frame `src` into
/// rows `m..m + h/2`, columns `m..m + w/2` of the extended map `ext` (width `we`; the rest is
/// left as it is), the same map with the blocks that keep a complete diagonal
/// (`kernels::block_mean_or_diagonal`) into `partial` (`w/2 × h/2`), and the cells' disparity
/// (2×2 means of `partial`, NaN where one of the four is, `w/4 × h/4`) into `cells`.
///
/// Two maps, because they serve two tests. The LoG measures curvature on `ext` (extended
/// across its holes, exactly for a plane): a block mean from two pixels is twice as noisy as
/// one from four, and on a speckled surface at the edge of the sensor's reach (7-Scenes'
/// counter top) its noise alone crossed the LoG threshold. Where a pixel counts as data, for
/// the planarity mask and for the cells, `partial` decides: scattered missing pixels (a stereo
/// camera's dropped matches, depth aligned to a larger colour image, a confidence mask) then
/// cost a cell only where both diagonals of one of its blocks are broken. (A cell of four
/// blocks' values, not of the pixels' own: taking it from a diagonal of blocks as well gained
/// a few planes at 10–20 % missing pixels but cost 7-Scenes' repeatability, session 46.)
///
/// Pieces of [`HALF_RES_PIECE_CELL_ROWS`] cell rows run on the caller's pool when `parallel`;
/// `scratch` holds one two-row buffer per piece (depth converted to disparity).
#[allow(clippy::too_many_arguments)]
pub(super) fn half_resolution(
    src: FullDisparity<'_>,
    w: usize,
    h: usize,
    ext: &mut [f32],
    we: usize,
    m: usize,
    partial: &mut [f32],
    cells: &mut [f32],
    scratch: &mut Vec<Vec<f32>>,
    parallel: bool,
) {
    let (w2, h2) = (w / 2, h / 2);
    let (wq, hq) = (w2 / 2, h2 / 2);
    // Half-resolution row `y2` into `out` and `part` (`w2` values each), through the two-row
    // `buf`.
    let half_row = |y2: usize, out: &mut [f32], part: &mut [f32], buf: &mut [f32]| {
        let (b0, b1) = buf.split_at_mut(w);
        let r0 = src.row(2 * y2, w, b0);
        let r1 = src.row(2 * y2 + 1, w, b1);
        downsample_rows(r0, r1, out, part);
    };
    // One piece: cell rows `j0..`, their half-resolution rows in `rows` (rows `2·j0..` of the
    // map, `we` apart) and their cells in `crow`.
    let piece =
        |j0: usize, rows: &mut [f32], prows: &mut [f32], crow: &mut [f32], buf: &mut Vec<f32>| {
            buf.resize(2 * w, 0.0);
            for (jj, ((pair, ppair), out)) in rows
                .chunks_exact_mut(2 * we)
                .zip(prows.chunks_exact_mut(2 * w2))
                .zip(crow.chunks_exact_mut(wq))
                .enumerate()
            {
                let j = j0 + jj;
                let (q0, q1) = pair.split_at_mut(we);
                let (q0, q1) = (&mut q0[m..m + w2], &mut q1[m..m + w2]);
                let (p0, p1) = ppair.split_at_mut(w2);
                half_row(2 * j, q0, p0, buf);
                half_row(2 * j + 1, q1, p1, buf);
                // A cell's value is the mean of its four blocks' (each the value at the block's
                // centre, from all four pixels or from a diagonal), NaN when a block has none.
                for ((o, p), q) in out
                    .iter_mut()
                    .zip(p0.chunks_exact(2))
                    .zip(p1.chunks_exact(2))
                {
                    *o = 0.25 * ((p[0] + p[1]) + (q[0] + q[1]));
                }
            }
        };
    let rows = &mut ext[m * we..(m + 2 * hq) * we];
    let (prows, podd) = partial[..w2 * h2].split_at_mut(2 * hq * w2);
    let cells = &mut cells[..wq * hq];
    let pieces = hq.div_ceil(HALF_RES_PIECE_CELL_ROWS).max(1);
    if scratch.len() < pieces {
        scratch.resize_with(pieces, Vec::new);
    }
    let (rows_per, cells_per) = (
        2 * HALF_RES_PIECE_CELL_ROWS * we,
        HALF_RES_PIECE_CELL_ROWS * wq,
    );
    let prows_per = 2 * HALF_RES_PIECE_CELL_ROWS * w2;
    if parallel {
        rows.par_chunks_mut(rows_per)
            .zip(prows.par_chunks_mut(prows_per))
            .zip(cells.par_chunks_mut(cells_per))
            .zip(scratch.par_iter_mut())
            .enumerate()
            .for_each(|(k, (((r, pr), c), buf))| {
                piece(k * HALF_RES_PIECE_CELL_ROWS, r, pr, c, buf);
            });
    } else {
        rows.chunks_mut(rows_per)
            .zip(prows.chunks_mut(prows_per))
            .zip(cells.chunks_mut(cells_per))
            .zip(scratch.iter_mut())
            .enumerate()
            .for_each(|(k, (((r, pr), c), buf))| {
                piece(k * HALF_RES_PIECE_CELL_ROWS, r, pr, c, buf);
            });
    }
    // An odd number of half-resolution rows: the last one has no cell row.
    if h2 > 2 * hq
        && let Some(buf) = scratch.first_mut()
    {
        buf.resize(2 * w, 0.0);
        let at = (m + 2 * hq) * we + m;
        half_row(2 * hq, &mut ext[at..at + w2], &mut podd[..w2], buf);
    }
}

//! One band of rows of the final pass ([`PlaneExtractor::final_pass`]): its scratch rows and
//! what it produces, the planes' moments over the band and its ambiguous pixels. Bands read
//! only the frame's shared state ([`FinalShared`]) and write their own rows of the label
//! image, so they run in parallel; their moments are added in row order, so the result does
//! not depend on the number of threads.

use super::*;

/// Rows per band of the final pass: a whole number of cell rows, so that a band starts a
/// cell row. A constant (not derived from the number of threads), so that the moments are
/// added in the same order on any number of threads. 15 bands for a 480-row frame.
pub(super) const FINAL_BAND_ROWS: usize = 8 * CELL;

/// Cell row `jj` of the cell labels (empty outside the grid).
fn cell_row(labels: &[u16], jj: usize, wq: usize) -> &[u16] {
    labels.get(jj * wq..(jj + 1) * wq).unwrap_or(&[])
}

/// What every band of the final pass reads: the frame's disparity, cell labels and plane fits.
#[derive(Clone, Copy)]
pub(super) struct FinalShared<'a> {
    /// The full-resolution disparity.
    pub(super) d: FullDisparity<'a>,
    /// Plane label per cell.
    pub(super) cell_labels: &'a [u16],
    /// Per plane: its fit in full-resolution pixel coordinates.
    pub(super) full_res_fits: &'a [DisparityAffine],
    /// Per plane: `∂D/∂x` as `f32`.
    pub(super) slope_x: &'a [f32],
    /// A row of zero cell labels.
    pub(super) zero_cell_row: &'a [u16],
    /// The per-pixel noise bound, `CellNoise::pixel_bound_px`.
    pub(super) bound: f32,
    /// The residual threshold `τ`, pixels.
    pub(super) tau: f32,
    /// Image width and cell-grid width.
    pub(super) w: usize,
    pub(super) wq: usize,
    /// Where each row's values were measured (a replicated decimated frame).
    pub(super) rows: RowCentres,
}

/// The scratch and the output of one band (kept by the extractor, reused frame after frame).
#[derive(Debug, Clone, Default)]
pub(super) struct FinalBand {
    /// One full-resolution disparity row.
    drow: Vec<f32>,
    /// Keep bytes of the row being assigned: 1 = done, 0 = search.
    keep_row: Vec<u8>,
    /// Per cell of the current cell row: 1 when an unlabelled cell touches a labelled one.
    cells_touching_plane: Vec<u8>,
    /// Per cell of the current cell row: 1 when it is labelled and a cell of another plane
    /// touches it.
    border_cells: Vec<u8>,
    /// Runs `(start, end, label, border)` of equal cell labels and border flags of the current
    /// cell row.
    cell_label_runs: Vec<(u32, u32, u16, bool)>,
    /// Keep bytes of the pixels of unlabelled cells of the current cell row (0 = search).
    unlabelled_keep: Vec<u8>,
    /// The 8-pixel chunks of the current row that have pixels to search, with their keep words.
    search_chunks: Vec<(u32, u64)>,
    /// Per chunk: the cell row (+1) its candidate list was computed for.
    candidates_cell_row: Vec<u32>,
    /// Per chunk: the candidate planes (label − 1) of the cells around it.
    candidate_planes: Vec<[u16; 16]>,
    /// Per chunk: how many entries of `candidate_planes` are used.
    candidate_count: Vec<u8>,
    /// Per plane: the disparity of the current row at x = 0 as `f32`.
    row_offsets: Vec<f32>,
    /// Per plane: pixels, rows and moments of the band.
    pub(super) sums: Vec<FinalAcc>,
    /// The band's pixels that fit two planes.
    pub(super) ambiguous: Vec<AmbiguousPixel>,
}

/// A pixel that two planes explain (see [`PlaneExtractor::final_pass`]), for the
/// disambiguation. Its column and row are kept (not its index), so that the disambiguation
/// needs no division per pixel.
#[derive(Debug, Clone, Copy)]
pub(super) struct AmbiguousPixel {
    pub(super) x: u32,
    pub(super) y: u32,
    /// The label the pixel took (the smaller residual).
    pub(super) best: u16,
    /// The other plane's label.
    pub(super) second: u16,
}

impl FinalBand {
    /// Assigns rows `y0..y0 + labels.len() / w` (`y0` a multiple of [`CELL`]) into `labels`
    /// (those rows of the label image, zero on entry).
    pub(super) fn run(&mut self, sh: &FinalShared<'_>, y0: usize, labels: &mut [u16]) {
        let w = sh.w;
        self.prepare(sh);
        let mut drow = std::mem::take(&mut self.drow);
        drow.resize(w, 0.0);
        for (r, row_l) in labels.chunks_exact_mut(w).enumerate() {
            let y = y0 + r;
            let j = y / CELL;
            if y.is_multiple_of(CELL) {
                self.prepare_cell_row(sh, j);
            }
            let row_d = sh.d.row(y, w, &mut drow[..w]);
            self.assign_incumbents(sh, row_d, row_l, y);
            self.mark_tail_columns(sh, j);
            let count = self.collect_search_chunks(w);
            self.search_row(sh, row_d, row_l, y, count);
        }
        self.drow = drow;
    }

    /// Fresh accumulators and candidate caches for a band of this frame.
    fn prepare(&mut self, sh: &FinalShared<'_>) {
        let (w, wq) = (sh.w, sh.wq);
        self.sums.clear();
        self.sums
            .resize(sh.full_res_fits.len(), FinalAcc::default());
        self.ambiguous.clear();
        // `fit_run` may write up to 7 bytes past a run.
        self.keep_row.resize(w + LANES, 0);
        let nchunks = w.div_ceil(LANES);
        self.candidates_cell_row.clear();
        self.candidates_cell_row.resize(nchunks, 0);
        self.candidate_planes.resize(nchunks, [0; 16]);
        self.candidate_count.resize(nchunks, 0);
        self.cells_touching_plane.clear();
        self.cells_touching_plane.resize(wq, 0);
        self.border_cells.clear();
        self.border_cells.resize(wq, 0);
    }

    /// Once per cell row: which unlabelled cells touch a labelled one (their pixels are
    /// searched), as keep bytes per pixel, and the runs of equal cell labels.
    fn prepare_cell_row(&mut self, sh: &FinalShared<'_>, j: usize) {
        let wq = sh.wq;
        let cl: &[u16] = sh.cell_labels;
        let hint_row = cell_row(cl, j, wq);
        let up_row = if j > 0 { cell_row(cl, j - 1, wq) } else { &[] };
        let dn_row = cell_row(cl, j + 1, wq);
        let zrow = sh.zero_cell_row;
        let nh = hint_row.len();
        let need = &mut self.cells_touching_plane[..nh];
        let up2 = if up_row.is_empty() { zrow } else { up_row };
        let dn2 = if dn_row.is_empty() { zrow } else { dn_row };
        touching(hint_row, up2, dn2, need);
        // The keep bytes of the pixels of unlabelled cells (0 = search).
        self.unlabelled_keep.clear();
        self.unlabelled_keep
            .extend(need.iter().flat_map(|&nd| [1 - nd; CELL]));
        // The cells at a border between planes, and the runs of equal cell labels and border
        // flags, shared by the rows of this cell row.
        let border = &mut self.border_cells[..nh];
        plane_borders(hint_row, up_row, dn_row, border);
        self.cell_label_runs.clear();
        let mut i = 0;
        while i < nh {
            let e = run_end(hint_row, i);
            let mut k = i;
            while k < e {
                let b = border[k];
                let mut m = k + 1;
                while m < e && border[m] == b {
                    m += 1;
                }
                self.cell_label_runs
                    .push((k as u32, m as u32, hint_row[i], b != 0));
                k = m;
            }
            i = e;
        }
    }

    /// The runs of labelled cells: their pixels within `τ` of the cell's plane take its label
    /// (and feed its moments on the sample rows); keep bytes: 1 = labelled or stays
    /// unlabelled, 0 = search.
    fn assign_incumbents(
        &mut self,
        sh: &FinalShared<'_>,
        row_d: &[f32],
        row_l: &mut [u16],
        y: usize,
    ) {
        let (w, tau) = (sh.w, sh.tau);
        let yf = sh.rows.of(y);
        let (stats, metric) = (is_sample_row(y), is_metric_row(y));
        let full: &[DisparityAffine] = sh.full_res_fits;
        let acc = &mut self.sums;
        let keep = &mut self.keep_row[..];
        let mut inv_dummy = InvSums::default();
        let mut sums_dummy = AffineSums::default();
        for &(i, e, v, border) in &self.cell_label_runs {
            let (i, e) = (i as usize, e as usize);
            let (x0, x1) = (CELL * i, (CELL * e).min(w));
            if border {
                // Cells at a border between planes: every pixel chooses (`search_row`).
                keep[x0..x1].fill(0);
            } else if let Some(a) = (v as usize).checked_sub(1).and_then(|ku| acc.get_mut(ku)) {
                // The rest of the row: `fit_run` reads and writes ahead.
                let (seg, ks) = (&row_d[x0..], &mut keep[x0..]);
                let f = &full[v as usize - 1];
                let c_row = f.b * yf + f.c;
                let n = x1 - x0;
                let lab = &mut row_l[x0..];
                let kept = if metric {
                    fit_run_labels::<true, true, true>(
                        seg,
                        ks,
                        lab,
                        v,
                        n,
                        x0,
                        yf,
                        f.a,
                        c_row,
                        tau,
                        &mut a.sums,
                        &mut a.inv,
                    )
                } else if stats {
                    fit_run_labels::<true, false, true>(
                        seg,
                        ks,
                        lab,
                        v,
                        n,
                        x0,
                        yf,
                        f.a,
                        c_row,
                        tau,
                        &mut a.sums,
                        &mut inv_dummy,
                    )
                } else {
                    fit_run_labels::<false, false, true>(
                        seg,
                        ks,
                        lab,
                        v,
                        n,
                        x0,
                        yf,
                        f.a,
                        c_row,
                        tau,
                        &mut sums_dummy,
                        &mut inv_dummy,
                    )
                };
                a.pixels += kept;
                a.add_rows(y);
            } else {
                // Unlabelled cells: searched only when touching a labelled cell (`x1` is
                // `CELL · e`, within the pattern of this cell row).
                let ks = &mut keep[x0..x1];
                match self.unlabelled_keep.get(x0..x1) {
                    Some(u) => ks.copy_from_slice(u),
                    None => ks.fill(1),
                }
            }
        }
    }

    /// Columns beyond the cell grid (width not a multiple of the cell), or rows without one:
    /// unlabelled cells, searched when a neighbouring cell is labelled (after the runs, which
    /// may write ahead).
    fn mark_tail_columns(&mut self, sh: &FinalShared<'_>, j: usize) {
        let (w, wq) = (sh.w, sh.wq);
        let cl: &[u16] = sh.cell_labels;
        let hint_row = cell_row(cl, j, wq);
        let up_row = if j > 0 { cell_row(cl, j - 1, wq) } else { &[] };
        let dn_row = cell_row(cl, j + 1, wq);
        let nh = hint_row.len();
        let g = |r: &[u16], ii: usize| r.get(ii).is_some_and(|&l| l != 0);
        for (x, k) in self.keep_row.iter_mut().enumerate().take(w).skip(CELL * nh) {
            let i = x / CELL;
            let t =
                (i > 0 && g(hint_row, i - 1)) || g(hint_row, i + 1) || g(up_row, i) || g(dn_row, i);
            *k = u8::from(!t);
        }
    }

    /// The 8-pixel chunks of the row with a pixel to search, with their keep words, into
    /// `search_chunks`; returns how many.
    fn collect_search_chunks(&mut self, w: usize) -> usize {
        let keep = &self.keep_row[..w];
        let nch = w.div_ceil(LANES);
        self.search_chunks.resize(nch + 1, (0, 0));
        let mut count = 0usize;
        let mut kw = keep.chunks_exact(LANES);
        let chunks = &mut self.search_chunks[..nch + 1];
        for (c, kc) in (&mut kw).enumerate() {
            let word = u64::from_le_bytes(<[u8; LANES]>::try_from(kc).unwrap_or([1; LANES]));
            // Written whether or not it is kept (`count <= c`), so that no branch depends on
            // the data: most rows alternate runs of kept and searched chunks.
            if let Some(slot) = chunks.get_mut(count) {
                *slot = (c as u32, word);
            }
            count += usize::from(word != ALL_KEPT);
        }
        let tail = kw.remainder();
        if !tail.is_empty() {
            let word = u64::from_le_bytes(pad(tail, 1));
            self.search_chunks[count] = ((w / LANES) as u32, word);
            count += usize::from(word != ALL_KEPT);
        }
        count
    }

    /// The searches, 8 pixels at a time, of the first `count` chunks of `search_chunks`: each
    /// valid pixel to search takes the plane of the cells around its chunk with the smallest
    /// residual when the noise explains it (`CellNoise::pixel_bound_px`), else its cell's plane
    /// if within `τ`, else the best within `τ` (pixels that two planes explain are recorded in
    /// `ambiguous`; see [`PlaneExtractor::final_pass`]).
    fn search_row(
        &mut self,
        sh: &FinalShared<'_>,
        row_d: &[f32],
        row_l: &mut [u16],
        y: usize,
        count: usize,
    ) {
        let (w, wq, tau) = (sh.w, sh.wq, sh.tau);
        let yf = sh.rows.of(y);
        let (stats, metric) = (is_sample_row(y), is_metric_row(y));
        let j = y / CELL;
        self.row_offsets.clear();
        self.row_offsets
            .extend(sh.full_res_fits.iter().map(|f| (f.b * yf + f.c) as f32));
        // With at most 64 planes, labels are at most 64 (bit masks of the candidates).
        let small = sh.full_res_fits.len() <= 64;
        let cl: &[u16] = sh.cell_labels;
        let up_row = if j > 0 { cell_row(cl, j - 1, wq) } else { &[] };
        let hint_row = cell_row(cl, j, wq);
        let dn_row = cell_row(cl, j + 1, wq);
        let full: &[DisparityAffine] = sh.full_res_fits;
        let (fa, rowc): (&[f32], &[f32]) = (sh.slope_x, &self.row_offsets);
        let acc = &mut self.sums;
        let amb = &mut self.ambiguous;
        let bound = sh.bound;
        for &(c, word) in &self.search_chunks[..count] {
            let x0 = c as usize * LANES;
            let x1 = (x0 + LANES).min(w);
            let mut todo = byte_mask(!word & ALL_KEPT);
            let (dc, lc) = (&row_d[x0..x1], &mut row_l[x0..x1]);
            let d8 = <[f32; LANES]>::try_from(dc).unwrap_or_else(|_| pad(dc, f32::NAN));
            todo &= valid_mask(&d8);
            if todo == 0 {
                continue;
            }
            // Candidates: the planes of the cells around the chunk (coherence), the same for
            // the rows of a cell row.
            let ci = c as usize;
            let tag = j as u32 + 1;
            if self.candidates_cell_row[ci] != tag {
                let (c0, c1) = (x0 / CELL, (x0 + LANES).div_ceil(CELL));
                let (a, b) = (c0.saturating_sub(1), c1 + 1);
                let nc = candidate_planes_around(
                    [up_row, hint_row, dn_row],
                    a,
                    b,
                    small,
                    &mut self.candidate_planes[ci],
                );
                self.candidate_count[ci] = nc as u8;
                self.candidates_cell_row[ci] = tag;
            }
            let near = &self.candidate_planes[ci][..self.candidate_count[ci] as usize];
            let two = search8_two(&d8, x0 as f32, near, fa, rowc, tau);
            todo &= nonzero_mask(&two.best);
            while todo != 0 {
                let o = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                let x = x0 + o;
                let (mut lab, mut other) = (two.best[o], two.second[o]);
                if two.best_res[o] > bound {
                    // No plane explains the pixel within the noise: its cell's plane keeps it
                    // while within τ (as away from borders), else the best within τ.
                    let inc = hint_row.get(x / CELL).copied().unwrap_or(0);
                    if inc != 0
                        && inc != lab
                        && let Some(f) = full.get(inc as usize - 1)
                        && (f64::from(dc[o]) - f.eval(x as f64, yf)).abs() < f64::from(tau)
                    {
                        (lab, other) = (inc, 0);
                    }
                } else if two.second_res[o] > bound {
                    // The best plane explains it within the noise and the second does not.
                    other = 0;
                }
                let Some(a) = acc.get_mut((lab as usize).wrapping_sub(1)) else {
                    continue;
                };
                lc[o] = lab;
                a.pixels += 1;
                a.add_rows(y);
                if stats {
                    let (xf, df) = (x as f64, f64::from(dc[o]));
                    a.sums.add(xf, yf, df);
                    if metric {
                        let r = df - full[lab as usize - 1].eval(xf, yf);
                        a.inv.add(xf, yf, df, r, 1.0);
                    }
                }
                if other != 0 {
                    amb.push(AmbiguousPixel {
                        x: x as u32,
                        y: y as u32,
                        best: lab,
                        second: other,
                    });
                }
            }
        }
    }
}

//! The final per-pixel pass: every pixel tested against the planes of its neighbourhood, the
//! labels and moments written row by row, ambiguous pixels resolved, small pieces dropped and
//! the planes finished (3D plane, RMS, centroid).

use super::*;

/// Cell row `jj` of the cell labels (empty outside the grid).
fn cell_row(labels: &[u16], jj: usize, wq: usize) -> &[u16] {
    labels.get(jj * wq..(jj + 1) * wq).unwrap_or(&[])
}

/// How many of the 8 neighbours of pixel `(x, y)` carry label `k1` and how many `k2`.
///
/// Away from the image border the eight labels are read as three fixed-size windows (no loop
/// over clipped ranges): the disambiguation visits every pixel that two planes explain, about
/// 10 k a frame, and the general loop cost ~250 instructions per pixel.
#[inline]
fn neighbour_votes(
    labels: &[u16],
    w: usize,
    h: usize,
    x: usize,
    y: usize,
    k1: u16,
    k2: u16,
) -> (u32, u32) {
    let count = |ls: &[u16]| {
        ls.iter().fold((0u32, 0u32), |(a, b), &l| {
            (a + u32::from(l == k1), b + u32::from(l == k2))
        })
    };
    if x > 0 && x + 1 < w && y > 0 && y + 1 < h {
        let i = y * w + x;
        let (up, dn) = (&labels[i - w - 1..i - w + 2], &labels[i + w - 1..i + w + 2]);
        let (u, d) = (count(up), count(dn));
        let (l, r) = (labels[i - 1], labels[i + 1]);
        return (
            u.0 + d.0 + u32::from(l == k1) + u32::from(r == k1),
            u.1 + d.1 + u32::from(l == k2) + u32::from(r == k2),
        );
    }
    let (mut c1, mut c2) = (0u32, 0u32);
    for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            if nx == x && ny == y {
                continue;
            }
            let l = labels[ny * w + nx];
            c1 += u32::from(l == k1);
            c2 += u32::from(l == k2);
        }
    }
    (c1, c2)
}

impl PlaneExtractor {
    /// The full-resolution assignment, with the final moments of the sample rows: each pixel
    /// takes its cell's label if that plane fits it within `τ` (runs of equal cell labels are
    /// tested in one vectorised sweep); otherwise, for the pixels of unlabelled cells touching
    /// a labelled cell, and for every pixel of a cell at a border between planes (a cell of
    /// another plane among its 8 neighbours), the planes of the cells around are searched, 8
    /// pixels at a time. A searched pixel takes the plane with the smallest disparity residual
    /// in units of its noise (`σ_D` and the `1/q` quantisation: the same for every plane, so the
    /// smallest residual) when that residual is within the noise — the 99.9 % bound
    /// `CellNoise::pixel_bound_px`, 0.26 px for the Kinect; the same confidence as the seeds'
    /// χ² tests. Otherwise its cell's plane keeps it while within `τ`, as away from borders, or
    /// the best plane within `τ` takes it. So a crease is where the two planes' disparities
    /// cross, pixel by pixel, not where the 16-pixel seed patches met. Pixels that a second
    /// plane also explains (within the noise when the best does, else within `τ`) are recorded
    /// for the disambiguation. Pixels of unlabelled cells away from planes stay unlabelled
    /// (coherence).
    ///
    /// Stages, row by row: [`Self::prepare_cell_row`] (once per cell row),
    /// [`Self::assign_incumbents`], [`Self::mark_tail_columns`], [`Self::collect_search_chunks`]
    /// and [`Self::search_row`].
    #[inline(never)]
    pub(super) fn final_pass(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        wq: usize,
        tau: f32,
        labels: &mut Vec<u16>,
    ) {
        // Each row is labelled in place: the row is appended as zeros to `labels` (which holds
        // the rows above on entry to the row), then written.
        labels.clear();
        let mut drow = std::mem::take(&mut self.disparity_row);
        drow.resize(w, 0.0);
        self.prepare_final(w, wq);
        for y in 0..h {
            let j = y / CELL;
            if y.is_multiple_of(CELL) {
                self.prepare_cell_row(j, wq);
            }
            let row_d = d.row(y, w, &mut drow[..w]);
            labels.resize((y + 1) * w, 0);
            let row_l = &mut labels[y * w..(y + 1) * w];
            self.assign_incumbents(row_d, row_l, y, w, tau);
            self.mark_tail_columns(j, wq, w);
            let count = self.collect_search_chunks(w);
            self.search_row(row_d, row_l, y, w, wq, count, tau);
        }
        self.disparity_row = drow;
    }

    /// Fresh accumulators, the planes in full-resolution coordinates and the per-chunk
    /// candidate caches.
    fn prepare_final(&mut self, w: usize, wq: usize) {
        self.final_sums.clear();
        self.final_sums.resize(
            self.planes.len(),
            FinalAcc {
                y0: usize::MAX,
                ..FinalAcc::default()
            },
        );
        self.ambiguous.clear();
        self.full_res_fits.clear();
        self.full_res_fits
            .extend(self.planes.iter().map(|p| cell_to_full(&p.f)));
        self.slope_x.clear();
        self.slope_x
            .extend(self.full_res_fits.iter().map(|f| f.a as f32));
        let nchunks = w.div_ceil(LANES);
        self.candidates_cell_row.clear();
        self.candidates_cell_row.resize(nchunks, 0);
        self.candidate_planes.resize(nchunks, [0; 16]);
        self.candidate_count.resize(nchunks, 0);
        self.cells_touching_plane.clear();
        self.cells_touching_plane.resize(wq, 0);
        self.border_cells.clear();
        self.border_cells.resize(wq, 0);
        self.zero_cell_row.clear();
        self.zero_cell_row.resize(wq, 0);
    }

    /// Once per cell row: which unlabelled cells touch a labelled one (their pixels are
    /// searched), as keep bytes per pixel, and the runs of equal cell labels.
    fn prepare_cell_row(&mut self, j: usize, wq: usize) {
        let cl: &[u16] = &self.cell_labels;
        let hint_row = cell_row(cl, j, wq);
        let up_row = if j > 0 { cell_row(cl, j - 1, wq) } else { &[] };
        let dn_row = cell_row(cl, j + 1, wq);
        let zrow = &self.zero_cell_row[..];
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
        row_d: &[f32],
        row_l: &mut [u16],
        y: usize,
        w: usize,
        tau: f32,
    ) {
        let yf = y as f64;
        let (stats, metric) = (is_sample_row(y), is_metric_row(y));
        let full: &[DisparityAffine] = &self.full_res_fits;
        let acc = &mut self.final_sums;
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
    fn mark_tail_columns(&mut self, j: usize, wq: usize, w: usize) {
        let cl: &[u16] = &self.cell_labels;
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
        for (c, kc) in (&mut kw).enumerate() {
            let word = u64::from_le_bytes(<[u8; LANES]>::try_from(kc).unwrap_or([1; LANES]));
            if word != ALL_KEPT {
                self.search_chunks[count] = (c as u32, word);
                count += 1;
            }
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
    /// `ambiguous`; see [`Self::final_pass`]).
    #[allow(clippy::too_many_arguments)]
    fn search_row(
        &mut self,
        row_d: &[f32],
        row_l: &mut [u16],
        y: usize,
        w: usize,
        wq: usize,
        count: usize,
        tau: f32,
    ) {
        let yf = y as f64;
        let (stats, metric) = (is_sample_row(y), is_metric_row(y));
        let j = y / CELL;
        self.row_offsets.clear();
        self.row_offsets
            .extend(self.full_res_fits.iter().map(|f| (f.b * yf + f.c) as f32));
        // With at most 64 planes, labels are at most 64 (bit masks of the candidates).
        let small = self.planes.len() <= 64;
        let cl: &[u16] = &self.cell_labels;
        let up_row = if j > 0 { cell_row(cl, j - 1, wq) } else { &[] };
        let hint_row = cell_row(cl, j, wq);
        let dn_row = cell_row(cl, j + 1, wq);
        let full: &[DisparityAffine] = &self.full_res_fits;
        let (fa, rowc): (&[f32], &[f32]) = (&self.slope_x, &self.row_offsets);
        let acc = &mut self.final_sums;
        let amb = &mut self.ambiguous;
        let bound = self.noise.pixel_bound_px() as f32;
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
                    amb.push(((y * w + x) as u32, lab, other));
                }
            }
        }
    }

    /// Pixels that two planes explain (both within the noise, or both within `τ` when the
    /// noise explains neither) take the label that dominates their 8-neighbourhood (ties keep
    /// the smaller residual); the statistics follow.
    #[inline(never)]
    pub(super) fn resolve_ambiguous(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        labels: &mut [u16],
    ) {
        for &(i, k1, k2) in &self.ambiguous {
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            let (c1, c2) = neighbour_votes(labels, w, h, x, y, k1, k2);
            let (u1, u2) = (k1 as usize - 1, k2 as usize - 1);
            if c2 > c1
                && labels[i] == k1
                && u1 < self.final_sums.len()
                && u2 < self.final_sums.len()
            {
                labels[i] = k2;
                self.final_sums[u1].pixels -= 1;
                self.final_sums[u2].pixels += 1;
                self.final_sums[u2].add_rows(y);
                if is_sample_row(y) {
                    let (xf, yf, df) = (x as f64, y as f64, f64::from(d.at(i)));
                    let (f1, f2) = (self.full_res_fits[u1], self.full_res_fits[u2]);
                    let a1 = &mut self.final_sums[u1];
                    a1.sums.remove(xf, yf, df);
                    if is_metric_row(y) {
                        a1.inv.add(xf, yf, df, df - f1.eval(xf, yf), -1.0);
                    }
                    let a2 = &mut self.final_sums[u2];
                    a2.sums.add(xf, yf, df);
                    if is_metric_row(y) {
                        a2.inv.add(xf, yf, df, df - f2.eval(xf, yf), 1.0);
                    }
                }
            }
        }
    }

    /// Drops 4-connected pieces of a plane's cells smaller than `min_piece_pixels / 16` cells.
    #[inline(never)]
    pub(super) fn drop_small_pieces(&mut self, wq: usize, hq: usize) {
        self.components.label(&self.cell_labels, wq, hq);
        let min = self.cfg.min_piece_pixels.div_ceil(CELL * CELL);
        for (ri, run) in self.components.runs.iter().enumerate() {
            if self.components.sizes[self.components.component[ri] as usize] >= min {
                continue;
            }
            let y = run.y as usize;
            self.cell_labels[y * wq + run.x0 as usize..y * wq + run.x1 as usize].fill(0);
        }
    }

    /// Final refit, 3D conversion, statistics, and compaction of the ids by decreasing size.
    #[inline(never)]
    pub(super) fn finish(
        &mut self,
        w: usize,
        h: usize,
        k: &Intrinsics,
        fb: f64,
        mut labels: Vec<u16>,
    ) -> Result<PlaneSegmentation> {
        let mut out: Vec<(usize, PlaneInfo)> = Vec::new();
        for (pi, a) in self.final_sums.iter().enumerate() {
            let n = a.sums.n;
            if a.pixels < self.cfg.min_pixels || n < 3.0 {
                continue;
            }
            let Some(f) = a.sums.solve() else { continue };
            let Ok(plane) = f.to_plane(k, fb) else {
                continue;
            };
            let s = &a.inv;
            let (centroid_m, rms_m) = if s.n >= 1.0 {
                (
                    Point3::new(
                        fb * (s.sxi - k.cx * s.si) / (k.fx * s.n),
                        fb * (s.syi - k.cy * s.si) / (k.fy * s.n),
                        fb * s.si / s.n,
                    ),
                    plane.offset_m * (s.sr2.max(0.0) / s.n).sqrt(),
                )
            } else {
                // No metric sample (a tiny plane): the point at the mean pixel.
                let (mx, my) = (a.sums.sx / n, a.sums.sy / n);
                let z = fb / f.eval(mx, my);
                (
                    Point3::new((mx - k.cx) * z / k.fx, (my - k.cy) * z / k.fy, z),
                    plane.offset_m * a.sums.rms(&f) / (fb / z),
                )
            };
            out.push((
                pi,
                PlaneInfo {
                    id: 0,
                    plane,
                    affine: f,
                    pixels: a.pixels,
                    rms_px: a.sums.rms(&f),
                    rms_m,
                    centroid_m,
                },
            ));
        }
        out.sort_by_key(|o| std::cmp::Reverse(o.1.pixels));
        self.relabel_lut.clear();
        self.relabel_lut.resize(self.final_sums.len() + 1, 0);
        for (new, (old, info)) in out.iter_mut().enumerate() {
            info.id = new as u16 + 1;
            self.relabel_lut[*old + 1] = info.id;
        }
        // Relabel only the rows of the planes whose id changes.
        let (mut y0, mut y1) = (usize::MAX, 0);
        for (i, a) in self.final_sums.iter().enumerate() {
            if self.relabel_lut[i + 1] as usize != i + 1 && a.pixels > 0 {
                y0 = y0.min(a.y0);
                y1 = y1.max(a.y1);
            }
        }
        if y0 < y1 && w > 0 {
            relabel(&mut labels[y0 * w..(y1 * w).min(w * h)], &self.relabel_lut);
        }
        self.final_sums.clear();
        Ok(PlaneSegmentation {
            labels: Image::from_vec(w, h, labels)?,
            planes: out.into_iter().map(|(_, p)| p).collect(),
        })
    }
}

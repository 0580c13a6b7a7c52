//! Refinement on 4×4 cells: k-means style reassignment of cells to the candidate planes of
//! their neighbourhood and refits.

use rayon::prelude::*;

use super::*;

/// Cell rows per band of a coarse pass. A constant (not derived from the number of threads), so
/// that the labels and the sums do not depend on the number of threads. 15 bands for a
/// 640×480 frame.
pub(super) const COARSE_BAND_ROWS: usize = 8;

/// The scratch and the output of one band of cell rows of a coarse pass (kept by the
/// extractor, reused frame after frame).
#[derive(Debug, Clone, Default)]
pub(super) struct CoarseBand {
    /// Per plane: the moments of the band's cells it took.
    sums: Vec<AffineSums>,
    /// Per plane: the box of those cells.
    boxes: Vec<[u32; 4]>,
    /// Labels that changed, and planar cells left unassigned.
    changed: usize,
    free: usize,
    /// Keep bytes of the row being assigned: 1 = done, 0 = search.
    keep: Vec<u8>,
    /// Per cell of the row: 1 at a border between planes.
    border: Vec<u8>,
    /// Per plane: the disparity of the current row at x = 0 as `f32`.
    row_offsets: Vec<f32>,
    /// Copy of the current row's labels taken before its searches.
    before_search: Vec<u16>,
    /// The label rows just above and below the band as the pass found them (empty at the
    /// frame's edges).
    above: Vec<u16>,
    below: Vec<u16>,
}

/// One band of a coarse pass: its index, its rows of cell labels and free-cell marks, and its
/// scratch.
type CoarseBandTask<'a> = (usize, ((&'a mut [u16], &'a mut [u8]), &'a mut CoarseBand));

/// What every band of a coarse pass reads.
#[derive(Clone, Copy)]
struct CoarseShared<'a> {
    planes: &'a [Cand],
    slope_x: &'a [f32],
    cell_disparity: &'a [f32],
    cell_planar: &'a [u8],
    /// The cell noise bound, `CellNoise::cell_bound_px`.
    bound: f32,
    tau: f32,
    wq: usize,
    /// At most 64 planes: the candidates are gathered as bits.
    small: bool,
}

impl PlaneExtractor {
    /// One assignment pass on the cells; refills the planes' sums and boxes. Returns the number
    /// of labels that changed and the number of planar but unassigned cells (marked in `free`).
    ///
    /// Runs of equal incumbent labels are tested against their plane in one vectorised sweep
    /// (the cells that pass are accumulated there); the cells that fail, unlabelled cells and
    /// the cells at a border between planes (a cell of another plane among their 8 neighbours)
    /// then take the best of the planes of the cells around them, searched 8 cells at a time:
    /// the smallest residual within `τ` (the cell noise is the same under every plane, so this
    /// is the smallest residual in units of the noise). A border cell that no plane explains
    /// within the noise (`CellNoise::cell_bound_px`, 99.9 %) keeps its plane while within `τ`,
    /// as away from borders. Without the border rule a cell keeps whichever plane reached it
    /// first while that plane is within `τ`: far away, where a crease bends the disparity by
    /// less than `τ` over many cells, borders stayed where the 16-pixel seed patches put them,
    /// and a "plane" seeded on patches straddling a crease kept its strip of both surfaces.
    ///
    /// The rows are visited in bands of [`COARSE_BAND_ROWS`] cell rows, on the caller's pool
    /// when it has more than one thread: within a band a row sees the labels this pass gave
    /// the row above it; the first row of a band sees the row above as the pass found it. The
    /// bands' sums are added in band order, so the result is the same on any number of
    /// threads.
    #[inline(never)]
    pub(super) fn coarse_pass(&mut self, wq: usize, hq: usize, tau: f32) -> (usize, usize) {
        self.slope_x.clear();
        self.slope_x
            .extend(self.planes.iter().map(|p| p.f.a as f32));
        let n = wq * hq;
        let nbands = hq.div_ceil(COARSE_BAND_ROWS);
        if self.coarse_bands.len() < nbands {
            self.coarse_bands.resize_with(nbands, CoarseBand::default);
        }
        // The rows around each band, before any band changes them.
        let labels = &self.cell_labels[..n];
        for (b, band) in self.coarse_bands[..nbands].iter_mut().enumerate() {
            let (j0, j1) = (b * COARSE_BAND_ROWS, ((b + 1) * COARSE_BAND_ROWS).min(hq));
            band.above.clear();
            if j0 > 0 {
                band.above
                    .extend_from_slice(&labels[(j0 - 1) * wq..j0 * wq]);
            }
            band.below.clear();
            if j1 < hq {
                band.below
                    .extend_from_slice(&labels[j1 * wq..(j1 + 1) * wq]);
            }
        }
        let shared = CoarseShared {
            planes: &self.planes,
            slope_x: &self.slope_x,
            cell_disparity: &self.cell_disparity[..n],
            cell_planar: &self.cell_planar[..n],
            bound: self.noise.cell_bound_px() as f32,
            tau,
            wq,
            small: self.planes.len() <= 64,
        };
        let rows = COARSE_BAND_ROWS * wq;
        let run = |(b, ((lab, free), band)): CoarseBandTask<'_>| {
            band.run(&shared, b * COARSE_BAND_ROWS, lab, free);
        };
        let bands = &mut self.coarse_bands[..nbands];
        let (cell_labels, free_cells) = (&mut self.cell_labels[..n], &mut self.free_cells[..n]);
        if rayon::current_num_threads() > 1 {
            cell_labels
                .par_chunks_mut(rows)
                .zip(free_cells.par_chunks_mut(rows))
                .zip(bands.par_iter_mut())
                .enumerate()
                // One band per task: the work is where the planes' borders are, and halves
                // of the frame are far from equal (without it, no gain on two threads).
                .with_max_len(1)
                .for_each(run);
        } else {
            cell_labels
                .chunks_mut(rows)
                .zip(free_cells.chunks_mut(rows))
                .zip(bands.iter_mut())
                .enumerate()
                .for_each(run);
        }
        // The bands' sums and boxes, in band order.
        let (mut changed, mut free) = (0usize, 0usize);
        for (k, p) in self.planes.iter_mut().enumerate() {
            p.sums = AffineSums::default();
            p.bbox = EMPTY_BOX;
            for band in &self.coarse_bands[..nbands] {
                p.sums.merge(&band.sums[k]);
                p.bbox = union_box(&p.bbox, &band.boxes[k]);
            }
        }
        for band in &self.coarse_bands[..nbands] {
            changed += band.changed;
            free += band.free;
        }
        (changed, free)
    }
}

impl CoarseBand {
    /// Assigns cell rows `j0..j0 + labels.len() / wq` (`labels` and `free` are those rows).
    fn run(&mut self, sh: &CoarseShared<'_>, j0: usize, labels: &mut [u16], free: &mut [u8]) {
        let wq = sh.wq;
        let np = sh.planes.len();
        self.sums.clear();
        self.sums.resize(np, AffineSums::default());
        self.boxes.clear();
        self.boxes.resize(np, EMPTY_BOX);
        (self.changed, self.free) = (0, 0);
        self.keep.resize(wq + LANES, 0);
        self.border.resize(wq, 0);
        let nrows = labels.len() / wq;
        let (band_above, band_below) = (
            std::mem::take(&mut self.above),
            std::mem::take(&mut self.below),
        );
        for r in 0..nrows {
            let j = j0 + r;
            let (above, rest) = labels.split_at_mut(r * wq);
            let (lrow, below) = rest.split_at_mut(wq);
            let up: &[u16] = if r > 0 {
                &above[(r - 1) * wq..]
            } else {
                &band_above
            };
            let dn: &[u16] = if r + 1 < nrows {
                &below[..wq]
            } else {
                &band_below
            };
            let frow = &mut free[r * wq..(r + 1) * wq];
            self.row(sh, j, lrow, up, dn, frow);
        }
        (self.above, self.below) = (band_above, band_below);
    }

    /// Assigns cell row `j` (`lrow`), with the rows `up` and `dn` around it (empty at the
    /// frame's edges).
    #[allow(clippy::too_many_arguments)]
    fn row(
        &mut self,
        sh: &CoarseShared<'_>,
        j: usize,
        lrow: &mut [u16],
        up: &[u16],
        dn: &[u16],
        frow: &mut [u8],
    ) {
        let (wq, tau, bound, small) = (sh.wq, sh.tau, sh.bound, sh.small);
        let planes = sh.planes;
        let mut inv = InvSums::default();
        // With at most 64 planes, the planes around a chunk are the bits of the labels of the
        // three rows around it (above: this pass's labels; this row: a copy from before its
        // searches; below: not yet searched).
        if small {
            self.before_search.clear();
            self.before_search.extend_from_slice(lrow);
        }
        let jf = j as f64;
        self.row_offsets.clear();
        self.row_offsets
            .extend(planes.iter().map(|p| (p.f.b * jf + p.f.c) as f32));
        let rowc: &[f32] = &self.row_offsets;
        let fa: &[f32] = sh.slope_x;
        let row = &sh.cell_disparity[j * wq..(j + 1) * wq];
        let mrow = &sh.cell_planar[j * wq..(j + 1) * wq];
        let keep = &mut self.keep[..];
        let mut near = [0u16; 16];
        // Cells at a border between planes choose among the planes around them.
        let border = &mut self.border[..wq];
        plane_borders(lrow, up, dn, border);
        // Incumbents.
        let mut i = 0;
        while i < wq {
            let (v, b) = (lrow[i], border[i]);
            // A run of equal labels and equal border flags.
            let e = i + border[i..run_end(lrow, i)]
                .iter()
                .take_while(|&&x| x == b)
                .count();
            let k = (v as usize).wrapping_sub(1);
            match planes.get(k) {
                Some(_) if b != 0 => keep[i..e].fill(0),
                Some(p) => {
                    let kept = fit_run::<true, false>(
                        &row[i..],
                        &mut keep[i..],
                        e - i,
                        i,
                        jf,
                        p.f.a,
                        p.f.b * jf + p.f.c,
                        tau,
                        &mut self.sums[k],
                        &mut inv,
                    );
                    if kept > 0 {
                        let ks = &keep[i..e];
                        let first = ks.iter().position(|&k| k != 0).unwrap_or(0);
                        let last = ks.iter().rposition(|&k| k != 0).unwrap_or(0);
                        grow(&mut self.boxes[k], i + first, i + last, j);
                    }
                }
                None => keep[i..e].fill(0),
            }
            i = e;
        }
        // The others, one tile (8 blocks) at a time.
        frow.fill(0);
        let mut i0 = 0;
        while i0 < wq {
            let i1 = (i0 + CHUNK).min(wq);
            let (dt, kt) = (&row[i0..i1], &keep[i0..i1]);
            let kk = <[u8; LANES]>::try_from(kt).unwrap_or_else(|_| pad(kt, 1));
            // Lanes to search: keep byte 0.
            let searched = byte_mask(!u64::from_le_bytes(kk) & ALL_KEPT);
            if searched == 0 {
                i0 = i1;
                continue;
            }
            let d8 = <[f32; LANES]>::try_from(dt).unwrap_or_else(|_| pad(dt, f32::NAN));
            let (labs, found, res) = if searched & valid_mask(&d8) != 0 {
                // Candidates: the planes of the cells around the chunk (spatial coherence;
                // coplanar disconnected regions join by merging).
                let (a, b) = (i0.saturating_sub(1), (i1 + 1).min(wq));
                // This row: the labels from before its searches when the bits are used, the
                // live ones otherwise.
                let this_row: &[u16] = if small { &self.before_search } else { lrow };
                let nc = candidate_planes_around([up, this_row, dn], a, b, small, &mut near);
                let two = search8_two(&d8, i0 as f32, &near[..nc], fa, rowc, tau);
                (two.best, nonzero_mask(&two.best), two.best_res)
            } else {
                ([0u16; LANES], 0, [0.0; LANES])
            };
            let (lt, mt) = (&mut lrow[i0..i1], &mrow[i0..i1]);
            let mut todo = searched & (found | nonzero_mask(lt) | byte_mask(pad_word(mt)));
            // Searched lanes outside `todo` stay unlabelled (invalid or no plane fits) and
            // were unlabelled, unmasked: nothing changes.
            while todo != 0 {
                let o = todo.trailing_zeros() as usize;
                todo &= todo - 1;
                let (mut lab, old) = (labs[o], lt[o]);
                if lab != 0
                    && res[o] > bound
                    && old != 0
                    && old != lab
                    && let Some(p) = planes.get((old as usize).wrapping_sub(1))
                    && (f64::from(dt[o]) - p.f.eval((i0 + o) as f64, jf)).abs() < f64::from(tau)
                {
                    // No plane explains the cell within the noise: a border cell keeps its
                    // plane while within τ, as away from borders.
                    lab = old;
                }
                self.changed += usize::from(lab != old);
                lt[o] = lab;
                let fr = lab == 0 && mt[o] == 1;
                frow[i0 + o] = u8::from(fr);
                self.free += usize::from(fr);
                let k = (lab as usize).wrapping_sub(1);
                if let (Some(s), Some(bb)) = (self.sums.get_mut(k), self.boxes.get_mut(k)) {
                    let ii = i0 + o;
                    s.add(ii as f64, jf, f64::from(dt[o]));
                    grow(bb, ii, ii, j);
                }
            }
            i0 = i1;
        }
    }
}

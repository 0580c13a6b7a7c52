//! Refinement on 4×4 cells: k-means style reassignment of cells to the candidate planes of
//! their neighbourhood and refits.

use super::*;

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
    #[inline(never)]
    pub(super) fn coarse_pass(&mut self, wq: usize, hq: usize, tau: f32) -> (usize, usize) {
        for p in self.planes.iter_mut() {
            p.sums = AffineSums::default();
            p.bbox = EMPTY_BOX;
        }
        self.slope_x.clear();
        self.slope_x
            .extend(self.planes.iter().map(|p| p.f.a as f32));
        // With at most 64 planes, the planes around a chunk are the bits of the labels of the
        // three rows around it (above: this pass's labels; this row: a copy from before its
        // searches; below: not yet searched).
        let small = self.planes.len() <= 64;
        let planes = &mut self.planes;
        let mut inv = InvSums::default();
        let (mut changed, mut free) = (0usize, 0usize);
        let bound = self.noise.cell_bound_px() as f32;
        self.border_cells.resize(wq, 0);
        for j in 0..hq {
            if small {
                self.cell_labels_before_search.clear();
                self.cell_labels_before_search
                    .extend_from_slice(&self.cell_labels[j * wq..(j + 1) * wq]);
            }
            let jf = j as f64;
            self.row_offsets.clear();
            self.row_offsets
                .extend(planes.iter().map(|p| (p.f.b * jf + p.f.c) as f32));
            let rowc: &[f32] = &self.row_offsets;
            let fa: &[f32] = &self.slope_x;
            let row = &self.cell_disparity[j * wq..(j + 1) * wq];
            let mrow = &self.cell_planar[j * wq..(j + 1) * wq];
            let (above, rest) = self.cell_labels.split_at_mut(j * wq);
            let (lrow, below) = rest.split_at_mut(wq);
            let up: &[u16] = if j > 0 { &above[(j - 1) * wq..] } else { &[] };
            let dn: &[u16] = below.get(..wq).unwrap_or(&[]);
            let frow = &mut self.free_cells[j * wq..(j + 1) * wq];
            let keep = &mut self.keep_row[..];
            let mut near = [0u16; 16];
            // Cells at a border between planes choose among the planes around them.
            let border = &mut self.border_cells[..wq];
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
                match planes.get_mut((v as usize).wrapping_sub(1)) {
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
                            &mut p.sums,
                            &mut inv,
                        );
                        if kept > 0 {
                            let ks = &keep[i..e];
                            let first = ks.iter().position(|&k| k != 0).unwrap_or(0);
                            let last = ks.iter().rposition(|&k| k != 0).unwrap_or(0);
                            grow(&mut p.bbox, i + first, i + last, j);
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
                    // Candidates: the planes of the cells around the chunk (spatial
                    // coherence; coplanar disconnected regions join by merging).
                    let (a, b) = (i0.saturating_sub(1), (i1 + 1).min(wq));
                    // This row: the labels from before its searches when the bits are
                    // used, the live ones otherwise.
                    let this_row: &[u16] = if small {
                        &self.cell_labels_before_search
                    } else {
                        lrow
                    };
                    let nc = candidate_planes_around([up, this_row, dn], a, b, small, &mut near);
                    let two = search8_two(&d8, i0 as f32, &near[..nc], fa, rowc, tau);
                    (two.best, nonzero_mask(&two.best), two.best_res)
                } else {
                    ([0u16; LANES], 0, [0.0; LANES])
                };
                let (lt, mt) = (&mut lrow[i0..i1], &mrow[i0..i1]);
                let mut todo = searched & (found | nonzero_mask(lt) | byte_mask(pad_word(mt)));
                // Searched lanes outside `todo` stay unlabelled (invalid or no plane fits)
                // and were unlabelled, unmasked: nothing changes.
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
                    changed += usize::from(lab != old);
                    lt[o] = lab;
                    let fr = lab == 0 && mt[o] == 1;
                    frow[i0 + o] = u8::from(fr);
                    free += usize::from(fr);
                    if let Some(p) = planes.get_mut((lab as usize).wrapping_sub(1)) {
                        let ii = i0 + o;
                        p.sums.add(ii as f64, jf, f64::from(dt[o]));
                        grow(&mut p.bbox, ii, ii, j);
                    }
                }
                i0 = i1;
            }
        }
        (changed, free)
    }
}

//! Seeds: connected components of the planar cells of the LoG mask, each with a robust
//! affine fit in disparity.

use super::*;

impl PlaneExtractor {
    /// Creates planes from the components in `self.components` (on the cell grid of width `wg`) with at
    /// least `min` cells: least squares, then refitted on the inliers within 2τ.
    #[inline(never)]
    pub(super) fn seed_from_components(&mut self, wg: usize, min: usize) {
        let nc = self.components.sizes.len();
        self.component_sums.clear();
        self.component_sums.resize(nc, AffineSums::default());
        self.component_box.clear();
        self.component_box.resize(nc, [u32::MAX, u32::MAX, 0, 0]);
        self.component_fit.clear();
        self.component_fit.resize(nc, None);
        let lim = 2.0 * self.cfg.threshold_px as f32;
        let mut inv = InvSums::default();
        for pass in 0..2 {
            if pass > 0 {
                self.component_sums.fill(AffineSums::default());
            }
            for (ri, run) in self.components.runs.iter().enumerate() {
                let c = self.components.component[ri] as usize;
                if self.components.sizes[c] < min {
                    continue;
                }
                let j = run.y as usize;
                let (x0, x1) = (run.x0 as usize, run.x1 as usize);
                // The rest of the row: `fit_run` reads and writes ahead.
                let seg = &self.cell_disparity[j * wg + x0..(j + 1) * wg];
                let keep = &mut self.keep_row[x0..];
                let n = x1 - x0;
                let jf = j as f64;
                let sums = &mut self.component_sums[c];
                if pass == 0 {
                    grow(&mut self.component_box[c], x0, x1 - 1, j);
                    // Plain least squares; residuals against the run's first value.
                    let d0 = f64::from(seg[0]);
                    fit_run::<true, false>(
                        seg,
                        keep,
                        n,
                        x0,
                        jf,
                        0.0,
                        d0,
                        f32::INFINITY,
                        sums,
                        &mut inv,
                    );
                } else if let Some(f) = self.component_fit[c] {
                    // Trimmed refit on the inliers within 2τ.
                    fit_run::<true, false>(
                        seg,
                        keep,
                        n,
                        x0,
                        jf,
                        f.a,
                        f.b * jf + f.c,
                        lim,
                        sums,
                        &mut inv,
                    );
                }
            }
            for c in 0..nc {
                if self.components.sizes[c] >= min && (pass == 0 || self.component_fit[c].is_some())
                {
                    let s = &self.component_sums[c];
                    self.component_fit[c] = if s.n >= (min as f64) * 0.5 {
                        s.solve()
                    } else {
                        None
                    };
                }
            }
        }
        // Each seed's blocks start with its label (the incumbent in the k-means passes).
        let mut plane_of: Vec<u16> = vec![0; nc];
        for (c, slot) in plane_of.iter_mut().enumerate() {
            if let Some(f) = self.component_fit[c]
                && self.planes.len() < MAX_PLANES
            {
                *slot = self.planes.len() as u16 + 1;
                self.planes.push(Cand {
                    f,
                    sums: self.component_sums[c],
                    bbox: self.component_box[c],
                    alive: true,
                    into: NONE,
                });
            }
        }
        for (ri, run) in self.components.runs.iter().enumerate() {
            let lab = plane_of[self.components.component[ri] as usize];
            if lab != 0 {
                let y = run.y as usize;
                self.cell_labels[y * wg + run.x0 as usize..y * wg + run.x1 as usize].fill(lab);
            }
        }
    }

    /// Seeds the regions the patches could not: 4-connected components of the planar cells
    /// left unlabelled (strips narrower than a patch, the rims of surfaces) with at least
    /// `min` cells, each with its robust fit.
    #[inline(never)]
    pub(super) fn seed_leftover_components(&mut self, wq: usize, hq: usize, min: usize) {
        for ((f, &p), &l) in self
            .free_cells
            .iter_mut()
            .zip(&self.cell_planar)
            .zip(&self.cell_labels)
        {
            *f = u8::from(p != 0 && l == 0);
        }
        self.components.label(&self.free_cells, wq, hq);
        let before = self.planes.len();
        self.seed_from_components(wq, min);
        // A component is a plane only when one affine function explains it within the noise
        // (the patches' test): rings of several surfaces at one disparity are not.
        let noise = self.noise;
        for p in &mut self.planes[before..] {
            if !noise.planar(p.sums.rss(&p.f), p.sums.n) {
                p.alive = false;
            }
        }
    }

    /// The planarity of the cells (all four of their half-resolution blocks planar), and fresh
    /// label and free-cell grids.
    #[inline(never)]
    pub(super) fn planar_cells(&mut self, w2: usize, wq: usize, hq: usize) {
        self.cell_labels.clear();
        self.cell_labels.resize(wq * hq, 0);
        self.cell_planar.resize(wq * hq, 0);
        self.free_cells.clear();
        self.free_cells.resize(wq * hq, 0);
        for (j, mq) in self.cell_planar.chunks_exact_mut(wq).take(hq).enumerate() {
            let m0 = &self.log_mask[2 * j * w2..(2 * j + 1) * w2];
            let m1 = &self.log_mask[(2 * j + 1) * w2..(2 * j + 2) * w2];
            for ((o, p), q) in mq
                .iter_mut()
                .zip(m0.chunks_exact(2))
                .zip(m1.chunks_exact(2))
            {
                *o = p[0] & p[1] & q[0] & q[1];
            }
        }
    }
}

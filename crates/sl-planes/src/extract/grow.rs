//! Growth of the planes over the cells the noise says they explain ([`PlaneExtractor::grow`]).

use super::*;

impl PlaneExtractor {
    /// Growth of every plane, round by round, into the unlabelled valid cells 4-connected to
    /// it whose mean disparity its fit explains within the cell noise
    /// (`CellNoise::cell_bound_px`, the 99.9 % bound of the seeds' tests), with the fits held
    /// fixed. In each round a candidate cell takes, among the planes of its labelled
    /// neighbours (labels as they were before the round), the one with the smallest residual,
    /// so the result does not depend on the order of the cells.
    ///
    /// The coarse passes reach one cell further per pass, so a surface seen as a thin strip
    /// (a wedge along the image border, a face between occlusion bands) whose noisy LoG cells
    /// fail kept only the few cells next to its seed: in the room benchmark, box faces covered
    /// at 65 % and counted as neither correct nor missed. Growth needs no parameter: a cell
    /// joins only when the noise explains it under the plane's fixed fit, so a plane cannot
    /// drift onto a neighbouring surface beyond the band where the two surfaces' disparities
    /// agree within the noise.
    #[inline(never)]
    pub(super) fn grow(&mut self, wq: usize, hq: usize) {
        let bound = self.noise.cell_bound_px();
        let n = wq * hq;
        let labels = &mut self.cell_labels[..n];
        let cells = &self.cell_disparity[..n];
        let planes = &self.planes;
        let queued = &mut self.grow_queued;
        queued.clear();
        queued.resize(n, 0);
        let candidates = &mut self.grow_candidates;
        let taken = &mut self.grow_taken;
        candidates.clear();
        // Neighbours of cell `c` (4-connected, within the grid).
        let neighbours = |c: usize| {
            let (i, j) = (c % wq, c / wq);
            [
                (i > 0).then(|| c - 1),
                (i + 1 < wq).then(|| c + 1),
                (j > 0).then(|| c - wq),
                (j + 1 < hq).then(|| c + wq),
            ]
        };
        // The first candidates: unlabelled valid cells next to a labelled one.
        for c in 0..n {
            if labels[c] == 0
                && !cells[c].is_nan()
                && neighbours(c).into_iter().flatten().any(|m| labels[m] != 0)
            {
                queued[c] = 1;
                candidates.push(c as u32);
            }
        }
        while !candidates.is_empty() {
            // Each candidate against the planes of its labelled neighbours.
            taken.clear();
            for &c in candidates.iter() {
                let c = c as usize;
                queued[c] = 0;
                let (x, y, d) = ((c % wq) as f64, (c / wq) as f64, f64::from(cells[c]));
                let mut best = (bound, 0u16);
                for m in neighbours(c).into_iter().flatten() {
                    let l = labels[m];
                    if l == 0 || l == best.1 {
                        continue;
                    }
                    if let Some(p) = planes.get(l as usize - 1) {
                        let r = (d - p.f.eval(x, y)).abs();
                        if r <= best.0 {
                            best = (r, l);
                        }
                    }
                }
                if best.1 != 0 {
                    taken.push((c as u32, best.1));
                }
            }
            // Label them, and queue their unlabelled valid neighbours.
            for &(c, l) in taken.iter() {
                labels[c as usize] = l;
            }
            candidates.clear();
            for &(c, _) in taken.iter() {
                for m in neighbours(c as usize).into_iter().flatten() {
                    if labels[m] == 0 && queued[m] == 0 && !cells[m].is_nan() {
                        queued[m] = 1;
                        candidates.push(m as u32);
                    }
                }
            }
        }
    }
}

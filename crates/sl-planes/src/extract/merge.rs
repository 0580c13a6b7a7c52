//! Merging seeds whose affine disparities agree, compacting the plane list and ordering it by
//! size.

use super::*;

impl PlaneExtractor {
    /// Merges planes that one affine function explains jointly: the least-squares plane of the
    /// union fits each of the two with an RMS below `merge_px`.
    #[inline(never)]
    pub(super) fn merge(&mut self) {
        let mp = self.cfg.merge_px;
        let pre = 4.0 * self.cfg.threshold_px;
        for _round in 0..8 {
            let mut merged = false;
            let n = self.planes.len();
            for i in 0..n {
                if !self.planes[i].alive {
                    continue;
                }
                for j in (i + 1)..n {
                    if !self.planes[j].alive {
                        continue;
                    }
                    let (pi, pj) = (&self.planes[i], &self.planes[j]);
                    let bb = union_box(&pi.bbox, &pj.bbox);
                    let df = DisparityAffine {
                        a: pi.f.a - pj.f.a,
                        b: pi.f.b - pj.f.b,
                        c: pi.f.c - pj.f.c,
                    };
                    let worst = [
                        (bb[0], bb[1]),
                        (bb[2], bb[1]),
                        (bb[0], bb[3]),
                        (bb[2], bb[3]),
                    ]
                    .iter()
                    .map(|&(x, y)| df.eval(f64::from(x), f64::from(y)).abs())
                    .fold(0.0, f64::max);
                    if worst > pre {
                        continue;
                    }
                    let mut u = pi.sums;
                    u.merge(&pj.sums);
                    let Some(f) = u.solve() else { continue };
                    if pi.sums.rms(&f) < mp && pj.sums.rms(&f) < mp {
                        let pi = &mut self.planes[i];
                        pi.sums = u;
                        pi.f = f;
                        pi.bbox = bb;
                        self.planes[j].alive = false;
                        self.planes[j].into = i as u32;
                        merged = true;
                    }
                }
            }
            if !merged {
                break;
            }
        }
    }

    /// Removes dead planes and renumbers the cell labels (merged planes' cells go
    /// to the plane they merged into).
    #[inline(never)]
    pub(super) fn compact(&mut self) {
        let n = self.planes.len();
        self.relabel_lut.clear();
        self.relabel_lut.resize(n + 1, 0);
        let mut next = 0u16;
        let newidx = &mut self.plane_order;
        newidx.clear();
        newidx.resize(n, 0);
        for (i, p) in self.planes.iter().enumerate() {
            if p.alive {
                next += 1;
                newidx[i] = u32::from(next);
            }
        }
        for i in 0..n {
            let mut r = i;
            let mut guard = 0;
            while !self.planes[r].alive && self.planes[r].into != NONE && guard < n {
                r = self.planes[r].into as usize;
                guard += 1;
            }
            self.relabel_lut[i + 1] = if self.planes[r].alive {
                newidx[r] as u16
            } else {
                0
            };
        }
        if self
            .relabel_lut
            .iter()
            .enumerate()
            .any(|(i, &v)| v as usize != i)
        {
            relabel(&mut self.cell_labels, &self.relabel_lut);
        }
        self.planes.retain(|p| p.alive);
        for p in self.planes.iter_mut() {
            p.into = NONE;
        }
    }

    /// Renumbers the planes by decreasing support (cells of the last pass), so that the
    /// final ids (by decreasing pixel count) usually need no relabelling of the full image.
    #[inline(never)]
    pub(super) fn order_by_size(&mut self) {
        let n = self.planes.len();
        let order = &mut self.plane_order;
        order.clear();
        order.extend(0..n as u32);
        order.sort_by(|&a, &b| {
            self.planes[b as usize]
                .sums
                .n
                .total_cmp(&self.planes[a as usize].sums.n)
        });
        if order.iter().enumerate().all(|(i, &o)| o as usize == i) {
            return;
        }
        self.relabel_lut.clear();
        self.relabel_lut.resize(n + 1, 0);
        self.planes_spare.clear();
        for (new, &old) in order.iter().enumerate() {
            self.relabel_lut[old as usize + 1] = new as u16 + 1;
            self.planes_spare.push(self.planes[old as usize]);
        }
        std::mem::swap(&mut self.planes, &mut self.planes_spare);
        relabel(&mut self.cell_labels, &self.relabel_lut);
    }
}

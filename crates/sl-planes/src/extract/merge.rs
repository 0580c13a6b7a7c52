//! Merging seeds whose affine disparities agree, compacting the plane list and ordering it by
//! size.

use super::patches::min_rss;
use super::*;

/// The largest difference of an affine disparity function over a box of cells (at its
/// corners), px.
fn worst_over_box(df: &DisparityAffine, b: &[u32; 4]) -> f64 {
    [(b[0], b[1]), (b[2], b[1]), (b[0], b[3]), (b[2], b[3])]
        .iter()
        .map(|&(x, y)| df.eval(f64::from(x), f64::from(y)).abs())
        .fold(0.0, f64::max)
}

impl PlaneExtractor {
    /// Merges planes that one affine function explains jointly, by either of two tests:
    /// - the least-squares plane of the union fits each of the two with an RMS below
    ///   `merge_px`, where the two affine functions differ by at most `4τ` over the union's
    ///   bounding box;
    /// - the noise model's test of the patch seeding ([`CellNoise`]): the extra residual of
    ///   one fit for both, `ΔRSS = RSS(a ∪ b) − RSS(a) − RSS(b)`, is within the 99.9 % quantile
    ///   of χ² with 3 degrees of freedom (times the cell variance and the correlation
    ///   inflation). This one needs no box: a small plane's slope is uncertain, so its affine
    ///   function extrapolated over a large neighbour's box may part from it by pixels although
    ///   one function explains both within the noise (a wall strip seeded beside an occluding
    ///   box, a spurious plane of the wall otherwise). Its only shortcut: the two functions
    ///   must agree within `4τ` over the smaller plane's own box.
    #[inline(never)]
    pub(super) fn merge(&mut self) {
        let mp = self.cfg.merge_px;
        let pre = 4.0 * self.cfg.threshold_px;
        let noise = self.noise;
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
                    let df = pi.f - pj.f;
                    let bb = union_box(&pi.bbox, &pj.bbox);
                    let small = if pi.sums.n < pj.sums.n {
                        &pi.bbox
                    } else {
                        &pj.bbox
                    };
                    let (agree_union, agree_small) = (
                        worst_over_box(&df, &bb) <= pre,
                        worst_over_box(&df, small) <= pre,
                    );
                    if !agree_small {
                        continue;
                    }
                    let mut u = pi.sums;
                    u.merge(&pj.sums);
                    let Some(f) = u.solve() else { continue };
                    let by_rms = agree_union && pi.sums.rms(&f) < mp && pj.sums.rms(&f) < mp;
                    let by_noise = || match (min_rss(&pi.sums), min_rss(&pj.sums)) {
                        (Some(ri), Some(rj)) => noise.same(u.rss(&f) - ri - rj),
                        _ => false,
                    };
                    if by_rms || by_noise() {
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

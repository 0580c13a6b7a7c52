//! The pixels along a crease between two planes, re-decided with the planes' local fits where
//! a plane is bent (issue 12).
//!
//! The final pass gives a pixel between two planes to the one whose affine function is
//! nearer. Where a surface is bent by the sensor's low-frequency distortion (Herrera et al.,
//! Smisek et al.), its whole-surface fit is off near the image border by a few tenths of a
//! pixel, while a small neighbour fitted on its own few pixels is not; the crossing line of
//! the two functions, where the pass puts the border, then lies several pixels inside the bent
//! surface, and the small plane takes a strip of it (a ceiling sliver with a 5-pixel strip of
//! the wall under it; a box face with the floor along its foot). That strip is what turns a
//! correct small plane into a spurious one.
//!
//! For each pair of planes that meet along a crease (4-neighbouring cells of both; their
//! functions within `2τ` of each other along it on average, as for the joining of bent
//! pieces), each plane's function near the border is measured on its own cells in a strip
//! beside it ([`STRIP_CELLS`] deep, the strip of the bend test) but beyond the cells whose
//! pixels are in dispute ([`disputed_cells`]: those within half a block-matching window of
//! the border, whose errors the two sides share). When the strip says the whole-surface
//! function is off there — the seeding's `χ²₃` test (99.9 %, the cells' noise with its
//! correlation) on the strip's residual sum of squares against it, beyond the strip's own
//! fit — that plane's local fit decides instead. A disputed pixel of either plane that both
//! functions explain within the pixel's noise (`CellNoise::pixel_bound_px`, as in the final
//! pass) takes the plane on its side of the line where the two functions cross — the crease —
//! when that line parts the two strips; any other takes the nearer function within `τ`. Only
//! the cells between the old border and that line are visited. Where neither plane is off,
//! nothing changes: on frames without distortion the stage moves (almost) no pixel.
//!
//! Off by default (`PlaneConfig::refine_seams`): on the simulated rooms with a 0.5 / 1 px
//! radial distortion it takes the spurious planes from 17 / 26 to 8 / 14 and changes nothing
//! without distortion, but on real frames it costs 0.1–0.3 ms per 640×480 frame (their
//! surfaces are bent: thousands of pixels move on NYU's frame) and leaves the real sequences'
//! repeatability where it was (docs/bench/README.md, session 43).

use super::bend::{STRIP_CELLS, border_gap, cell_centre_px, for_each_cell_border};
use super::*;
use crate::fit::AffineSums;

/// Most border cells of one pair whose strip neighbourhoods feed the local fits: a longer
/// border is sampled every `n`-th cell in scan order (as [`super::bend`] does).
const MAX_BORDER_SAMPLES: usize = 16;

/// Cells on each side of a border whose pixels are re-decided: half the larger side of the
/// block-matching window (the noise model's correlation window), whole cells, at least one.
fn disputed_cells(window_x_px: f64, window_y_px: f64) -> usize {
    let half = 0.5 * window_x_px.max(window_y_px);
    ((half / CELL as f64).ceil() as usize).clamp(1, STRIP_CELLS - 1)
}

impl PlaneExtractor {
    /// Re-decides the disputed pixels along the creases between planes whose whole fits are
    /// off there (see the module documentation), updating the labels and the planes' pixel
    /// counts and moments.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refine_seams(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        wq: usize,
        hq: usize,
        tau: f32,
        labels: &mut [u16],
    ) {
        let n = self.final_sums.len();
        if n < 2
            || wq == 0
            || hq == 0
            || self.cell_labels.len() < wq * hq
            || self.cell_disparity.len() < wq * hq
            || self.full_res_fits.len() < n
            || labels.len() < w * h
        {
            return;
        }
        self.collect_plane_seams(wq, hq);
        if self.seam_pairs.is_empty() {
            return;
        }
        let near = disputed_cells(self.cfg.noise_window_x_px, self.cfg.noise_window_y_px);
        self.seam_mark.clear();
        self.seam_mark.resize(wq * hq, 0);
        let tau = f64::from(tau);
        let mut seams = std::mem::take(&mut self.seam_pairs);
        for run in seams.chunk_by(|s, t| (s.0, s.1) == (t.0, t.1)) {
            self.refine_pair(run, near, d, w, h, wq, hq, tau, labels);
        }
        seams.clear();
        self.seam_pairs = seams;
    }

    /// Every border between 4-neighbouring cells of two planes, as `(a, b, cell of a, cell of
    /// b)` with plane indices `a < b`, sorted by pair (`seam_pairs`).
    #[inline(never)]
    fn collect_plane_seams(&mut self, wq: usize, hq: usize) {
        let cl = &self.cell_labels;
        let seams = &mut self.seam_pairs;
        seams.clear();
        let mut push = |ca: usize, cb: usize| {
            let (la, lb) = (cl[ca], cl[cb]);
            if la == 0 || lb == 0 || la == lb {
                return;
            }
            seams.push(if la < lb {
                (la - 1, lb - 1, ca as u32, cb as u32)
            } else {
                (lb - 1, la - 1, cb as u32, ca as u32)
            });
        };
        for_each_cell_border(cl, wq, hq, &mut push);
        seams.sort_unstable();
    }

    /// [`PlaneExtractor::refine_seams`] for the border `run` of one pair of planes.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn refine_pair(
        &mut self,
        run: &[(u16, u16, u32, u32)],
        near: usize,
        d: FullDisparity<'_>,
        w: usize,
        h: usize,
        wq: usize,
        hq: usize,
        tau: f64,
        labels: &mut [u16],
    ) {
        let (a, b) = (run[0].0 as usize, run[0].1 as usize);
        if run.len() < 2 || b >= self.final_sums.len() {
            return;
        }
        let (fa, fb) = (self.full_res_fits[a], self.full_res_fits[b]);
        // A crease, not a depth step: the two functions meet along the border.
        let gap = run
            .iter()
            .map(|s| border_gap(&fa, &fb, s.2 as usize, s.3 as usize, wq))
            .sum::<f64>()
            / run.len() as f64;
        if gap > 2.0 * tau {
            return;
        }
        let (la, lb) = (a as u16 + 1, b as u16 + 1);
        let cl = &self.cell_labels;
        let mark = &mut self.seam_mark;
        // Three fresh stamps: the sampled border's disputed cells, the strip cells, and the
        // whole border's disputed cells.
        self.seam_stamp = self.seam_stamp.wrapping_add(3);
        if self.seam_stamp < 3 {
            mark.fill(0);
            self.seam_stamp = 3;
        }
        let (disputed, strip, listed) = (self.seam_stamp - 2, self.seam_stamp - 1, self.seam_stamp);
        // The rows of cells within `r` of either cell of border `s` (two 4-neighbours: one box),
        // as index ranges.
        let around = |s: &(u16, u16, u32, u32), r: usize| {
            let (ca, cb) = (s.2 as usize, s.3 as usize);
            let (ia, ja, ib, jb) = (ca % wq, ca / wq, cb % wq, cb / wq);
            let (i0, i1) = (ia.min(ib).saturating_sub(r), (ia.max(ib) + r).min(wq - 1));
            let (j0, j1) = (ja.min(jb).saturating_sub(r), (ja.max(jb) + r).min(hq - 1));
            (j0..=j1).map(move |j| j * wq + i0..j * wq + i1 + 1)
        };
        // The strips' local fits, from the cells' mean disparities, beside (at most
        // `MAX_BORDER_SAMPLES` of) the border's cells, beyond their disputed cells.
        // Neighbouring border cells' strips overlap: every `STRIP_CELLS / 2`-th is enough.
        let step = run.len().div_ceil(MAX_BORDER_SAMPLES).max(STRIP_CELLS / 2);
        for s in run.iter().step_by(step) {
            for row in around(s, near) {
                mark[row].fill(disputed);
            }
        }
        let mut sums = [AffineSums::default(); 2];
        for s in run.iter().step_by(step) {
            for row in around(s, STRIP_CELLS) {
                for ku in row {
                    if mark[ku] == disputed || mark[ku] == strip {
                        continue;
                    }
                    mark[ku] = strip;
                    let l = cl[ku];
                    let dv = self.cell_disparity[ku];
                    if (l == la || l == lb) && dv.is_finite() && dv > 0.0 {
                        let (x, y) = cell_centre_px(ku, wq);
                        sums[usize::from(l == lb)].add(x, y, f64::from(dv));
                    }
                }
            }
        }
        // A side's whole fit is off when the strip's residual against it exceeds the strip's
        // own fit's by more than the noise allows.
        let noise = self.noise;
        let off = |s: &AffineSums, whole: &DisparityAffine| -> Option<DisparityAffine> {
            let local = s.solve()?;
            (!noise.same(s.rss(whole) - s.rss(&local))).then_some(local)
        };
        let (oa, ob) = (off(&sums[0], &fa), off(&sums[1], &fb));
        if oa.is_none() && ob.is_none() {
            return;
        }
        let (ga, gb) = (oa.unwrap_or(fa), ob.unwrap_or(fb));
        // Which side of the line where the local functions cross (`ga = gb`) each plane's
        // strip lies on: a pixel that both explain within the noise takes the plane of its
        // side (the crease is that line), when the line parts the two strips.
        let centroid = |s: &AffineSums| (s.sx / s.n, s.sy / s.n);
        let side_of_a = if sums[0].n > 0.0 && sums[1].n > 0.0 {
            let ((xa, ya), (xb, yb)) = (centroid(&sums[0]), centroid(&sums[1]));
            let (va, vb) = (
                ga.eval(xa, ya) - gb.eval(xa, ya),
                ga.eval(xb, yb) - gb.eval(xb, yb),
            );
            ((va > 0.0) != (vb > 0.0)).then_some(va > 0.0)
        } else {
            None
        };
        let bound = self.noise.pixel_bound_px();
        // The disputed cells along the whole border.
        self.seam_cells.clear();
        for s in run {
            for row in around(s, near) {
                for ku in row {
                    if mark[ku] != listed && (cl[ku] == la || cl[ku] == lb) {
                        mark[ku] = listed;
                        self.seam_cells.push(ku as u32);
                    }
                }
            }
        }
        let cells = std::mem::take(&mut self.seam_cells);
        // Only the pixels between the old border (where `fa = fb`) and the new one (`ga = gb`)
        // can change: a cell wholly on one side of both is skipped.
        let (old, new) = (fa - fb, ga - gb);
        let half = 0.5 * (CELL - 1) as f64;
        let (reach_old, reach_new) = (
            half * (old.a.abs() + old.b.abs()),
            half * (new.a.abs() + new.b.abs()),
        );
        for &cell in &cells {
            let (ci, cj) = (cell as usize % wq, cell as usize / wq);
            // Over the cell's pixels an affine function stays within `half·(|a| + |b|)` of its
            // value at the centre: the cell is skipped when both functions keep one sign there,
            // the same.
            let (xc, yc) = cell_centre_px(cell as usize, wq);
            let (vo, vn) = (old.eval(xc, yc), new.eval(xc, yc));
            if vo.abs() > reach_old && vn.abs() > reach_new && (vo > 0.0) == (vn > 0.0) {
                continue;
            }
            for y in CELL * cj..(CELL * cj + CELL).min(h) {
                let yf = self.rows.of(y);
                for x in CELL * ci..(CELL * ci + CELL).min(w) {
                    let i = y * w + x;
                    let l = labels[i];
                    if l != la && l != lb {
                        continue;
                    }
                    let dv = d.at(i);
                    if !(dv > 0.0 && dv.is_finite()) {
                        continue;
                    }
                    let (xf, df) = (x as f64, f64::from(dv));
                    let (va, vb) = (ga.eval(xf, yf), gb.eval(xf, yf));
                    let (ra, rb) = ((df - va).abs(), (df - vb).abs());
                    let to = if let Some(a_positive) = side_of_a
                        && ra <= bound
                        && rb <= bound
                    {
                        if (va > vb) == a_positive { la } else { lb }
                    } else if ra < rb && ra < tau {
                        la
                    } else if rb < ra && rb < tau {
                        lb
                    } else {
                        l
                    };
                    if to == l {
                        continue;
                    }
                    labels[i] = to;
                    self.move_pixel(usize::from(l) - 1, usize::from(to) - 1, x, y, df);
                }
            }
        }
        self.seam_cells = cells;
    }
}

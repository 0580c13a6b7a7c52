//! The final per-pixel pass: every pixel tested against the planes of its neighbourhood, the
//! labels and moments written band by band in parallel (`final_band`), ambiguous pixels
//! resolved, small pieces dropped and
//! the planes finished (3D plane, RMS, centroid).

use rayon::prelude::*;

use super::final_band::{FINAL_BAND_ROWS, FinalBand, FinalShared};
use super::*;

/// How many of the 8 neighbours of pixel `(x, y)` carry label `k1` and how many `k2`.
///
/// Away from the image border the eight labels are read as three fixed-size windows (no loop
/// over clipped ranges): the disambiguation visits every pixel that two planes explain, 5–30 k
/// a frame, and the general loop cost ~250 instructions per pixel.
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

/// Rows of the label image relabelled per rayon task when the pool has more than one thread.
const RELABEL_ROWS: usize = 32;

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
    /// The rows are assigned in bands of [`FINAL_BAND_ROWS`] rows in parallel (each band
    /// row by row, see [`FinalBand::run`]); the bands' moments are added in row order.
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
        self.prepare_final(wq);
        let parallel = rayon::current_num_threads() > 1;
        labels.clear();
        if parallel {
            labels.par_extend(rayon::iter::repeat_n(0u16, w * h));
        } else {
            labels.resize(w * h, 0);
        }
        let bands = h.div_ceil(FINAL_BAND_ROWS);
        if self.final_bands.len() < bands {
            self.final_bands.resize_with(bands, FinalBand::default);
        }
        let shared = FinalShared {
            d,
            cell_labels: &self.cell_labels,
            full_res_fits: &self.full_res_fits,
            slope_x: &self.slope_x,
            zero_cell_row: &self.zero_cell_row,
            bound: self.noise.pixel_bound_px() as f32,
            tau,
            w,
            wq,
            rows: self.rows,
        };
        let run = |(b, (rows, band)): (usize, (&mut [u16], &mut FinalBand))| {
            band.run(&shared, b * FINAL_BAND_ROWS, rows);
        };
        if parallel {
            labels
                .par_chunks_mut(FINAL_BAND_ROWS * w)
                .zip(self.final_bands.par_iter_mut())
                .enumerate()
                .for_each(run);
        } else {
            labels
                .chunks_mut(FINAL_BAND_ROWS * w)
                .zip(self.final_bands.iter_mut())
                .enumerate()
                .for_each(run);
        }
        // The bands' moments and ambiguous pixels, in row order.
        for band in &self.final_bands[..bands] {
            for (acc, part) in self.final_sums.iter_mut().zip(&band.sums) {
                acc.merge(part);
            }
            self.ambiguous.extend_from_slice(&band.ambiguous);
        }
    }

    /// Fresh accumulators and the planes in full-resolution coordinates.
    fn prepare_final(&mut self, wq: usize) {
        self.final_sums.clear();
        self.final_sums
            .resize(self.planes.len(), FinalAcc::default());
        self.ambiguous.clear();
        self.full_res_fits.clear();
        self.full_res_fits
            .extend(self.planes.iter().map(|p| cell_to_full(&p.f)));
        self.slope_x.clear();
        self.slope_x
            .extend(self.full_res_fits.iter().map(|f| f.a as f32));
        self.zero_cell_row.clear();
        self.zero_cell_row.resize(wq, 0);
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
        let ambiguous = std::mem::take(&mut self.ambiguous);
        for a in &ambiguous {
            let (x, y, k1, k2) = (a.x as usize, a.y as usize, a.best, a.second);
            let i = y * w + x;
            let (c1, c2) = neighbour_votes(labels, w, h, x, y, k1, k2);
            let (u1, u2) = (k1 as usize - 1, k2 as usize - 1);
            if c2 > c1
                && labels[i] == k1
                && u1 < self.final_sums.len()
                && u2 < self.final_sums.len()
            {
                labels[i] = k2;
                self.move_pixel(u1, u2, x, y, f64::from(d.at(i)));
            }
        }
        self.ambiguous = ambiguous;
    }

    /// Moves pixel `(x, y)` of disparity `df` from plane `from` to plane `to` in the final
    /// moments (pixel counts, rows, and the sample rows' sums).
    #[inline]
    pub(super) fn move_pixel(&mut self, from: usize, to: usize, x: usize, y: usize, df: f64) {
        let n = self.final_sums.len();
        if from >= n || to >= n {
            return;
        }
        self.final_sums[from].pixels -= 1;
        self.final_sums[to].pixels += 1;
        self.final_sums[to].add_rows(y);
        if is_sample_row(y) {
            let (xf, yf) = (x as f64, self.rows.of(y));
            let (f1, f2) = (self.full_res_fits[from], self.full_res_fits[to]);
            let a1 = &mut self.final_sums[from];
            a1.sums.remove(xf, yf, df);
            if is_metric_row(y) {
                a1.inv.add(xf, yf, df, df - f1.eval(xf, yf), -1.0);
            }
            let a2 = &mut self.final_sums[to];
            a2.sums.add(xf, yf, df);
            if is_metric_row(y) {
                a2.inv.add(xf, yf, df, df - f2.eval(xf, yf), 1.0);
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
        self.dropped_uncertain.clear();
        self.dropped_uncertain.resize(self.final_sums.len(), 0);
        // Pieces of bent surfaces (`bend`): a joined piece's pixels take its root's label.
        let joined = self.joined_into.len() == self.final_sums.len();
        let root = |pi: usize| {
            if joined {
                self.joined_into[pi] as usize
            } else {
                pi
            }
        };
        for (pi, a) in self.final_sums.iter().enumerate() {
            let n = a.sums.n;
            if root(pi) != pi || a.pixels < self.cfg.min_pixels || n < 3.0 {
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
            let sigmas = plane_sigmas(&a.sums, &f, k, fb, &self.fit_noise);
            if sigmas.normal_deg > self.cfg.max_normal_sigma_deg {
                self.dropped_uncertain[pi] = 1;
                continue;
            }
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
                    normal_sigma_deg: sigmas.normal_deg,
                    offset_sigma_m: sigmas.offset_m,
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
        for pi in 0..self.final_sums.len() {
            let r = root(pi);
            if r != pi {
                self.relabel_lut[pi + 1] = self.relabel_lut[r + 1];
                self.dropped_uncertain[pi] = self.dropped_uncertain[r];
            }
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
            let rows = &mut labels[y0 * w..(y1 * w).min(w * h)];
            let lut: &[u16] = &self.relabel_lut;
            if rayon::current_num_threads() > 1 {
                // Whole rows per task; each label is mapped on its own, so the split does not
                // change the result.
                rows.par_chunks_mut(RELABEL_ROWS * w)
                    .for_each(|part| relabel(part, lut));
            } else {
                relabel(rows, lut);
            }
        }
        self.final_sums.clear();
        Ok(PlaneSegmentation {
            labels: Image::from_vec(w, h, labels)?,
            planes: out.into_iter().map(|(_, p)| p).collect(),
        })
    }
}

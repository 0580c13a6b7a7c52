//! Planes that span a crease, split along it (issue 12).
//!
//! Far away, or where the sensor's low-frequency distortion has bent a surface's rim beyond
//! `τ` of its own plane, the pixels along a crease between two surfaces (a floor and a wall, a
//! box face and the wall beside it) can be explained within `τ` by one affine function and
//! come out as one "plane" spanning both surfaces. Its residual is not white: it has the
//! shape of a fold. A surface bent by the distortion is not affine either, but it bends
//! smoothly. The test tells the two apart on the plane's labelled pixels of an 8 × 8-pixel grid,
//! or of a 4 × 4 grid for a plane under [`DENSE_BELOW_PIXELS`] (the final labels, so a strip
//! the final pass added to a plane pixel by pixel is in its samples), by two models of its
//! residual against its affine fit:
//!
//! 1. **Curvature beyond the distortion.** A quadratic surface (6 parameters): its strongest
//!    curvature `λ` (the Hessian's dominant eigenvalue) must exceed the largest curvature the
//!    sensor's distortion gives a surface (`PlaneConfig::bend_px_per_px2`, scaled as `585/f`)
//!    by more than `Z₉₉.₉` standard deviations. The variance of `λ` is that of the
//!    least-squares coefficients with the pixels' noise (`σ_D² + 1/(12q²)`, or the fit's own
//!    mean square residual where larger), inflated by the correlation of the block-matching
//!    error over the grid (`κ`, as for [`PlaneInfo::normal_sigma_deg`]). A plane the noise
//!    model cannot tell from a bent surface is left alone.
//! 2. **A fold, not a bend.** A hinge — two affine pieces meeting along a line across the
//!    curvature's direction, 4 parameters plus the line's position (tried at the 31 inner edges
//!    of 32 equal bins of the samples along that direction) — must leave a smaller residual
//!    than the quadratic, which has two parameters more. A smoothly bent surface is fitted better by the
//!    quadratic; two planes meeting at a crease by the hinge.
//!
//! A plane that passes both is split where the two sides' own affine fits intersect (a straight
//! line in the image: two planes meet along a 3D line), or along the hinge when they do not
//! cross between the sides (a step); the line crosses each row once, so the pixels are
//! relabelled by ranges (only the smaller side's, whose moments are subtracted from the
//! plane's). A side with fewer than `min_pixels` pixels is no plane: its pixels and cells are
//! left unlabelled; a larger side keeps the plane's index or becomes a
//! new plane, and is tested again (up to [`MAX_SPLIT_DEPTH`] levels, for bands over three
//! surfaces). The split happens before the pieces of bent surfaces are joined (`bend`), which
//! may give a side back to the surface it belongs to.
//!
//! Written by hand: the model comparison is specific to the disparity parameterisation.

use super::patches::Z_999;
use super::*;
use crate::quadratic::{HingeBins, QuadraticSums, RowMoments};

/// Scale of the fits' coordinates, pixels (a plane's coordinates become of order one).
const COORD_SCALE_PX: f64 = 64.0;

/// How many times the pieces of a split plane are tested again (a band over three surfaces
/// needs two splits).
const MAX_SPLIT_DEPTH: u8 = 3;

/// The test samples the labelled pixels of a grid [`GRID_X`] × [`GRID_Y`] pixels apart (from
/// [`GRID_OFFSET`]): pixels 8 apart are still correlated through the 9 × 11-pixel matching
/// window, so the grid holds most of the information of every pixel (the correlation
/// inflation follows, `FitNoise::on_grid`), and the strips the final pass added to a plane are
/// in it. (A grid twice as dense along the rows left 32 instead of 35 spurious planes on the
/// examined rooms with 1 px of distortion, at about twice the cost.)
pub(super) const GRID_X: usize = 8;
/// Rows of the sampling grid.
pub(super) const GRID_Y: usize = 8;

/// Offset of the sampling grid in both directions, pixels (the middle of a grid square).
const GRID_OFFSET: usize = GRID_X / 2;

/// Pixels of a row looked at together for a plane's label when a plane is split.
const SCAN_CHUNK: usize = 32;

/// Planes with fewer pixels than this are sampled densely — every [`DENSE_STEP`]-th pixel of
/// the sample rows (every fourth, as the plane's own fit), within the columns the grid saw them
/// in — instead of on the grid, and tested without the grid's screening: the grid's 1-in-64
/// pixels leave a small plane (a box face with a strip of the wall beside it) too few samples
/// to place its fold. At most 1,024 samples a plane. (Below 32,768 pixels instead: the same
/// rooms' scores at more cost.)
const DENSE_BELOW_PIXELS: usize = 16_384;

/// Columns of the dense sampling: every fourth pixel of the sample rows (4 × 4 pixels apart:
/// as informative as every pixel of those rows through the matching window's correlation,
/// `κ` = 6.6 against 25.4, at a quarter of the samples).
pub(super) const DENSE_STEP: usize = SAMPLE_ROW_STEP;

/// Fewest samples a plane needs to be tested (well above the 6 parameters of the quadratic).
const MIN_SAMPLES: usize = 32;

/// One plane (or piece) to test: its index, its samples `crease_samples[start..end]`, the centre of the fits' coordinates and how many splits made it.
#[derive(Debug, Clone, Copy)]
pub(super) struct CreaseWork {
    plane: u16,
    start: u32,
    end: u32,
    centre: (f64, f64),
    /// The correlation inflation of the samples (`κ` of their grid).
    kappa: f64,
    depth: u8,
}

/// A sample of the crease test: a labelled pixel of the grid and its disparity.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct CreaseSample {
    x: f32,
    y: f32,
    d: f32,
}

/// Where a plane is split: side A is where `p·x + q·y + r ≥ 0`; the two sides' affine fits.
#[derive(Debug, Clone, Copy)]
struct SplitLine {
    p: f64,
    q: f64,
    r: f64,
    fit_a: DisparityAffine,
    fit_b: DisparityAffine,
}

impl SplitLine {
    /// The same line with its sides swapped.
    fn flipped(self) -> Self {
        Self {
            p: -self.p,
            q: -self.q,
            r: -self.r,
            fit_a: self.fit_b,
            fit_b: self.fit_a,
        }
    }

    /// Whether pixel `(x, y)` is on side A.
    #[inline]
    fn side_a(&self, x: f64, y: f64) -> bool {
        self.p * x + self.q * y + self.r >= 0.0
    }

    /// The pixels of row `y` (width `w`) on side A and on side B, as ranges.
    fn row_ranges(&self, y: usize, w: usize) -> (std::ops::Range<usize>, std::ops::Range<usize>) {
        let c = self.q * y as f64 + self.r;
        let p = self.p;
        if p.abs() < 1e-12 {
            return if c >= 0.0 { (0..w, w..w) } else { (0..0, 0..w) };
        }
        let cross = -c / p;
        let clamp = |x: f64| x.clamp(0.0, w as f64) as usize;
        if p > 0.0 {
            // A is x ≥ cross.
            let xa = clamp(cross.ceil());
            (xa..w, 0..xa)
        } else {
            // A is x ≤ cross.
            let xb = clamp(cross.floor() + 1.0);
            (0..xb, xb..w)
        }
    }
}

/// Replaces `from` by `to` in `labels`; how many were replaced.
fn replace_label(labels: &mut [u16], from: u16, to: u16) -> usize {
    let mut chunks = labels.chunks_exact_mut(SCAN_CHUNK);
    let mut n = 0usize;
    for c in &mut chunks {
        let mut k = 0u16;
        for l in c.iter_mut() {
            let hit = *l == from;
            k += u16::from(hit);
            *l = if hit { to } else { *l };
        }
        n += usize::from(k);
    }
    for l in chunks.into_remainder() {
        if *l == from {
            *l = to;
            n += 1;
        }
    }
    n
}

impl PlaneExtractor {
    /// Splits the planes of the final pass that span a crease (see the module documentation).
    /// `fx` is the focal length of the grid being extracted; `labels` the full-resolution
    /// labels of the final pass, updated with the final statistics.
    #[inline(never)]
    pub(super) fn split_creases(
        &mut self,
        d: FullDisparity<'_>,
        w: usize,
        wq: usize,
        fx: f64,
        labels: &mut [u16],
    ) {
        let n0 = self.final_sums.len();
        let bend = self.cfg.bend_px_per_px2 * bend::BEND_MEASURED_AT_FOCAL_PX / fx;
        if n0 == 0 || w == 0 || !bend.is_finite() || self.full_res_fits.len() < n0 {
            return;
        }
        self.curvature_sums(d, w, labels);
        // The planes curved beyond the bend: their samples, then the hinge test.
        self.crease_work.clear();
        self.crease_samples.clear();
        for p in 0..n0 {
            let centre = self.crease_centres[p];
            if !centre.0.is_finite() {
                continue;
            }
            let dense = self.final_sums[p].pixels < DENSE_BELOW_PIXELS;
            let kappa = if dense {
                self.crease_dense_noise.kappa
            } else if self
                .crease_direction(&self.crease_quad[p], bend, self.crease_noise.kappa)
                .is_some()
            {
                self.crease_noise.kappa
            } else {
                continue;
            };
            let start = self.crease_samples.len() as u32;
            let a = self.final_sums[p];
            if dense {
                // Within the columns the grid saw the plane in, one grid step wider each side.
                let (c0, c1) = self.crease_columns[p];
                let columns = if c0 <= c1 {
                    (c0 as usize).saturating_sub(GRID_X)..(c1 as usize + GRID_X + 1).min(w)
                } else {
                    0..w
                };
                let first = a.y0.div_ceil(SAMPLE_ROW_STEP) * SAMPLE_ROW_STEP;
                let rows = (first..a.y1).step_by(SAMPLE_ROW_STEP);
                self.gather_samples(p, d, w, labels, rows, columns.step_by(DENSE_STEP));
            } else {
                let first =
                    GRID_OFFSET + a.y0.saturating_sub(GRID_OFFSET).div_ceil(GRID_Y) * GRID_Y;
                let rows = (first..a.y1).step_by(GRID_Y);
                self.gather_samples(p, d, w, labels, rows, (GRID_OFFSET..w).step_by(GRID_X));
            }
            let end = self.crease_samples.len() as u32;
            self.crease_work.push(CreaseWork {
                plane: p as u16,
                start,
                end,
                centre,
                kappa,
                depth: 0,
            });
        }
        while let Some(job) = self.crease_work.pop() {
            let Some(line) = self.crease_test(&job, bend) else {
                continue;
            };
            self.split_along_crease(job, line, d, w, wq, labels);
        }
    }

    /// Whether plane `p` is large enough to be split.
    fn crease_candidate(&self, p: usize) -> bool {
        self.final_sums
            .get(p)
            .is_some_and(|a| a.pixels >= 2 * self.cfg.min_pixels && a.sums.n >= 3.0)
    }

    /// The quadratic sums of every candidate plane's residual over its pixels on the sampling
    /// grid, about its centroid (`crease_centres`, NaN for the planes not tested), a row at a
    /// time.
    fn curvature_sums(&mut self, d: FullDisparity<'_>, w: usize, labels: &[u16]) {
        let n = self.final_sums.len();
        self.crease_quad.clear();
        self.crease_quad.resize(n, QuadraticSums::default());
        self.crease_rows.clear();
        self.crease_rows.resize(n, RowMoments::default());
        self.crease_centres.clear();
        self.crease_columns.clear();
        self.crease_columns.resize(n, (u32::MAX, 0));
        for p in 0..n {
            let s = &self.final_sums[p].sums;
            self.crease_centres.push(if self.crease_candidate(p) {
                (s.sx / s.n, s.sy / s.n)
            } else {
                (f64::NAN, f64::NAN)
            });
        }
        let inv_s = 1.0 / COORD_SCALE_PX;
        let h = labels.len() / w;
        for y in (GRID_OFFSET..h).step_by(GRID_Y) {
            self.crease_touched.clear();
            let yf = self.rows.of(y);
            for x in (GRID_OFFSET..w).step_by(GRID_X) {
                let Some(p) = usize::from(labels[y * w + x]).checked_sub(1) else {
                    continue;
                };
                if !self.crease_centres.get(p).is_some_and(|c| c.0.is_finite()) {
                    continue;
                }
                let xf = x as f64;
                let r = f64::from(d.at(y * w + x)) - self.full_res_fits[p].eval(xf, yf);
                let m = &mut self.crease_rows[p];
                if m.is_empty() {
                    self.crease_touched.push(p as u16);
                }
                m.add((xf - self.crease_centres[p].0) * inv_s, r);
                let span = &mut self.crease_columns[p];
                *span = (span.0.min(x as u32), span.1.max(x as u32));
            }
            for &p in &self.crease_touched {
                let p = usize::from(p);
                let v = (yf - self.crease_centres[p].1) * inv_s;
                self.crease_quad[p].add_row(v, &self.crease_rows[p]);
                self.crease_rows[p] = RowMoments::default();
            }
        }
    }

    /// The direction `(du, dv)` of the quadratic fit's strongest curvature when it exceeds the
    /// distortion's bend `bend` (px/px²) by more than the noise allows (samples of the pixels'
    /// variance, correlated with inflation `kappa`); `None` otherwise.
    fn crease_direction(&self, quad: &QuadraticSums, bend: f64, kappa: f64) -> Option<(f64, f64)> {
        let q = quad.solve()?;
        if q.n < MIN_SAMPLES {
            return None;
        }
        let c = q.curvature();
        let s2 = COORD_SCALE_PX * COORD_SCALE_PX;
        let lambda = c.magnitude / s2;
        let var_sample = self.crease_noise.var_px.max(q.rss / (q.n as f64 - 6.0));
        let sigma = (c.unit_variance * kappa * var_sample).sqrt() / s2;
        (lambda - bend > Z_999 * sigma).then_some(c.direction)
    }

    /// Appends the pixels of plane `p` at `rows` × `columns` (row by row) to
    /// `crease_samples`.
    fn gather_samples(
        &mut self,
        p: usize,
        d: FullDisparity<'_>,
        w: usize,
        labels: &[u16],
        rows: std::iter::StepBy<std::ops::Range<usize>>,
        columns: std::iter::StepBy<std::ops::Range<usize>>,
    ) {
        let label = p as u16 + 1;
        let h = labels.len() / w;
        for y in rows.take_while(|&y| y < h) {
            for x in columns.clone() {
                if labels[y * w + x] == label {
                    self.crease_samples.push(CreaseSample {
                        x: x as f32,
                        y: y as f32,
                        d: d.at(y * w + x),
                    });
                }
            }
        }
    }

    /// The crease test on one plane's samples: the split line when the plane spans a crease.
    fn crease_test(&self, job: &CreaseWork, bend: f64) -> Option<SplitLine> {
        let samples = &self.crease_samples[job.start as usize..job.end as usize];
        if samples.len() < MIN_SAMPLES {
            return None;
        }
        let (x0, y0) = job.centre;
        let s = COORD_SCALE_PX;
        // Residuals against the plane's current fit (any affine reference would do: both
        // models contain the affine functions).
        let f = self.full_res_fits[usize::from(job.plane)];
        let scaled = |p: &CreaseSample| {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            ((x - x0) / s, (y - y0) / s, f64::from(p.d) - f.eval(x, y))
        };
        // The curvature test on these samples (a piece of a split plane is tested again).
        let mut quad = QuadraticSums::default();
        let mut row = RowMoments::default();
        for (i, p) in samples.iter().enumerate() {
            let (u, _, r) = scaled(p);
            row.add(u, r);
            if samples.get(i + 1).is_none_or(|q| q.y != p.y) {
                quad.add_row((f64::from(p.y) - y0) / s, &row);
                row = RowMoments::default();
            }
        }
        let (du, dv) = self.crease_direction(&quad, bend, job.kappa)?;
        let q_rss = quad.solve()?.rss;
        // The hinge along the curvature's direction, at every inner bin edge.
        let t = |p: &CreaseSample| {
            let (u, v, _) = scaled(p);
            u * du + v * dv
        };
        let (t_min, t_max) = samples
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |m, p| {
                (m.0.min(t(p)), m.1.max(t(p)))
            });
        let mut bins = HingeBins::new(t_min, t_max);
        for p in samples {
            let (u, v, r) = scaled(p);
            bins.add(u, v, u * du + v * dv, r);
        }
        let (h_rss, t0) = bins.best()?;
        // (A NaN residual never splits.)
        if h_rss.partial_cmp(&q_rss) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        // The two sides' own affine fits of the disparity (pixel coordinates).
        let (mut sa, mut sb) = (AffineSums::default(), AffineSums::default());
        for p in samples {
            let side = if t(p) <= t0 { &mut sa } else { &mut sb };
            side.add(f64::from(p.x), f64::from(p.y), f64::from(p.d));
        }
        // Along the hinge, side A is t ≤ t₀: −du·x − dv·y + (du·x₀ + dv·y₀ + t₀·s) ≥ 0.
        let hinge = |fit_a, fit_b| SplitLine {
            p: -du,
            q: -dv,
            r: du * x0 + dv * y0 + t0 * s,
            fit_a,
            fit_b,
        };
        let (Some(fa), Some(fb)) = (sa.solve(), sb.solve()) else {
            return Some(hinge(f, f));
        };
        let g = |sums: &AffineSums| {
            let (x, y) = (sums.sx / sums.n, sums.sy / sums.n);
            fa.eval(x, y) - fb.eval(x, y)
        };
        let (ga, gb) = (g(&sa), g(&sb));
        if ga == 0.0 || gb == 0.0 || (ga > 0.0) == (gb > 0.0) {
            // The fits do not cross between the sides: a step, cut along the hinge.
            return Some(hinge(fa, fb));
        }
        // Where the fits cross: side A is where `f_a − f_b` has the sign it has on A.
        let sign = ga.signum();
        Some(SplitLine {
            p: sign * (fa.a - fb.a),
            q: sign * (fa.b - fb.b),
            r: sign * (fa.c - fb.c),
            fit_a: fa,
            fit_b: fb,
        })
    }

    /// Splits plane `job.plane` along `line`: pixels, statistics, fits, cells and samples;
    /// the sides large enough to be planes are tested again.
    fn split_along_crease(
        &mut self,
        job: CreaseWork,
        line: SplitLine,
        d: FullDisparity<'_>,
        w: usize,
        wq: usize,
        labels: &mut [u16],
    ) {
        let pi = usize::from(job.plane);
        let new = self.final_sums.len();
        if new + 1 >= MAX_PLANES {
            return;
        }
        // Side B, the smaller one (by the samples), takes the new label: only its half of
        // each row is scanned, for the labels, its pixels and its moments; side A's pixels and
        // moments are the plane's less B's, and its metric sums (residuals against its own
        // fit) come from its half of the metric rows.
        let samples = &self.crease_samples[job.start as usize..job.end as usize];
        let na = samples
            .iter()
            .filter(|p| line.side_a(f64::from(p.x), f64::from(p.y)))
            .count();
        let line = if na < samples.len() - na {
            line.flipped()
        } else {
            line
        };
        let old = self.final_sums[pi];
        let mut acc_b = FinalAcc::default();
        let (old_label, new_label) = (pi as u16 + 1, new as u16 + 1);
        let rows = old.y0..old.y1.min(labels.len() / w);
        for y in rows.clone() {
            let row = &mut labels[y * w..(y + 1) * w];
            let (_, rb) = line.row_ranges(y, w);
            let count = replace_label(&mut row[rb], old_label, new_label);
            if count > 0 {
                acc_b.pixels += count;
                acc_b.add_rows(y);
            }
        }
        let mut acc_a = FinalAcc {
            sums: old.sums,
            inv: InvSums::default(),
            pixels: old.pixels.saturating_sub(acc_b.pixels),
            y0: old.y0,
            y1: old.y1,
        };
        for y in rows.clone().filter(|&y| is_sample_row(y)) {
            let yf = self.rows.of(y);
            let row = &labels[y * w..(y + 1) * w];
            let (ra, rb) = line.row_ranges(y, w);
            let metric = is_metric_row(y);
            for (range, label, acc, fit, sums) in [
                (rb, new_label, &mut acc_b, &line.fit_b, true),
                (ra, old_label, &mut acc_a, &line.fit_a, false),
            ] {
                if !(sums || metric) {
                    continue;
                }
                let seg = &row[range.clone()];
                for (ci, chunk) in seg.chunks(SCAN_CHUNK).enumerate() {
                    if !holds_label(chunk, label) {
                        continue;
                    }
                    for (xi, _) in chunk.iter().enumerate().filter(|(_, l)| **l == label) {
                        let x = range.start + ci * SCAN_CHUNK + xi;
                        let (xf, df) = (x as f64, f64::from(d.at(y * w + x)));
                        if sums {
                            acc.sums.add(xf, yf, df);
                        }
                        if metric {
                            acc.inv.add(xf, yf, df, df - fit.eval(xf, yf), 1.0);
                        }
                    }
                }
            }
        }
        acc_a.sums.subtract(&acc_b.sums);
        let min = self.cfg.min_pixels;
        let (keep_a, keep_b) = (acc_a.pixels >= min, acc_b.pixels >= min);
        // A side too small to be a plane: its pixels are left unlabelled.
        for (keep, acc, label) in [(keep_a, &acc_a, old_label), (keep_b, &acc_b, new_label)] {
            if !keep && acc.pixels > 0 {
                replace_label(&mut labels[acc.y0 * w..acc.y1 * w], label, 0);
            }
        }
        let label_b = if keep_b { new_label } else { 0 };
        // The cells (for the joining of bent pieces) follow their centres.
        let (j0, j1) = (rows.start / CELL, rows.end.div_ceil(CELL));
        for j in j0..j1.min(self.cell_labels.len() / wq.max(1)) {
            for i in 0..wq {
                let k = j * wq + i;
                if self.cell_labels[k] == old_label {
                    let (x, y) = bend::cell_centre_px(k, wq);
                    if !line.side_a(x, y) {
                        self.cell_labels[k] = label_b;
                    } else if !keep_a {
                        self.cell_labels[k] = 0;
                    }
                }
            }
        }
        self.final_sums[pi] = if keep_a { acc_a } else { FinalAcc::default() };
        self.full_res_fits[pi] = line.fit_a;
        self.final_sums
            .push(if keep_b { acc_b } else { FinalAcc::default() });
        self.full_res_fits.push(line.fit_b);
        if job.depth + 1 >= MAX_SPLIT_DEPTH {
            return;
        }
        // The samples follow their pixels (side A first, each side row by row); each piece is
        // tested again about its own centroid.
        let (start, end) = (job.start as usize, job.end as usize);
        let samples = &mut self.crease_samples[start..end];
        let mut na = 0;
        for i in 0..samples.len() {
            if line.side_a(f64::from(samples[i].x), f64::from(samples[i].y)) {
                samples.swap(i, na);
                na += 1;
            }
        }
        samples[..na].sort_unstable_by(|a, b| a.y.total_cmp(&b.y));
        samples[na..].sort_unstable_by(|a, b| a.y.total_cmp(&b.y));
        for (keep, plane, range) in [
            (keep_a, pi, start..start + na),
            (keep_b, new, start + na..end),
        ] {
            if keep && self.final_sums[plane].pixels >= 2 * min && range.len() >= MIN_SAMPLES {
                let s = &self.final_sums[plane].sums;
                self.crease_work.push(CreaseWork {
                    plane: plane as u16,
                    start: range.start as u32,
                    end: range.end as u32,
                    centre: (s.sx / s.n, s.sy / s.n),
                    kappa: job.kappa,
                    depth: job.depth + 1,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extract::tests::gauss;

    /// An extractor whose plane 0 has the grid samples of `surface` (disparity, px, of pixel
    /// coordinates) over a 200 × 120-pixel region, with white noise of the pixels' deviation
    /// (the correlation inflation is then conservative), fitted by its least-squares affine
    /// function.
    fn extractor_with(surface: impl Fn(f64, f64) -> f64, seed: u64) -> PlaneExtractor {
        let mut ex = PlaneExtractor::new(PlaneConfig::default()).unwrap();
        ex.crease_noise = FitNoise::on_grid(0.07, 8, 9.0, 11.0, GRID_X, GRID_Y);
        let sigma = ex.crease_noise.var_px.sqrt();
        let mut state = seed;
        let mut sums = AffineSums::default();
        for y in (100..220).step_by(GRID_Y) {
            for x in (200..400).step_by(GRID_X) {
                let (xf, yf) = (f64::from(x), f64::from(y));
                let d = surface(xf, yf) + sigma * gauss(&mut state);
                sums.add(xf, yf, d);
                ex.crease_samples.push(CreaseSample {
                    x: xf as f32,
                    y: yf as f32,
                    d: d as f32,
                });
            }
        }
        ex.full_res_fits.push(sums.solve().unwrap());
        ex
    }

    fn test(ex: &mut PlaneExtractor) -> Option<SplitLine> {
        let n = ex.crease_samples.len();
        let (sx, sy) = ex.crease_samples.iter().fold((0.0, 0.0), |(a, b), p| {
            (a + f64::from(p.x), b + f64::from(p.y))
        });
        let job = CreaseWork {
            plane: 0,
            start: 0,
            end: n as u32,
            centre: (sx / n as f64, sy / n as f64),
            kappa: ex.crease_noise.kappa,
            depth: 0,
        };
        // The Kinect's bend bound at f = 585 px.
        ex.crease_test(&job, ex.cfg.bend_px_per_px2)
    }

    #[test]
    fn a_plane_and_a_bent_surface_are_not_split() {
        for seed in 0..5 {
            let mut plane = extractor_with(|x, y| 20.0 + 0.01 * x - 0.02 * y, seed);
            assert!(test(&mut plane).is_none(), "plane, seed {seed}");
            // Bent by three times the largest curvature the distortion makes: well beyond
            // the bound, but smooth.
            let k = 3.0 * PlaneConfig::default().bend_px_per_px2;
            let mut bent = extractor_with(
                |x, y| 20.0 + 0.01 * x + 0.5 * k * ((x - 300.0).powi(2) + (y - 160.0).powi(2)),
                seed,
            );
            assert!(test(&mut bent).is_none(), "bent, seed {seed}");
        }
    }

    #[test]
    fn two_planes_meeting_at_a_crease_are_split_along_it() {
        // Slopes that differ by 0.03 px/px across a crease at x = 330 (a floor meeting a
        // wall about 3 m away): one affine function leaves at most ~0.4 px over the region.
        let crease_x = 330.0;
        for seed in 0..5 {
            let mut ex = extractor_with(
                |x, y| 20.0 + 0.01 * x - 0.002 * y + 0.03 * (x - crease_x).max(0.0),
                seed,
            );
            let line = test(&mut ex).expect("a crease");
            // The split follows the crease within a few pixels along the whole region.
            for y in [100.0, 160.0, 219.0] {
                assert!(line.side_a(crease_x - 6.0, y) != line.side_a(crease_x + 6.0, y));
            }
        }
    }
}

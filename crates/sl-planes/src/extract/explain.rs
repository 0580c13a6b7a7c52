//! Why a large region was not made a plane (issue 12, `sldepth planes --explain`): the
//! unlabelled regions of the last extraction, each with the test that turned it down, read from
//! the extractor's cell-grid buffers (no second extraction).

use super::*;
use crate::extract::patches::{PATCH, PatchStatus};

/// Why a region is on no plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum RejectReason {
    /// Most of its cells fail the LoG planarity test (`log_threshold_px`): curved, or at depth
    /// jumps.
    NotPlanarLog,
    /// Most of its patches have a residual larger than the noise allows (the χ² test with
    /// `σ_D`, `1/q` and the correlation window): its disparity is not affine at the 16-pixel
    /// scale.
    ResidualNotWhite,
    /// Its patches are planar, but one affine function does not explain the whole region
    /// within the noise (several surfaces, or a curved one), and no part that one plane explains
    /// reached `min_pixels`.
    SeveralSurfaces,
    /// One affine function explains it within the noise, but it was too small a seed
    /// (`min_pixels`), dropped as a small piece (`min_piece_pixels`) or as too uncertain a
    /// plane (`max_normal_sigma_deg`), or its pixels are beyond `threshold_px` of the plane it
    /// touches.
    Unseeded,
    /// Most of it was a plane that the noise model determines less well than
    /// `max_normal_sigma_deg` asks, and so was not reported.
    Uncertain,
    /// Most of it was given back by the plane beside it as a piece of another surface that
    /// plane had taken in (`PlaneConfig::give_back_taken_in`): off that plane's fit and its
    /// surroundings by more than the noise allows.
    GivenBack,
    /// The whole frame's disparity error, as measured on its own patches, has a standard
    /// deviation above `threshold_px`: no plane can hold its pixels within the threshold, and
    /// none was extracted ([`PlaneExtractor::noise_beyond_threshold`]).
    NoiseBeyondThreshold,
}

impl RejectReason {
    /// A short explanation for users.
    pub fn describe(&self) -> &'static str {
        match self {
            Self::NotPlanarLog => "most cells fail the LoG planarity test (curved or depth jumps)",
            Self::ResidualNotWhite => {
                "patch residuals exceed the sensor noise (not affine in disparity)"
            }
            Self::SeveralSurfaces => {
                "planar patches, but no single plane explains them (several surfaces or curved)"
            }
            Self::Unseeded => "one plane fits it, but its seed was too small or it was dropped",
            Self::Uncertain => {
                "a plane, left out: its normal is less certain than max_normal_sigma_deg"
            }
            Self::GivenBack => {
                "given back by the plane beside it: off its fit and surroundings beyond the noise"
            }
            Self::NoiseBeyondThreshold => {
                "the frame's measured disparity noise exceeds threshold_px: no plane extracted"
            }
        }
    }
}

/// One region of valid depth that no plane took.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionExplanation {
    /// Pixels of the region (cells of 4×4 pixels with a valid disparity, mostly unlabelled).
    pub pixels: usize,
    /// Bounding box `[x0, y0, x1, y1]`, pixels (inclusive).
    pub bbox_px: [usize; 4],
    /// The test that turned it down.
    pub reason: RejectReason,
    /// Share of its cells that fail the LoG test.
    pub log_rejected_fraction: f64,
    /// Share of its usable patches whose residual exceeds the noise.
    pub residual_rejected_fraction: f64,
    /// RMS disparity residual of one affine fit of its cells, pixels.
    pub rms_px: f64,
}

impl PlaneExtractor {
    /// The regions of at least `min_pixels` valid pixels that the last extraction (whose result
    /// is `seg`) left on no plane, largest first, with the reason. Empty when `seg` is not the
    /// last extraction's size. For a frame extracted on its sensor's grid (a decimated camera,
    /// [`PlaneExtractor::extract_depth`]) the regions are found there and reported in the
    /// frame's pixels; `min_pixels` counts the sensor's pixels there, as
    /// [`PlaneConfig::min_pixels`] does.
    pub fn explain_unlabelled(
        &self,
        seg: &PlaneSegmentation,
        min_pixels: usize,
    ) -> Vec<RegionExplanation> {
        let Some((n, grid)) = &self.sensor_grid else {
            return self.explain_labels(&seg.labels, min_pixels);
        };
        let n = *n;
        let (w, h) = seg.labels.dimensions();
        if grid.dimensions() != (w * n, h * n) {
            return Vec::new();
        }
        let mut out = self.explain_labels(grid, min_pixels);
        for r in &mut out {
            r.pixels /= n * n;
            r.bbox_px = r.bbox_px.map(|v| v / n);
        }
        out
    }

    /// [`PlaneExtractor::explain_unlabelled`] for the label image of the extractor's own grid.
    fn explain_labels(&self, labels: &Image<u16>, min_pixels: usize) -> Vec<RegionExplanation> {
        let (w, h) = labels.dimensions();
        let (wq, hq) = (w / 2 / 2, h / 2 / 2);
        if wq * hq == 0 || self.cell_disparity.len() < wq * hq || self.cell_planar.len() < wq * hq {
            return Vec::new();
        }
        let labels = labels.data();
        // Cells with a valid disparity and at most half of their pixels labelled.
        let mut free = vec![0u8; wq * hq];
        for j in 0..hq {
            for i in 0..wq {
                let d = self.cell_disparity[j * wq + i];
                if !(d.is_finite() && d > 0.0) {
                    continue;
                }
                let mut labelled = 0;
                for y in CELL * j..CELL * (j + 1) {
                    for x in CELL * i..CELL * (i + 1) {
                        labelled += usize::from(labels[y * w + x] != 0);
                    }
                }
                free[j * wq + i] = u8::from(labelled * 2 <= CELL * CELL);
            }
        }
        let mut comps = RunLabeler::default();
        comps.label(&free, wq, hq);
        let nc = comps.sizes.len();
        let mut sums = vec![AffineSums::default(); nc];
        let mut log_bad = vec![0usize; nc];
        // Cells of the planes left out as too uncertain (`PlaneConfig::max_normal_sigma_deg`).
        let mut uncertain = vec![0usize; nc];
        let dropped = |i: usize| {
            self.cell_labels
                .get(i)
                .and_then(|&l| usize::from(l).checked_sub(1))
                .and_then(|p| self.dropped_uncertain.get(p))
                .is_some_and(|&d| d != 0)
        };
        // Cells given back by a plane as a piece it had taken in (`taken_in`).
        let mut given_back = vec![0usize; nc];
        let mut boxes = vec![[u32::MAX, u32::MAX, 0, 0]; nc];
        let (wp, hp) = (wq / PATCH, hq / PATCH);
        let mut patch_seen = vec![u32::MAX; wp * hp];
        let mut patches = vec![(0usize, 0usize); nc];
        for (ri, run) in comps.runs.iter().enumerate() {
            let c = comps.component[ri] as usize;
            let j = run.y as usize;
            grow(&mut boxes[c], run.x0 as usize, run.x1 as usize - 1, j);
            for i in run.x0 as usize..run.x1 as usize {
                let d = self.cell_disparity[j * wq + i];
                sums[c].add(i as f64, j as f64, f64::from(d));
                log_bad[c] += usize::from(self.cell_planar[j * wq + i] == 0);
                uncertain[c] += usize::from(dropped(j * wq + i));
                given_back[c] += usize::from(
                    self.given_back_cells
                        .get(j * wq + i)
                        .is_some_and(|&g| g != 0),
                );
                let (pi, pj) = (i / PATCH, j / PATCH);
                if pi < wp && pj < hp && patch_seen[pj * wp + pi] != c as u32 {
                    patch_seen[pj * wp + pi] = c as u32;
                    match self.patch_status.get(pj * wp + pi) {
                        Some(PatchStatus::Planar) => patches[c].0 += 1,
                        Some(PatchStatus::Residual) => {
                            patches[c].0 += 1;
                            patches[c].1 += 1;
                        }
                        _ => {}
                    }
                }
            }
        }
        let mut out = Vec::new();
        for c in 0..nc {
            let pixels = comps.sizes[c] * CELL * CELL;
            if pixels < min_pixels.max(1) {
                continue;
            }
            let s = &sums[c];
            let n = s.n.max(1.0);
            let log_frac = log_bad[c] as f64 / n;
            let res_frac = patches[c].1 as f64 / patches[c].0.max(1) as f64;
            let (rms, one_plane) = match s.solve() {
                Some(f) => (s.rms(&f), self.noise.planar(s.rss(&f), s.n)),
                None => (f64::NAN, false),
            };
            let reason = if self.noise_beyond_threshold {
                RejectReason::NoiseBeyondThreshold
            } else if uncertain[c] as f64 > 0.5 * n {
                RejectReason::Uncertain
            } else if given_back[c] as f64 > 0.5 * n {
                RejectReason::GivenBack
            } else if log_frac > 0.5 {
                RejectReason::NotPlanarLog
            } else if patches[c].0 > 0 && res_frac > 0.5 {
                RejectReason::ResidualNotWhite
            } else if one_plane {
                RejectReason::Unseeded
            } else {
                RejectReason::SeveralSurfaces
            };
            let b = boxes[c];
            out.push(RegionExplanation {
                pixels,
                bbox_px: [
                    b[0] as usize * CELL,
                    b[1] as usize * CELL,
                    b[2] as usize * CELL + CELL - 1,
                    b[3] as usize * CELL + CELL - 1,
                ],
                reason,
                log_rejected_fraction: log_frac,
                residual_rejected_fraction: res_frac,
                rms_px: rms,
            });
        }
        out.sort_by_key(|r| std::cmp::Reverse(r.pixels));
        out
    }
}

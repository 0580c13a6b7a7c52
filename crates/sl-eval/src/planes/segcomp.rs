//! The Hoover et al. (1996) segmentation comparison ("SegComp") at an overlap tolerance `T`.
//!
//! Given a ground-truth label image and a machine segmentation (0 = unlabelled in both), with
//! `O(m, g)` the number of pixels in machine region `m` and ground-truth region `g`:
//! - **correct detection** of `g` by `m`: `O ≥ T·|m|` and `O ≥ T·|g|`;
//! - **over-segmentation** of `g` into `m₁…m_x` (x ≥ 2): each `O(mᵢ, g) ≥ T·|mᵢ|` and
//!   `Σ O(mᵢ, g) ≥ T·|g|`;
//! - **under-segmentation** of `g₁…g_x` (x ≥ 2) into `m`: each `O(m, gᵢ) ≥ T·|gᵢ|` and
//!   `Σ O(m, gᵢ) ≥ T·|m|`;
//! - **missed**: a ground-truth region in none of the above; **noise**: a machine region in none.
//!
//! Correct detections are classified first; regions in a correct detection take no further
//! part. Pixels outside `valid` (e.g. no depth) are ignored when counting sizes and overlaps.

use std::collections::HashMap;

use sl_core::Image;

use crate::error::{EvalError, Result};

/// The counts of a SegComp comparison.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SegCompScore {
    /// Ground-truth regions considered.
    pub gt_regions: usize,
    /// Machine regions considered.
    pub machine_regions: usize,
    /// Correct detections.
    pub correct: usize,
    /// Ground-truth regions over-segmented.
    pub over_segmented: usize,
    /// Machine regions that under-segment several ground-truth regions.
    pub under_segmented: usize,
    /// Ground-truth regions missed.
    pub missed: usize,
    /// Machine regions that are noise.
    pub noise: usize,
}

/// Compares a machine segmentation against the ground truth at tolerance `t` (0.5 < t ≤ 1;
/// Hoover et al. use 0.8). Ground-truth regions with fewer than `min_gt_pixels` valid pixels are
/// ignored (their pixels count as unlabelled).
pub fn segcomp(
    gt: &Image<u16>,
    seg: &Image<u16>,
    valid: Option<&[bool]>,
    t: f64,
    min_gt_pixels: usize,
) -> Result<SegCompScore> {
    segcomp_detail(gt, seg, valid, t, min_gt_pixels).map(|d| d.score)
}

/// A SegComp comparison with the regions behind the counts.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SegCompDetail {
    /// The counts.
    pub score: SegCompScore,
    /// The machine regions classified as noise: `(label, valid pixels)`, by label.
    pub noise_regions: Vec<(u16, usize)>,
    /// The ground-truth regions missed: `(label, valid pixels)`, by label.
    pub missed_regions: Vec<(u16, usize)>,
    /// The noise regions that detect a ground-truth region *below* `min_gt_pixels` correctly
    /// (`O ≥ T·|m|` and `O ≥ T·|g|`): `(label, valid pixels)`, by label. They are noise for the
    /// counts (that ground truth is not scored) but match a surface, so they are not spurious.
    pub small_surface_regions: Vec<(u16, usize)>,
    /// The noise regions that lie on one scored ground-truth region (`O ≥ T·|m|`) but cover
    /// too little of it (`O < T·|g|`) to detect it: pieces of one surface, not regions that
    /// span several. `(label, valid pixels)`, by label.
    pub partial_surface_regions: Vec<(u16, usize)>,
}

impl SegCompDetail {
    /// Noise regions of at least `min_pixels` that match no surface at all (not even one too
    /// small to be scored, see [`SegCompDetail::small_surface_regions`]): spurious planes.
    pub fn spurious(&self, min_pixels: usize) -> usize {
        self.noise_regions
            .iter()
            .filter(|(m, n)| {
                *n >= min_pixels && !self.small_surface_regions.iter().any(|(s, _)| s == m)
            })
            .count()
    }

    /// The spurious planes of [`SegCompDetail::spurious`] that are partial detections (see
    /// [`SegCompDetail::partial_surface_regions`]): a piece of one surface rather than a region
    /// spanning several. They stay spurious; this says what kind they are.
    pub fn spurious_partial(&self, min_pixels: usize) -> usize {
        self.noise_regions
            .iter()
            .filter(|(m, n)| {
                *n >= min_pixels
                    && !self.small_surface_regions.iter().any(|(s, _)| s == m)
                    && self.partial_surface_regions.iter().any(|(p, _)| p == m)
            })
            .count()
    }
}

/// [`segcomp`] with the lists of noise and missed regions.
pub fn segcomp_detail(
    gt: &Image<u16>,
    seg: &Image<u16>,
    valid: Option<&[bool]>,
    t: f64,
    min_gt_pixels: usize,
) -> Result<SegCompDetail> {
    if gt.dimensions() != seg.dimensions() {
        return Err(EvalError::SizeMismatch {
            expected_width: gt.width(),
            expected_height: gt.height(),
            width: seg.width(),
            height: seg.height(),
        });
    }
    if let Some(v) = valid
        && v.len() != gt.data().len()
    {
        return Err(EvalError::InvalidParameter(
            "valid mask has the wrong length".into(),
        ));
    }
    if !(t > 0.5 && t <= 1.0) {
        return Err(EvalError::InvalidParameter(format!(
            "tolerance {} must be in (0.5, 1]",
            sl_core::Compact(t)
        )));
    }
    let ok = |i: usize| valid.is_none_or(|v| v[i]);
    let mut gsize: HashMap<u16, usize> = HashMap::new();
    for (i, &g) in gt.data().iter().enumerate() {
        if g != 0 && ok(i) {
            *gsize.entry(g).or_default() += 1;
        }
    }
    let mut small: HashMap<u16, usize> = gsize.clone();
    gsize.retain(|_, n| *n >= min_gt_pixels.max(1));
    small.retain(|g, _| !gsize.contains_key(g));
    let mut msize: HashMap<u16, usize> = HashMap::new();
    let mut overlap: HashMap<(u16, u16), usize> = HashMap::new();
    let mut small_overlap: HashMap<(u16, u16), usize> = HashMap::new();
    for (i, (&g, &m)) in gt.data().iter().zip(seg.data()).enumerate() {
        if m == 0 || !ok(i) {
            continue;
        }
        *msize.entry(m).or_default() += 1;
        if g != 0 && gsize.contains_key(&g) {
            *overlap.entry((m, g)).or_default() += 1;
        } else if g != 0 {
            *small_overlap.entry((m, g)).or_default() += 1;
        }
    }
    let mut gkeys: Vec<u16> = gsize.keys().copied().collect();
    gkeys.sort_unstable();
    let mut mkeys: Vec<u16> = msize.keys().copied().collect();
    mkeys.sort_unstable();
    let o = |m: u16, g: u16| overlap.get(&(m, g)).copied().unwrap_or(0) as f64;
    let mut g_used: HashMap<u16, bool> = gkeys.iter().map(|&g| (g, false)).collect();
    let mut m_used: HashMap<u16, bool> = mkeys.iter().map(|&m| (m, false)).collect();
    let mut score = SegCompScore {
        gt_regions: gkeys.len(),
        machine_regions: mkeys.len(),
        ..Default::default()
    };
    // Correct detections (at T > 0.5 each region has at most one partner).
    for &g in &gkeys {
        for &m in &mkeys {
            if m_used[&m] {
                continue;
            }
            let ov = o(m, g);
            if ov >= t * msize[&m] as f64 && ov >= t * gsize[&g] as f64 {
                score.correct += 1;
                g_used.insert(g, true);
                m_used.insert(m, true);
                break;
            }
        }
    }
    // Over-segmentation of g.
    for &g in &gkeys {
        if g_used[&g] {
            continue;
        }
        let parts: Vec<u16> = mkeys
            .iter()
            .copied()
            .filter(|&m| !m_used[&m] && o(m, g) >= t * msize[&m] as f64 && o(m, g) > 0.0)
            .collect();
        let total: f64 = parts.iter().map(|&m| o(m, g)).sum();
        if parts.len() >= 2 && total >= t * gsize[&g] as f64 {
            score.over_segmented += 1;
            g_used.insert(g, true);
            for m in parts {
                m_used.insert(m, true);
            }
        }
    }
    // Under-segmentation into m.
    for &m in &mkeys {
        if m_used[&m] {
            continue;
        }
        let parts: Vec<u16> = gkeys
            .iter()
            .copied()
            .filter(|&g| !g_used[&g] && o(m, g) >= t * gsize[&g] as f64 && o(m, g) > 0.0)
            .collect();
        let total: f64 = parts.iter().map(|&g| o(m, g)).sum();
        if parts.len() >= 2 && total >= t * msize[&m] as f64 {
            score.under_segmented += 1;
            m_used.insert(m, true);
            for g in parts {
                g_used.insert(g, true);
            }
        }
    }
    let missed_regions: Vec<(u16, usize)> = gkeys
        .iter()
        .filter(|g| !g_used[g])
        .map(|g| (*g, gsize[g]))
        .collect();
    let noise_regions: Vec<(u16, usize)> = mkeys
        .iter()
        .filter(|m| !m_used[m])
        .map(|m| (*m, msize[m]))
        .collect();
    let small_surface_regions: Vec<(u16, usize)> = noise_regions
        .iter()
        .copied()
        .filter(|&(m, mn)| {
            small_overlap.iter().any(|(&(mm, g), &ov)| {
                mm == m && ov as f64 >= t * mn as f64 && ov as f64 >= t * small[&g] as f64
            })
        })
        .collect();
    let partial_surface_regions: Vec<(u16, usize)> = noise_regions
        .iter()
        .copied()
        .filter(|&(m, mn)| gkeys.iter().any(|&g| o(m, g) >= t * mn as f64))
        .collect();
    score.missed = missed_regions.len();
    score.noise = noise_regions.len();
    Ok(SegCompDetail {
        score,
        noise_regions,
        missed_regions,
        small_surface_regions,
        partial_surface_regions,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl FnMut(usize, usize) -> u16) -> Image<u16> {
        Image::from_fn(w, h, f)
    }

    #[test]
    fn correct_over_under_missed_noise() {
        // Ground truth: left half 1, right half 2.
        let gt = img(20, 10, |x, _| if x < 10 { 1 } else { 2 });
        // Perfect.
        let s = segcomp(&gt, &gt, None, 0.8, 1).unwrap();
        assert_eq!((s.correct, s.missed, s.noise), (2, 0, 0));
        // Left split into two, right merged with nothing: over-segmentation + correct.
        let over = img(
            20,
            10,
            |x, y| if x < 10 { if y < 5 { 5 } else { 6 } } else { 7 },
        );
        let s = segcomp(&gt, &over, None, 0.8, 1).unwrap();
        assert_eq!(
            (
                s.correct,
                s.over_segmented,
                s.under_segmented,
                s.missed,
                s.noise
            ),
            (1, 1, 0, 0, 0)
        );
        // One machine region covering both: under-segmentation.
        let under = img(20, 10, |_, _| 3);
        let s = segcomp(&gt, &under, None, 0.8, 1).unwrap();
        assert_eq!(
            (s.correct, s.under_segmented, s.missed, s.noise),
            (0, 1, 0, 0)
        );
        // Right half only 50 % labelled, plus a noise region in the unlabelled area: right is
        // missed, and both right-side machine regions are noise.
        let gt3 = img(20, 10, |x, _| {
            if x < 10 {
                1
            } else if x < 15 {
                2
            } else {
                0
            }
        });
        let partial = img(20, 10, |x, y| {
            if x < 10 {
                1
            } else if y < 3 && x < 15 {
                2
            } else if x >= 15 {
                9
            } else {
                0
            }
        });
        let s = segcomp(&gt3, &partial, None, 0.8, 1).unwrap();
        assert_eq!((s.correct, s.missed, s.noise), (1, 1, 2));
        let d = segcomp_detail(&gt3, &partial, None, 0.8, 1).unwrap();
        assert_eq!(d.noise_regions, vec![(2, 15), (9, 50)]);
        assert_eq!(d.missed_regions, vec![(2, 50)]);
        assert_eq!((d.spurious(16), d.spurious(15)), (1, 2));
        // Region 2 lies on ground-truth region 2 but covers 30 % of it: a partial detection;
        // region 9 lies on no scored surface.
        assert_eq!(d.partial_surface_regions, vec![(2, 15)]);
        assert_eq!((d.spurious_partial(15), d.spurious_partial(16)), (1, 0));
        // The valid mask removes pixels from both images.
        let valid: Vec<bool> = (0..200).map(|i| (i % 20) < 10 || (i / 20) < 3).collect();
        let s = segcomp(&gt3, &partial, Some(&valid), 0.8, 1).unwrap();
        assert_eq!((s.correct, s.missed), (2, 0));
        assert!(segcomp(&gt, &img(5, 5, |_, _| 0), None, 0.8, 1).is_err());
    }

    #[test]
    fn a_region_on_a_surface_too_small_to_score_is_noise_but_not_spurious() {
        // Ground truth: a large region 1 (x < 16) and a small region 2 (x ≥ 16, 40 px).
        let gt = img(20, 10, |x, _| if x < 16 { 1 } else { 2 });
        // The machine finds both; region 2 is below the 50-pixel cut.
        let d = segcomp_detail(&gt, &gt, None, 0.8, 50).unwrap();
        assert_eq!(
            (d.score.gt_regions, d.score.correct, d.score.noise),
            (1, 1, 1)
        );
        assert_eq!(d.noise_regions, vec![(2, 40)]);
        assert_eq!(d.small_surface_regions, vec![(2, 40)]);
        assert_eq!(d.spurious(10), 0);
        // A machine region straddling both surfaces matches neither: spurious.
        let gt = img(40, 10, |x, _| if x < 36 { 1 } else { 2 });
        let straddle = img(40, 10, |x, _| if x < 32 { 1 } else { 3 });
        let d = segcomp_detail(&gt, &straddle, None, 0.8, 50).unwrap();
        assert_eq!(
            (d.score.correct, d.noise_regions.clone()),
            (1, vec![(3, 80)])
        );
        assert!(d.small_surface_regions.is_empty());
        assert_eq!(d.spurious(10), 1);
        // Half of it on each surface: not a piece of one.
        assert!(d.partial_surface_regions.is_empty());
        assert_eq!(d.spurious_partial(10), 0);
    }
}

//! Occlusion bands: per row, the runs of invalid pixels between a foreground pixel and a much
//! deeper background pixel, by side, with the projector shadow their depths predict.

use serde::Serialize;
use sl_core::DepthImage;

use super::{WidthStats, median};

/// Invalid bands on one side of foreground objects.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SideBands {
    /// Widths of the invalid runs.
    pub widths: WidthStats,
    /// Median width of the projector shadow predicted from the bounding depths,
    /// `f·B·(1/Z_fg − 1/Z_bg)`, pixels (NaN without runs).
    pub median_shadow_px: f64,
    /// Edges with this jump and no invalid pixel between foreground and background.
    pub direct_edges: usize,
    /// Median depth of the foreground pixel bounding the bands, metres (NaN without runs).
    pub median_fg_m: f64,
    /// Median depth of the background pixel bounding the bands, metres (NaN without runs).
    pub median_bg_m: f64,
    /// Every edge of this side (a band or direct) by the projector shadow its two depths
    /// predict, in the bins of [`SHADOW_BINS_PX`]: how many edges, how many with a band. A
    /// sensor that invalidated the pixels beside every depth edge would put a band at most
    /// edges of every bin; the projector's shadow alone only where the predicted shadow is
    /// wider than what the matcher fills (docs/NOISE_MODEL.md).
    pub by_shadow: Vec<ShadowBin>,
}

/// Upper edges of the predicted-shadow bins of [`SideBands::by_shadow`], pixels (the last bin
/// is open).
pub const SHADOW_BINS_PX: [f64; 4] = [2.0, 5.0, 10.0, f64::INFINITY];

/// The edges of one side whose predicted projector shadow lies in one bin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ShadowBin {
    /// Upper edge of the bin, pixels (the lower is the previous bin's; `inf` for the last).
    pub upper_px: f64,
    /// Edges in the bin.
    pub edges: usize,
    /// Of them, edges with an invalid band.
    pub with_band: usize,
}

impl ShadowBin {
    /// Share of the bin's edges with a band (NaN without edges).
    pub fn share(&self) -> f64 {
        if self.edges == 0 {
            f64::NAN
        } else {
            self.with_band as f64 / self.edges as f64
        }
    }
}

/// Invalid bands at occlusion edges.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OcclusionBands {
    /// Bands on the left of foreground objects (the background is further left).
    pub left: SideBands,
    /// Bands on the right of foreground objects.
    pub right: SideBands,
}

/// The edges of one side of foreground objects, as they are found.
struct SideEdges {
    /// Per band: its width, the predicted shadow, the foreground and background depths.
    widths: Vec<f64>,
    shadows: Vec<f64>,
    fg: Vec<f64>,
    bg: Vec<f64>,
    /// Edges with no invalid pixel between foreground and background.
    direct: usize,
    bins: [ShadowBin; SHADOW_BINS_PX.len()],
}

impl SideEdges {
    fn new() -> Self {
        Self {
            widths: Vec::new(),
            shadows: Vec::new(),
            fg: Vec::new(),
            bg: Vec::new(),
            direct: 0,
            bins: SHADOW_BINS_PX.map(|upper_px| ShadowBin {
                upper_px,
                edges: 0,
                with_band: 0,
            }),
        }
    }

    /// An edge between foreground depth `fg` and background depth `bg`, `run` invalid pixels
    /// apart, whose projector shadow is predicted `shadow` pixels wide.
    fn add(&mut self, run: usize, shadow: f64, fg: f64, bg: f64) {
        let i = SHADOW_BINS_PX
            .iter()
            .position(|u| shadow < *u)
            .unwrap_or(SHADOW_BINS_PX.len() - 1);
        self.bins[i].edges += 1;
        self.bins[i].with_band += usize::from(run > 0);
        if run == 0 {
            self.direct += 1;
        } else {
            self.widths.push(run as f64);
            self.shadows.push(shadow);
            self.fg.push(fg);
            self.bg.push(bg);
        }
    }

    fn finish(self) -> SideBands {
        SideBands {
            widths: WidthStats::from_widths(self.widths),
            median_shadow_px: median(self.shadows),
            direct_edges: self.direct,
            median_fg_m: median(self.fg),
            median_bg_m: median(self.bg),
            by_shadow: self.bins.to_vec(),
        }
    }
}

/// The invalid bands at occlusion edges, per row (see the module documentation).
pub fn occlusion_bands(
    depth: &DepthImage,
    fb_px_m: f64,
    jump_m: f64,
    max_band_px: usize,
) -> OcclusionBands {
    let (w, h) = (depth.width(), depth.height());
    let zs = depth.data();
    let valid = |z: f32| z > 0.0 && z.is_finite();
    let (mut left, mut right) = (SideEdges::new(), SideEdges::new());
    for y in 0..h {
        let row = &zs[y * w..(y + 1) * w];
        let mut prev: Option<usize> = None;
        for (x, &z) in row.iter().enumerate() {
            if !valid(z) {
                continue;
            }
            if let Some(p) = prev {
                let (za, zb) = (f64::from(row[p]), f64::from(z));
                let run = x - p - 1;
                if run <= max_band_px {
                    let shadow = fb_px_m * (1.0 / za.min(zb) - 1.0 / za.max(zb));
                    if zb - za > jump_m {
                        // Foreground on the left: the band lies on its right.
                        right.add(run, shadow, za, zb);
                    } else if za - zb > jump_m {
                        left.add(run, shadow, zb, za);
                    }
                }
            }
            prev = Some(x);
        }
    }
    // Every depth here is valid (positive and finite), so the medians see no NaN.
    OcclusionBands {
        left: left.finish(),
        right: right.finish(),
    }
}

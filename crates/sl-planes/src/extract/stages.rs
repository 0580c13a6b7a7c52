//! Per-stage timing of an extraction ([`Stage`], [`StageTimes`]).

use super::*;

/// The stages of [`PlaneExtractor`], for [`StageTimes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Set-up of the input. The depth → disparity conversion and the 2×2 and 4×4 averaging
    /// are done with the LoG's input, so their time counts in [`Stage::Log`].
    Disparity,
    /// Depth → disparity and 2×2 / 4×4 averaging, box LoG, threshold and erosion (half
    /// resolution), and the planar cells.
    Log,
    /// Connected components (planar cells, free cells, coherence pieces) and the growth of
    /// the planes over the cells they explain.
    Components,
    /// Per-component robust affine fits.
    SeedFits,
    /// Merging of close planes and renumbering, and after the final pass the splitting of the
    /// planes across a crease, the optional giving back of the pieces a plane took in, and the
    /// joining of the pieces of bent surfaces.
    Merge,
    /// k-means assignment passes on the cells (searches, sums, refits).
    Refine,
    /// Full-resolution assignment with the final moments.
    FinalPass,
    /// Neighbourhood disambiguation of pixels that fit two planes.
    Disambiguate,
    /// Final refit, 3D planes, statistics and output labels.
    Output,
}

impl Stage {
    /// All stages in pipeline order.
    pub const ALL: [Stage; 9] = [
        Stage::Disparity,
        Stage::Log,
        Stage::Components,
        Stage::SeedFits,
        Stage::Merge,
        Stage::Refine,
        Stage::FinalPass,
        Stage::Disambiguate,
        Stage::Output,
    ];

    /// A short name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Disparity => "input set-up",
            Stage::Log => "disparity+log",
            Stage::Components => "components",
            Stage::SeedFits => "seed fits",
            Stage::Merge => "merge",
            Stage::Refine => "k-means refine",
            Stage::FinalPass => "final pass",
            Stage::Disambiguate => "disambiguate",
            Stage::Output => "output/stats",
        }
    }
}

/// Wall-clock time per stage of the last extraction, nanoseconds (see
/// [`PlaneExtractor::stage_times`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct StageTimes {
    ns: [u64; 9],
}

impl StageTimes {
    /// Nanoseconds spent in `stage`.
    pub fn ns(&self, stage: Stage) -> u64 {
        self.ns[stage as usize]
    }

    /// Total nanoseconds.
    pub fn total_ns(&self) -> u64 {
        self.ns.iter().sum()
    }

    pub(super) fn add(&mut self, stage: Stage, t0: &mut Instant) {
        let now = Instant::now();
        self.ns[stage as usize] += (now - *t0).as_nanos() as u64;
        *t0 = now;
    }
}

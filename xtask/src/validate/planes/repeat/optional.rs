//! The repeatability with the extractor's optional taken-in stage
//! (`PlaneConfig::give_back_taken_in`, off by default) beside the default's. Reported, not
//! checked.

use std::fmt::Write as _;

use anyhow::Result;
use sl_planes::PlaneConfig;

use super::{EXP, REPEAT_MIN_PIXELS, SeqResult, Sequence, run_sequence};
use crate::validate::Context;

/// Runs every sequence again with the taken-in stage and writes the two side by side.
pub(super) fn taken_in(
    ctx: &mut Context,
    md: &mut String,
    seqs: &[Sequence],
    default: &[SeqResult],
) -> Result<()> {
    let mut cfg = PlaneConfig::default();
    cfg.give_back_taken_in = true;
    let _ = write!(
        md,
        "\n**With the pieces a plane took in given back** (`PlaneConfig::give_back_taken_in`, \
         off by default; `sl-planes/src/extract/taken_in.rs`): 8 × 8-pixel blocks of a plane's \
         pixels off a quadratic fit of the whole plane and off the blocks around them by more than \
         the noise model's 99.9 % bound (grown over adjacent blocks beyond its 99 % bound), in \
         connected pieces of at least `min_piece_pixels`, are left unlabelled and the \
         plane refitted. Planes shrink with it, and some fall below the benchmark's \
         {REPEAT_MIN_PIXELS} px: compare the counts found again as well as the shares. \
         Reported, not checked.\n\n\
         | sequence | k | default: tested | found again | with the stage: tested | found again | pixels |\n|---|---|---|---|---|---|---|\n",
    );
    for (seq, base) in seqs.iter().zip(default) {
        let r = run_sequence(seq, 1, cfg)?;
        for ((k, g), (_, b)) in r.gaps.iter().zip(&base.gaps) {
            let _ = writeln!(
                md,
                "| {} | {k} | {} | {} ({:.1} %) | {} | {} ({:.1} %) | {:.1} % |",
                r.name,
                b.planes,
                b.repeated,
                100.0 * b.plane_rate(),
                g.planes,
                g.repeated,
                100.0 * g.plane_rate(),
                100.0 * g.pixel_rate()
            );
            ctx.row(
                EXP,
                &format!("{} taken-in given back repeat k={k} planes", r.name),
                g.plane_rate(),
                "",
            );
        }
    }
    Ok(())
}

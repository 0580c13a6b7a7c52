//! Faster motion (issue 13): the real sequences with only every k-th frame (the same views
//! with k times the motion between frames; TUM fr1/rpy-200 up to about 16° at k = 4), through
//! `Reconstruction` as `sldepth track` runs them (the preset's lens model, the multi-scale
//! prefilter, timestamps k frame intervals apart), with a global shutter and with the preset's
//! rolling-shutter readout (the Kinect's, [`sl_core::preset::KINECT_READOUT_S`]; what `sldepth
//! track` and Python's `Tracker` model by default against the fused model).
//!
//! Why: the rest of fr1/rpy beyond the 200 frames of `../shared/data` turns faster (motion
//! capture, 0.1 s windows: 67 °/s on average and 107 °/s at the 90th percentile, against 57 and
//! 88 °/s over the first 200 frames), and a recording at 15 frames/s, or one that drops frames,
//! has twice the motion between frames. Until session 40 the global shutter tracked every 2nd
//! and 3rd TUM frame with no frame lost; the agreement rules of sessions 39–41 (planes and
//! samples on no plane vouch only as far as they agree with the fused model) lose frames there,
//! where the readout's skew differs from frame to frame.
//!
//! **Checks** (the default): with the preset's readout, every k-th frame of each sequence, for
//! every k of the table, tracked with no frame lost and in one fragment (until session 62 the
//! every 2nd frame only: TUM's every 4th lost 7 frames and started a second fragment before the
//! relocalisation against keyframes). The global-shutter rows are reported, and so are TUM's
//! every 5th and 6th frame (since session 84 a frame whose plane-based alignments the two frames
//! cannot tell apart is aligned from each against the model: at k = 5 one lost frame fewer).

use anyhow::Result;
use sl_core::{CameraToWorld, DepthImage};
use sl_track::ReconstructionConfig;

use super::super::Context;
use super::fragments::{prepared, run};

/// The largest k whose rows are checks; beyond it (TUM's every 5th and 6th frame: a median
/// 10° and 12° between frames, 21° and 19° at the fastest) the rows are reported.
const CHECKED_UP_TO: usize = 4;

pub(super) fn run_section(ctx: &mut Context) -> Result<String> {
    if ctx.quick() {
        return Ok(String::new());
    }
    // Each sequence, its camera preset and the k tried (7-Scenes has 50 frames).
    let sequences = [
        (
            sl_testkit::tum_rpy_200_sequence(200).filter(|s| s.frames.len() == 200),
            "tum-fr1",
            &[1usize, 2, 3, 4, 5, 6][..],
        ),
        (
            sl_testkit::seven_scenes_sequence(50).filter(|s| s.frames.len() == 50),
            "7-scenes",
            &[1, 2, 3][..],
        ),
    ];
    let mut md = String::from(
        "\n**Faster motion**: the real sequences with only every k-th frame (k times the motion \
         between frames; the rest of TUM fr1/rpy, beyond these 200 frames, turns about 1.2× \
         faster), tracked as `sldepth track` does (the preset's lens model, multi-scale \
         prefilter, frame to model, new fragment after 1 s), with a global shutter and with the \
         preset's rolling-shutter readout (the default). ATE over the poses in fragment 0's \
         world, against the motion capture (TUM) or the data set's KinectFusion poses \
         (7-Scenes). With the readout, no frame lost and one fragment is checked up to \
         every 4th frame; TUM's every 5th and 6th are reported.\n\n\
         | sequence | every k-th frame | shutter | frames | lost | fragments | ATE (cm) |\n|---|---|---|---|---|---|---|\n",
    );
    for (seq, preset, every) in sequences {
        let Some(seq) = seq else { continue };
        let cam = seq.camera;
        let frames_all = prepared(&seq, preset)?;
        let readout_s = sl_core::preset::find(preset)?.rolling_shutter_readout_s;
        for &k in every {
            let frames: Vec<(&DepthImage, Option<f64>)> = frames_all
                .iter()
                .step_by(k)
                .map(|(d, s)| (d, Some(*s)))
                .collect();
            let truth: Vec<CameraToWorld> = seq.frames.iter().step_by(k).map(|f| f.1).collect();
            for (label, readout) in [("global", 0.0), ("readout (default)", readout_s)] {
                let mut cfg = ReconstructionConfig::default_for(cam.sensor);
                cfg.tracker.rolling_shutter_readout_s = readout;
                let r = run(cam, cfg, &frames, k as u32)?;
                let ate = super::ate_m(&truth, &r.poses);
                md.push_str(&format!(
                    "| {} | {k} | {label} | {} | {} | {} | {:.2} |\n",
                    seq.name,
                    frames.len(),
                    r.lost,
                    r.fragments,
                    ate * 1e2
                ));
                let key = if readout > 0.0 { "readout" } else { "global" };
                let group = format!("track-faster-{}", seq.name);
                ctx.row(
                    &group,
                    &format!("every {k} {key} lost"),
                    r.lost as f64,
                    "frames",
                );
                ctx.row(&group, &format!("every {k} {key} ate"), ate * 1e2, "cm");
                if readout > 0.0 && k <= CHECKED_UP_TO {
                    ctx.check(
                        format!(
                            "faster motion: {}, {}, default readout: no frame lost, one fragment",
                            seq.name,
                            every_kth(k)
                        ),
                        r.lost == 0 && r.fragments == 1,
                        format!("{} lost, {} fragments", r.lost, r.fragments),
                    );
                }
            }
        }
    }
    Ok(md)
}

/// "every frame", "every 2nd frame", "every 3rd frame", "every 4th frame", …
fn every_kth(k: usize) -> String {
    match k {
        1 => "every frame".to_string(),
        2 => "every 2nd frame".to_string(),
        3 => "every 3rd frame".to_string(),
        _ => format!("every {k}th frame"),
    }
}

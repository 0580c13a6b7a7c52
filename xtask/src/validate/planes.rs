//! Section 3.4–3.5 of the paper: plane extraction with a fixed threshold in disparity
//! (Figures 8–9 as numbers) and motion from planes (Figure 10).
//!
//! 1. Simulated scenes with ground-truth labels (`sl-noise`): `three-planes` (the paper's
//!    Figure 8: table A and book B 1 cm apart ~0.6 m away, wall C ~3 m away), `corridor` (floor,
//!    ceiling, walls from 0.6 to 4.5 m), `boxes` and `figure-walls`. Scored with the Hoover et
//!    al. SegComp metric at 80 % overlap (ground-truth regions under 500 valid pixels ignored)
//!    for the disparity method and sequential metric RANSAC at 5 mm and 20 mm.
//!    Then the randomised room benchmark (issue 12, `rooms`): 60 seeded rooms and corridors
//!    (`sl_noise::sim::room_scene`) through the realistic simulator, SegComp for ground-truth
//!    planes of at least 2,000 pixels and spurious planes, ours and metric RANSAC.
//! 2. Real frames (TUM fr1/rpy, NYU raw disparity, 7-Scenes): overlays and timings; then the
//!    repeatability benchmark (issue 12, `repeat`): planes of frame i found again in frame i + k
//!    (k = 1, 5, 10) with the ground-truth poses, TUM fr1/rpy 200 and 7-Scenes, beside what
//!    the data themselves allow (`repeat::same_patch`: the same pixels fitted in both frames).
//! 3. Motion on TUM fr1/rpy pairs 5–20 frames apart (rotations of 8–43°): rotation error against
//!    motion capture for the identity (initial error), plane matching alone, the plane estimate
//!    verified against the depth data (or "undetermined"), and planes + point-to-plane ICP
//!    (`refine_motion_icp_verified`: the ICP pose only when the depth data accept it, else the
//!    plane estimate; ground truth never enters that decision).
//!
//! Ground-truth frame convention: TUM's `groundtruth.txt` gives the camera-to-world pose of
//! the colour camera's optical frame. The relative motion of frame j in frame i's camera
//! coordinates is `T_i⁻¹·T_j` (rotation `R_i⁻¹·R_j`), which is exactly our convention
//! `X_a = R·X_b + t`. The rotation error is the angle of `R_est⁻¹·R_gt`. We estimate in the
//! depth camera's frame; if it is rotated by `Q` from the colour frame, our estimate targets
//! `Q·R_gt·Q⁻¹`, whose angle equals that of `R_gt` and whose difference from `R_gt` is at most
//! about `2·sin(θ/2)·∠Q` (θ the motion): for the Kinect's sub-degree depth–colour rotation and
//! θ ≈ 20° that is below 0.1°, so the comparison is fair to ~0.1°.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context as _, Result};
use sl_core::{Camera, DepthImage, Image};
use sl_eval::planes::{SegCompScore, overlay, segcomp};
use sl_noise::sim::{KinectSimulator, named_scene};
use sl_planes::{PlaneConfig, PlaneExtractor, PlaneSegmentation, RansacConfig, metric_ransac};
use sl_track::{
    IcpConfig, IcpOutcome, MotionConfidence, MotionConfig, MotionFrame, Verification, VerifyConfig,
    estimate_motion, estimate_motion_verified, icp_point_to_plane, refine_motion_icp_verified,
};

use super::Context;

mod dark;
mod noisier;
mod repeat;
mod rooms;

const EXP: &str = "planes";
/// Ground-truth regions smaller than this (valid pixels) are ignored by SegComp.
const MIN_GT_PIXELS: usize = 500;
/// The SegComp overlap tolerance.
const TOLERANCE: f64 = 0.8;

/// Runs the experiment.
pub fn run(ctx: &mut Context) -> Result<()> {
    synthetic(ctx)?;
    rooms::rooms(ctx)?;
    real(ctx)?;
    repeat::repeat(ctx)?;
    motion(ctx)?;
    Ok(())
}

fn score_line(s: &SegCompScore) -> String {
    format!(
        "{} | {} | {} | {} | {} | {}",
        s.gt_regions, s.correct, s.over_segmented, s.under_segmented, s.missed, s.noise
    )
}

/// Keeps only the listed ground-truth labels.
fn restrict(gt: &Image<u16>, keep: &[u16]) -> Image<u16> {
    gt.map(|l| if keep.contains(l) { *l } else { 0 })
}

fn save_overlay(path: &Path, seg: &PlaneSegmentation, base: &[u8]) -> Result<()> {
    let (w, h) = seg.labels.dimensions();
    let rgb = overlay::overlay_rgb(&seg.labels, base, 0.6).context("overlay size")?;
    let px: Vec<[u8; 3]> = rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    sl_io::write_rgb_png(path, &Image::from_vec(w, h, px)?)?;
    Ok(())
}

fn synthetic(ctx: &mut Context) -> Result<()> {
    synthetic_with(ctx, "white", KinectSimulator::kinect_v1().white())?;
    synthetic_with(ctx, "realistic", KinectSimulator::kinect_v1())
}

/// The SegComp table on one noise model: `white` (the paper's; the checks) or `realistic`
/// (issue 11; reported beside it, not checked).
fn synthetic_with(ctx: &mut Context, noise: &str, sim: KinectSimulator) -> Result<()> {
    let white = noise == "white";
    let mut md = String::new();
    if !white {
        md.push_str(
            "The realistic simulator (issue 11: correlated block-matching error, occlusion \
             bands, drop-outs; docs/NOISE_MODEL.md), same scenes, seed and scoring as the \
             white-noise table; reported, not checked.\n\n",
        );
    }
    md.push_str(
        "Simulated Kinect frames (σ_D = 0.07 px, 1/8 px quantisation, 1 mm depth rounding) with \
         ground-truth labels; SegComp (Hoover et al.) at 80 % overlap, ground-truth regions \
         under 500 pixels ignored.\n\n| scene | method | GT regions | correct | over | under | missed | noise | ms |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    let prefix = if white {
        String::new()
    } else {
        format!("{noise}: ")
    };
    let scenes: &[&str] = if ctx.quick() {
        &["three-planes", "corridor"]
    } else {
        &["three-planes", "corridor", "boxes", "figure-walls"]
    };
    for &name in scenes {
        let ns = named_scene(name)?;
        let cam = Camera {
            intrinsics: ns.intrinsics,
            sensor: sim.sensor,
        };
        let frame = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 11);
        let valid: Vec<bool> = frame.depth.data().iter().map(|&z| z > 0.0).collect();
        let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
        let t = Instant::now();
        let disp = ex.extract_depth(&frame.depth, &cam)?;
        let disp_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut results = vec![("disparity".to_string(), disp, disp_ms)];
        for t_mm in [5.0, 20.0] {
            let t = Instant::now();
            let seg = metric_ransac(&frame.depth, &cam, &{
                let mut c = RansacConfig::default();
                c.threshold_m = t_mm / 1000.0;
                c
            })?;
            results.push((
                format!("metric-ransac {t_mm} mm"),
                seg,
                t.elapsed().as_secs_f64() * 1e3,
            ));
        }
        let base = overlay::depth_to_rgb(&frame.depth);
        for (method, seg, ms) in &results {
            let s = segcomp(
                &frame.labels,
                &seg.labels,
                Some(&valid),
                TOLERANCE,
                MIN_GT_PIXELS,
            )?;
            let _ = writeln!(md, "| {name} | {method} | {} | {ms:.1} |", score_line(&s));
            let tag = method.replace(' ', "-");
            for (metric, v) in [
                ("correct", s.correct),
                ("over", s.over_segmented),
                ("under", s.under_segmented),
                ("missed", s.missed),
                ("noise", s.noise),
            ] {
                ctx.row(
                    EXP,
                    &format!("{prefix}{name} {tag} {metric}"),
                    v as f64,
                    "regions",
                );
            }
            if white {
                save_overlay(
                    &ctx.out_dir().join(format!("planes-{name}-{tag}.png")),
                    seg,
                    &base,
                )?;
            }
        }
        if white && name == "three-planes" {
            three_planes_checks(ctx, &ns, &frame.labels, &valid, &results)?;
        }
        let _ = writeln!(md);
    }
    if white {
        md.push_str(
            "\nOverlays: `planes-<scene>-<method>.png` (grey = not on a plane).\n\n\
             ![three-planes, disparity](planes-three-planes-disparity.png) \
             ![three-planes, RANSAC 5 mm](planes-three-planes-metric-ransac-5-mm.png) \
             ![three-planes, RANSAC 20 mm](planes-three-planes-metric-ransac-20-mm.png)\n",
        );
        ctx.section("Plane extraction on simulated scenes (Figure 8)", md);
    } else {
        ctx.section("Plane extraction on the realistic simulator (issue 11)", md);
    }
    Ok(())
}

/// Per-plane checks on the Figure 8 scene: the disparity method detects A, B and C correctly;
/// metric RANSAC fails on C at 5 mm and merges A and B at 20 mm (the paper's two failures).
fn three_planes_checks(
    ctx: &mut Context,
    ns: &sl_noise::sim::NamedScene,
    gt: &Image<u16>,
    valid: &[bool],
    results: &[(String, PlaneSegmentation, f64)],
) -> Result<()> {
    let find = |prefix: &str| {
        ns.label_names
            .iter()
            .find(|(_, n)| n.starts_with(prefix))
            .map(|(l, _)| *l)
    };
    let (Some(a), Some(b), Some(c)) = (find("plane A"), find("plane B"), find("plane C")) else {
        ctx.check(
            "three-planes labels",
            false,
            "scene lacks plane A/B/C labels",
        );
        return Ok(());
    };
    let one = |seg: &PlaneSegmentation, l: u16| -> Result<bool> {
        Ok(segcomp(
            &restrict(gt, &[l]),
            &seg.labels,
            Some(valid),
            TOLERANCE,
            MIN_GT_PIXELS,
        )?
        .correct
            == 1)
    };
    let d = &results[0].1;
    let (da, db, dc) = (one(d, a)?, one(d, b)?, one(d, c)?);
    ctx.check(
        "disparity method detects planes A, B and C correctly (SegComp 80 %)",
        da && db && dc,
        format!("A {da}, B {db}, C {dc}; {} planes", d.planes.len()),
    );
    let r5 = &results[1].1;
    let (a5, b5, c5) = (one(r5, a)?, one(r5, b)?, one(r5, c)?);
    ctx.check(
        "metric RANSAC 5 mm fails on the far plane C",
        !c5,
        format!("A {a5}, B {b5}, C {c5}"),
    );
    let r20 = &results[2].1;
    let ab = segcomp(
        &restrict(gt, &[a, b]),
        &r20.labels,
        Some(valid),
        TOLERANCE,
        MIN_GT_PIXELS,
    )?;
    let c20 = one(r20, c)?;
    ctx.check(
        "metric RANSAC 20 mm does not separate A from B",
        ab.correct < 2,
        format!("A+B: {ab:?}; C correct {c20}"),
    );
    Ok(())
}

fn tum_camera() -> Result<Camera> {
    Ok(Camera::preset("tum-fr1")?)
}

fn rgb_flat(path: &Path) -> Option<Vec<u8>> {
    let img = sl_io::read_rgb(path).ok()?;
    (img.dimensions() == (640, 480)).then(|| img.data().iter().flatten().copied().collect())
}

/// Times an extraction: the minimum over `reps` runs, ms, on one thread and on the caller's
/// pool.
fn timed(
    reps: usize,
    mut f: impl FnMut() -> Result<PlaneSegmentation> + Send,
) -> Result<(PlaneSegmentation, [f64; 2])> {
    // One thread (a pool of one: issue 12's budget is per frame on one core), then the
    // caller's pool (all threads), alternating.
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut best = [f64::INFINITY; 2];
    let mut out = None;
    for _ in 0..reps.max(1) {
        for (k, slot) in best.iter_mut().enumerate() {
            let t = Instant::now();
            let s = if k == 0 { one.install(&mut f)? } else { f()? };
            *slot = slot.min(t.elapsed().as_secs_f64() * 1e3);
            out = Some(s);
        }
    }
    Ok((out.context("no run")?, best))
}

fn real(ctx: &mut Context) -> Result<()> {
    let Some(data) = ctx.data_dir().map(Path::to_path_buf) else {
        ctx.section(
            "Plane extraction on real frames",
            "Skipped: ../shared/data not found.",
        );
        return Ok(());
    };
    let reps = if ctx.quick() { 3 } else { 15 };
    let mut md = String::from(
        "Default parameters (τ = 0.5 px residual, LoG threshold 0.1 px, σ = 2 px, ≥ 1000 px per plane). \
         Time: minimum of repeated runs, extraction only, on one thread and on all threads of a \
         shared 2-core machine.\n\n\
         | frame | planes | labelled % of valid | ms, one thread | ms, all threads |\n|---|---|---|---|---|\n",
    );
    let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
    let mut imgs = Vec::new();
    // TUM fr1/rpy, first associated frame, over its colour image.
    let tum_dir = data.join("tum-fr1-rpy");
    if let Ok(seq) = sl_io::trajectory::read_tum_associations(tum_dir.join("associations.txt"))
        && let Some(first) = seq.first()
    {
        let depth = sl_io::read_depth(
            &first.depth_path,
            &sl_io::ReadConfig::default().with_scale(5000.0),
        )?
        .depth;
        let cam = tum_camera()?;
        let (seg, ms) = timed(reps, || Ok(ex.extract_depth(&depth, &cam)?))?;
        let base = rgb_flat(&first.rgb_path).unwrap_or_else(|| overlay::depth_to_rgb(&depth));
        report_real(
            ctx,
            &mut md,
            "tum-fr1-rpy",
            &depth,
            &seg,
            ms,
            &base,
            &mut imgs,
        )?;
    }
    // NYU raw disparity, directly.
    let nyu = data.join("open3d-testdata/nyu-raw-disparity.pgm");
    if nyu.exists() {
        let raw = sl_io::read_nyu_raw(&nyu)?;
        let disp = sl_io::depth::nyu_raw_to_disparity(&raw, sl_io::depth::NYU_DOFF);
        let cam = Camera {
            intrinsics: sl_io::depth::nyu_intrinsics(),
            sensor: sl_io::depth::nyu_sensor_model(),
        };
        let (seg, ms) = timed(reps, || Ok(ex.extract_disparity(&disp, &cam)?))?;
        let depth = disp.to_depth(&cam.sensor);
        let base = overlay::depth_to_rgb(&depth);
        report_real(ctx, &mut md, "nyu-raw", &depth, &seg, ms, &base, &mut imgs)?;
    }
    // Depth-only frames, drawn over the depth (7-Scenes depth is not registered to colour):
    // (name, path under the data directory, units per metre, camera preset).
    let depth_only = [
        (
            "7scenes-redkitchen",
            "7scenes-redkitchen/frame-000150.depth.png",
            1000.0,
            "7-scenes",
        ),
        (
            "open3d-tum",
            "open3d-testdata/tum-depth.png",
            5000.0,
            "ros-default",
        ),
    ];
    for (name, rel, scale, preset) in depth_only {
        let path = data.join(rel);
        if !path.exists() {
            continue;
        }
        let depth =
            sl_io::read_depth(&path, &sl_io::ReadConfig::default().with_scale(scale))?.depth;
        let cam = Camera::preset(preset)?;
        let (seg, ms) = timed(reps, || Ok(ex.extract_depth(&depth, &cam)?))?;
        let base = overlay::depth_to_rgb(&depth);
        report_real(ctx, &mut md, name, &depth, &seg, ms, &base, &mut imgs)?;
    }
    md.push('\n');
    for i in &imgs {
        let _ = write!(md, "![{i}]({i}) ");
    }
    md.push_str(
        "\n\nOn real Kinect frames large surfaces are sometimes split into bands: the Kinect v1's \
         low-frequency depth distortion makes a real plane only approximately affine in disparity \
         (tenths of a pixel over the frame), which a fixed 0.5 px threshold resolves into several \
         planes with nearly equal normals.\n",
    );
    ctx.section("Plane extraction on real frames (Figure 9)", md);
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn report_real(
    ctx: &mut Context,
    md: &mut String,
    name: &str,
    depth: &DepthImage,
    seg: &PlaneSegmentation,
    ms: [f64; 2],
    base: &[u8],
    imgs: &mut Vec<String>,
) -> Result<()> {
    let labelled: usize = seg.planes.iter().map(|p| p.pixels).sum();
    let pct = 100.0 * labelled as f64 / depth.valid_count().max(1) as f64;
    let _ = writeln!(
        md,
        "| {name} | {} | {pct:.1} | {:.2} | {:.2} |",
        seg.planes.len(),
        ms[0],
        ms[1]
    );
    ctx.row(EXP, &format!("{name} planes"), seg.planes.len() as f64, "");
    ctx.row(EXP, &format!("{name} extraction time"), ms[0], "ms");
    ctx.row(
        EXP,
        &format!("{name} extraction time all threads"),
        ms[1],
        "ms",
    );
    let file = format!("planes-real-{name}.png");
    save_overlay(&ctx.out_dir().join(&file), seg, base)?;
    imgs.push(file);
    Ok(())
}

/// One TUM pair of the motion table.
struct PairResult {
    from: usize,
    to: usize,
    gt_deg: f64,
    /// Plane matching alone (identity prior): error and confidence.
    unverified: Option<(f64, MotionConfidence)>,
    /// Verified plane estimate: error, planes+ICP error (of the accepted pose: ICP's when the
    /// data accepted the refinement, else the plane estimate), the verification and the ICP
    /// outcome; or the reason it was refused.
    verified: std::result::Result<(f64, f64, Verification, IcpOutcome), String>,
    icp_only: f64,
    /// Extraction of both frames + verified motion, ms.
    planes_ms: f64,
    /// ICP from the plane estimate, ms.
    icp_ms: f64,
}

/// The TUM fr1/rpy pairs: `gap` frames apart from every 5th start frame, for gaps 5–20 (the
/// paper's pair 0 → 10 and the large rotations 10 → 20, 0 → 15, 0 → 20 among them).
fn motion_pairs(n: usize, quick: bool) -> Vec<(usize, usize)> {
    if quick {
        return [(0, 10), (10, 20), (0, 15), (0, 20)]
            .into_iter()
            .filter(|&(_, j)| j < n)
            .collect();
    }
    let mut out = Vec::new();
    for gap in [5, 10, 15, 20] {
        let mut i = 0;
        while i + gap < n {
            out.push((i, i + gap));
            i += 5;
        }
    }
    out
}

/// Bound on the planes+ICP error of every verified pair, degrees. The reference itself is
/// uncertain at fr1/rpy's angular speed (22.7° between frames 0 and 10, i.e. ~65°/s, so every
/// 10 ms of depth/motion-capture timing error is 0.65°: the nearest 100 Hz mocap sample is up
/// to 5 ms away and the Kinect's depth timestamps carry their own latency), plus the
/// depth-vs-colour camera rotation and ICP's residual on a rolling-shutter sensor under fast
/// motion: about 1–2° in all, bounded here by 3°.
const ICP_BOUND_DEG: f64 = 3.0;
/// The paper's plane-based error on its pair (teddy 204/207, against ICP), degrees.
const PAPER_DEG: f64 = 2.36;

fn motion(ctx: &mut Context) -> Result<()> {
    let Some(data) = ctx.data_dir().map(Path::to_path_buf) else {
        ctx.section("Motion from planes", "Skipped: ../shared/data not found.");
        return Ok(());
    };
    let dir = data.join("tum-fr1-rpy");
    let seq = sl_io::read_tum_sequence(&dir, 0.02)
        .with_context(|| format!("reading {}", dir.display()))?;
    let n = seq.frames.len();
    if n < 12 {
        ctx.section(
            "Motion from planes",
            format!("Skipped: only {n} TUM frames with poses."),
        );
        return Ok(());
    }
    let cam = tum_camera()?;
    let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
    let mcfg = MotionConfig::default();
    let vcfg = VerifyConfig::default();
    let icp_cfg = IcpConfig::default();
    let opts = sl_io::ReadConfig::default().with_scale(5000.0);
    // The frames are resampled into the pinhole image with the `tum-fr1` lens model, as
    // `sldepth motion --camera tum-fr1` does by default.
    let lens = sl_core::preset::find("tum-fr1")?
        .lens
        .map(|l| sl_core::Undistorter::new(&cam.intrinsics, &l));
    let read = |path: &Path| -> Result<sl_core::DepthImage> {
        let d = sl_io::read_depth(path, &opts)?.depth;
        Ok(match &lens {
            Some(u) => u.apply(&d)?,
            None => d,
        })
    };
    let mut results = Vec::new();
    for (i, j) in motion_pairs(n, ctx.quick()) {
        let (fa, fb) = (&seq.frames[i], &seq.frames[j]);
        let da = read(&fa.depth_path)?;
        let db = read(&fb.depth_path)?;
        let gt = fa.pose.inverse() * fb.pose;
        let err =
            |q: &sl_core::nalgebra::UnitQuaternion<f64>| q.angle_to(&gt.rotation()).to_degrees();
        let t0 = Instant::now();
        let sa = ex.extract_depth(&da, &cam)?;
        let sb = ex.extract_depth(&db, &cam)?;
        let verified = estimate_motion_verified(
            MotionFrame {
                depth: &da,
                planes: &sa.planes,
            },
            MotionFrame {
                depth: &db,
                planes: &sb.planes,
            },
            &cam,
            None,
            &mcfg,
            &vcfg,
        );
        let planes_ms = t0.elapsed().as_secs_f64() * 1e3;
        let unverified = estimate_motion(&sa.planes, &sb.planes, None, &mcfg)
            .ok()
            .map(|m| (err(&m.rotation), m.confidence));
        let icp_only = icp_point_to_plane(
            &da,
            &db,
            &cam,
            &sl_core::CameraToCamera::identity(),
            &icp_cfg,
        )
        .map_or(f64::NAN, |r| err(&r.pose.rotation()));
        let (verified, icp_ms) = match verified {
            Ok(m) => {
                let t1 = Instant::now();
                let outcome = refine_motion_icp_verified(
                    &da,
                    &db,
                    &cam,
                    &m,
                    &IcpConfig::refinement(),
                    &mcfg,
                    &vcfg,
                )?;
                let refined = err(&outcome.pose.rotation());
                let icp_ms = t1.elapsed().as_secs_f64() * 1e3;
                let Some(v) = m.verification.clone() else {
                    anyhow::bail!("a verified motion without its verification");
                };
                (Ok((err(&m.rotation), refined, v, outcome)), icp_ms)
            }
            Err(e) => (Err(e.to_string()), f64::NAN),
        };
        results.push(PairResult {
            from: i,
            to: j,
            gt_deg: gt.rotation_angle_deg(),
            unverified,
            verified,
            icp_only,
            planes_ms,
            icp_ms,
        });
    }
    motion_report(ctx, &results);
    Ok(())
}

fn motion_report(ctx: &mut Context, results: &[PairResult]) {
    let mut md = String::from(
        "TUM fr1/rpy (camera rolling/pitching/yawing in place), frame pairs `i → j` several \
         frames apart, resampled into the pinhole image with the `tum-fr1` lens model (as \
         `sldepth motion --camera tum-fr1` does); rotation error = angle of `R_est⁻¹·R_gt` against motion capture (see the \
         module docs for the frame convention). *GT* is the true rotation angle, i.e. the error \
         of the identity. *planes (unverified)* is plane matching alone with the small-motion \
         prior (`estimate_motion`), with its confidence flag. *planes* is the verified plane \
         estimate without any prior (`estimate_motion_verified`: every plane hypothesis is \
         checked against both depth maps; *undetermined* when no rotation explains the data, \
         two distinct ones do, or the shared view cannot pin the rotation down). *planes+ICP* \
         refines the verified estimate by point-to-plane ICP (`refine_motion_icp_verified`, \
         from the verified alignment with a 5 cm correspondence gate) and reports the accepted \
         pose: ICP's only when it is itself verified on both depth maps (≥ 90 % of the \
         overlapping points explained) and explains no smaller a share than the verified \
         estimate (up to 0.1 %), else the plane estimate; *ICP acc.* says which, with the \
         reason of a rejection, and *ICP inliers* is the share ICP's pose explains (decided on \
         the depth data, never on ground truth). *ICP only* starts ICP from the identity. *inliers* is the share of overlapping points the verified alignment \
         explains; *alt.* the largest share a rotation more than 15° away explains (another \
         hypothesis refined on the data, or the winner turned by 15° about a camera axis or a \
         plane normal) — a motion is verified only with inliers ≥ 90 % and alt. significantly \
         below 90 % (the upper end of its 99.9 % Wilson interval on the overlapping samples \
         under 90 %; 89 % of 500 samples is not). \
         *ms*: plane extraction of both frames + verified motion (and the ICP \
         refinement), debug-profile build on a shared 2-core machine.\n\n\
         | pair | GT ° | planes (unverified) ° | planes ° | planes+ICP ° | ICP acc. | ICP only ° | inliers % | ICP inliers % | alt. % | ms planes | ms ICP |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut undetermined = Vec::new();
    let (mut sums, mut count) = ([0.0f64; 4], 0usize);
    let mut worst_planes = 0.0f64;
    let mut worst_icp = 0.0f64;
    let mut icp_accepted = 0usize;
    for r in results {
        let unv = r.unverified.map_or("failed".to_string(), |(e, c)| {
            format!("{e:.2} ({})", c.as_str())
        });
        let pair = format!("{} → {}", r.from, r.to);
        match &r.verified {
            Ok((planes, refined, v, icp)) => {
                let alt = v.alternative_inlier_fraction.max(v.turned_inlier_fraction);
                let acc = match &icp.rejection {
                    None => "yes".to_string(),
                    Some(why) => format!("no ({})", why.as_str()),
                };
                let icp_inl = icp
                    .inlier_fraction_after
                    .map_or("–".to_string(), |f| format!("{:.1}", 100.0 * f));
                let _ = writeln!(
                    md,
                    "| {pair} | {:.2} | {unv} | {planes:.2} | {refined:.2} | {acc} | {:.2} | {:.1} | {icp_inl} | {:.1} | {:.0} | {:.0} |",
                    r.gt_deg,
                    r.icp_only,
                    100.0 * v.inlier_fraction,
                    100.0 * alt,
                    r.planes_ms,
                    r.icp_ms
                );
                icp_accepted += usize::from(icp.accepted);
                worst_planes = worst_planes.max(*planes);
                worst_icp = worst_icp.max(if refined.is_finite() {
                    *refined
                } else {
                    f64::INFINITY
                });
                if r.icp_only.is_finite() {
                    sums[0] += r.gt_deg;
                    sums[1] += planes;
                    sums[2] += refined;
                    sums[3] += r.icp_only;
                    count += 1;
                }
                ctx.row(EXP, &format!("tum {pair} planes error"), *planes, "deg");
                ctx.row(
                    EXP,
                    &format!("tum {pair} planes+ICP error"),
                    *refined,
                    "deg",
                );
                ctx.row(
                    EXP,
                    &format!("tum {pair} ICP accepted"),
                    f64::from(u8::from(icp.accepted)),
                    "",
                );
                if let Some(f) = icp.inlier_fraction_after {
                    ctx.row(EXP, &format!("tum {pair} ICP inlier fraction"), f, "");
                }
            }
            Err(reason) => {
                let _ = writeln!(
                    md,
                    "| {pair} | {:.2} | {unv} | undetermined | – | – | {:.2} | – | – | – | {:.0} | – |",
                    r.gt_deg, r.icp_only, r.planes_ms
                );
                undetermined.push(format!("- {pair}: {reason}"));
            }
        }
    }
    let verified = results.len() - undetermined.len();
    ctx.row(EXP, "tum pairs verified", verified as f64, "pairs");
    ctx.row(
        EXP,
        "tum pairs with ICP refinement accepted",
        icp_accepted as f64,
        "pairs",
    );
    ctx.row(
        EXP,
        "tum pairs undetermined",
        undetermined.len() as f64,
        "pairs",
    );
    let _ = writeln!(
        md,
        "\nICP refinement accepted by the depth data on {icp_accepted} of the {verified} verified \
         pairs (elsewhere planes+ICP is the plane estimate)."
    );
    if !undetermined.is_empty() {
        md.push_str("\nUndetermined pairs (the verified estimator's reason):\n\n");
        md.push_str(&undetermined.join("\n"));
        md.push('\n');
    }
    if count > 0 {
        let c = count as f64;
        let _ = writeln!(
            md,
            "\nMean over the {count} verified pairs: identity {:.2}°, planes {:.2}°, planes+ICP {:.2}°, ICP only {:.2}°; worst verified planes {worst_planes:.2}°, planes+ICP {worst_icp:.2}°. The paper (teddy frames 204/207, ICP as reference): 22.7° → 2.36°.",
            sums[0] / c,
            sums[1] / c,
            sums[2] / c,
            sums[3] / c
        );
        for (k, name) in ["identity", "planes", "planes+ICP", "ICP only"]
            .iter()
            .enumerate()
        {
            ctx.row(
                EXP,
                &format!("tum rotation error {name} (mean, verified pairs)"),
                sums[k] / c,
                "deg",
            );
        }
        ctx.check(
            "verified plane rotations beat the identity on TUM fr1/rpy (mean error)",
            sums[1] < sums[0],
            format!(
                "planes {:.2}° vs identity {:.2}° over {count} pairs",
                sums[1] / c,
                sums[0] / c
            ),
        );
    }
    let distinct = MotionConfig::default().distinct_deg;
    ctx.check(
        format!(
            "no verified plane rotation is off by more than distinct_deg = {distinct}° (the \
             verification rejects alternatives that far away)"
        ),
        verified > 0 && worst_planes < distinct,
        format!("worst verified planes error {worst_planes:.2}° over {verified} pairs"),
    );
    ctx.check(
        format!(
            "every verified pair: planes+ICP below {ICP_BOUND_DEG}° (motion-capture sync at \
             fr1/rpy's speed + ICP residual)"
        ),
        verified > 0 && worst_icp < ICP_BOUND_DEG,
        format!("worst planes+ICP error {worst_icp:.2}°"),
    );
    let paper = results.iter().find(|r| r.from == 0 && r.to == 10);
    let (ok, detail) = match paper.map(|r| &r.verified) {
        Some(Ok((planes, refined, _, _))) => (
            *refined < PAPER_DEG,
            format!("planes {planes:.2}°, planes+ICP {refined:.2}° (paper: 22.7° → {PAPER_DEG}°)"),
        ),
        Some(Err(reason)) => (false, format!("undetermined: {reason}")),
        None => (false, "pair 0 → 10 not evaluated".to_string()),
    };
    ctx.check(
        format!("TUM pair 0 → 10 (22.7°, the paper's case): planes+ICP below {PAPER_DEG}°"),
        ok,
        detail,
    );
    for (i, j) in [(10, 20), (0, 15), (0, 20)] {
        let Some(r) = results.iter().find(|r| r.from == i && r.to == j) else {
            continue;
        };
        let (ok, detail) = match &r.verified {
            Ok((planes, refined, _, _)) => (
                *planes < distinct && *refined < ICP_BOUND_DEG,
                format!("verified: planes {planes:.2}°, planes+ICP {refined:.2}°"),
            ),
            Err(reason) => (true, format!("reported undetermined: {reason}")),
        };
        ctx.check(
            format!(
                "large rotation {i} → {j} ({:.1}°): verified within the bounds ({distinct}°, \
                 planes+ICP {ICP_BOUND_DEG}°) or reported undetermined, never a wrong rotation",
                r.gt_deg
            ),
            ok,
            detail,
        );
    }
    ctx.section("Motion from planes (Figure 10)", md);
}

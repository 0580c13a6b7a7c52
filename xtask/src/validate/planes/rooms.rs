//! The randomised room benchmark (issue 12): `sl_noise::sim::room_scene` rooms and corridors
//! through the realistic simulator, scored with SegComp (Hoover et al., 80 % overlap) for every
//! ground-truth plane of at least 2,000 pixels, for the disparity method and metric RANSAC;
//! spurious planes (machine regions matching no ground truth) of at least 2,000 pixels counted.

use std::fmt::Write as _;
use std::time::Instant;

use anyhow::Result;
use sl_core::{Camera, Image};
use sl_eval::planes::{SegCompDetail, overlay, segcomp_detail};
use sl_noise::sim::{
    KinectSimulator, NoiseModel, ROOM_BENCHMARK_SEEDS, RealisticNoise, RoomKind, room_scene,
};

/// Room seeds examined while developing (session 11): failures looked at, nothing tuned.
const ROOM_EXAMINED_SEEDS: std::ops::Range<u64> = 60..300;
/// Room seeds never looked at during development.
pub(super) const ROOM_HELD_OUT_SEEDS: std::ops::Range<u64> = 1000..1240;
/// Room seeds of the other-camera table (session 12), never looked at before it.
const ROOM_CAMERA_SEEDS: std::ops::Range<u64> = 2000..2060;
/// Camera presets of the other-camera table: a PrimeSense, two RealSense and an OAK-D.
const ROOM_CAMERAS: [&str; 4] = ["primesense", "d435", "d415", "oak-d"];
/// Amplitudes of the low-frequency disparity distortion of the distortion table (pixels at the
/// image corner; `RealisticNoise::distortion_px`): Herrera et al.'s Kinect calibration and the
/// bend measured on TUM's largest planes (sessions 21 and 27: about 1·10⁻⁵ px/px², 0.9 px at the
/// corner for a radial bowl) span this range.
const ROOM_DISTORTION_PX: [f64; 2] = [0.5, 1.0];
use sl_planes::{PlaneConfig, PlaneExtractor, PlaneSegmentation, RansacConfig, metric_ransac};

use super::{EXP, TOLERANCE, save_overlay};
use crate::validate::Context;

/// An optional stage of the extractor: its config field, its tag in the results, and how to
/// switch it on.
type OptionalStage = (&'static str, &'static str, fn(&mut PlaneConfig));

/// Ground-truth planes smaller than this (valid pixels) are not scored; machine regions of at
/// least this size that match nothing are spurious.
pub const ROOM_MIN_PIXELS: usize = 2000;
/// The target: share of ground-truth planes detected correctly.
const TARGET_CORRECT: f64 = 0.95;

/// One method's result on one scene.
pub(super) struct Scored {
    detail: SegCompDetail,
    ms: f64,
}

/// Totals over the scenes.
#[derive(Default, Clone, Copy)]
pub(super) struct Totals {
    gt: usize,
    correct: usize,
    over: usize,
    under: usize,
    missed: usize,
    noise: usize,
    spurious: usize,
    /// Of the spurious planes, the pieces of one surface (`SegCompDetail::spurious_partial`).
    spurious_partial: usize,
    worst_ms: f64,
}

impl Totals {
    pub(super) fn add(&mut self, s: &Scored) {
        let c = &s.detail.score;
        self.gt += c.gt_regions;
        self.correct += c.correct;
        self.over += c.over_segmented;
        self.under += c.under_segmented;
        self.missed += c.missed;
        self.noise += c.noise;
        self.spurious += s.detail.spurious(ROOM_MIN_PIXELS);
        self.spurious_partial += s.detail.spurious_partial(ROOM_MIN_PIXELS);
        self.worst_ms = self.worst_ms.max(s.ms);
    }

    pub(super) fn line(&self, method: &str) -> String {
        format!(
            "| {method} | {} | {} ({:.1} %) | {} | {} | {} | {} | {} | {:.1} |",
            self.gt,
            self.correct,
            100.0 * self.correct as f64 / self.gt.max(1) as f64,
            self.over,
            self.under,
            self.missed,
            self.noise,
            self.spurious_cell(),
            self.worst_ms
        )
    }

    /// The spurious count, with how many of them are pieces of one surface.
    fn spurious_cell(&self) -> String {
        if self.spurious_partial == 0 {
            self.spurious.to_string()
        } else {
            format!("{} ({} partial)", self.spurious, self.spurious_partial)
        }
    }
}

fn score(gt: &Image<u16>, seg: &PlaneSegmentation, valid: &[bool], ms: f64) -> Result<Scored> {
    Ok(Scored {
        detail: segcomp_detail(gt, &seg.labels, Some(valid), TOLERANCE, ROOM_MIN_PIXELS)?,
        ms,
    })
}

/// The scores of one set of seeds.
struct SeedSet {
    ours: Totals,
    ransac: Totals,
    /// Per-scene table rows.
    per_scene: String,
    /// (correct fraction − 0.01 × spurious, seed), per scene.
    worst: Vec<(f64, u64)>,
}

/// Simulates and scores the scenes `seeds` with our extractor and metric RANSAC.
fn score_seeds(ex: &mut PlaneExtractor, seeds: std::ops::Range<u64>) -> Result<SeedSet> {
    score_seeds_through(ex, seeds, None, 0.0)
}

/// Room `seed` through `camera` (default: the Kinect sensor model at the room's focal length)
/// and the realistic simulator with a radial disparity bias of `distortion_px`: the frame, the
/// camera and the scene's kind.
fn room_frame(
    seed: u64,
    camera: Option<&Camera>,
    distortion_px: f64,
) -> Result<(sl_noise::sim::SimulatedFrame, Camera, &'static str)> {
    let rs = room_scene(seed)?;
    let cam = match camera {
        Some(c) => *c,
        None => {
            let mut sensor = sl_core::SensorModel::kinect_v1();
            sensor.focal_px = rs.intrinsics.fx;
            Camera {
                intrinsics: rs.intrinsics,
                sensor,
            }
        }
    };
    let mut noise = RealisticNoise::default();
    noise.distortion_px = distortion_px;
    let sim = KinectSimulator::with_sensor(cam.sensor).with_noise(NoiseModel::Realistic(noise));
    let frame = sim.simulate(&rs.scene, &cam.intrinsics, &rs.pose, seed);
    let kind = match rs.kind {
        RoomKind::Room => "room",
        RoomKind::Corridor => "corridor",
    };
    Ok((frame, cam, kind))
}

/// Our extractor's totals on the rooms `seeds` (Kinect cameras) with a low-frequency disparity
/// distortion of `distortion_px` at the image corner (0 = none).
fn score_ours(
    ex: &mut PlaneExtractor,
    seeds: impl IntoIterator<Item = u64>,
    distortion_px: f64,
) -> Result<Totals> {
    let mut t = Totals::default();
    for seed in seeds {
        let (frame, cam, _) = room_frame(seed, None, distortion_px)?;
        t.add(&extract_scored(ex, &frame, &cam)?);
    }
    Ok(t)
}

/// `frame` extracted by `ex` through `cam`, timed and scored against its ground truth.
pub(super) fn extract_scored(
    ex: &mut PlaneExtractor,
    frame: &sl_noise::sim::SimulatedFrame,
    cam: &Camera,
) -> Result<Scored> {
    let valid: Vec<bool> = frame.depth.data().iter().map(|&z| z > 0.0).collect();
    let start = Instant::now();
    let seg = ex.extract_depth(&frame.depth, cam)?;
    score(
        &frame.labels,
        &seg,
        &valid,
        start.elapsed().as_secs_f64() * 1e3,
    )
}

/// [`score_seeds`] through `camera` (its intrinsics and sensor model replace the room's
/// random 640×480 Kinect) when given, with a low-frequency disparity distortion of
/// `distortion_px` at the image corner (`RealisticNoise::distortion_px`; 0 = none).
fn score_seeds_through(
    ex: &mut PlaneExtractor,
    seeds: std::ops::Range<u64>,
    camera: Option<&Camera>,
    distortion_px: f64,
) -> Result<SeedSet> {
    let mut set = SeedSet {
        ours: Totals::default(),
        ransac: Totals::default(),
        per_scene: String::new(),
        worst: Vec::new(),
    };
    for seed in seeds {
        let (frame, cam, kind) = room_frame(seed, camera, distortion_px)?;
        let valid: Vec<bool> = frame.depth.data().iter().map(|&z| z > 0.0).collect();
        let t = Instant::now();
        let seg = ex.extract_depth(&frame.depth, &cam)?;
        let a = score(&frame.labels, &seg, &valid, t.elapsed().as_secs_f64() * 1e3)?;
        let t = Instant::now();
        let rseg = metric_ransac(&frame.depth, &cam, &RansacConfig::default())?;
        let b = score(
            &frame.labels,
            &rseg,
            &valid,
            t.elapsed().as_secs_f64() * 1e3,
        )?;
        set.ours.add(&a);
        set.ransac.add(&b);
        let (sa, sb) = (&a.detail.score, &b.detail.score);
        let _ = writeln!(
            set.per_scene,
            "| {seed} | {kind} | {:.0} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            cam.intrinsics.fx,
            sa.gt_regions,
            sa.correct,
            sa.over_segmented,
            sa.under_segmented,
            sa.missed,
            sa.noise,
            a.detail.spurious(ROOM_MIN_PIXELS),
            sb.correct,
            b.detail.spurious(ROOM_MIN_PIXELS),
        );
        let frac = sa.correct as f64 / sa.gt_regions.max(1) as f64
            - 0.01 * a.detail.spurious(ROOM_MIN_PIXELS) as f64;
        set.worst.push((frac, seed));
    }
    Ok(set)
}

/// Largest factor between the scatter of the planes' errors and their predicted uncertainty
/// (either way) that the calibration check accepts (the bound of the sl-planes unit test,
/// decided before either was run).
const CALIBRATION_FACTOR: f64 = 1.5;

/// Whether the extracted planes' `normal_sigma_deg` and `offset_sigma_m` describe their errors
/// on the simulated rooms `seeds`: every plane of at least `ROOM_MIN_PIXELS` whose pixels lie
/// (80 %) on one true surface, against that surface's exact plane (from the exact render).
fn uncertainty_calibration(
    ctx: &mut Context,
    md: &mut String,
    seeds: std::ops::Range<u64>,
) -> Result<()> {
    let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
    let (mut e2, mut s2, mut o2, mut so2, mut within) = (0.0, 0.0, 0.0, 0.0, 0usize);
    let mut planes = 0usize;
    for seed in seeds {
        let (frame, cam, _) = room_frame(seed, None, 0.0)?;
        let seg = ex.extract_depth(&frame.depth, &cam)?;
        let (k, w) = (&cam.intrinsics, cam.intrinsics.width);
        let (labels, truth) = (frame.labels.data(), frame.truth.data());
        // Pixels per (plane, true surface), then each plane's surface: the one under 80 % of
        // its pixels.
        let mut count = std::collections::HashMap::<(u16, u16), usize>::new();
        for (&l, &t) in seg.labels.data().iter().zip(labels) {
            if l != 0 && t != 0 {
                *count.entry((l, t)).or_default() += 1;
            }
        }
        let surface_of = |p: &sl_planes::PlaneInfo| {
            count
                .iter()
                .filter(|((l, _), _)| *l == p.id)
                .max_by_key(|((_, t), n)| (**n, *t))
                .filter(|(_, n)| **n as f64 >= 0.8 * p.pixels as f64)
                .map(|((_, t), _)| *t)
        };
        let tested: Vec<_> = seg
            .planes
            .iter()
            .filter(|p| p.pixels >= ROOM_MIN_PIXELS && p.normal_sigma_deg.is_finite())
            .filter_map(|p| Some((p, surface_of(p)?)))
            .collect();
        // The exact points of those surfaces, in one pass.
        let mut points = std::collections::HashMap::<u16, Vec<_>>::new();
        for &(_, t) in &tested {
            points.entry(t).or_default();
        }
        for (i, (l, &z)) in labels.iter().zip(truth).enumerate() {
            if z > 0.0
                && let Some(v) = points.get_mut(l)
            {
                v.push(k.back_project((i % w) as f64, (i / w) as f64, f64::from(z)));
            }
        }
        for (p, surface) in tested {
            let Some(fit) = points.get(&surface).and_then(|v| sl_core::fit_plane(v)) else {
                continue;
            };
            let exact = fit.plane.facing_origin();
            let err = p.plane.angle_to_deg(&exact);
            let off = exact
                .signed_distance_m(&p.plane.project(&p.centroid_m))
                .abs();
            e2 += err * err;
            s2 += p.normal_sigma_deg * p.normal_sigma_deg;
            o2 += off * off;
            so2 += p.offset_sigma_m * p.offset_sigma_m;
            within += usize::from(err <= 2.0 * p.normal_sigma_deg);
            planes += 1;
        }
    }
    let ratio = (e2 / s2.max(1e-30)).sqrt();
    let ratio_off = (o2 / so2.max(1e-30)).sqrt();
    let share2 = within as f64 / planes.max(1) as f64;
    let _ = writeln!(
        md,
        "**Are the planes' uncertainties right?** On these {planes} planes of at least \
         {ROOM_MIN_PIXELS} px whose pixels lie on one true surface, against its exact plane: RMS \
         normal error / RMS `normal_sigma_deg` = {ratio:.2}, RMS offset error at the centroid / \
         RMS `offset_sigma_m` = {ratio_off:.2}; {:.1} % of the normals within 2σ (a Gaussian \
         error in two tangent directions: 98 %).\n",
        100.0 * share2
    );
    ctx.row(EXP, "rooms normal error / sigma", ratio, "");
    ctx.row(EXP, "rooms offset error / sigma", ratio_off, "");
    let inside = |r: f64| (1.0 / CALIBRATION_FACTOR..=CALIBRATION_FACTOR).contains(&r);
    ctx.check(
        format!(
            "the planes' uncertainties describe their errors on the simulated rooms \
             (RMS error / RMS σ within a factor {CALIBRATION_FACTOR}, normal and offset)"
        ),
        planes > 0 && inside(ratio) && inside(ratio_off),
        format!("{planes} planes: normal {ratio:.2}, offset {ratio_off:.2}"),
    );
    Ok(())
}

/// What leaving out the uncertain planes (`PlaneConfig::max_normal_sigma_deg`, off by
/// default) does on the examined and held-out rooms together: correct detections and spurious
/// planes for a few bounds (reported, not a gate; no bound is chosen here).
fn uncertain_planes_left_out(ctx: &mut Context, md: &mut String) -> Result<()> {
    let _ = writeln!(
        md,
        "**Leaving out uncertain planes** (`PlaneConfig::max_normal_sigma_deg`, `sldepth planes \
         --max-normal-sigma-deg`; off by default): the examined and held-out seeds together, \
         planes whose normal the noise model determines less well than the bound left \
         unlabelled.\n\n| bound | GT planes | correct | over | under | missed | noise | spurious ≥ \
         {ROOM_MIN_PIXELS} px | worst ms |\n|---|---|---|---|---|---|---|---|---|"
    );
    for bound in [f64::INFINITY, 4.0, 2.0, 1.0] {
        let mut cfg = PlaneConfig::default();
        cfg.max_normal_sigma_deg = bound;
        let mut ex = PlaneExtractor::new(cfg)?;
        let t = score_ours(&mut ex, ROOM_EXAMINED_SEEDS.chain(ROOM_HELD_OUT_SEEDS), 0.0)?;
        let label = if bound.is_finite() {
            format!("{bound}°")
        } else {
            "none (default)".to_owned()
        };
        let _ = writeln!(md, "{}", t.line(&label));
        share_rows(ctx, &format!("rooms unseen max sigma {label}"), &t);
    }
    md.push('\n');
    Ok(())
}

/// The rows `"{prefix} correct share"` and `"{prefix} spurious"` of one set's totals.
pub(super) fn share_rows(ctx: &mut Context, prefix: &str, t: &Totals) {
    ctx.row(
        EXP,
        &format!("{prefix} correct share"),
        t.correct as f64 / t.gt.max(1) as f64,
        "",
    );
    ctx.row(
        EXP,
        &format!("{prefix} spurious"),
        t.spurious as f64,
        "regions",
    );
    ctx.row(
        EXP,
        &format!("{prefix} spurious partial"),
        t.spurious_partial as f64,
        "regions",
    );
}

/// Runs the room benchmark and writes its section.
pub fn rooms(ctx: &mut Context) -> Result<()> {
    let n = if ctx.quick() {
        12
    } else {
        ROOM_BENCHMARK_SEEDS
    };
    let mut md = format!(
        "{n} seeded rooms and corridors (`sl_noise::sim::room_scene`: floor, ceiling, four walls, \
         0–3 boxes; camera 0.6–1.8 m high, pitch −35…+10°, roll ±15°, any yaw (corridors: along \
         the corridor ±35°), f = 520–600 px, range 0.5–5 m) through the realistic simulator \
         (correlated disparity error, terraces, occlusion bands; docs/NOISE_MODEL.md), seed = scene. \
         SegComp (Hoover et al.) at 80 % overlap for the ground-truth planes of at least \
         {ROOM_MIN_PIXELS} valid pixels; *spurious* = noise regions of at least {ROOM_MIN_PIXELS} \
         pixels that match no surface (a region that correctly detects a surface too small to be \
         scored is not spurious); *partial*: the spurious planes that lie on one surface (at least \
         80 % of their pixels) but cover less than 80 % of it, pieces of one surface rather than \
         planes spanning several (they stay spurious). Methods: the disparity extractor with default \
         parameters, metric RANSAC with its defaults (10 mm). ms: one run, one thread.\n\n"
    );
    let per_scene_head = "| scene | kind | f px | GT | ours correct | over | under | missed | noise | spurious | RANSAC correct | spurious |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n";
    let mut ex = PlaneExtractor::new(PlaneConfig::default())?;
    let SeedSet {
        ours,
        ransac,
        per_scene,
        mut worst,
    } = score_seeds(&mut ex, 0..n)?;
    let per_scene = format!("{per_scene_head}{per_scene}");
    let _ = writeln!(
        md,
        "| method | GT planes | correct | over | under | missed | noise | spurious ≥ {ROOM_MIN_PIXELS} px | worst ms |\n\
         |---|---|---|---|---|---|---|---|---|\n{}\n{}\n",
        ours.line("disparity (ours)"),
        ransac.line("metric RANSAC 10 mm")
    );
    let frac = ours.correct as f64 / ours.gt.max(1) as f64;
    let _ = writeln!(
        md,
        "Issue-12 targets: ≥ {:.0} % of the ground-truth planes correct — {:.1} %, **{}**; no \
         spurious plane ≥ {ROOM_MIN_PIXELS} px — {}, **{}**.\n",
        100.0 * TARGET_CORRECT,
        100.0 * frac,
        if frac >= TARGET_CORRECT {
            "met"
        } else {
            "not met"
        },
        ours.spurious,
        if ours.spurious == 0 { "met" } else { "not met" },
    );
    for (tag, t) in [("disparity", &ours), ("ransac", &ransac)] {
        ctx.row(
            EXP,
            &format!("rooms {tag} gt planes"),
            t.gt as f64,
            "regions",
        );
        ctx.row(
            EXP,
            &format!("rooms {tag} correct"),
            t.correct as f64,
            "regions",
        );
        ctx.row(EXP, &format!("rooms {tag} over"), t.over as f64, "regions");
        ctx.row(
            EXP,
            &format!("rooms {tag} under"),
            t.under as f64,
            "regions",
        );
        ctx.row(
            EXP,
            &format!("rooms {tag} missed"),
            t.missed as f64,
            "regions",
        );
        ctx.row(
            EXP,
            &format!("rooms {tag} noise"),
            t.noise as f64,
            "regions",
        );
        ctx.row(
            EXP,
            &format!("rooms {tag} spurious"),
            t.spurious as f64,
            "regions",
        );
        ctx.row(
            EXP,
            &format!("rooms {tag} spurious partial"),
            t.spurious_partial as f64,
            "regions",
        );
    }
    ctx.check(
        format!("room benchmark scores ≥ 50 scenes ({n} run)"),
        ctx.quick() || n >= 50,
        format!("{} ground-truth planes", ours.gt),
    );
    // Scenes the extractor was never developed on (full runs only): the same rules and targets.
    if !ctx.quick() {
        for (label, seeds) in [
            ("examined", ROOM_EXAMINED_SEEDS),
            ("held-out", ROOM_HELD_OUT_SEEDS),
        ] {
            let set = score_seeds(&mut ex, seeds.clone())?;
            let (o, r) = (&set.ours, &set.ransac);
            let _ = writeln!(
                md,
                "**{label} seeds {}–{}** ({}): \n\n| method | GT planes | correct | over | under | missed | noise | spurious ≥ {ROOM_MIN_PIXELS} px | worst ms |\n|---|---|---|---|---|---|---|---|---|\n{}\n{}\n",
                seeds.start,
                seeds.end - 1,
                match label {
                    "examined" =>
                        "looked at while developing the border extension of session 11, not tuned on: it has no parameter",
                    _ => "never looked at during development; reported, not a gate",
                },
                o.line("disparity (ours)"),
                r.line("metric RANSAC 10 mm"),
            );
            for (tag, t) in [("disparity", o), ("ransac", r)] {
                share_rows(ctx, &format!("rooms {label} {tag}"), t);
            }
        }
        uncertain_planes_left_out(ctx, &mut md)?;
    }
    uncertainty_calibration(ctx, &mut md, 0..n)?;
    // Other cameras (full runs only): new seeds through each preset's intrinsics and sensor.
    if !ctx.quick() {
        let _ = writeln!(
            md,
            "**Other cameras**, seeds {}–{} (never looked at during development; reported, not a \
             gate): the same rooms seen through each preset's intrinsics and sensor model (focal \
             length, baseline, sub-pixel step, σ_D), the realistic simulator's default matching \
             window, the extractor's defaults.\n\n| camera | size | f px | B m | method | GT planes | correct | over | under | missed | noise | spurious ≥ {ROOM_MIN_PIXELS} px | worst ms |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|",
            ROOM_CAMERA_SEEDS.start,
            ROOM_CAMERA_SEEDS.end - 1,
        );
        for name in ROOM_CAMERAS {
            let cam = Camera::preset(name)?;
            let set = score_seeds_through(&mut ex, ROOM_CAMERA_SEEDS, Some(&cam), 0.0)?;
            let k = cam.intrinsics;
            for (method, t) in [
                ("disparity (ours)", &set.ours),
                ("metric RANSAC 10 mm", &set.ransac),
            ] {
                let _ = writeln!(
                    md,
                    "| {name} | {}×{} | {:.0} | {:.3} {}",
                    k.width,
                    k.height,
                    k.fx,
                    cam.sensor.baseline_m,
                    t.line(method)
                );
            }
            share_rows(ctx, &format!("rooms camera {name} disparity"), &set.ours);
        }
        md.push('\n');
    }
    // The Kinect's low-frequency disparity distortion (full runs only): the examined rooms again.
    if !ctx.quick() {
        let _ = writeln!(
            md,
            "**Low-frequency disparity distortion**, the examined seeds {}–{} again with a smooth \
             radial disparity bias `a·r²/r²_corner` added (`RealisticNoise::distortion_px`, the \
             option for the Kinect's distortion of Herrera et al. and Smisek et al.). Real frames \
             are bent by about this much (TUM's largest planes: median curvature 1.1·10⁻⁵ px/px², \
             0.9 px at the corner for a bowl) but not as one bowl: one radial coefficient fitted per \
             TUM frame varies from −0.7 to +0.7 px and lowers the planes' RMS residual by 0.00–0.02 \
             px (docs/bench/README.md, session 30). Reported, not a gate. The extractor's plane \
             model is affine in disparity: a surface filling the frame is left up to `2a/3` off \
             its affine fit at the corners, which seed planes of their own; adjacent planes whose \
             slopes agree at their border within the noise and whose whole fits differ by no \
             more than the bend allows (`PlaneConfig::bend_px_per_px2`, the `bend` stage) take \
             one label (session 31: spurious 29 / 137 → 21 / 44). A bent surface's rim also went \
             to the neighbour across a far crease in the scenes looked at (seed 186).\n\n\
             | distortion a | method | GT planes | correct | over | under | missed | noise | \
             spurious ≥ {ROOM_MIN_PIXELS} px | worst ms |\n|---|---|---|---|---|---|---|---|---|---|",
            ROOM_EXAMINED_SEEDS.start,
            ROOM_EXAMINED_SEEDS.end - 1,
        );
        for a in ROOM_DISTORTION_PX {
            let set = score_seeds_through(&mut ex, ROOM_EXAMINED_SEEDS, None, a)?;
            for (method, t) in [
                ("disparity (ours)", &set.ours),
                ("metric RANSAC 10 mm", &set.ransac),
            ] {
                let _ = writeln!(md, "| {a:.1} px {}", t.line(method));
            }
            share_rows(
                ctx,
                &format!("rooms distortion {a:.1} px disparity"),
                &set.ours,
            );
            // The same with each optional stage (off by default).
            let optional: [OptionalStage; 2] = [
                ("refine_seams", "refine-seams", |c| c.refine_seams = true),
                ("give_back_taken_in", "give-back-taken-in", |c| {
                    c.give_back_taken_in = true
                }),
            ];
            for (name, tag, switch_on) in optional {
                let mut cfg = *ex.config();
                switch_on(&mut cfg);
                let mut with_stage = PlaneExtractor::new(cfg)?;
                let t = score_ours(&mut with_stage, ROOM_EXAMINED_SEEDS, a)?;
                let _ = writeln!(
                    md,
                    "| {a:.1} px {}",
                    t.line(&format!("disparity, `{name}`"))
                );
                share_rows(
                    ctx,
                    &format!("rooms distortion {a:.1} px disparity {tag}"),
                    &t,
                );
            }
        }
        md.push_str(
            "\n`refine_seams` (off by default, session 43) re-decides the pixels along a crease \
             with the two planes' local fits where a plane's whole fit is off there: the rim a \
             small neighbour took from a bent surface goes back to it. Without distortion it \
             changes no score above; on real frames it costs 0.1–0.3 ms per frame. \
             `give_back_taken_in` (off by default, session 75) leaves unlabelled the pieces of a \
             neighbouring surface a plane took in (blocks off a quadratic fit of the plane by \
             more than the noise model allows); on real frames it costs 0.4–0.7 ms per frame.\n",
        );
        md.push('\n');
        super::noisier::noisier_sensor(ctx, &mut md)?;
        super::dark::dark_materials(ctx, &mut md)?;
    }
    // Overlays of the three worst scenes: ours and the ground truth.
    worst.sort_by(|a, b| a.0.total_cmp(&b.0));
    md.push_str("Worst scenes (ours | ground truth):\n\n");
    for &(_, seed) in worst.iter().take(3) {
        let rs = room_scene(seed)?;
        let mut sensor = sl_core::SensorModel::kinect_v1();
        sensor.focal_px = rs.intrinsics.fx;
        let frame = KinectSimulator::with_sensor(sensor).simulate(
            &rs.scene,
            &rs.intrinsics,
            &rs.pose,
            seed,
        );
        let cam = Camera {
            intrinsics: rs.intrinsics,
            sensor,
        };
        let seg = ex.extract_depth(&frame.depth, &cam)?;
        let base = overlay::depth_to_rgb(&frame.depth);
        let a = format!("planes-room-{seed:02}-ours.png");
        let b = format!("planes-room-{seed:02}-truth.png");
        save_overlay(&ctx.out_dir().join(&a), &seg, &base)?;
        let truth = PlaneSegmentation {
            labels: frame.labels.clone(),
            planes: Vec::new(),
        };
        save_overlay(&ctx.out_dir().join(&b), &truth, &base)?;
        let _ = writeln!(md, "![room {seed} ours]({a}) ![room {seed} truth]({b})\n");
    }
    md.push_str("\n<details><summary>Per scene</summary>\n\n");
    md.push_str(&per_scene);
    md.push_str("\n</details>\n");
    ctx.section("Plane extraction: randomised room benchmark (issue 12)", md);
    Ok(())
}

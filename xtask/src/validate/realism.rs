//! Issue 11: real Kinect frames and the realistic simulator side by side.
//!
//! For each real data set (person, TUM fr1/rpy, 7-Scenes, the PCL floor scan, NYU raw) the
//! planes are found with `sl-planes`, and `sl_noise::stats::noise_stats` measures σ_D, the
//! residual autocorrelation at lags 1–16 px, the terrace widths and the occlusion-band widths.
//! The realistic simulator is run with the same camera (its intrinsics, `f·B` and its data
//! set's registration) on named scenes (`floor`, `figure-walls`, `boxes`) for the noise
//! statistics, and on a board before a wall at the real frames' median foreground and
//! background depths for the bands, and measured the same way. Targets (issue 11):
//! correlations within ±0.1 of the real median, σ_D within 20 %, band widths within ±3 px.
//! The default parameters were fitted on person + TUM; 7-Scenes, the floor scan and NYU are
//! held out. Without `../shared/data` the experiment says so and skips.

use std::fmt::Write as _;

use anyhow::Result;
use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{Camera, CameraToWorld, DepthImage};
use sl_noise::sim::{KinectSimulator, NoiseModel, Plane, Quad, RealisticNoise, Scene, named_scene};
use sl_noise::stats::{
    NoiseStats, NoiseStatsConfig, SHADOW_BINS_PX, ShadowBin, SideBands, noise_stats,
};
use sl_planes::{PlaneConfig, extract_planes};

use super::Context;

/// Lags compared (16 px is reported but not a target: the 64-px tile fits remove most of it).
const TARGET_LAGS: [usize; 4] = [1, 2, 4, 8];
/// Correlation tolerance.
const ACF_TOL: f64 = 0.1;
/// σ_D relative tolerance.
const SIGMA_TOL: f64 = 0.2;
/// Band width tolerance, pixels.
const BAND_TOL_PX: f64 = 3.0;

/// Summary of a set of frames (medians over frames).
#[derive(Debug, Clone)]
struct Summary {
    sigma: f64,
    acf_x: Vec<f64>,
    acf_y: Vec<f64>,
    terrace_median: f64,
    terrace_mean: f64,
    left: f64,
    right: f64,
    left_fg_bg: (f64, f64),
    right_fg_bg: (f64, f64),
    /// The occlusion edges (jumps beyond 15 cm) by predicted projector shadow, pooled over the
    /// frames, left / right.
    by_shadow: (Vec<ShadowBin>, Vec<ShadowBin>),
}

/// The shadow bins of one side, summed over frames.
fn pooled_bins<'a>(sides: impl Iterator<Item = &'a SideBands>) -> Vec<ShadowBin> {
    let mut out: Vec<ShadowBin> = Vec::new();
    for s in sides {
        if out.is_empty() {
            out = s.by_shadow.clone();
            continue;
        }
        for (o, b) in out.iter_mut().zip(&s.by_shadow) {
            o.edges += b.edges;
            o.with_band += b.with_band;
        }
    }
    out
}

/// Share of all the edges of these bins with an invalid band (NaN without edges).
fn band_share(bins: &[ShadowBin]) -> f64 {
    let (with_band, edges) = bins
        .iter()
        .fold((0, 0), |(b, e), s| (b + s.with_band, e + s.edges));
    if edges == 0 {
        f64::NAN
    } else {
        with_band as f64 / edges as f64
    }
}

/// The median of the finite values (NaN for none).
fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    sl_noise::analysis::median(&mut v).unwrap_or(f64::NAN)
}

fn stats_of(depth: &DepthImage, camera: &Camera) -> Result<NoiseStats> {
    let mut cfg = PlaneConfig::default();
    cfg.min_pixels = 2000;
    let seg = extract_planes(depth, camera, &cfg)?;
    Ok(noise_stats(
        depth,
        camera.sensor.fb(),
        &seg.labels,
        &NoiseStatsConfig::default(),
    )?)
}

fn summarise(all: &[NoiseStats]) -> Summary {
    let lag = |s: &NoiseStats, l: usize| s.acf_at(l).unwrap_or((f64::NAN, f64::NAN));
    let lags = sl_noise::stats::DEFAULT_LAGS;
    Summary {
        sigma: median(all.iter().map(|s| s.sigma_d_px).collect()),
        acf_x: lags
            .iter()
            .map(|&l| median(all.iter().map(|s| lag(s, l).0).collect()))
            .collect(),
        acf_y: lags
            .iter()
            .map(|&l| median(all.iter().map(|s| lag(s, l).1).collect()))
            .collect(),
        terrace_median: median(all.iter().map(|s| s.terraces.widths.median_px).collect()),
        terrace_mean: median(all.iter().map(|s| s.terraces.widths.mean_px).collect()),
        left: median(
            all.iter()
                .map(|s| s.occlusion.left.widths.median_px)
                .collect(),
        ),
        right: median(
            all.iter()
                .map(|s| s.occlusion.right.widths.median_px)
                .collect(),
        ),
        left_fg_bg: (
            median(all.iter().map(|s| s.occlusion.left.median_fg_m).collect()),
            median(all.iter().map(|s| s.occlusion.left.median_bg_m).collect()),
        ),
        right_fg_bg: (
            median(all.iter().map(|s| s.occlusion.right.median_fg_m).collect()),
            median(all.iter().map(|s| s.occlusion.right.median_bg_m).collect()),
        ),
        by_shadow: (
            pooled_bins(all.iter().map(|s| &s.occlusion.left)),
            pooled_bins(all.iter().map(|s| &s.occlusion.right)),
        ),
    }
}

/// A board (0.5 m wide, 3 m tall) at `zf` centred on the optical axis before a wall at `zb`.
fn board_scene(zf: f64, zb: f64) -> Result<Scene> {
    let mut scene = Scene::new();
    scene.add(Plane::new(Point3::new(0.0, 0.0, zb), Vector3::z())?);
    scene.add(Quad::new(
        Point3::new(0.0, 0.0, zf),
        Vector3::new(0.25 * zf, 0.0, 0.0),
        Vector3::new(0.0, 1.5, 0.0),
    )?);
    Ok(scene)
}

/// Runs the experiment.
pub fn run(ctx: &mut Context) -> Result<()> {
    let mut md = String::new();
    if ctx.data_dir().is_none() {
        md.push_str("Skipped: `../shared/data` (the real frames) is not present.\n");
        ctx.section(
            "Real Kinect noise vs the realistic simulator (issue 11)",
            md,
        );
        ctx.check("skipped without real data", true, "no ../shared/data");
        return Ok(());
    }
    let quick = ctx.quick();
    let groups: Vec<(&str, &str, bool, Vec<sl_testkit::RealFrame>)> = vec![
        (
            "person",
            "ros-default",
            true,
            sl_testkit::person().into_iter().collect(),
        ),
        (
            "TUM fr1/rpy",
            "tum-fr1",
            true,
            sl_testkit::tum_rpy(if quick { 5 } else { 30 }),
        ),
        (
            "7-Scenes",
            "7-scenes",
            false,
            sl_testkit::seven_scenes(if quick { 5 } else { 50 }),
        ),
        ("floor scan", "pcl-openni", false, sl_testkit::floor_scan(3)),
        (
            "NYU raw",
            "nyu-v2",
            false,
            sl_testkit::nyu_raw().into_iter().collect(),
        ),
    ];
    let seeds: &[u64] = if quick { &[1] } else { &[1, 2] };
    let _ = writeln!(
        md,
        "Real frames and the realistic simulator (default `RealisticNoise` for the data set's \
         camera; window {}×{} px, σ_D = {} px) measured by `sl_noise::stats::noise_stats` on the \
         planes `sl-planes` finds (affine disparity fits in 64-px tiles; medians over tiles, \
         then over frames). Simulated noise statistics: scenes floor, figure-walls, boxes \
         (seeds {seeds:?}) through the data set's camera; simulated bands: a board before a \
         wall at the real frames' median foreground/background depths. Fitted on person + TUM; \
         7-Scenes, floor scan and NYU are held out. Targets: |Δρ| ≤ {ACF_TOL} (lags 1–8), σ_D \
         within {:.0} %, bands within ±{BAND_TOL_PX} px. `ok`/`NOT MET` per statistic.\n",
        RealisticNoise::default().window_x,
        RealisticNoise::default().window_y,
        sl_core::SensorModel::kinect_v1().sigma_d_px,
        SIGMA_TOL * 100.0
    );
    struct Group {
        name: &'static str,
        fitted: bool,
        frames: usize,
        real: Summary,
        sim: Summary,
        sim_left: f64,
        sim_right: f64,
        /// Share of the simulated board's edges with a band, left / right.
        sim_share: (f64, f64),
    }
    let mut done: Vec<Group> = Vec::new();
    let mut missing = Vec::new();
    for (name, cam_name, fitted, frames) in groups {
        if frames.is_empty() {
            missing.push(name);
            continue;
        }
        let camera = Camera::preset(cam_name)?;
        let mut real = Vec::new();
        for f in &frames {
            match stats_of(&f.depth, &f.camera) {
                Ok(s) => real.push(s),
                Err(e) => eprintln!("  {}: {e:#}", f.name),
            }
        }
        let r = summarise(&real);
        // Simulated noise statistics, through this data set's camera.
        let sim = KinectSimulator::with_sensor(camera.sensor)
            .with_noise(NoiseModel::Realistic(RealisticNoise::for_camera(cam_name)));
        let mut simulated = Vec::new();
        for scene in ["floor", "figure-walls", "boxes"] {
            let ns = named_scene(scene)?;
            for &seed in seeds {
                let fr = sim.simulate(&ns.scene, &camera.intrinsics, &ns.pose, seed);
                simulated.push(stats_of(&fr.depth, &camera)?);
            }
        }
        let s = summarise(&simulated);
        // Simulated bands at the real geometry (no run but direct edges = a band of 0 px).
        let band = |fg_bg: (f64, f64), left: bool| -> Result<(f64, f64)> {
            let (zf, zb) = fg_bg;
            if !(zf.is_finite() && zb.is_finite() && zb > zf) {
                return Ok((f64::NAN, f64::NAN));
            }
            let scene = board_scene(zf, zb)?;
            let fr = sim.simulate(&scene, &camera.intrinsics, &CameraToWorld::identity(), 1);
            let st = stats_of(&fr.depth, &camera)?;
            let side = if left {
                &st.occlusion.left
            } else {
                &st.occlusion.right
            };
            let width = if side.widths.count == 0 && side.direct_edges > 0 {
                0.0
            } else {
                side.widths.median_px
            };
            Ok((width, band_share(&side.by_shadow)))
        };
        let (sim_left, sim_left_share) = band(r.left_fg_bg, true)?;
        let (sim_right, sim_right_share) = band(r.right_fg_bg, false)?;
        done.push(Group {
            name,
            fitted,
            frames: frames.len(),
            real: r,
            sim: s,
            sim_left,
            sim_right,
            sim_share: (sim_left_share, sim_right_share),
        });
    }
    if done.is_empty() {
        md.push_str("\nNo real frame could be read: skipped.\n");
        ctx.section(
            "Real Kinect noise vs the realistic simulator (issue 11)",
            md,
        );
        ctx.check("skipped without real frames", true, "no frames");
        return Ok(());
    }
    for m in &missing {
        let _ = writeln!(md, "\n{m}: not found, left out.");
    }
    // Table 1: noise statistics, every data set, their median, and the simulator.
    let _ = write!(md, "\n| statistic |");
    for g in &done {
        let _ = write!(
            md,
            " {} ({}{}) |",
            g.name,
            g.frames,
            if g.fitted { ", fit" } else { "" }
        );
    }
    md.push_str(
        " real median | fit median (person, TUM) | simulated | target vs real median |\n|---|",
    );
    for _ in 0..done.len() + 4 {
        md.push_str("---|");
    }
    md.push('\n');
    let mut met = 0;
    let mut total = 0;
    let mut table_row = |md: &mut String,
                         stat: &str,
                         get: &dyn Fn(&Summary) -> f64,
                         target: Option<&dyn Fn(f64, f64) -> bool>|
     -> Option<bool> {
        let _ = write!(md, "| {stat} |");
        for g in &done {
            let _ = write!(md, " {:.3} |", get(&g.real));
        }
        let real_med = median(done.iter().map(|g| get(&g.real)).collect());
        let fit_med = median(
            done.iter()
                .filter(|g| g.fitted)
                .map(|g| get(&g.real))
                .collect(),
        );
        let sim_med = median(done.iter().map(|g| get(&g.sim)).collect());
        let ok = target.map(|t| t(sim_med, real_med));
        let verdict = match ok {
            Some(true) => "ok",
            Some(false) => "NOT MET",
            None => "–",
        };
        let _ = writeln!(
            md,
            " {real_med:.3} | {fit_med:.3} | {sim_med:.3} | {verdict} |"
        );
        if let Some(ok) = ok {
            total += 1;
            met += usize::from(ok);
        }
        ok
    };
    let sigma_t = |s: f64, r: f64| (s / r - 1.0).abs() <= SIGMA_TOL;
    let acf_t = |s: f64, r: f64| (s - r).abs() <= ACF_TOL;
    let mut failed = Vec::new();
    if table_row(&mut md, "σ_D (px)", &|s: &Summary| s.sigma, Some(&sigma_t)) == Some(false) {
        failed.push("σ_D".to_string());
    }
    for (i, lag) in sl_noise::stats::DEFAULT_LAGS.iter().enumerate() {
        let target = TARGET_LAGS.contains(lag);
        for axis in ["x", "y"] {
            let get = move |s: &Summary| if axis == "x" { s.acf_x[i] } else { s.acf_y[i] };
            let ok = table_row(
                &mut md,
                &format!("ρ_{axis}({lag} px)"),
                &get,
                if target { Some(&acf_t) } else { None },
            );
            if ok == Some(false) {
                failed.push(format!("ρ_{axis}({lag})"));
            }
        }
    }
    table_row(
        &mut md,
        "terrace width, median (px)",
        &|s: &Summary| s.terrace_median,
        None,
    );
    table_row(
        &mut md,
        "terrace width, mean (px)",
        &|s: &Summary| s.terrace_mean,
        None,
    );
    let _ = writeln!(md, "\nNoise statistics: {met}/{total} targets met.");
    ctx.row("realism", "noise-statistic targets met", met as f64, "");
    ctx.row("realism", "noise-statistic targets", total as f64, "");
    ctx.check(
        "simulated σ_D within 20 % and ρ(1..8 px) within 0.1 of the real median",
        failed.is_empty(),
        if failed.is_empty() {
            format!("{met}/{total} met")
        } else {
            format!("not met: {}", failed.join(", "))
        },
    );
    // Table 2: occlusion bands, same camera.
    md.push_str(
        "\n| data set | role | side | real fg / bg depth (m) | real band (px) | simulated (px) | target ±3 px | edges with a band, real / simulated |\n|---|---|---|---|---|---|---|---|\n",
    );
    let mut band_met = 0;
    let mut band_total = 0;
    for g in &done {
        for (side, rv, sv, fb, shares) in [
            (
                "left",
                g.real.left,
                g.sim_left,
                g.real.left_fg_bg,
                (band_share(&g.real.by_shadow.0), g.sim_share.0),
            ),
            (
                "right",
                g.real.right,
                g.sim_right,
                g.real.right_fg_bg,
                (band_share(&g.real.by_shadow.1), g.sim_share.1),
            ),
        ] {
            let ok = (rv.is_finite() && sv.is_finite()).then(|| (rv - sv).abs() <= BAND_TOL_PX);
            let verdict = match ok {
                Some(true) => "ok",
                Some(false) => "NOT MET",
                None => "–",
            };
            if let Some(ok) = ok {
                band_total += 1;
                band_met += usize::from(ok);
            }
            let _ = writeln!(
                md,
                "| {} | {} | {side} | {:.2} / {:.2} | {rv:.1} | {sv:.1} | {verdict} | {:.0} % / {:.0} % |",
                g.name,
                if g.fitted { "fit" } else { "held out" },
                fb.0,
                fb.1,
                100.0 * shares.0,
                100.0 * shares.1
            );
            ctx.row(
                "realism",
                &format!("{} band {side} share real", g.name),
                shares.0,
                "",
            );
            ctx.row("realism", &format!("{} band {side} real", g.name), rv, "px");
            ctx.row("realism", &format!("{} band {side} sim", g.name), sv, "px");
        }
    }
    let _ = writeln!(
        md,
        "\nOcclusion bands: {band_met}/{band_total} targets met. The band width is the median \
         over the rows that have a band; the last column is the share of all the edges of that \
         side (jumps beyond 15 cm) that have one, the real frames pooled. The simulated board \
         makes a band at every edge or at none; the real rooms make them at some (on the held-out \
         sets at a fifth to a quarter of the edges: transparent bins and clutter in NYU, a dark \
         plinth recess and a black worktop's edge in 7-Scenes — docs/NOISE_MODEL.md)."
    );
    // Table 3: the real edges by the shadow their depths predict (reported, not checked).
    md.push_str(
        "\nThe real edges by the projector shadow `f·B·(1/Z_fg − 1/Z_bg)` their two depths \
         predict: the share with an invalid band (of how many edges). A sensor that invalidated \
         the pixels beside every depth edge would put a band at most edges of every column; the \
         projector's shadow alone only in the wide columns.\n\n| data set | side |",
    );
    let mut lo = 0.0;
    for u in SHADOW_BINS_PX {
        if u.is_finite() {
            let _ = write!(md, " shadow {lo:.0}–{u:.0} px |");
        } else {
            let _ = write!(md, " shadow {lo:.0}+ px |");
        }
        lo = u;
    }
    md.push_str("\n|---|---|");
    for _ in SHADOW_BINS_PX {
        md.push_str("---|");
    }
    md.push('\n');
    for g in &done {
        for (side, bins) in [
            ("left", &g.real.by_shadow.0),
            ("right", &g.real.by_shadow.1),
        ] {
            let _ = write!(md, "| {} | {side} |", g.name);
            for b in bins {
                if b.edges == 0 {
                    md.push_str(" – |");
                } else {
                    let _ = write!(md, " {:.0} % of {} |", 100.0 * b.share(), b.edges);
                }
            }
            md.push('\n');
        }
    }
    ctx.row("realism", "band targets met", band_met as f64, "");
    ctx.row("realism", "band targets", band_total as f64, "");
    ctx.section(
        "Real Kinect noise vs the realistic simulator (issue 11)",
        md,
    );
    Ok(())
}

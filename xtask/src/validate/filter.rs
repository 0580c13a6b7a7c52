//! Section 3.1–3.2 of the paper: adaptive bilateral filtering (Figures 3–4 as numbers).
//!
//! 1. Simulated Kinect frames with ground truth (`sl-noise`): the `floor` scene (a tilted floor
//!    from 0.8 to 3.9 m, Figure 3) and the `figure-walls` scene (a figure ~1 m away before two
//!    walls meeting at 90° at ~3 m, Figure 4), several noise seeds each. RMSE against the exact
//!    depth per depth band and at pixels within 2 px of a true depth edge, for the raw frame,
//!    the Gaussian, the bilateral at each σ_d of a sweep, the adaptive filter at the default k
//!    and the disparity-domain bilateral; all with the same 7×7 window and σ_s = 1.5 px.
//!    The default multiplier `m` of `k = m·σ_D/(f·B)` is chosen here: a sweep of `m` on the
//!    same frames, the best overall RMSE wins (and must be the constant in sl-filter).
//! 2. Real frames (`person-depth.png`, the PCL floor scan, a TUM frame): the dominant plane
//!    (RANSAC, see `sl_eval::filter::dominant_plane_region`) and the plane-fit residual per depth
//!    band before and after each filter.
//!
//! Checks (thresholds fixed before measuring): the adaptive filter beats raw in every band,
//! beats the best single-σ_d bilateral overall, and its edge RMSE stays "near raw's", defined
//! as at most 1.1× the raw edge RMSE.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context as _, Result};
use sl_core::{Camera, DepthImage, Intrinsics, SensorModel};
use sl_eval::filter::{self as eval, BandError, KINECT_BANDS_M};
use sl_filter::{
    DEFAULT_K_MULTIPLIER, DEFAULT_RADIUS_PX, DepthFilter, MultiScale, default_sigma_s_px,
};
use sl_noise::sim::{KinectSimulator, named_scene};

use super::Context;

mod multiscale;
use multiscale::{multiscale_cameras, multiscale_real, multiscale_sim};

const EXP: &str = "filter";
/// Multipliers `m` swept for the default k.
const M_SWEEP: [f64; 11] = [1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 12.0, 16.0, 24.0, 32.0];
/// Fixed range σ of the bilateral sweep, millimetres.
const SIGMA_D_SWEEP_MM: [f64; 10] = [2.0, 5.0, 10.0, 15.0, 20.0, 40.0, 80.0, 120.0, 160.0, 240.0];
/// "Near raw" at depth edges.
const EDGE_TOLERANCE: f64 = 1.1;
/// The scenes of the evaluation table (the Figure 3 and Figure 4 situations).
const EVAL_SCENES: [&str; 2] = ["floor", "figure-walls"];

/// One simulated frame with its ground truth.
struct SimFrame {
    scene: &'static str,
    truth: DepthImage,
    depth: DepthImage,
    k: Intrinsics,
    edges: Vec<bool>,
}

/// `seeds` simulated frames (seeds 1000, 1001, …) of each named scene, with their true depth
/// edges (jumps over 5 cm, dilated by 2 px).
fn simulate_frames(sim: &KinectSimulator, scenes: &[&str], seeds: u64) -> Result<Vec<SimFrame>> {
    let mut frames = Vec::new();
    for name in scenes {
        let ns = named_scene(name)?;
        for seed in 0..seeds {
            let fr = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 1000 + seed);
            let edges = eval::depth_edge_mask(&fr.truth, 0.05, 2);
            frames.push(SimFrame {
                scene: ns.name,
                truth: fr.truth,
                depth: fr.depth,
                k: ns.intrinsics,
                edges,
            });
        }
    }
    Ok(frames)
}

/// Pooled squared errors per band and at edges.
#[derive(Default, Clone)]
struct Acc {
    n: [usize; 3],
    ss: [f64; 3],
    edge_n: usize,
    edge_ss: f64,
}

impl Acc {
    fn add(&mut self, est: &DepthImage, f: &SimFrame) -> Result<()> {
        self.add_masked(est, &f.truth, None, &f.edges)
    }
    /// Adds one estimate: its error per depth band over `surface` (every pixel when `None`)
    /// and at the `edges` pixels.
    fn add_masked(
        &mut self,
        est: &DepthImage,
        truth: &DepthImage,
        surface: Option<&[bool]>,
        edges: &[bool],
    ) -> Result<()> {
        for (i, b) in eval::rmse_by_band(est, truth, surface, &KINECT_BANDS_M)?
            .iter()
            .enumerate()
        {
            self.add_band(i, b);
        }
        let e = eval::rmse_by_band(est, truth, Some(edges), &[(0.0, f32::INFINITY)])?;
        if e[0].pixels > 0 {
            self.edge_n += e[0].pixels;
            self.edge_ss += e[0].rmse_m * e[0].rmse_m * e[0].pixels as f64;
        }
        Ok(())
    }
    fn add_band(&mut self, i: usize, b: &BandError) {
        if b.pixels > 0 {
            self.n[i] += b.pixels;
            self.ss[i] += b.rmse_m * b.rmse_m * b.pixels as f64;
        }
    }
    fn band(&self, i: usize) -> f64 {
        (self.ss[i] / self.n[i].max(1) as f64).sqrt()
    }
    fn overall(&self) -> f64 {
        (self.ss.iter().sum::<f64>() / self.n.iter().sum::<usize>().max(1) as f64).sqrt()
    }
    fn edge(&self) -> f64 {
        (self.edge_ss / self.edge_n.max(1) as f64).sqrt()
    }
}

/// Runs the experiment.
pub fn run(ctx: &mut Context) -> Result<()> {
    let sim = KinectSimulator::kinect_v1().white();
    let sensor = sim.sensor;
    let seeds: u64 = if ctx.quick() { 1 } else { 3 };
    // The evaluation scenes of the issue, plus two with small depth steps (a book 1 cm above a
    // table; boxes on a floor) that only the choice of m sees: without them the sweep would
    // favour ever larger range σ, which blurs small steps the two evaluation scenes lack.
    let frames = simulate_frames(
        &sim,
        &["floor", "figure-walls", "three-planes", "boxes"],
        seeds,
    )?;
    let r = DEFAULT_RADIUS_PX;
    let s = default_sigma_s_px(r);
    let score_on = |f: Option<&DepthFilter>, sweep: bool| -> Result<Acc> {
        let mut acc = Acc::default();
        for fr in frames
            .iter()
            .filter(|fr| sweep || EVAL_SCENES.contains(&fr.scene))
        {
            match f {
                Some(f) => acc.add(&f.apply(&fr.depth)?, fr)?,
                None => acc.add(&fr.depth, fr)?,
            }
        }
        Ok(acc)
    };
    let score = |f: Option<&DepthFilter>| score_on(f, false);

    // 1. The sweep of m for the default k.
    let mut sweep_md = String::from(
        "| m | k (per m) | σ_d at 1 m / 3 m (mm) | RMSE < 1.5 m | 1.5–2.5 m | > 2.5 m | overall | edges |\n|---|---|---|---|---|---|---|---|\n",
    );
    let mut best_m = (f64::NAN, f64::INFINITY);
    let mut default_overall = f64::NAN;
    for m in M_SWEEP {
        let k = m * sensor.sigma_d_px / sensor.fb();
        let a = score_on(Some(&DepthFilter::adaptive(r, s, k)), true)?;
        writeln!(
            sweep_md,
            "| {m} | {k:.5} | {:.1} / {:.1} | {} | {} | {} | **{}** | {} |",
            k * 1e3,
            9.0 * k * 1e3,
            mm(a.band(0)),
            mm(a.band(1)),
            mm(a.band(2)),
            mm(a.overall()),
            mm(a.edge())
        )?;
        ctx.row(
            EXP,
            &format!("sweep m={m} overall RMSE"),
            a.overall() * 1e3,
            "mm",
        );
        if a.overall() < best_m.1 {
            best_m = (m, a.overall());
        }
        if (m - DEFAULT_K_MULTIPLIER).abs() < 1e-9 {
            default_overall = a.overall();
        }
    }
    ctx.check(
        "default k multiplier is the sweep optimum",
        default_overall <= best_m.1 * 1.005,
        format!(
            "DEFAULT_K_MULTIPLIER = {DEFAULT_K_MULTIPLIER} gives {} mm overall; sweep best m = {} with {} mm",
            mm(default_overall),
            best_m.0,
            mm(best_m.1)
        ),
    );

    // 2. The methods.
    let mut methods: Vec<(String, Option<DepthFilter>)> = vec![
        ("raw".into(), None),
        (
            format!("gaussian σ_s {s}"),
            Some(DepthFilter::gaussian(r, s)),
        ),
    ];
    for sd in SIGMA_D_SWEEP_MM {
        methods.push((
            format!("bilateral σ_d {sd} mm"),
            Some(DepthFilter::bilateral(r, s, sd * 1e-3)),
        ));
    }
    let adaptive = DepthFilter::default_for(sl_filter::Method::Adaptive, &sensor);
    let disparity = DepthFilter::default_for(sl_filter::Method::Disparity, &sensor);
    methods.push(("adaptive (default k)".into(), Some(adaptive)));
    methods.push(("disparity (default σ_D)".into(), Some(disparity)));
    let mut table = String::from(
        "| method | RMSE < 1.5 m | 1.5–2.5 m | > 2.5 m | overall | edges (≤ 2 px) | overall, 4 scenes |\n|---|---|---|---|---|---|---|\n",
    );
    let mut results = Vec::new();
    let mut results4 = Vec::new();
    for (name, f) in &methods {
        let a = score(f.as_ref())?;
        let a4 = score_on(f.as_ref(), true)?;
        writeln!(
            table,
            "| {name} | {} | {} | {} | {} | {} | {} |",
            mm(a.band(0)),
            mm(a.band(1)),
            mm(a.band(2)),
            mm(a.overall()),
            mm(a.edge()),
            mm(a4.overall())
        )?;
        ctx.row(
            EXP,
            &format!("{name} RMSE overall (4 scenes)"),
            a4.overall() * 1e3,
            "mm",
        );
        results4.push((name.clone(), a4));
        for (i, band) in ["<1.5m", "1.5-2.5m", ">2.5m"].iter().enumerate() {
            ctx.row(EXP, &format!("{name} RMSE {band}"), a.band(i) * 1e3, "mm");
        }
        ctx.row(
            EXP,
            &format!("{name} RMSE overall"),
            a.overall() * 1e3,
            "mm",
        );
        ctx.row(EXP, &format!("{name} RMSE edges"), a.edge() * 1e3, "mm");
        results.push((name.clone(), a));
    }
    let get = |prefix: &str| {
        results
            .iter()
            .find(|(n, _)| n.starts_with(prefix))
            .map(|(_, a)| a.clone())
            .unwrap_or_default()
    };
    let raw = get("raw");
    let ada = get("adaptive");
    let disp = get("disparity");
    let best_bilateral = results
        .iter()
        .filter(|(n, _)| n.starts_with("bilateral"))
        .min_by(|a, b| a.1.overall().total_cmp(&b.1.overall()))
        .map(|(n, a)| (n.clone(), a.clone()))
        .unwrap_or_default();
    let ada4 = results4
        .iter()
        .find(|(n, _)| n.starts_with("adaptive"))
        .map(|(_, a)| a.overall())
        .unwrap_or(f64::NAN);
    let best_bilateral4 = results4
        .iter()
        .filter(|(n, _)| n.starts_with("bilateral"))
        .min_by(|a, b| a.1.overall().total_cmp(&b.1.overall()))
        .map(|(n, a)| (n.clone(), a.overall()))
        .unwrap_or_default();
    let bands_ok = (0..3).all(|i| ada.n[i] == 0 || ada.band(i) < raw.band(i));
    ctx.check(
        "adaptive beats raw in every depth band",
        bands_ok,
        format!(
            "adaptive {} / {} / {} mm vs raw {} / {} / {} mm",
            mm(ada.band(0)),
            mm(ada.band(1)),
            mm(ada.band(2)),
            mm(raw.band(0)),
            mm(raw.band(1)),
            mm(raw.band(2))
        ),
    );
    ctx.check(
        "adaptive beats the best single-σ_d bilateral overall",
        ada.overall() < best_bilateral.1.overall(),
        format!(
            "adaptive {} mm vs best bilateral ({}) {} mm",
            mm(ada.overall()),
            best_bilateral.0,
            mm(best_bilateral.1.overall())
        ),
    );
    ctx.check(
        "adaptive beats the best single-σ_d bilateral overall on all four scenes",
        ada4 < best_bilateral4.1,
        format!(
            "adaptive {} mm vs best bilateral ({}) {} mm",
            mm(ada4),
            best_bilateral4.0,
            mm(best_bilateral4.1)
        ),
    );
    ctx.check(
        "adaptive edge error near raw (≤ 1.1× raw)",
        ada.edge() <= EDGE_TOLERANCE * raw.edge(),
        format!(
            "adaptive {} mm vs raw {} mm at pixels ≤ 2 px from a true depth edge",
            mm(ada.edge()),
            mm(raw.edge())
        ),
    );
    let rel = disp.overall() / ada.overall() - 1.0;
    let verdict = if rel.abs() < 0.01 {
        "matches (within 1 %)"
    } else if rel < 0.0 {
        "beats"
    } else {
        "is worse than"
    };
    let frames_desc: Vec<String> = EVAL_SCENES.iter().map(|s| s.to_string()).collect();

    // Side-by-side normals of the first frame of each scene.
    let mut images = String::new();
    for scene in ["floor", "figure-walls"] {
        if let Some(fr) = frames.iter().find(|f| f.scene == scene) {
            let bil = best_bilateral_filter(&methods, &best_bilateral.0);
            let path = write_normals(
                ctx.out_dir(),
                &format!("filter_{scene}_normals.png"),
                &fr.depth,
                &fr.k,
                &[
                    Some(DepthFilter::gaussian(r, s)),
                    bil,
                    Some(adaptive),
                    Some(disparity),
                ],
            )?;
            writeln!(
                images,
                "![{scene}: raw | gaussian | best bilateral | adaptive | disparity]({path})"
            )?;
        }
    }
    ctx.section(
        "Depth filters (paper §3.1–3.2): simulated Kinect frames",
        format!(
            "Frames: {} (`sl-noise` Kinect simulator, σ_D = {} px, 1/8 px quantisation, 1 mm steps), \
             {} seed(s) each; 7×7 window, σ_s = {s} px for every filter. RMSE against the exact depth, \
             pooled over frames, per band of the true depth; *edges* = pixels within 2 px of a true \
             depth jump > 5 %.\n\n**Sweep of the default multiplier m** (k = m·σ_D/(f·B), σ_d(Z) = m·σ_Z(Z)), on the two \
             evaluation scenes plus `three-planes` (a book 1 cm above a table at 0.6 m) and `boxes`, \
             so that small depth steps count:\n\n{sweep_md}\n\
             Best m = {} ({} mm overall); sl-filter's DEFAULT_K_MULTIPLIER = {DEFAULT_K_MULTIPLIER}.\n\n\
             **Methods:**\n\n{table}\nThe disparity-domain bilateral {verdict} the adaptive filter overall \
             ({:.3} mm vs {:.3} mm).\n\nNormals (raw | Gaussian | best bilateral | adaptive | disparity):\n\n{images}",
            frames_desc.join(", "),
            sensor.sigma_d_px,
            seeds,
            best_m.0,
            mm(best_m.1),
            disp.overall() * 1e3,
            ada.overall() * 1e3,
        ),
    );
    realistic_rows(ctx, &methods, seeds)?;
    real_frames(ctx, &methods)?;
    multiscale_sim(ctx, seeds)?;
    if !ctx.quick() {
        multiscale_cameras(ctx, seeds)?;
    }
    multiscale_real(ctx)?;
    Ok(())
}

/// Issue 11: the same methods on the realistic simulator (correlated block-matching error,
/// occlusion bands, drop-outs), beside the white-noise table above. Reported, not checked: the
/// checks above are the paper's claims on its white-noise model.
fn realistic_rows(
    ctx: &mut Context,
    methods: &[(String, Option<DepthFilter>)],
    seeds: u64,
) -> Result<()> {
    let sim = KinectSimulator::kinect_v1();
    let frames = simulate_frames(&sim, &EVAL_SCENES, seeds)?;
    // Surfaces: pixels more than 4 px from a true depth jump (the matcher fattens foreground
    // edges into the shadow by 3 px, an error of the jump's size that would swamp the bands).
    let surfaces: Vec<Vec<bool>> = frames
        .iter()
        .map(|fr| {
            eval::depth_edge_mask(&fr.truth, 0.05, 4)
                .iter()
                .map(|e| !e)
                .collect()
        })
        .collect();
    let mut table = String::from(
        "| method | RMSE < 1.5 m | 1.5–2.5 m | > 2.5 m | overall | edges (≤ 2 px) | overall / raw |\n|---|---|---|---|---|---|---|\n",
    );
    let mut raw_overall = f64::NAN;
    for (name, f) in methods {
        let mut acc = Acc::default();
        for (fr, surf) in frames.iter().zip(&surfaces) {
            let est = match f {
                Some(f) => f.apply(&fr.depth)?,
                None => fr.depth.clone(),
            };
            acc.add_masked(&est, &fr.truth, Some(surf), &fr.edges)?;
        }
        if f.is_none() {
            raw_overall = acc.overall();
        }
        writeln!(
            table,
            "| {name} | {} | {} | {} | {} | {} | {:.2} |",
            mm(acc.band(0)),
            mm(acc.band(1)),
            mm(acc.band(2)),
            mm(acc.overall()),
            mm(acc.edge()),
            acc.overall() / raw_overall
        )?;
        ctx.row(
            EXP,
            &format!("realistic: {name} RMSE overall"),
            acc.overall() * 1e3,
            "mm",
        );
        ctx.row(
            EXP,
            &format!("realistic: {name} RMSE edges"),
            acc.edge() * 1e3,
            "mm",
        );
    }
    ctx.section(
        "Depth filters on the realistic simulator (issue 11)",
        format!(
            "The methods of the table above on the realistic simulator (`NoiseModel::Realistic`, \
             the default since issue 11: disparity error correlated over the 9×11 px matching \
             window, occlusion bands, drop-outs; see docs/NOISE_MODEL.md), scenes {}, {seeds} \
             seed(s) each. Bands: RMSE over surface pixels (more than 4 px from a true depth jump; \
             the matcher's foreground fattening puts the jump's whole size on the 3 px next to an \
             edge) valid in both output and truth; edges: pixels ≤ 2 px from a jump, as above. The \
             white-noise results above stay the reference for the paper's claims.\n\n{table}",
            EVAL_SCENES.join(", ")
        ),
    );
    Ok(())
}

fn best_bilateral_filter(
    methods: &[(String, Option<DepthFilter>)],
    name: &str,
) -> Option<DepthFilter> {
    methods
        .iter()
        .find(|(n, _)| n == name)
        .and_then(|(_, f)| *f)
}

fn mm(v_m: f64) -> String {
    if v_m.is_finite() {
        format!("{:.2}", v_m * 1e3)
    } else {
        "–".into()
    }
}

/// Writes raw and filtered shaded normals side by side; returns the file name.
fn write_normals(
    dir: &Path,
    name: &str,
    depth: &DepthImage,
    k: &Intrinsics,
    filters: &[Option<DepthFilter>],
) -> Result<String> {
    let mut imgs = vec![sl_eval::render::shaded_normals(depth, k)?];
    for f in filters.iter().flatten() {
        imgs.push(sl_eval::render::shaded_normals(&f.apply(depth)?, k)?);
    }
    let refs: Vec<&_> = imgs.iter().collect();
    let img = sl_eval::render::side_by_side(&refs)?;
    std::fs::create_dir_all(dir)?;
    sl_io::rgb::write_rgb_png(dir.join(name), &img)?;
    Ok(name.to_string())
}

/// Real frames: plane-fit residual per band on the dominant plane.
fn real_frames(ctx: &mut Context, methods: &[(String, Option<DepthFilter>)]) -> Result<()> {
    let Some(data) = ctx.data_dir().map(Path::to_path_buf) else {
        ctx.section(
            "Depth filters: real frames",
            "skipped: ../shared/data not found".to_string(),
        );
        return Ok(());
    };
    let tum_first = std::fs::read_to_string(data.join("tum-fr1-rpy/associations.txt"))
        .ok()
        .and_then(|s| {
            s.lines()
                .next()
                .and_then(|l| l.split_whitespace().nth(3).map(str::to_string))
        });
    let pcl_first = std::fs::read_dir(data.join("pcl-floor-box"))
        .ok()
        .and_then(|d| {
            let mut v: Vec<_> = d
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.to_string_lossy().ends_with("_depth.tiff"))
                .collect();
            v.sort();
            v.into_iter().next()
        });
    let mut frames: Vec<(String, std::path::PathBuf, f64, Intrinsics)> = vec![(
        "person-depth.png (wall)".into(),
        data.join("open3d-testdata/person-depth.png"),
        1000.0,
        Camera::preset("ros-default")?.intrinsics,
    )];
    if let Some(p) = pcl_first {
        frames.push((
            "pcl-floor-box (floor)".into(),
            p,
            1000.0,
            Camera::preset("pcl-openni")?.intrinsics,
        ));
    }
    if let Some(rel) = tum_first {
        frames.push((
            "tum-fr1-rpy frame 0".into(),
            data.join("tum-fr1-rpy").join(rel),
            5000.0,
            Camera::preset("tum-fr1")?.intrinsics,
        ));
    }
    let mut md = String::from(
        "Residual = RMS orthogonal distance to a least-squares plane fitted (per method) on the dominant \
         plane's region: RANSAC (500 samples) with an inlier band 3σ_Z(Z) + ΔZ(Z) + 2 mm, refitted, mask \
         closed by 2 px and eroded by r + 1 = 4 px (see `sl_eval::filter::dominant_plane_region`). \
         Filters use the frame's camera (f from the intrinsics, B = 75 mm, σ_D = 0.07 px).\n\n",
    );
    let mut first_img = None;
    for (name, path, scale, k) in frames {
        let loaded = match sl_io::depth::read_depth(
            &path,
            &sl_io::depth::ReadConfig::default().with_scale(scale),
        ) {
            Ok(l) => l,
            Err(e) => {
                writeln!(md, "- {name}: could not read {} ({e})", path.display())?;
                continue;
            }
        };
        let camera = Camera::from_intrinsics(k, None, None)?;
        let sensor: SensorModel = camera.sensor;
        let depth = loaded.depth;
        let Some(region) =
            eval::dominant_plane_region(&depth, &k, &sensor, DEFAULT_RADIUS_PX + 1, 500, 7)
                .with_context(|| format!("plane region of {name}"))?
        else {
            writeln!(md, "- {name}: no dominant plane found")?;
            continue;
        };
        let npx = region.mask.iter().filter(|&&m| m).count();
        writeln!(
            md,
            "**{name}** — region of {npx} px, plane normal ({:.2}, {:.2}, {:.2}):\n",
            region.plane.normal[0], region.plane.normal[1], region.plane.normal[2]
        )?;
        md.push_str("| method | < 1.5 m | 1.5–2.5 m | > 2.5 m |\n|---|---|---|---|\n");
        // Per-frame sensor for the sensor-derived filters; the fixed ones as in the simulation.
        for (mname, f) in methods {
            let f = match (mname.as_str(), f) {
                (n, _) if n.starts_with("adaptive") => Some(DepthFilter::default_for(
                    sl_filter::Method::Adaptive,
                    &sensor,
                )),
                (n, _) if n.starts_with("disparity") => Some(DepthFilter::default_for(
                    sl_filter::Method::Disparity,
                    &sensor,
                )),
                (_, f) => *f,
            };
            let out = match &f {
                Some(f) => f.apply(&depth)?,
                None => depth.clone(),
            };
            let res = eval::plane_residual_by_band(&out, &k, &region.mask, &KINECT_BANDS_M)?;
            let cell = |b: &BandError| {
                if b.pixels > 0 {
                    format!("{} ({} px)", mm(b.rmse_m), b.pixels)
                } else {
                    "–".into()
                }
            };
            writeln!(
                md,
                "| {mname} | {} | {} | {} |",
                cell(&res[0]),
                cell(&res[1]),
                cell(&res[2])
            )?;
            for (i, band) in ["<1.5m", "1.5-2.5m", ">2.5m"].iter().enumerate() {
                if res[i].pixels > 0 {
                    ctx.row(
                        EXP,
                        &format!("{name} {mname} plane residual {band}"),
                        res[i].rmse_m * 1e3,
                        "mm",
                    );
                }
            }
        }
        md.push('\n');
        if first_img.is_none() {
            let f = [
                methods
                    .iter()
                    .find(|(n, _)| n.starts_with("gaussian"))
                    .and_then(|(_, f)| *f),
                Some(DepthFilter::bilateral(
                    DEFAULT_RADIUS_PX,
                    default_sigma_s_px(DEFAULT_RADIUS_PX),
                    0.02,
                )),
                Some(DepthFilter::default_for(
                    sl_filter::Method::Adaptive,
                    &sensor,
                )),
                Some(DepthFilter::default_for(
                    sl_filter::Method::Disparity,
                    &sensor,
                )),
            ];
            first_img = Some(write_normals(
                ctx.out_dir(),
                "filter_person_normals.png",
                &depth,
                &k,
                &f,
            )?);
        }
    }
    if let Some(p) = first_img {
        writeln!(
            md,
            "Normals of person-depth.png (raw | Gaussian | bilateral 20 mm | adaptive | disparity):\n\n![person]({p})"
        )?;
    }
    ctx.section(
        "Depth filters: real frames (plane residual per depth band)",
        md,
    );
    Ok(())
}

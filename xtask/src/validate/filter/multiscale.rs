//! Issue 11: the multi-scale filter (`sl_filter::MultiScale`) against the single-pass filters,
//! on the realistic simulator and on real frames (residual per depth band, normal spread, and
//! the share of the raw residual at scales no shape-keeping filter can remove).

use super::*;

/// Real-frame bands of the issue-11 target ("at ≥ 2 m").
const REAL_BANDS_M: [(f32, f32); 3] = [(0.0, 1.5), (1.5, 2.0), (2.0, f32::INFINITY)];

/// A filter of the multi-scale comparison: a single pass or the multi-scale filter.
enum Candidate {
    Raw,
    One(DepthFilter),
    Multi(MultiScale),
}

impl Candidate {
    fn apply(&self, d: &DepthImage) -> Result<DepthImage> {
        Ok(match self {
            Candidate::Raw => d.clone(),
            Candidate::One(f) => f.apply(d)?,
            Candidate::Multi(m) => m.apply(d)?,
        })
    }
}

/// The candidates for a sensor: raw, the paper's adaptive default, the disparity default, and
/// the multi-scale filter (adaptive 7×7, then 5×5 disparity passes at dilations 2 and 4).
fn candidates(sensor: &SensorModel) -> Vec<(&'static str, Candidate)> {
    vec![
        ("raw", Candidate::Raw),
        (
            "adaptive 7×7 (default)",
            Candidate::One(DepthFilter::default_for(
                sl_filter::Method::Adaptive,
                sensor,
            )),
        ),
        (
            "disparity 7×7",
            Candidate::One(DepthFilter::default_for(
                sl_filter::Method::Disparity,
                sensor,
            )),
        ),
        (
            "multiscale (adaptive 7×7 + disparity 5×5 at dilation 2, 4)",
            Candidate::Multi(MultiScale::default_for(sensor)),
        ),
    ]
}

/// Issue 11 §3: the multi-scale filter on both simulators (surface RMSE and the edge benchmark).
pub(super) fn multiscale_sim(ctx: &mut Context, seeds: u64) -> Result<()> {
    let mut md = String::new();
    for (label, sim) in [
        ("white (paper)", KinectSimulator::kinect_v1().white()),
        ("realistic (default)", KinectSimulator::kinect_v1()),
    ] {
        // Pooled over the evaluation scenes, then each scene alone.
        let mut groups: Vec<(String, Vec<&str>)> =
            vec![(EVAL_SCENES.join(", "), EVAL_SCENES.to_vec())];
        groups.extend(EVAL_SCENES.iter().map(|s| (s.to_string(), vec![*s])));
        for (gname, scenes) in groups {
            let mut frames = Vec::new();
            for name in scenes {
                let ns = named_scene(name)?;
                for seed in 0..seeds {
                    let fr = sim.simulate(&ns.scene, &ns.intrinsics, &ns.pose, 1000 + seed);
                    let edges = eval::depth_edge_mask(&fr.truth, 0.05, 2);
                    let surf: Vec<bool> = eval::depth_edge_mask(&fr.truth, 0.05, 4)
                        .iter()
                        .map(|e| !e)
                        .collect();
                    frames.push((fr.truth, fr.depth, edges, surf));
                }
            }
            writeln!(
                md,
                "**{label} simulator** ({gname}, {seeds} seed(s)):\n\n| method | surface RMSE < 1.5 m | 1.5–2.5 m | > 2.5 m | overall | overall / raw | edges (≤ 2 px) | edges / raw |\n|---|---|---|---|---|---|---|---|"
            )?;
            let (mut raw_all, mut raw_edge) = (f64::NAN, f64::NAN);
            for (name, c) in candidates(&sim.sensor) {
                let mut acc = Acc::default();
                for (truth, depth, edges, surf) in &frames {
                    let est = c.apply(depth)?;
                    for (i, b) in eval::rmse_by_band(&est, truth, Some(surf), &KINECT_BANDS_M)?
                        .iter()
                        .enumerate()
                    {
                        acc.add_band(i, b);
                    }
                    let e = eval::rmse_by_band(&est, truth, Some(edges), &[(0.0, f32::INFINITY)])?;
                    if e[0].pixels > 0 {
                        acc.edge_n += e[0].pixels;
                        acc.edge_ss += e[0].rmse_m * e[0].rmse_m * e[0].pixels as f64;
                    }
                }
                if matches!(c, Candidate::Raw) {
                    raw_all = acc.overall();
                    raw_edge = acc.edge();
                }
                writeln!(
                    md,
                    "| {name} | {} | {} | {} | {} | {:.2} | {} | {:.2} |",
                    mm(acc.band(0)),
                    mm(acc.band(1)),
                    mm(acc.band(2)),
                    mm(acc.overall()),
                    acc.overall() / raw_all,
                    mm(acc.edge()),
                    acc.edge() / raw_edge
                )?;
                ctx.row(
                    EXP,
                    &format!("multiscale table {label} [{gname}]: {name} surface RMSE"),
                    acc.overall() * 1e3,
                    "mm",
                );
                ctx.row(
                    EXP,
                    &format!("multiscale table {label} [{gname}]: {name} edge RMSE"),
                    acc.edge() * 1e3,
                    "mm",
                );
            }
            md.push('\n');
        }
    }
    ctx.section(
        "Depth filters: multi-scale filter on the simulators (issue 11 §3)",
        format!(
            "Surface RMSE (pixels more than 4 px from a true depth jump) and edge RMSE (pixels \
             ≤ 2 px from a jump > 5 %) against the exact depth. The issue's edge target: within \
             10 % of raw. Reported, not checked (the multi-scale filter is not the default).\n\n{md}"
        ),
    );
    Ok(())
}

/// Issue 11 §3: plane residual and normal spread at < 2 m and ≥ 2 m on real frames, for the
/// multi-scale candidates.
pub(super) fn multiscale_real(ctx: &mut Context) -> Result<()> {
    if ctx.data_dir().is_none() {
        ctx.section(
            "Depth filters: multi-scale filter on real frames",
            "skipped: ../shared/data not found".to_string(),
        );
        return Ok(());
    }
    let mut frames = Vec::new();
    frames.extend(sl_testkit::person());
    frames.extend(sl_testkit::floor_scan(3));
    frames.extend(sl_testkit::tum_rpy(30).into_iter().step_by(10));
    let mut md = String::from(
        "Per frame, the dominant plane's region as in the table above (RANSAC on the raw frame, \
         eroded by 4 px). *Residual*: RMS distance to a least-squares plane fitted per method \
         (`plane_residual_by_band`), mm, with the ratio to raw. *Spread*: RMS angle of the \
         pixel normals (central differences ±1 px) to the region's plane, degrees \
         (`normal_spread_by_band`). *Low-pass share*: the RMS of the raw residual after a \
         masked Gaussian of σ = 16 px, i.e. the part of the raw residual on scales no local \
         filter that keeps shape can remove (surface shape, the Kinect's low-frequency \
         distortion).\n\n| frame | method | residual < 1.5 m | 1.5–2 m | ≥ 2 m | spread < 2 m | spread ≥ 2 m |\n|---|---|---|---|---|---|---|\n",
    );
    let mut lowpass = String::new();
    let mut lowpass_img = String::new();
    for fr in &frames {
        let k = fr.camera.intrinsics;
        let sensor = fr.camera.sensor;
        let Some(region) =
            eval::dominant_plane_region(&fr.depth, &k, &sensor, DEFAULT_RADIUS_PX + 1, 500, 7)?
        else {
            continue;
        };
        lowpass_share(&mut lowpass, &fr.name, &fr.depth, &k, &region)?;
        if fr.name == "person" {
            let mut imgs = Vec::new();
            for (_, c) in candidates(&sensor) {
                if !matches!(c, Candidate::One(f) if f.method() == sl_filter::Method::Disparity) {
                    imgs.push(sl_eval::render::shaded_normals(&c.apply(&fr.depth)?, &k)?);
                }
            }
            let refs: Vec<&_> = imgs.iter().collect();
            std::fs::create_dir_all(ctx.out_dir())?;
            sl_io::rgb::write_rgb_png(
                ctx.out_dir().join("filter_person_multiscale_normals.png"),
                &sl_eval::render::side_by_side(&refs)?,
            )?;
            writeln!(
                lowpass_img,
                "\n![person-depth.png normals: raw | adaptive 7×7 | multiscale](filter_person_multiscale_normals.png)"
            )?;
        }
        let mut raw = [f64::NAN; 3];
        for (name, c) in candidates(&sensor) {
            let out = c.apply(&fr.depth)?;
            let res = eval::plane_residual_by_band(&out, &k, &region.mask, &REAL_BANDS_M)?;
            let spr = eval::normal_spread_by_band(
                &out,
                &k,
                &region.mask,
                &region.plane.normal,
                1,
                &[(0.0, 2.0), (2.0, f32::INFINITY)],
            )?;
            if matches!(c, Candidate::Raw) {
                for (r, b) in raw.iter_mut().zip(&res) {
                    *r = b.rmse_m;
                }
            }
            let cell = |i: usize| {
                let b = &res[i];
                if b.pixels > 0 {
                    format!("{} ({:.2}×)", mm(b.rmse_m), b.rmse_m / raw[i])
                } else {
                    "–".into()
                }
            };
            let sp = |i: usize| {
                if spr[i].pixels > 0 {
                    format!("{:.2}°", spr[i].rms_deg)
                } else {
                    "–".into()
                }
            };
            writeln!(
                md,
                "| {} | {name} | {} | {} | {} | {} | {} |",
                fr.name,
                cell(0),
                cell(1),
                cell(2),
                sp(0),
                sp(1)
            )?;
            if res[2].pixels > 0 {
                ctx.row(
                    EXP,
                    &format!("real {} {name} plane residual >=2m", fr.name),
                    res[2].rmse_m * 1e3,
                    "mm",
                );
            }
        }
    }
    ctx.section(
        "Depth filters: multi-scale filter on real frames (issue 11 §3)",
        format!("{md}\n**Raw residual split by scale** (σ = 16 px masked Gaussian):\n\n| frame | band | raw residual | low-pass part | high-pass part |\n|---|---|---|---|---|\n{lowpass}{lowpass_img}"),
    );
    Ok(())
}

/// Splits the raw plane residual of `region` into its σ = 16 px low-pass and the rest, per band
/// (< 2 m, ≥ 2 m), as table rows.
fn lowpass_share(
    md: &mut String,
    name: &str,
    depth: &DepthImage,
    k: &Intrinsics,
    region: &eval::PlaneRegion,
) -> Result<()> {
    let (w, h) = (depth.width(), depth.height());
    let z = depth.data();
    // Signed distances, offset by 1 m so the Gaussian (which skips zeros) sees them as valid.
    let mut r = vec![0.0f32; w * h];
    for (i, v) in r.iter_mut().enumerate() {
        if region.mask[i] && z[i] > 0.0 {
            let d = f64::from(z[i]);
            let p = sl_core::nalgebra::Point3::new(
                ((i % w) as f64 - k.cx) / k.fx * d,
                ((i / w) as f64 - k.cy) / k.fy * d,
                d,
            );
            *v = (1.0 + region.plane.signed_distance_m(&p)) as f32;
        }
    }
    let img = DepthImage::from_vec(w, h, r)?;
    let lp = DepthFilter::gaussian(32, 16.0).apply(&img)?;
    let mut acc = [(0.0f64, 0.0f64, 0.0f64, 0usize); 2];
    for ((&t, &l), &d) in img.data().iter().zip(lp.data()).zip(z) {
        if t > 0.0 {
            let b = usize::from(d >= 2.0);
            let (t, l) = (f64::from(t) - 1.0, f64::from(l) - 1.0);
            acc[b].0 += t * t;
            acc[b].1 += l * l;
            acc[b].2 += (t - l) * (t - l);
            acc[b].3 += 1;
        }
    }
    for (b, a) in acc.iter().enumerate() {
        if a.3 > 0 {
            let n = a.3 as f64;
            writeln!(
                md,
                "| {name} | {} | {} | {} | {} |",
                if b == 0 { "< 2 m" } else { "≥ 2 m" },
                mm((a.0 / n).sqrt()),
                mm((a.1 / n).sqrt()),
                mm((a.2 / n).sqrt())
            )?;
        }
    }
    Ok(())
}

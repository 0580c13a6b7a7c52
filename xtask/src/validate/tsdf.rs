//! Section 3.3 of the paper: noise-weighted volumetric scan merging (Figures 5–7 as numbers).
//!
//! 1. Simulated, with ground truth: a plate with a fine sinusoidal relief (±3 mm, 4 cm
//!    wavelength) scanned once from 0.75 m and once from 1.5 m by the Kinect simulator of
//!    `sl-noise` (known poses). The two scans are fused with `uniform`, `inv-z2` and `inv-z4`
//!    weights; the distance from the fused mesh vertices to the true surface (mean, RMS, 95th
//!    percentile) is reported, and `inv-z4` must have a clearly lower RMS (we expect ≥ 25 %
//!    lower than `uniform`). Cross-sections of F for both weights are written side by side,
//!    with both zero crossings over the true profile and their distance from it along the
//!    line below them (the paper's Figure 7).
//! 2. Real: the ICL-NUIM and 7-Scenes frames fused with each weight (4 mm voxels, 2 cm
//!    truncation): vertex and triangle counts, timings, and a shaded rendering of each mesh
//!    from the first camera.
//! 3. Truncation (`tsdf_trunc`): the real sequences fused with the former fixed 2 cm band and
//!    the default sensor-adaptive band; fused-surface plane residuals and vertex counts.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context as _, Result};
use sl_core::nalgebra::{Point3, Vector3};
use sl_core::{Camera, CameraToWorld, Image, Intrinsics};
use sl_eval::DistanceStats;
use sl_noise::sim::{KinectSimulator, ReliefPlate, Scene, look_at};
use sl_tsdf::slice::hconcat;
use sl_tsdf::{Axis, DepthLookup, MeshConfig, SliceSpec, TsdfConfig, TsdfVolume, WeightMode};

use super::Context;

const EXP: &str = "tsdf";
/// Relief amplitude (metres) and wavelength.
const RELIEF_AMPLITUDE_M: f64 = 0.003;
const RELIEF_WAVELENGTH_M: f64 = 0.04;
/// Plate half size.
const PLATE_HALF_M: f64 = 0.15;
/// The evaluated region: the plate interior (edges excluded, where each scan's silhouette and
/// the plate's rim add errors unrelated to the weighting).
const EVAL_HALF_M: f64 = 0.12;

/// Runs the experiment.
pub fn run(ctx: &mut Context) -> Result<()> {
    simulated(ctx)?;
    real(ctx)?;
    super::tsdf_trunc::run(ctx)?;
    Ok(())
}

fn weight_modes() -> [WeightMode; 3] {
    [WeightMode::Uniform, WeightMode::InvZ2, WeightMode::InvZ4]
}

fn simulated(ctx: &mut Context) -> Result<()> {
    let plate = ReliefPlate::new(
        Point3::origin(),
        Vector3::new(PLATE_HALF_M, 0.0, 0.0),
        Vector3::new(0.0, PLATE_HALF_M, 0.0),
        RELIEF_AMPLITUDE_M,
        RELIEF_WAVELENGTH_M,
    )?;
    let mut scene = Scene::new();
    scene.add(plate);
    let camera = Camera::kinect_v1();
    let k = camera.intrinsics;
    let sim = KinectSimulator::kinect_v1().white();
    // The plate faces +z; the close scan from 0.75 m, the distant one from 1.5 m, both a little
    // off-axis so the two pixel grids do not line up.
    let near = look_at(
        Point3::new(0.04, -0.03, 0.75),
        Point3::origin(),
        Vector3::y(),
    )?;
    let far = look_at(
        Point3::new(-0.10, 0.06, 1.5),
        Point3::origin(),
        Vector3::y(),
    )?;
    let seeds: &[u64] = if ctx.quick() { &[1] } else { &[1, 2, 3] };
    let voxel_m = 0.002;
    // Truncation: 3σ_Z of the distant scan (3.6 mm at 1.5 m) plus its depth step (6.5 mm)
    // rounded up: 1.2 cm = 6 voxels.
    let trunc_m = 0.012;
    let keep = |p: &Point3<f64>| p.x.abs() < EVAL_HALF_M && p.y.abs() < EVAL_HALF_M;

    let mut md = String::new();
    writeln!(
        md,
        "A {:.0}x{:.0} cm plate with a ±{:.0} mm sinusoidal relief ({:.0} cm wavelength), scanned by the \
         simulated Kinect v1 (σ_D = {} px, 1/8 px disparity, 1 mm depth steps) once from 0.75 m and once \
         from 1.5 m, fused at {:.0} mm voxels with {:.0} mm truncation. Distances from the mesh vertices over \
         the central {:.0}x{:.0} cm to the true surface (`Scene::distance`), over {} noise seed(s).\n",
        2.0 * PLATE_HALF_M * 100.0,
        2.0 * PLATE_HALF_M * 100.0,
        RELIEF_AMPLITUDE_M * 1e3,
        RELIEF_WAVELENGTH_M * 100.0,
        camera.sensor.sigma_d_px,
        voxel_m * 1e3,
        trunc_m * 1e3,
        2.0 * EVAL_HALF_M * 100.0,
        2.0 * EVAL_HALF_M * 100.0,
        seeds.len()
    )?;
    writeln!(
        md,
        "| fusion | vertices | mean (mm) | RMS (mm) | p95 (mm) |"
    )?;
    writeln!(md, "|---|---|---|---|---|")?;

    let mut results: Vec<(String, DistanceStats)> = Vec::new();
    let mut slices = Vec::new();
    // Single scans for context, then the merges.
    let nearest = DepthLookup::Nearest;
    let mut configs: Vec<(String, WeightMode, bool, bool, DepthLookup)> = vec![
        (
            "near scan only (0.75 m)".into(),
            WeightMode::Uniform,
            true,
            false,
            nearest,
        ),
        (
            "far scan only (1.5 m)".into(),
            WeightMode::Uniform,
            false,
            true,
            nearest,
        ),
    ];
    for w in weight_modes() {
        configs.push((format!("both, {}", w.name()), w, true, true, nearest));
    }
    // Beyond the paper: each voxel reads inverse depth interpolated between the four pixels
    // around its projection (`DepthLookup::Bilinear`) instead of the nearest pixel's depth.
    configs.push((
        "both, inv-z4, bilinear depth".into(),
        WeightMode::InvZ4,
        true,
        true,
        DepthLookup::Bilinear,
    ));
    for (name, weight, use_near, use_far, lookup) in &configs {
        let mut dists = Vec::new();
        let mut verts = 0;
        for (si, &seed) in seeds.iter().enumerate() {
            let mut params = TsdfConfig::default();
            params.voxel_m = voxel_m;
            params.trunc_m = trunc_m;
            params.weight = *weight;
            params.max_depth_m = 3.0;
            params.depth_lookup = *lookup;
            let mut vol = TsdfVolume::new(params)?;
            if *use_near {
                let f = sim.simulate(&scene, &k, &near, seed * 2);
                vol.integrate(&f.depth, &k, &near)?;
            }
            if *use_far {
                let f = sim.simulate(&scene, &k, &far, seed * 2 + 1);
                vol.integrate(&f.depth, &k, &far)?;
            }
            let mesh = vol.extract_mesh(&MeshConfig::default());
            verts += mesh.vertex_count();
            dists.extend(sl_eval::tsdf::vertex_distances(&mesh, keep, |p| {
                scene.distance(p)
            }));
            if si == 0
                && *use_near
                && *use_far
                && *lookup == DepthLookup::Nearest
                && matches!(weight, WeightMode::Uniform | WeightMode::InvZ4)
            {
                // y = λ/4: the relief crest line along x.
                let spec = SliceSpec {
                    axis: Axis::Y,
                    coord_m: RELIEF_WAVELENGTH_M / 4.0,
                    pixels_per_voxel: 8,
                    window_m: Some(([-0.08, 0.08], [-0.012, 0.012])),
                };
                slices.push((weight.name(), vol.slice(&spec)?));
            }
        }
        let stats =
            DistanceStats::from_distances(&dists).context("no vertices in the evaluated region")?;
        writeln!(
            md,
            "| {name} | {} | {:.3} | {:.3} | {:.3} |",
            verts / seeds.len(),
            stats.mean_m * 1e3,
            stats.rms_m * 1e3,
            stats.p95_m * 1e3
        )?;
        for (metric, v) in [
            ("mean", stats.mean_m),
            ("rms", stats.rms_m),
            ("p95", stats.p95_m),
        ] {
            ctx.row(EXP, &format!("sim {name} {metric}"), v * 1e3, "mm");
        }
        results.push((name.clone(), stats));
    }
    let rms = |label: &str| {
        results
            .iter()
            .find(|(n, _)| n == label)
            .map(|(_, s)| s.rms_m)
    };
    if let (Some(u), Some(w)) = (rms("both, uniform"), rms("both, inv-z4")) {
        let reduction = 1.0 - w / u;
        ctx.row(
            EXP,
            "sim inv-z4 RMS reduction vs uniform",
            reduction * 100.0,
            "%",
        );
        writeln!(
            md,
            "\n`inv-z4` RMS is {:.1} % lower than `uniform`.",
            reduction * 100.0
        )?;
        ctx.check(
            "inv-z4 merge has >= 25 % lower RMS error than uniform",
            reduction >= 0.25,
            format!(
                "uniform {:.3} mm, inv-z4 {:.3} mm ({:.1} % lower)",
                u * 1e3,
                w * 1e3,
                reduction * 100.0
            ),
        );
    }
    if let (Some(n), Some(b)) = (rms("both, inv-z4"), rms("both, inv-z4, bilinear depth")) {
        writeln!(
            md,
            "With bilinear depth (`DepthLookup::Bilinear`) the `inv-z4` RMS is {:.1} % lower than with \
             the nearest pixel's.",
            (1.0 - b / n) * 100.0
        )?;
        ctx.check(
            "bilinear depth lookup fuses the relief no less accurately than the nearest pixel",
            b <= n,
            format!("nearest {:.3} mm, bilinear {:.3} mm", n * 1e3, b * 1e3),
        );
    }

    // Figure 7: both cross-sections; below them their zero crossings over the true profile,
    // and each zero crossing's distance from the true profile along the line.
    if slices.len() == 2 {
        let (a, b) = (&slices[0].1, &slices[1].1);
        let ia = a.to_rgb([0, 0, 0]);
        let ib = b.to_rgb([0, 0, 0]);
        let mut overlay = Image::filled(a.values.width(), a.values.height(), [255u8, 255, 255]);
        draw_true_profile(&mut overlay, a, &plate_height_at_crest);
        a.draw_zero_crossing(&mut overlay, UNIFORM_RGB);
        b.draw_zero_crossing(&mut overlay, INV_Z4_RGB);
        let errors = [a, b].map(|s| zero_crossing_errors(s, &plate_height_at_crest));
        let mean_abs = errors.each_ref().map(|e| {
            let v: Vec<f64> = e.iter().flatten().copied().collect();
            (v.iter().sum::<f64>() / v.len().max(1) as f64, v.len())
        });
        // Full height of the error panel: the larger 99th percentile, rounded up to the grid.
        let mut all: Vec<f64> = errors.iter().flatten().flatten().copied().collect();
        all.sort_by(f64::total_cmp);
        let p99 = all.get(all.len() * 99 / 100).copied().unwrap_or(0.0);
        let full_scale_m = (p99 / ERROR_GRID_M).ceil().max(1.0) * ERROR_GRID_M;
        let panel = error_panel(
            overlay.width(),
            overlay.height(),
            &[(&errors[0], UNIFORM_RGB), (&errors[1], INV_Z4_RGB)],
            full_scale_m,
        );
        let fig = hconcat(&[&ia, &ib], 6);
        let fig = vstack(&fig, &hconcat(&[&overlay, &panel], 6), 6);
        let path = ctx.out_dir().join("tsdf_cross_sections.png");
        sl_tsdf::io::write_png(&path, &fig)?;
        for ((name, _), (mae, _)) in slices.iter().zip(&mean_abs) {
            ctx.row(
                EXP,
                &format!("sim crest-line zero crossing {name} mean |error|"),
                mae * 1e3,
                "mm",
            );
        }
        writeln!(
            md,
            "\n![cross-sections](tsdf_cross_sections.png)\n\nTop: F on the plane y = {:.0} mm (x from −80 to \
             80 mm across, z from −12 to 12 mm up; blue behind, red in front of the surface, black zero \
             crossing, grey unobserved) for `uniform` (left) and `inv-z4` (right). Bottom left: the zero \
             crossings, `uniform` in red and `inv-z4` in blue, over the true relief profile in grey (same axes \
             as the top row). Bottom right: the distance of each zero crossing from the true profile along x \
             (same x axis; 0 at the bottom, {:.1} mm at the top — the larger 99th percentile, rounded up; larger \
             values are clipped —, grid lines every {:.1} mm; red `uniform`, blue `inv-z4`): mean {:.3} mm for `uniform` and {:.3} mm for `inv-z4` over {} and {} columns with a \
             zero crossing.",
            RELIEF_WAVELENGTH_M / 4.0 * 1e3,
            full_scale_m * 1e3,
            ERROR_GRID_M * 1e3,
            mean_abs[0].0 * 1e3,
            mean_abs[1].0 * 1e3,
            mean_abs[0].1,
            mean_abs[1].1,
        )?;
    }
    ctx.section(
        "TSDF fusion: 1/Z⁴ weights on a simulated relief (paper Fig. 5–7)",
        md,
    );
    Ok(())
}

/// Line colours of the two fusions in the cross-section figure.
const UNIFORM_RGB: [u8; 3] = [220, 30, 30];
const INV_Z4_RGB: [u8; 3] = [30, 60, 220];
/// Grid spacing of the error panel, metres.
const ERROR_GRID_M: f64 = 0.0005;

/// Per column of `slice`: the distance from the zero crossing of F (the first `+ → −`
/// change from the top, i.e. the surface seen from the front, linear between the two pixels)
/// to the true height `h(u)`; `None` where the column has no crossing.
fn zero_crossing_errors(slice: &sl_tsdf::Slice, h: &dyn Fn(f64) -> f64) -> Vec<Option<f64>> {
    let (w, hgt) = (slice.values.width(), slice.values.height());
    let d = slice.values.data();
    (0..w)
        .map(|x| {
            let u = slice.origin_m[0] + x as f64 * slice.pixel_m;
            (0..hgt.saturating_sub(1)).find_map(|y| {
                let (fa, fb) = (d[y * w + x], d[(y + 1) * w + x]);
                (fa >= 0.0 && fb < 0.0).then(|| {
                    // Row y is at v = origin + (hgt − 1 − y)·pixel; the crossing is below it.
                    let v_a = slice.origin_m[1] + (hgt - 1 - y) as f64 * slice.pixel_m;
                    let t = f64::from(fa) / f64::from(fa - fb);
                    (v_a - t * slice.pixel_m - h(u)).abs()
                })
            })
        })
        .collect()
}

/// A white `w`×`h` panel plotting each curve (value per column, metres) from 0 at the bottom
/// row to `full_scale_m` at the top (values above are clipped to the top row), with light grey
/// grid lines every [`ERROR_GRID_M`].
fn error_panel(
    w: usize,
    h: usize,
    curves: &[(&[Option<f64>], [u8; 3])],
    full_scale_m: f64,
) -> Image<[u8; 3]> {
    let mut img = Image::filled(w, h, [255u8, 255, 255]);
    if h < 2 {
        return img;
    }
    let row_of = |e: f64| {
        let r = (h - 1) as f64 * (1.0 - (e / full_scale_m).clamp(0.0, 1.0));
        r.round() as usize
    };
    let mut g = 0.0;
    while g <= full_scale_m + 1e-12 {
        let y = row_of(g);
        for p in &mut img.data_mut()[y * w..(y + 1) * w] {
            *p = [210, 210, 210];
        }
        g += ERROR_GRID_M;
    }
    for (values, rgb) in curves {
        let mut prev: Option<usize> = None;
        for (x, e) in values.iter().enumerate().take(w) {
            let Some(e) = e else {
                prev = None;
                continue;
            };
            let row = row_of(*e);
            let (lo, hi) = match prev {
                Some(p) => (p.min(row), p.max(row)),
                None => (row, row),
            };
            for y in lo..=hi {
                img.data_mut()[y * w + x] = *rgb;
            }
            prev = Some(row);
        }
    }
    img
}

/// True relief height along the crest line y = λ/4 (where sin(k·y) = 1).
fn plate_height_at_crest(x: f64) -> f64 {
    RELIEF_AMPLITUDE_M * (std::f64::consts::TAU / RELIEF_WAVELENGTH_M * x).sin()
}

/// Draws `z = h(u)` in grey on an image laid out like `slice` (columns u, rows v = z upwards).
fn draw_true_profile(img: &mut Image<[u8; 3]>, slice: &sl_tsdf::Slice, h: &dyn Fn(f64) -> f64) {
    let (w, hgt) = (img.width(), img.height());
    let mut prev: Option<usize> = None;
    for x in 0..w {
        let u = slice.origin_m[0] + x as f64 * slice.pixel_m;
        let row_f = (hgt - 1) as f64 - (h(u) - slice.origin_m[1]) / slice.pixel_m;
        if !(row_f >= 0.0 && row_f < hgt as f64) {
            prev = None;
            continue;
        }
        let row = row_f.round() as usize;
        let (lo, hi) = match prev {
            Some(p) => (p.min(row), p.max(row)),
            None => (row, row),
        };
        for y in lo..=hi {
            img.data_mut()[y * w + x] = [150, 150, 150];
        }
        prev = Some(row);
    }
}

fn vstack(top: &Image<[u8; 3]>, bottom: &Image<[u8; 3]>, gap: usize) -> Image<[u8; 3]> {
    let w = top.width().max(bottom.width());
    let h = top.height() + gap + bottom.height();
    let mut out = Image::filled(w, h, [200u8, 200, 200]);
    for (y0, img) in [(0, top), (top.height() + gap, bottom)] {
        for y in 0..img.height() {
            out.data_mut()[(y0 + y) * w..(y0 + y) * w + img.width()].copy_from_slice(img.row(y));
        }
    }
    out
}

struct RealSeq {
    name: &'static str,
    k: Intrinsics,
    frames: Vec<(sl_core::DepthImage, CameraToWorld)>,
}

fn load_real(data: &Path, quick: bool) -> Result<Vec<RealSeq>> {
    let mut out = Vec::new();
    let read = |p: &Path| -> Result<sl_core::DepthImage> {
        Ok(
            sl_io::depth::read_depth(p, &sl_io::depth::ReadConfig::default())
                .with_context(|| format!("reading {}", p.display()))?
                .depth,
        )
    };
    let icl = data.join("open3d-testdata/icl-livingroom");
    if icl.is_dir() {
        let frames =
            sl_io::trajectory::read_open3d_log_frames(icl.join("odometry.log"), icl.join("depth"))?;
        let k = sl_io::camera::read_camera_json(icl.join("camera.json"))?.intrinsics;
        let frames = frames
            .iter()
            .map(|f| Ok((read(&f.depth_path)?, f.pose)))
            .collect::<Result<_>>()?;
        out.push(RealSeq {
            name: "icl-livingroom",
            k,
            frames,
        });
    }
    let seven = data.join("7scenes-redkitchen");
    if seven.is_dir() {
        let mut frames = sl_io::trajectory::read_7scenes_sequence(&seven)?;
        frames.truncate(if quick { 10 } else { 50 });
        let k = sl_io::camera::read_7scenes_intrinsics(seven.join("camera-intrinsics.txt"))?;
        let frames = frames
            .iter()
            .map(|f| Ok((read(&f.depth_path)?, f.pose)))
            .collect::<Result<_>>()?;
        out.push(RealSeq {
            name: "7scenes-redkitchen",
            k,
            frames,
        });
    }
    Ok(out)
}

fn real(ctx: &mut Context) -> Result<()> {
    let Some(data) = ctx.data_dir().map(Path::to_path_buf) else {
        ctx.section(
            "TSDF fusion: real frames",
            "skipped: ../shared/data not found (the simulated experiment above still ran).",
        );
        return Ok(());
    };
    let seqs = load_real(&data, ctx.quick())?;
    let mut md = String::new();
    writeln!(
        md,
        "4 mm voxels, the default sensor-adaptive truncation (2 cm floor, 3σ_Z beyond 2.1 m), depth ≤ 4 m. Times are wall-clock on this machine (debug/dev profile \
         unless xtask was built with --release; see the benchmark for release numbers). Meshes are written as \
         PLY next to this report.\n"
    )?;
    writeln!(
        md,
        "| sequence | weight | frames | integrate ms/frame (median) | marching cubes ms | vertices | triangles | blocks | MiB |"
    )?;
    writeln!(md, "|---|---|---|---|---|---|---|---|---|")?;
    let mut images = Vec::new();
    for seq in &seqs {
        for weight in weight_modes() {
            let mut params = TsdfConfig::default();
            params.voxel_m = 0.004;
            params.trunc_m = 0.02;
            params.max_depth_m = 4.0;
            params.weight = weight;
            let mut vol = TsdfVolume::new(params)?;
            let mut ms = Vec::new();
            for (d, p) in &seq.frames {
                let t0 = Instant::now();
                vol.integrate(d, &seq.k, p)?;
                ms.push(t0.elapsed().as_secs_f64() * 1e3);
            }
            ms.sort_by(f64::total_cmp);
            let med = ms[ms.len() / 2];
            let t0 = Instant::now();
            let mesh = vol.extract_mesh(&MeshConfig::default());
            let extract_ms = t0.elapsed().as_secs_f64() * 1e3;
            let topo = mesh.topology();
            let tag = format!("{}_{}", seq.name, weight.name());
            sl_tsdf::io::write_mesh_ply(
                ctx.out_dir().join(format!("tsdf_{tag}.ply")),
                &mesh,
                sl_io::PlyFormat::BinaryLittleEndian,
            )?;
            let img = sl_eval::render::render_mesh(&mesh, &seq.k, &seq.frames[0].1)?;
            let png = format!("tsdf_{tag}.png");
            sl_tsdf::io::write_png(ctx.out_dir().join(&png), &img)?;
            images.push((tag.clone(), png));
            writeln!(
                md,
                "| {} | {} | {} | {:.1} | {:.0} | {} | {} | {} | {:.0} |",
                seq.name,
                weight.name(),
                seq.frames.len(),
                med,
                extract_ms,
                mesh.vertex_count(),
                mesh.triangle_count(),
                vol.block_count(),
                vol.memory_bytes() as f64 / f64::from(1 << 20)
            )?;
            ctx.row(
                EXP,
                &format!("{tag} vertices"),
                mesh.vertex_count() as f64,
                "",
            );
            ctx.row(EXP, &format!("{tag} integrate median"), med, "ms");
            ctx.row(EXP, &format!("{tag} marching cubes"), extract_ms, "ms");
            ctx.check(
                format!("{tag}: mesh is edge-manifold and consistently oriented"),
                topo.nonmanifold_edges == 0
                    && topo.inconsistent_edges == 0
                    && mesh.vertex_count() > 10_000,
                format!("{topo:?}, {} vertices", mesh.vertex_count()),
            );
        }
    }
    writeln!(md)?;
    for (tag, png) in &images {
        writeln!(md, "![{tag}]({png})")?;
    }
    ctx.section("TSDF fusion: real frames (ICL-NUIM, 7-Scenes)", md);
    Ok(())
}

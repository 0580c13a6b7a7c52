//! Release timing and a quick real-frame check of the multi-scale filter (issue 11):
//!
//! ```text
//! cargo run --release -p sl-filter --example multiscale_probe            # plane residuals
//! RAYON_NUM_THREADS=1 cargo run --release -p sl-filter --example multiscale_probe -- time
//! ```
//!
//! The residual table prints, per real frame (`../shared/data`: person, the floor scan, TUM
//! fr1/rpy frames 0, 10, 20), the dominant plane's residual per depth band for raw, the adaptive
//! 7×7 default and multi-scale filters with several dilation sets. The full comparison (normal
//! spread, the simulated edge benchmark) is in `cargo xtask validate --only filter`.

use std::error::Error;
use std::time::Instant;

use sl_core::DepthImage;
use sl_eval::filter as eval;
use sl_filter::{DepthFilter, Isa, Method, MultiScale, current_threads};

/// Planar regions measured per frame (walls, floors, desks).
const PLANES: usize = 6;
/// Depth bands, metres (the issue-11 target is at ≥ 2 m).
const BANDS_M: [(f32, f32); 3] = [(0.0, 1.5), (1.5, 2.0), (2.0, f32::INFINITY)];

type Res<T> = Result<T, Box<dyn Error>>;

/// Minimum and median of 41 runs, ms.
fn time(f: &dyn Fn() -> Res<()>) -> Res<(f64, f64)> {
    let mut v = Vec::with_capacity(41);
    for _ in 0..41 {
        let t = Instant::now();
        f()?;
        v.push(t.elapsed().as_secs_f64() * 1e3);
    }
    v.sort_by(f64::total_cmp);
    Ok((v[0], v[20]))
}

fn main() -> Res<()> {
    let mut frames = Vec::new();
    frames.extend(sl_testkit::person());
    frames.extend(sl_testkit::floor_scan(3));
    frames.extend(sl_testkit::tum_rpy(30).into_iter().step_by(10));
    frames.extend(sl_testkit::seven_scenes(30).into_iter().step_by(15));
    frames.extend(
        sl_testkit::tum_rpy_200(200)
            .into_iter()
            .skip(100)
            .step_by(50),
    );
    let Some(first) = frames.first() else {
        println!("no real frames (../shared/data not found)");
        return Ok(());
    };
    if std::env::args().nth(1).as_deref() == Some("time") {
        let sensor = first.camera.sensor;
        let ms = MultiScale::default_for(&sensor);
        let ad = DepthFilter::default_for(Method::Adaptive, &sensor);
        for _ in 0..3 {
            let a = time(&|| Ok(ad.apply(&first.depth).map(drop)?))?;
            let m = time(&|| Ok(ms.apply(&first.depth).map(drop)?))?;
            println!(
                "{}: threads {} isa {:?}: adaptive 7x7 min/median {:.2}/{:.2} ms; multiscale {:.2}/{:.2} ms",
                first.name,
                current_threads(),
                Isa::detect(),
                a.0,
                a.1,
                m.0,
                m.1
            );
        }
        return Ok(());
    }
    for fr in &frames {
        let k = fr.camera.intrinsics;
        let sensor = fr.camera.sensor;
        let regions = eval::plane_regions(
            &fr.depth,
            &k,
            &sensor,
            &eval::RegionSearch {
                max_planes: PLANES,
                ..eval::RegionSearch::default()
            },
        )?;
        if regions.is_empty() {
            println!("{}: no plane", fr.name);
            continue;
        }
        let mut cands: Vec<(String, MultiScale)> = Vec::new();
        let base = MultiScale {
            dilations: Vec::new(),
            ..MultiScale::default_for(&sensor)
        };
        cands.push(("adaptive 7x7".into(), base.clone()));
        for dil in [vec![2usize], vec![2, 4], vec![2, 4, 8]] {
            cands.push((
                format!("multiscale {dil:?}"),
                MultiScale {
                    dilations: dil,
                    ..base.clone()
                },
            ));
        }
        println!(
            "{} ({} planes, px per band {:?})",
            fr.name,
            regions.len(),
            raw_px(&fr.depth, &k, &regions)?
        );
        let raw = eval::plane_residual_by_band_pooled(&fr.depth, &k, &regions, &BANDS_M)?;
        let line = |name: &str, res: &[eval::BandError]| {
            let mut s = format!("  {name:22}");
            for (b, r) in res.iter().zip(&raw) {
                if b.pixels > 0 {
                    s += &format!(" | {:6.2} mm ({:.2}x)", b.rmse_m * 1e3, b.rmse_m / r.rmse_m);
                } else {
                    s += " | -";
                }
            }
            s
        };
        println!("{}", line("raw", &raw));
        for (name, f) in &cands {
            let out: DepthImage = f.apply(&fr.depth)?;
            let res = eval::plane_residual_by_band_pooled(&out, &k, &regions, &BANDS_M)?;
            println!("{}", line(name, &res));
        }
    }
    Ok(())
}

/// Region pixels per band.
fn raw_px(d: &DepthImage, k: &sl_core::Intrinsics, r: &[eval::PlaneRegion]) -> Res<Vec<usize>> {
    Ok(eval::plane_residual_by_band_pooled(d, k, r, &BANDS_M)?
        .iter()
        .map(|b| b.pixels)
        .collect())
}

//! The paper's Figure 2 from a [`ResolutionAnalysis`]: (a) the sorted unique depths against
//! their index, (b) `ln ΔZ` against `ln Z` with the fitted line. No I/O: [`resolution_svg`]
//! returns an SVG document, [`resolution_rgb`] an RGB raster the caller can save as PNG.

use std::fmt::Write as _;

use sl_core::Image;
use sl_noise::analysis::ResolutionAnalysis;

/// Axis ticks: "nice" values (1, 2, 5 × 10ⁿ) covering `[lo, hi]`, about `target` of them.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo || target == 0 {
        return Vec::new();
    }
    let raw = (hi - lo) / target as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|i| i as f64 * step).collect()
}

/// A data → pixel mapping for one panel.
#[derive(Debug, Clone, Copy)]
struct Frame {
    x0: f64,
    y0: f64,
    w: f64,
    h: f64,
    xmin: f64,
    xmax: f64,
    ymin: f64,
    ymax: f64,
}

impl Frame {
    fn new(rect: (f64, f64, f64, f64), xs: &[f64], ys: &[f64]) -> Self {
        let (xmin, xmax) = padded_range(xs);
        let (ymin, ymax) = padded_range(ys);
        Self {
            x0: rect.0,
            y0: rect.1,
            w: rect.2,
            h: rect.3,
            xmin,
            xmax,
            ymin,
            ymax,
        }
    }
    fn px(&self, x: f64) -> f64 {
        self.x0 + (x - self.xmin) / (self.xmax - self.xmin) * self.w
    }
    fn py(&self, y: f64) -> f64 {
        self.y0 + self.h - (y - self.ymin) / (self.ymax - self.ymin) * self.h
    }
}

/// Min/max with 5 % padding (a unit range around a single value).
fn padded_range(v: &[f64]) -> (f64, f64) {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
        return (lo - 0.5, hi + 0.5);
    }
    let pad = 0.05 * (hi - lo);
    (lo - pad, hi + pad)
}

fn fmt_tick(v: f64) -> String {
    if v.abs() >= 100.0 || v == v.round() {
        format!("{v:.0}")
    } else if (v * 10.0 - (v * 10.0).round()).abs() < 1e-9 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

fn svg_axes(s: &mut String, f: &Frame, xlabel: &str, ylabel: &str, title: &str) {
    let _ = writeln!(
        s,
        r##"<rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="#000"/>"##,
        f.x0, f.y0, f.w, f.h
    );
    for t in nice_ticks(f.xmin, f.xmax, 6) {
        let x = f.px(t);
        let yb = f.y0 + f.h;
        let _ = writeln!(
            s,
            r##"<line x1="{x:.1}" y1="{yb:.1}" x2="{x:.1}" y2="{:.1}" stroke="#000"/><line x1="{x:.1}" y1="{:.1}" x2="{x:.1}" y2="{yb:.1}" stroke="#ddd"/><text x="{x:.1}" y="{:.1}" text-anchor="middle">{}</text>"##,
            yb + 5.0,
            f.y0,
            yb + 18.0,
            fmt_tick(t)
        );
    }
    for t in nice_ticks(f.ymin, f.ymax, 6) {
        let y = f.py(t);
        let _ = writeln!(
            s,
            r##"<line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#000"/><line x1="{:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end">{}</text>"##,
            f.x0 - 5.0,
            f.x0,
            f.x0,
            f.x0 + f.w,
            f.x0 - 8.0,
            y + 4.0,
            fmt_tick(t)
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{xlabel}</text>"#,
        f.x0 + f.w / 2.0,
        f.y0 + f.h + 38.0
    );
    let (lx, ly) = (f.x0 - 52.0, f.y0 + f.h / 2.0);
    let _ = writeln!(
        s,
        r#"<text x="{lx:.1}" y="{ly:.1}" text-anchor="middle" transform="rotate(-90 {lx:.1} {ly:.1})">{ylabel}</text>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-weight="bold">{title}</text>"#,
        f.x0 + f.w / 2.0,
        f.y0 - 10.0
    );
}

/// The paper's Figure 2 as a standalone SVG document (1000×440 px): panel (a) sorted unique
/// depths (mm) against their index; panel (b) `ln ΔZ` against `ln Z` (mm) with the OLS line
/// (solid) and the Theil–Sen line (dashed); the title gives both slopes and the implied `f·B`.
pub fn resolution_svg(a: &ResolutionAnalysis) -> String {
    let mut s = String::new();
    let (w, h) = (1000.0, 440.0);
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r##"<rect width="100%" height="100%" fill="#fff"/>"##);
    let fb = a
        .fb_px_m
        .map_or(String::new(), |f| format!(", implied fB = {f:.2} px·m"));
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="20" text-anchor="middle" font-size="14">Depth resolution: {} unique depths, slope {:.3} (OLS), {:.3} (Theil–Sen){fb}</text>"#,
        w / 2.0,
        a.unique_depths,
        a.slope,
        a.slope_robust
    );
    // Panel (a).
    let idx: Vec<f64> = (0..a.sorted_depths_m.len()).map(|i| i as f64).collect();
    let zmm: Vec<f64> = a.sorted_depths_m.iter().map(|z| z * 1000.0).collect();
    let fa = Frame::new((80.0, 60.0, 370.0, 310.0), &idx, &zmm);
    svg_axes(
        &mut s,
        &fa,
        "index k",
        "Z (mm)",
        "(a) unique depths, sorted",
    );
    let mut path = String::new();
    for (i, (x, y)) in idx.iter().zip(&zmm).enumerate() {
        let _ = write!(
            path,
            "{}{:.1},{:.1} ",
            if i == 0 { "M" } else { "L" },
            fa.px(*x),
            fa.py(*y)
        );
    }
    let _ = writeln!(
        s,
        r##"<path d="{path}" fill="none" stroke="#1f77b4" stroke-width="1.5"/>"##
    );
    // Panel (b).
    let fbp = Frame::new((580.0, 60.0, 390.0, 310.0), &a.ln_z_mm, &a.ln_dz_mm);
    svg_axes(
        &mut s,
        &fbp,
        "ln Z (Z in mm)",
        "ln ΔZ (ΔZ in mm)",
        "(b) ln ΔZ vs ln Z",
    );
    for (x, y) in a.ln_z_mm.iter().zip(&a.ln_dz_mm) {
        let _ = writeln!(
            s,
            r##"<circle cx="{:.1}" cy="{:.1}" r="1.8" fill="#1f77b4"/>"##,
            fbp.px(*x),
            fbp.py(*y)
        );
    }
    let clip_line = |slope: f64, intercept: f64, style: &str, s: &mut String| {
        let (x1, x2) = (fbp.xmin, fbp.xmax);
        let (y1, y2) = (slope * x1 + intercept, slope * x2 + intercept);
        if y1.is_finite() && y2.is_finite() {
            let _ = writeln!(
                s,
                r##"<line x1="{:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" {style}/>"##,
                fbp.px(x1),
                fbp.py(y1),
                fbp.px(x2),
                fbp.py(y2)
            );
        }
    };
    let _ = writeln!(
        s,
        r##"<clipPath id="pb"><rect x="{:.1}" y="{:.1}" width="{:.1}" height="{:.1}"/></clipPath><g clip-path="url(#pb)">"##,
        fbp.x0, fbp.y0, fbp.w, fbp.h
    );
    clip_line(
        a.slope,
        a.intercept,
        r##"stroke="#d62728" stroke-width="2""##,
        &mut s,
    );
    clip_line(
        a.slope_robust,
        a.intercept_robust,
        r##"stroke="#2ca02c" stroke-width="1.5" stroke-dasharray="6 4""##,
        &mut s,
    );
    let _ = writeln!(s, "</g>");
    let _ = writeln!(
        s,
        r##"<text x="{:.1}" y="{:.1}" fill="#d62728">OLS slope {:.3}</text><text x="{:.1}" y="{:.1}" fill="#2ca02c">Theil–Sen slope {:.3}</text>"##,
        fbp.x0 + 10.0,
        fbp.y0 + 18.0,
        a.slope,
        fbp.x0 + 10.0,
        fbp.y0 + 34.0,
        a.slope_robust
    );
    let _ = writeln!(s, "</svg>");
    s
}

/// A raster version of [`resolution_svg`] (no text): white background, two framed panels,
/// (a) the sorted depths as a blue curve, (b) the `ln ΔZ` points in blue with the OLS line in
/// red and the Theil–Sen line in green, grey grid lines at the SVG's tick positions.
/// Sizes below 40×20 give a blank image.
pub fn resolution_rgb(a: &ResolutionAnalysis, width: usize, height: usize) -> Image<[u8; 3]> {
    let mut img = Image::filled(width, height, [255u8; 3]);
    if width < 40 || height < 20 {
        return img;
    }
    let (wf, hf) = (width as f64, height as f64);
    let margin = (0.06 * wf.min(hf)).max(4.0);
    let panel_w = wf / 2.0 - 2.0 * margin;
    let panel_h = hf - 2.0 * margin;
    let idx: Vec<f64> = (0..a.sorted_depths_m.len()).map(|i| i as f64).collect();
    let zmm: Vec<f64> = a.sorted_depths_m.iter().map(|z| z * 1000.0).collect();
    let fa = Frame::new((margin, margin, panel_w, panel_h), &idx, &zmm);
    let fbp = Frame::new(
        (wf / 2.0 + margin, margin, panel_w, panel_h),
        &a.ln_z_mm,
        &a.ln_dz_mm,
    );
    let (grey, black, blue, red, green) = (
        [220, 220, 220],
        [0, 0, 0],
        [31, 119, 180],
        [214, 39, 40],
        [44, 160, 44],
    );
    for f in [&fa, &fbp] {
        for t in nice_ticks(f.xmin, f.xmax, 6) {
            draw_line(&mut img, (f.px(t), f.y0), (f.px(t), f.y0 + f.h), grey, None);
        }
        for t in nice_ticks(f.ymin, f.ymax, 6) {
            draw_line(&mut img, (f.x0, f.py(t)), (f.x0 + f.w, f.py(t)), grey, None);
        }
        let (x1, y1) = (f.x0 + f.w, f.y0 + f.h);
        for (p, q) in [
            ((f.x0, f.y0), (x1, f.y0)),
            ((x1, f.y0), (x1, y1)),
            ((x1, y1), (f.x0, y1)),
            ((f.x0, y1), (f.x0, f.y0)),
        ] {
            draw_line(&mut img, p, q, black, None);
        }
    }
    for w in idx.iter().zip(&zmm).collect::<Vec<_>>().windows(2) {
        draw_line(
            &mut img,
            (fa.px(*w[0].0), fa.py(*w[0].1)),
            (fa.px(*w[1].0), fa.py(*w[1].1)),
            blue,
            None,
        );
    }
    for (x, y) in a.ln_z_mm.iter().zip(&a.ln_dz_mm) {
        let (cx, cy) = (fbp.px(*x), fbp.py(*y));
        for dy in -1..=1 {
            for dx in -1..=1 {
                put(&mut img, cx + f64::from(dx), cy + f64::from(dy), blue);
            }
        }
    }
    let clip = Some((fbp.x0, fbp.y0, fbp.x0 + fbp.w, fbp.y0 + fbp.h));
    for (slope, intercept, colour) in [
        (a.slope, a.intercept, red),
        (a.slope_robust, a.intercept_robust, green),
    ] {
        let (xa, xb) = (fbp.xmin, fbp.xmax);
        draw_line(
            &mut img,
            (fbp.px(xa), fbp.py(slope * xa + intercept)),
            (fbp.px(xb), fbp.py(slope * xb + intercept)),
            colour,
            clip,
        );
    }
    img
}

fn put(img: &mut Image<[u8; 3]>, x: f64, y: f64, c: [u8; 3]) {
    if !(x.is_finite() && y.is_finite()) || x < 0.0 || y < 0.0 {
        return;
    }
    let (xi, yi) = (x.round() as usize, y.round() as usize);
    let w = img.width();
    if xi < w && yi < img.height() {
        img.data_mut()[yi * w + xi] = c;
    }
}

/// Draws a line by sampling (at most 8192 samples), optionally clipped to a rectangle.
fn draw_line(
    img: &mut Image<[u8; 3]>,
    p: (f64, f64),
    q: (f64, f64),
    c: [u8; 3],
    clip: Option<(f64, f64, f64, f64)>,
) {
    let len = (q.0 - p.0).hypot(q.1 - p.1);
    if !len.is_finite() {
        return;
    }
    let n = (len.ceil() as usize).clamp(1, 8192);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        let (x, y) = (p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1));
        if let Some((x0, y0, x1, y1)) = clip
            && (x < x0 || x > x1 || y < y0 || y > y1)
        {
            continue;
        }
        put(img, x, y, c);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sl_noise::analysis::{AnalysisConfig, analyze_depths};
    use sl_noise::sim::KinectSimulator;

    fn analysis() -> ResolutionAnalysis {
        let sim = KinectSimulator {
            min_depth_m: 0.5,
            max_depth_m: 3.0,
            ..KinectSimulator::kinect_v1().white()
        };
        analyze_depths(sim.representable_depths(), &AnalysisConfig::default()).unwrap()
    }

    #[test]
    fn ticks_are_nice_and_cover() {
        assert_eq!(
            nice_ticks(0.0, 10.0, 5),
            vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]
        );
        let t = nice_ticks(6.1, 8.1, 6);
        assert!(t.first().unwrap() >= &6.1 && t.last().unwrap() <= &8.1 && t.len() >= 4);
        assert!(nice_ticks(1.0, 1.0, 5).is_empty());
    }

    #[test]
    fn svg_has_both_panels_points_and_slope() {
        let a = analysis();
        let svg = resolution_svg(&a);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches("<circle").count(), a.ln_z_mm.len());
        assert!(svg.contains("(a) unique depths") && svg.contains("(b) ln ΔZ vs ln Z"));
        assert!(svg.contains(&format!("slope {:.3}", a.slope)));
        // Balanced text elements.
        assert_eq!(svg.matches("<text").count(), svg.matches("</text>").count());
    }

    #[test]
    fn raster_draws_points_and_fit() {
        let a = analysis();
        let img = resolution_rgb(&a, 800, 400);
        assert_eq!((img.width(), img.height()), (800, 400));
        let count = |c: [u8; 3]| img.data().iter().filter(|p| **p == c).count();
        assert!(count([31, 119, 180]) > 500, "blue");
        assert!(count([214, 39, 40]) > 200, "red");
        // The fitted line lies in the right panel.
        let w = img.width();
        assert!(
            img.data()
                .iter()
                .enumerate()
                .filter(|(_, p)| **p == [214, 39, 40])
                .all(|(i, _)| i % w >= w / 2)
        );
        let tiny = resolution_rgb(&a, 10, 10);
        assert!(tiny.data().iter().all(|p| *p == [255; 3]));
    }
}

//! The realistic structured-light sensor (issue 11): correlated block-matching disparity error,
//! `1/q` quantisation and 1 mm rounding (terraces), occlusion bands from ray marching, and
//! drop-outs at grazing angles and depth discontinuities.
//!
//! **Physics.** A Kinect-class camera finds the disparity of a pixel by matching a window of
//! about 9×9 pixels of the projected speckle pattern. Its error is the window's average of
//! per-pixel speckle errors, so neighbours share most of their error: the disparity error is a
//! white field *smoothed by the matching window*, with the triangular autocorrelation
//! `1 − |l|/w` of a box of width `w` (before quantisation). That field, scaled to the sensor's
//! `σ_D`, is added to the exact disparity; the sum is quantised to `1/q` px and the depth
//! `f·B/D` rounded to 1 mm, so flat disparity plateaus (terraces) many pixels wide come out by
//! themselves.
//!
//! The projector sits a baseline `B` beside the IR camera (+x, image right): background points
//! hidden from it by a foreground object are not lit and cannot be measured (the band on the
//! left of foreground objects). Data sets that registered depth to the colour camera (TUM,
//! Open3D's person frame) see the scene from the colour camera, `b_rgb` further right: the IR
//! camera, now `b_rgb` to the left, cannot see the background just right of a foreground object
//! (a band on the right), and the projector is only `B − b_rgb` away (a narrower band on the
//! left). Both bands are found by ray tests of the candidates that a march along the image
//! row (the epipolar line) through the exact depth proposes, so their widths follow from the
//! geometry. Pixels whose matching window straddles a depth discontinuity are invalid within
//! [`RealisticNoise::edge_px`] of it; surfaces seen at more than
//! [`RealisticNoise::max_incidence_deg`] from their normal return no pattern, and, when
//! [`RealisticNoise::min_return`] is set, neither do surfaces too dark or too far for it.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use sl_core::{CameraToWorld, DepthImage, Image, Intrinsics};

/// Parameters of the realistic sensor. Start from [`RealisticNoise::default`] (a raw Kinect v1)
/// or [`RealisticNoise::for_camera`] and assign fields.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct RealisticNoise {
    /// Width of the block-matching window along x, pixels (≥ 1; 1 = no correlation along x).
    pub window_x: usize,
    /// Height of the block-matching window along y, pixels (≥ 1).
    pub window_y: usize,
    /// Size of a speckle of the projected pattern in the IR image, pixels (≥ 1): the per-pixel
    /// matching error is itself shared over one speckle before the window averages it.
    pub speckle_px: usize,
    /// Pixels of a projector shadow next to the foreground that the matcher fills with the
    /// foreground's depth (its window still sees the foreground's pattern: foreground
    /// fattening); 0 = none.
    pub shadow_fill_px: usize,
    /// Invalidate points the projector cannot light (ray march towards the projector).
    pub projector_shadows: bool,
    /// Offset of the output (colour) camera from the IR camera along +x, metres, for frames
    /// registered to the colour camera (0 = the IR camera's own view, no registration).
    pub registration_baseline_m: f64,
    /// Pixels on each side of a depth discontinuity that are invalid (0 = none).
    pub edge_px: usize,
    /// Disparity jump between neighbouring pixels that makes a discontinuity, pixels.
    pub edge_jump_px: f64,
    /// Largest angle between the viewing ray and the surface normal that still returns depth,
    /// degrees (90 disables the grazing-angle drop-out).
    pub max_incidence_deg: f64,
    /// Amplitude of a smooth radial disparity bias, pixels (`a·r²/r²_corner`, 0 = off): the
    /// low-frequency distortion calibrated for the Kinect by Herrera et al. and Smisek et al.
    pub distortion_px: f64,
    /// The weakest return of the projected pattern that still matches, relative to a white
    /// surface (reflectance 1) facing the camera 1 m away; 0 (the default) = off. A pixel
    /// whose surface returns `ρ·cos θ / r²` less than this is invalid (`ρ` the surface's
    /// [`crate::sim::Scene::reflectance`], `θ` the angle between the ray and the surface
    /// normal, `r` the distance along the ray in metres): the projector's irradiance falls as
    /// `1/r²` and a Lambertian surface reflects `ρ·cos θ` of it, while the patch a pixel sees
    /// grows as fast as its solid angle shrinks. So dark surfaces drop out nearer than white
    /// ones. Not fitted: `0.04` puts a white surface's limit at 5 m, the Kinect's range, and a
    /// black one's (`ρ` = 0.1) at 1.6 m.
    pub min_return: f64,
}

/// Matching window of the default model, pixels (see `docs/NOISE_MODEL.md` for the fit).
pub const DEFAULT_WINDOW_X: usize = 9;
/// Matching window height of the default model, pixels.
pub const DEFAULT_WINDOW_Y: usize = 11;
/// Speckle size of the default model, pixels.
pub const DEFAULT_SPECKLE_PX: usize = 1;
/// Shadow pixels filled by foreground fattening in the default model.
pub const DEFAULT_SHADOW_FILL_PX: usize = 3;
/// Colour-camera offset of registered Kinect v1 frames, metres (the RGB camera sits about
/// 2.5 cm from the IR camera, between it and the projector).
pub const KINECT_RGB_OFFSET_M: f64 = 0.025;

impl Default for RealisticNoise {
    fn default() -> Self {
        Self {
            window_x: DEFAULT_WINDOW_X,
            window_y: DEFAULT_WINDOW_Y,
            speckle_px: DEFAULT_SPECKLE_PX,
            shadow_fill_px: DEFAULT_SHADOW_FILL_PX,
            projector_shadows: true,
            registration_baseline_m: 0.0,
            edge_px: 0,
            edge_jump_px: 0.5,
            max_incidence_deg: 80.0,
            distortion_px: 0.0,
            min_return: 0.0,
        }
    }
}

impl RealisticNoise {
    /// The model for a camera preset of `sl_core::preset`: data sets whose depth was registered
    /// to the colour camera (`tum-fr1`, `tum-fr2`, `tum-fr3`, `ros-default`, `icl-nuim`) get the
    /// colour-camera offset [`KINECT_RGB_OFFSET_M`]; every other camera is the raw IR view.
    pub fn for_camera(name: &str) -> Self {
        let registered = matches!(
            name,
            "tum-fr1" | "tum-fr2" | "tum-fr3" | "ros-default" | "icl-nuim"
        );
        Self {
            registration_baseline_m: if registered { KINECT_RGB_OFFSET_M } else { 0.0 },
            ..Self::default()
        }
    }

    /// Checks the ranges (windows ≥ 1, angles in (0, 90], finite values).
    pub fn validate(&self) -> crate::Result<()> {
        let bad = |m: String| Err(crate::NoiseError::InvalidParameter(m));
        if self.window_x == 0
            || self.window_y == 0
            || self.window_x > 255
            || self.window_y > 255
            || self.speckle_px == 0
            || self.speckle_px > 15
        {
            return bad(format!(
                "matching window {}x{} must be 1..=255 on each side, speckle {} 1..=15",
                self.window_x, self.window_y, self.speckle_px
            ));
        }
        if !(self.max_incidence_deg > 0.0 && self.max_incidence_deg <= 90.0) {
            return bad(format!(
                "max_incidence_deg {} must be in (0, 90]",
                sl_core::Compact(self.max_incidence_deg)
            ));
        }
        if !(self.registration_baseline_m.is_finite()
            && self.edge_jump_px.is_finite()
            && self.edge_jump_px > 0.0
            && self.distortion_px.is_finite())
        {
            return bad("registration baseline, edge jump and distortion must be finite, the edge jump positive".into());
        }
        if !(self.min_return.is_finite() && self.min_return >= 0.0) {
            return bad(format!(
                "min_return {} must be a finite number >= 0",
                crate::error::num(self.min_return)
            ));
        }
        Ok(())
    }
}

/// The kernel of one axis: a box of `window` convolved with a box of `speckle`, normalised to
/// unit sum of squares (so a unit white field stays unit variance).
fn kernel(window: usize, speckle: usize) -> Vec<f64> {
    let (w, s) = (window.max(1), speckle.max(1));
    let mut k = vec![0.0f64; w + s - 1];
    for i in 0..w {
        for j in 0..s {
            k[i + j] += 1.0;
        }
    }
    let norm = k.iter().map(|v| v * v).sum::<f64>().sqrt();
    k.iter().map(|v| v / norm).collect()
}

/// The correlated unit-variance disparity error field of a `w`×`h` image: a white Gaussian
/// field (one ChaCha8 stream per row of the padded field, seeded by `seed`) shared over a
/// speckle (`speckle`×`speckle` box) and averaged over the `wx`×`wy` matching window (box),
/// separably, scaled to unit variance. Depends only on `(seed, w, h, wx, wy, speckle)`, not on
/// threads.
pub fn correlated_field(
    w: usize,
    h: usize,
    wx: usize,
    wy: usize,
    speckle: usize,
    seed: u64,
) -> Vec<f32> {
    let kx = kernel(wx, speckle);
    let ky = kernel(wy, speckle);
    let (pw, ph) = (w + kx.len() - 1, h + ky.len() - 1);
    if w == 0 || h == 0 {
        return vec![0.0; w * h];
    }
    // White field, one stream per padded row.
    let mut white = vec![0.0f32; pw * ph];
    white.par_chunks_mut(pw).enumerate().for_each(|(y, row)| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        // Streams distinct from the white model's (row y uses stream y there).
        rng.set_stream((1u64 << 32) + y as u64);
        for v in row.iter_mut() {
            let n: f32 = StandardNormal.sample(&mut rng);
            *v = n;
        }
    });
    // Horizontal pass.
    let mut hpass = vec![0.0f32; w * ph];
    hpass
        .par_chunks_mut(w)
        .zip(white.par_chunks(pw))
        .for_each(|(out, row)| {
            for (x, o) in out.iter_mut().enumerate() {
                let mut s = 0.0f64;
                for (t, k) in kx.iter().enumerate() {
                    s += k * f64::from(row[x + t]);
                }
                *o = s as f32;
            }
        });
    // Vertical pass.
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, orow)| {
        for (x, o) in orow.iter_mut().enumerate() {
            let mut s = 0.0f64;
            for (t, k) in ky.iter().enumerate() {
                s += k * f64::from(hpass[(y + t) * w + x]);
            }
            *o = s as f32;
        }
    });
    out
}

/// Pixels within `edge_px` (along x and y) of a discontinuity of the exact disparity `fb/Z`
/// (a jump above `jump_px`, or valid next to background), as a mask.
pub fn edge_mask(truth: &DepthImage, fb: f64, edge_px: usize, jump_px: f64) -> Vec<bool> {
    let (w, h) = (truth.width(), truth.height());
    let z = truth.data();
    let disp = |i: usize| {
        let v = f64::from(z[i]);
        if v > 0.0 && v.is_finite() {
            fb / v
        } else {
            0.0
        }
    };
    let mut mask = vec![false; w * h];
    if edge_px == 0 || w == 0 {
        return mask;
    }
    let is_edge = |a: usize, b: usize| {
        let (da, db) = (disp(a), disp(b));
        (da > 0.0 || db > 0.0) && (da - db).abs() > jump_px
    };
    // Mark the edge pixels: both neighbours of every discontinuity, then dilate.
    let mut seed = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w && is_edge(i, i + 1) {
                seed[i] = true;
                seed[i + 1] = true;
            }
            if y + 1 < h && is_edge(i, i + w) {
                seed[i] = true;
                seed[i + w] = true;
            }
        }
    }
    let r = edge_px - 1;
    // Separable square dilation by r (a dilation of 0 keeps the two pixels at the edge).
    let mut tmp = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if seed[y * w + x] {
                for xx in x.saturating_sub(r)..=(x + r).min(w - 1) {
                    tmp[y * w + xx] = true;
                }
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            if tmp[y * w + x] {
                for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
                    mask[yy * w + x] = true;
                }
            }
        }
    }
    mask
}

/// `true` where the surface point seen at a pixel is hidden from a viewpoint `offset_m` along
/// the camera's x axis (the projector, or the IR camera of a registered frame), found by
/// ray-marching the exact depth `truth` along the pixel's row (the epipolar line).
///
/// The segment from the point `P` (disparity `d = f_x·b/Z` for the offset `b`) to the viewpoint
/// projects onto the same row, and at `Δu` pixels towards the viewpoint it has disparity
/// `d + Δu` exactly (a pinhole with a pure x offset). It is blocked when the surface seen there
/// is nearer: `f_x·b/Z(u + Δu) > d + Δu`. One pass per row keeps the running maximum of
/// `f_x·b/Z(u') − u'` (or `+ u'` for a viewpoint on the left), so the test is O(width) per row.
/// Occluders outside the image are not seen.
pub(crate) fn hidden_along_rows(truth: &DepthImage, fx: f64, offset_m: f64) -> Vec<bool> {
    let (w, h) = (truth.width(), truth.height());
    let mut mask = vec![false; w * h];
    if w == 0 || offset_m == 0.0 || !(fx.is_finite() && offset_m.is_finite()) {
        return mask;
    }
    let fb = fx * offset_m.abs();
    let right = offset_m > 0.0;
    // A blocker must be nearer by more than this, pixels (ignores rounding on one surface).
    const TOL: f64 = 1e-6;
    mask.par_chunks_mut(w)
        .zip(truth.data().par_chunks(w))
        .for_each(|(mrow, trow)| {
            let disp = |x: usize| {
                let z = f64::from(trow[x]);
                if z > 0.0 && z.is_finite() {
                    fb / z
                } else {
                    f64::NEG_INFINITY
                }
            };
            let mut best = f64::NEG_INFINITY;
            if right {
                for x in (0..w).rev() {
                    let d = disp(x);
                    let key = d - x as f64;
                    if d.is_finite() && best > key + TOL {
                        mrow[x] = true;
                    }
                    best = best.max(key);
                }
            } else {
                for (x, m) in mrow.iter_mut().enumerate() {
                    let d = disp(x);
                    let key = d + x as f64;
                    if d.is_finite() && best > key + TOL {
                        *m = true;
                    }
                    best = best.max(key);
                }
            }
        });
    mask
}

/// `true` where the surface point seen at a pixel is hidden from the viewpoint `offset_m` along
/// the camera's x axis, by an exact ray test against `scene` — run only on the candidates of
/// [`hidden_along_rows`] (a superset: a blocker of the ray is always nearer than the ray at its
/// pixel) widened by one pixel on each side for sampling. The row march alone would also
/// shadow points whose ray passes *behind* a thin nearer object (an arm before a wall).
pub(crate) fn hidden_from(
    scene: &crate::sim::Scene,
    k: &Intrinsics,
    camera_to_world: &CameraToWorld,
    truth: &DepthImage,
    offset_m: f64,
) -> Vec<bool> {
    let (w, h) = (truth.width(), truth.height());
    let candidates = hidden_along_rows(truth, k.fx, offset_m);
    let mut mask = vec![false; w * h];
    if w == 0 {
        return mask;
    }
    let eye = camera_to_world.isometry() * nalgebra::Point3::new(offset_m, 0.0, 0.0);
    mask.par_chunks_mut(w)
        .zip(truth.data().par_chunks(w))
        .zip(candidates.par_chunks(w))
        .enumerate()
        .for_each(|(y, ((mrow, trow), crow))| {
            for x in 0..w {
                let near = crow[x] || (x > 0 && crow[x - 1]) || (x + 1 < w && crow[x + 1]);
                let z = trow[x];
                if !(near && z > 0.0 && z.is_finite()) {
                    continue;
                }
                let p =
                    camera_to_world.isometry() * k.back_project(x as f64, y as f64, f64::from(z));
                let dir = p - eye;
                // Hidden when something lies between the viewpoint and the point (the
                // tolerance ignores the point's own surface).
                let tol = 1e-6 + 1e-4 / dir.norm().max(1e-9);
                mrow[x] = scene
                    .trace(&eye, &dir)
                    .is_some_and(|(_, hit)| hit.t < 1.0 - tol);
            }
        });
    mask
}

/// `|cos θ|` between the ray of pixel `(x, y)` and the camera-frame normal `n`, and the length
/// of that ray for a unit z (`‖ray‖`, so that the point at depth `Z` is `Z·‖ray‖` away).
fn incidence(k: &Intrinsics, x: usize, y: usize, n: [f32; 3]) -> (f64, f64) {
    let r = k.ray(x as f64, y as f64);
    let len = r.norm();
    let r = r / len;
    (
        (f64::from(n[0]) * r.x + f64::from(n[1]) * r.y + f64::from(n[2]) * r.z).abs(),
        len,
    )
}

/// `true` where the surface is seen at more than `max_deg` from its normal.
pub(crate) fn grazing_mask(k: &Intrinsics, normals: &Image<[f32; 3]>, max_deg: f64) -> Vec<bool> {
    let (w, h) = (normals.width(), normals.height());
    if max_deg >= 90.0 {
        return vec![false; w * h];
    }
    let cos_max = max_deg.to_radians().cos();
    let n = normals.data();
    let mut out = vec![false; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                let nn = n[y * w + x];
                if nn == [0.0; 3] {
                    continue;
                }
                *o = incidence(k, x, y, nn).0 < cos_max;
            }
        });
    out
}

/// `true` where the surface seen at a pixel returns less of the pattern than `min_return`
/// (see [`RealisticNoise::min_return`]): `ρ·cos θ / r²` from the exact depth, the normals
/// and the labels' reflectances (the caller skips it when `min_return` is 0).
pub(crate) fn weak_return_mask(
    k: &Intrinsics,
    render: &crate::sim::Render,
    scene: &crate::sim::Scene,
    min_return: f64,
) -> Vec<bool> {
    let (w, h) = (render.depth.width(), render.depth.height());
    let mut out = vec![false; w * h];
    if w == 0 {
        return out;
    }
    let (z, n, labels) = (
        render.depth.data(),
        render.normals.data(),
        render.labels.data(),
    );
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let label = labels[i];
            if label == 0 || !z[i].is_finite() || z[i] <= 0.0 {
                continue;
            }
            let (cos, len) = incidence(k, x, y, n[i]);
            // The ray has unit z: the point is `Z·ray`, at distance `Z·‖ray‖`.
            let r = f64::from(z[i]) * len;
            *o = scene.reflectance(label) * cos < min_return * r * r;
        }
    });
    out
}

/// Foreground fattening: in every row, the last `fill` pixels of each run of `shadow` (the
/// pixels next to the foreground on its right, the side the projector shadow ends at) take the
/// measured depth of the foreground pixel just after the run, when that pixel is valid and
/// nearer in the exact depth; they are removed from `shadow`.
pub(crate) fn fill_shadow_edges(
    shadow: &mut [bool],
    depth: &mut DepthImage,
    truth: &DepthImage,
    fill: usize,
) {
    let w = depth.width();
    if fill == 0 || w == 0 {
        return;
    }
    let t = truth.data();
    let d = depth.data_mut();
    for (y, srow) in shadow.chunks_mut(w).enumerate() {
        let row = y * w;
        let mut x = 0;
        while x < w {
            if !srow[x] {
                x += 1;
                continue;
            }
            let start = x;
            while x < w && srow[x] {
                x += 1;
            }
            // Run [start, x); the foreground pixel is x.
            if x < w && d[row + x] > 0.0 && t[row + x] < t[row + x - 1] {
                let fg = d[row + x];
                for xx in x.saturating_sub(fill).max(start)..x {
                    srow[xx] = false;
                    d[row + xx] = fg;
                }
            }
        }
    }
}

//! The normal map of a pyramid level and the per-point constants of the association pass
//! ([`PointAux`]), in branch-free batches of [`LANES`] pixels, with the per-pixel references
//! the tests compare them with.

use super::*;

/// Which pixels of a level get a normal: those on the grid of every `stride`-th column and
/// row (`off_grid = false`; `stride = 1`: all), or the others (`off_grid = true`, completing a
/// level built on the grid).
#[derive(Debug, Clone, Copy)]
pub(super) struct Select {
    pub(super) stride: usize,
    pub(super) off_grid: bool,
}

impl Select {
    /// Sets the selected entries of image row `y` to `f(x)`; the others to `unset` when
    /// selecting the grid, unchanged when completing it.
    #[inline(always)]
    #[cfg(test)]
    fn apply<T: Copy>(&self, row: &mut [T], y: usize, unset: T, f: impl Fn(usize) -> T) {
        let s = self.stride.max(1);
        let row_on_grid = y.is_multiple_of(s);
        match (self.off_grid, row_on_grid) {
            (false, false) => row.fill(unset),
            (false, true) => {
                if s > 1 {
                    row.fill(unset);
                }
                for (x, v) in row.iter_mut().enumerate().step_by(s) {
                    *v = f(x);
                }
            }
            (true, false) => {
                for (x, v) in row.iter_mut().enumerate() {
                    *v = f(x);
                }
            }
            (true, true) => {
                for (x, v) in row.iter_mut().enumerate() {
                    if !x.is_multiple_of(s) {
                        *v = f(x);
                    }
                }
            }
        }
    }
}

/// Fills `level.aux` from its points and normals on the selected pixels (the others: the
/// default when selecting the grid, unchanged when completing it). The reference of
/// [`normals_and_aux`], which computes the same bits in batches.
#[cfg(test)]
pub(super) fn point_aux(level: &mut Level, sensor: &SensorModel, fl: f32, w: usize, sel: Select) {
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let n = level.points.len();
    level.aux.resize(n, PointAux::default());
    level
        .aux
        .par_chunks_mut(w.max(1))
        .zip(level.points.par_chunks(w.max(1)))
        .zip(level.normals.par_chunks(w.max(1)))
        .enumerate()
        .for_each(|(y, ((arow, prow), nrow))| {
            sel.apply(arow, y, PointAux::default(), |x| {
                let (pc, nc) = (&prow[x], &nrow[x]);
                if nc.x.is_finite() {
                    let z = pc.z;
                    PointAux {
                        ray_len: pc.coords.norm(),
                        cz2: c * z * z,
                        cos_gate: normal_gate_cos(c, z, fl),
                    }
                } else {
                    PointAux::default()
                }
            })
        });
}

/// The normal map of one level (on the pixels `sel` selects; NaN on the others when selecting
/// a grid, unchanged when completing one) from its depth and vertices. Normals are central
/// differences over `±r` pixels: Kinect depth is quantised into terraces (1 cm steps at 2 m)
/// and one-pixel differences give normals tens of degrees off; at full resolution `r = 2` (the
/// coarser levels are already averaged, `r = 1`). The reference of [`normals_and_aux`], which
/// computes the same bits in batches.
#[cfg(test)]
pub(super) fn normals(
    level: &mut Level,
    k: &Intrinsics,
    sensor: &SensorModel,
    r: usize,
    sel: Select,
) {
    let (w, h) = (k.width, k.height);
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    level.normals.resize(w * h, nan_n);
    let fx = k.fx as f32;
    let depth = &level.depth;
    let c = (sensor.sigma_d_px / sensor.fb()) as f32;
    let points = &level.points;
    let normal_at = |x: usize, y: usize| -> Vector3<f32> {
        if x < r || y < r || x + r >= w || y + r >= h {
            return nan_n;
        }
        let i = y * w + x;
        let z = depth[i];
        if z <= 0.0 {
            return nan_n;
        }
        let gate = edge_jump_m(r as f32, z, fx, c);
        let nb = [i - r, i + r, i - r * w, i + r * w];
        if nb
            .iter()
            .any(|&j| depth[j] <= 0.0 || depth[j].is_nan() || (depth[j] - z).abs() > gate)
        {
            return nan_n;
        }
        let dx = points[i + r] - points[i - r];
        let dy = points[i + r * w] - points[i - r * w];
        let m = dx.cross(&dy);
        let len = m.norm();
        if len <= 0.0 || len.is_nan() {
            return nan_n;
        }
        let m = m / len;
        if m.dot(&points[i].coords) > 0.0 {
            -m
        } else {
            m
        }
    };
    level
        .normals
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| sel.apply(row, y, nan_n, |x| normal_at(x, y)));
}

/// Pixels per batch of [`normals_and_aux`]: one AVX2 register of `f32`, two SSE2 registers.
const LANES: usize = 8;

/// The normals of a level's selected pixels and their [`PointAux`] (see `normals` and
/// `point_aux` in the tests: the same operations in the same order, so the same bits), in
/// batches of [`LANES`] pixels of a row — consecutive, or a grid row's pixels `stride` apart —:
/// the depths around them loaded, the points recomputed from them as [`vertices`] computes
/// them, the arithmetic in branch-free structure-of-arrays loops the compiler vectorises, and
/// the selected pixels' results written back (completing a grid, a batch computes the grid's
/// pixels too and drops them). A per-pixel closure with early returns cost about 150
/// instructions a normal, most of the pyramid's time (session 34).
pub(super) fn normals_and_aux(
    level: &mut Level,
    k: &Intrinsics,
    sensor: &SensorModel,
    r: usize,
    fl: f32,
    sel: Select,
) {
    let (w, h) = (k.width, k.height);
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    level.normals.resize(w * h, nan_n);
    level.aux.resize(w * h, PointAux::default());
    let consts = NormalConsts {
        w,
        r,
        fx: k.fx as f32,
        fy: k.fy as f32,
        cx: k.cx as f32,
        cy: k.cy as f32,
        c: (sensor.sigma_d_px / sensor.fb()) as f32,
        fl,
    };
    let depth = &level.depth;
    level
        .normals
        .par_chunks_mut(w.max(1))
        .zip(level.aux.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(y, (nrow, arow))| {
            let s = sel.stride.max(1);
            let row_on_grid = y.is_multiple_of(s);
            if !sel.off_grid && (!row_on_grid || s > 1) {
                nrow.fill(nan_n);
                arow.fill(PointAux::default());
            }
            if !sel.off_grid && !row_on_grid {
                return;
            }
            let selected = |x: usize| match (sel.off_grid, row_on_grid) {
                (false, _) => x.is_multiple_of(s),
                (true, false) => true,
                (true, true) => !x.is_multiple_of(s),
            };
            // Pixels whose neighbours `r` away leave the image get no normal.
            let interior = y >= r && y + r < h && w > 2 * r;
            let (lo, hi) = if interior { (r, w - r) } else { (0, 0) };
            for x in (0..lo).chain(hi..w).filter(|&x| selected(x)) {
                nrow[x] = nan_n;
                arow[x] = PointAux::default();
            }
            if hi < lo + LANES {
                // Fewer interior pixels than a batch: one batch over the clamped range.
                for x in (lo..hi).filter(|&x| selected(x)) {
                    let (n, a) = normal_one(&consts, depth, x, y);
                    nrow[x] = n;
                    arow[x] = a;
                }
                return;
            }
            if !sel.off_grid && s > 1 {
                // A grid row: batches of `LANES` grid pixels `s` apart, the rest one by one.
                let mut x0 = lo.next_multiple_of(s);
                while x0 + (LANES - 1) * s < hi {
                    let (normals, aux) = normal_batch(&consts, depth, x0, s, y);
                    for l in 0..LANES {
                        nrow[x0 + l * s] = normals[l];
                        arow[x0 + l * s] = aux[l];
                    }
                    x0 += LANES * s;
                }
                for x in (x0..hi).step_by(s) {
                    let (n, a) = normal_one(&consts, depth, x, y);
                    nrow[x] = n;
                    arow[x] = a;
                }
                return;
            }
            let mut x0 = lo;
            while x0 < hi {
                // The last batch ends at `hi` (it recomputes some pixels: the same values).
                let start = x0.min(hi - LANES);
                let (normals, aux) = normal_batch(&consts, depth, start, 1, y);
                for l in 0..LANES {
                    let x = start + l;
                    if x >= x0 && selected(x) {
                        nrow[x] = normals[l];
                        arow[x] = aux[l];
                    }
                }
                x0 = start + LANES;
            }
        });
}

/// The constants of [`normal_batch`].
struct NormalConsts {
    w: usize,
    /// The central differences' baseline, pixels.
    r: usize,
    /// The level's intrinsics.
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    /// `σ_D/(f·B)`: σ_Z = c·z².
    c: f32,
    /// The full-resolution focal length, pixels (the normal gate).
    fl: f32,
}

/// `LANES` values of `v`, `step` apart from `i` on.
#[inline(always)]
fn lanes(v: &[f32], i: usize, step: usize) -> [f32; LANES] {
    let mut out = [0f32; LANES];
    if step == 1 {
        out.copy_from_slice(&v[i..i + LANES]);
    } else {
        let span = &v[i..=i + (LANES - 1) * step];
        for (o, x) in out.iter_mut().zip(span.iter().step_by(step)) {
            *o = *x;
        }
    }
    out
}

/// The normal and [`PointAux`] of interior pixel `(x, y)` (its neighbours `r` away inside the
/// image): [`normal_batch`]'s arithmetic with the pixel in every lane, lane 0 kept.
fn normal_one(k: &NormalConsts, depth: &[f32], x: usize, y: usize) -> (Vector3<f32>, PointAux) {
    let (w, r) = (k.w, k.r);
    let i = y * w + x;
    let at = |j: usize| [depth[j]; LANES];
    let (n, a) = normal_lanes(
        k,
        [at(i), at(i - r), at(i + r), at(i - r * w), at(i + r * w)],
        x,
        0,
        y,
    );
    (n[0], a[0])
}

/// The normals and [`PointAux`] of the interior pixels `x0 + l·step` (`l < LANES`) of row `y`.
#[inline(always)]
fn normal_batch(
    k: &NormalConsts,
    depth: &[f32],
    x0: usize,
    step: usize,
    y: usize,
) -> ([Vector3<f32>; LANES], [PointAux; LANES]) {
    let (w, r) = (k.w, k.r);
    let i = y * w + x0;
    normal_lanes(
        k,
        [
            lanes(depth, i, step),
            lanes(depth, i - r, step),
            lanes(depth, i + r, step),
            lanes(depth, i - r * w, step),
            lanes(depth, i + r * w, step),
        ],
        x0,
        step,
        y,
    )
}

/// The arithmetic of [`normal_batch`] on the depths `[centre, left, right, up, down]` of the
/// pixels `x0 + l·step` of row `y` (lane `l`; [`normal_one`] passes one pixel in every lane,
/// `step` 0).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn normal_lanes(
    k: &NormalConsts,
    d: [[f32; LANES]; 5],
    x0: usize,
    step: usize,
    y: usize,
) -> ([Vector3<f32>; LANES], [PointAux; LANES]) {
    let r = k.r;
    let [z, zl, zr, zu, zd] = d;
    // Pixel coordinates as `f32` (exact: images are far narrower than 2²⁴ pixels), built from
    // lane offsets so that the conversions vectorise.
    const OFFSETS: [f32; LANES] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    let (x0f, rf, stepf) = (x0 as f32, r as f32, step as f32);
    let (yf, yu, yd) = (y as f32, (y - r) as f32, (y + r) as f32);
    let point = |xf: f32, yf: f32, z: f32| {
        // As `vertices`: ((x − cx)·z/fx, (y − cy)·z/fy, z).
        ((xf - k.cx) * z / k.fx, (yf - k.cy) * z / k.fy)
    };
    let mut out = [[0f32; LANES]; 3];
    let mut valid = [false; LANES];
    let mut aux = [[0f32; LANES]; 3];
    for l in 0..LANES {
        let xf = x0f + OFFSETS[l] * stepf;
        let zc = z[l];
        let gate = edge_jump_m(r as f32, zc, k.fx, k.c);
        let mut edge = false;
        for dj in [zl[l], zr[l], zu[l], zd[l]] {
            // (Non-short-circuit: branch-free, so that the loop vectorises.)
            edge |= (dj <= 0.0) | dj.is_nan() | ((dj - zc).abs() > gate);
        }
        let (plx, ply) = point(xf - rf, yf, zl[l]);
        let (prx, pry) = point(xf + rf, yf, zr[l]);
        let (pux, puy) = point(xf, yu, zu[l]);
        let (pdx, pdy) = point(xf, yd, zd[l]);
        let dx = [prx - plx, pry - ply, zr[l] - zl[l]];
        let dy = [pdx - pux, pdy - puy, zd[l] - zu[l]];
        // `dx.cross(&dy)`, its norm and the unit normal, as nalgebra computes them.
        let m = [
            dx[1] * dy[2] - dx[2] * dy[1],
            dx[2] * dy[0] - dx[0] * dy[2],
            dx[0] * dy[1] - dx[1] * dy[0],
        ];
        let len = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
        let u = [m[0] / len, m[1] / len, m[2] / len];
        let (pcx, pcy) = point(xf, yf, zc);
        let facing = u[0] * pcx + u[1] * pcy + u[2] * zc;
        let flip = facing > 0.0;
        // (`z <= 0` is the invalid depth; a NaN centre is not rejected here, as in `normals`.)
        valid[l] = ((zc > 0.0) | zc.is_nan()) & !edge & (len > 0.0);
        for a in 0..3 {
            out[a][l] = if flip { -u[a] } else { u[a] };
        }
        aux[0][l] = (pcx * pcx + pcy * pcy + zc * zc).sqrt();
        aux[1][l] = k.c * zc * zc;
        aux[2][l] = normal_gate_cos(k.c, zc, k.fl);
    }
    let nan_n = Vector3::new(f32::NAN, f32::NAN, f32::NAN);
    let mut normals = [nan_n; LANES];
    let mut auxes = [PointAux::default(); LANES];
    for l in 0..LANES {
        if valid[l] {
            normals[l] = Vector3::new(out[0][l], out[1][l], out[2][l]);
        }
        // Where the normal is finite, as `point_aux` decides from the stored normal.
        if normals[l].x.is_finite() {
            auxes[l] = PointAux {
                ray_len: aux[0][l],
                cz2: aux[1][l],
                cos_gate: aux[2][l],
            };
        }
    }
    (normals, auxes)
}

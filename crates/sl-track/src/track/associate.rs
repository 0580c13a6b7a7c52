//! The association pass's inner loop over one image row: projective association of the row's
//! samples with the reference maps, the gates, and their terms of the normal equations. The
//! samples are processed in batches of [`LANES`] with the arithmetic in structure-of-arrays
//! loops the compiler vectorises, the reference lookups as a scalar gather between them, and
//! the sums added sample by sample in row order — the same operations, in the same order, as a
//! plain loop over the samples, so the sums are bit-identical to it.

use nalgebra::{Point3, Vector3};
use sl_core::whole::round_index;

use super::pyramid::PointAux;
use super::reference::{ReferenceMaps, variance_along_normal};

/// Samples per batch: one AVX2 register of `f32`, two SSE2 registers.
const LANES: usize = 8;

/// The constants of one association pass (pose, reference camera, gates, weighting).
#[derive(Debug, Clone, Copy)]
pub(super) struct PassConsts<'a> {
    /// Camera-to-world rotation of the frame (row-major) and translation.
    pub rot: [f32; 9],
    pub tr: [f32; 3],
    /// Frame camera to reference camera: rotation (row-major) and translation.
    pub m: [f32; 9],
    pub tm: [f32; 3],
    /// The reference camera's intrinsics, and its size as `f32`.
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub rw: f32,
    pub rh: f32,
    pub gate_sigmas: f32,
    pub huber_k: f32,
    /// The residual scale of uniform weighting (`inv_var = false`).
    pub uniform_sigma: f32,
    pub inv_var: bool,
    /// The centre the rotation of the Jacobian is taken about (world).
    pub ctr: [f32; 3],
    /// The loss of an associated point outside the gates.
    pub cap: f32,
    pub allowance: f32,
    pub min_cos: f32,
    pub reference: &'a ReferenceMaps,
}

/// One image row's share of the pass's sums, accumulated in `f32` (four products per SIMD
/// instruction where `f64` gives two) and added to the block's `f64` sums at the end of the
/// row. A row holds at most a few thousand terms, so the `f32` partial sums carry a relative
/// error of about 10⁻⁶ — far below the noise of the data they sum — while the `f64` block and
/// image sums keep the totals exact to the last digits that matter.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RowSums {
    pub h: [f32; 21],
    pub g: [f32; 6],
    pub valid: u32,
    pub associated: u32,
    pub inliers: u32,
    pub chi2: f32,
    pub r2_m2: f32,
    /// Σ of `huber(r/σ) − cap` over the inliers (the cap per associated point is added as a
    /// count).
    pub loss_below_cap: f32,
}

impl RowSums {
    /// Scales the row's Jacobians by `factor`: `H` by its square, `g` by it (the rows of a
    /// rolling-shutter frame, see `solve::RowPoses`).
    pub(super) fn scale_jacobian(&mut self, factor: f32) {
        let f2 = factor * factor;
        for h in &mut self.h {
            *h *= f2;
        }
        for g in &mut self.g {
            *g *= factor;
        }
    }
}

impl RowSums {
    #[inline(always)]
    fn accumulate(&mut self, j: &[f32; 6], r: f32, w: f32) {
        let mut k = 0;
        for a in 0..6 {
            let wa = w * j[a];
            for jb in &j[a..] {
                self.h[k] += wa * jb;
                k += 1;
            }
            self.g[a] += wa * r;
        }
    }
}

/// The sums of the samples `x = 0, stride, 2·stride, …` of one row of a level: its points and
/// normals (camera frame) and per-point constants.
///
/// The negated compares are the skip conditions of the one-sample-at-a-time loop kept as they
/// are, so that NaN decides alike (a NaN compare is false, so it does not skip).
#[inline(always)]
pub(super) fn row_sums(
    c: &PassConsts<'_>,
    prow: &[Point3<f32>],
    nrow: &[Vector3<f32>],
    arow: &[PointAux],
    stride: usize,
) -> RowSums {
    row_sums_with(c, prow, nrow, arow, stride, |_| {})
}

/// [`row_sums`], handing each sample's term of the robust objective to `each`, in sample
/// order: the truncated Huber loss of an inlier, the cap for a valid sample outside the gates
/// or on no surface, 0 for an invalid one (as [`crate::track::solve::Sums::total_loss`] counts
/// them). With a closure that does nothing the compiler removes the calls.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
#[inline(always)]
pub(super) fn row_sums_with(
    c: &PassConsts<'_>,
    prow: &[Point3<f32>],
    nrow: &[Vector3<f32>],
    arow: &[PointAux],
    stride: usize,
    mut each: impl FnMut(f32),
) -> RowSums {
    let mut s = RowSums::default();
    let stride = stride.max(1);
    let n = prow.len().min(nrow.len()).min(arow.len());
    let samples = n.div_ceil(stride);
    let reference = c.reference;
    let ref_width = reference.intrinsics.width;
    let lateral = reference.lateral_sigma_per_m;
    let mut start = 0;
    while start < samples {
        let len = (samples - start).min(LANES);
        // Stage 1 (loads): the batch's points, normals and constants as structure of arrays;
        // lanes past the row's end stay invalid.
        let mut p = [[0.0f32; LANES]; 3];
        let mut nc = [[0.0f32; LANES]; 3];
        let mut ray_len = [1.0f32; LANES];
        let mut cz2 = [0.0f32; LANES];
        let mut cos_gate = [0.0f32; LANES];
        let mut valid = [false; LANES];
        for l in 0..len {
            let x = (start + l) * stride;
            let (pp, nn, aux) = (&prow[x], &nrow[x], &arow[x]);
            p[0][l] = pp.x;
            p[1][l] = pp.y;
            p[2][l] = pp.z;
            nc[0][l] = nn.x;
            nc[1][l] = nn.y;
            nc[2][l] = nn.z;
            ray_len[l] = aux.ray_len;
            cz2[l] = aux.cz2;
            cos_gate[l] = aux.cos_gate;
            valid[l] = nn.x.is_finite();
        }
        // Stage 2 (vectorised): the reference pixel each point projects to.
        let mut u = [0i32; LANES];
        let mut v = [0i32; LANES];
        let mut projects = [false; LANES];
        for l in 0..LANES {
            let pc = [p[0][l], p[1][l], p[2][l]];
            let xr = affine(&c.m, &c.tm, &pc);
            let iz = 1.0 / xr[2];
            let (uo, ui) = round_index(c.fx * xr[0] * iz + c.cx, c.rw);
            let (vo, vi) = round_index(c.fy * xr[1] * iz + c.cy, c.rh);
            u[l] = ui;
            v[l] = vi;
            projects[l] = valid[l] & !(xr[2] <= 0.0) & uo & vo;
        }
        // Stage 3 (scalar gather): the reference's normal, point and variance there.
        let mut nr = [[0.0f32; LANES]; 3];
        let mut q = [[0.0f32; LANES]; 3];
        let mut var_ref = [0.0f32; LANES];
        let mut associated = [false; LANES];
        for l in 0..len {
            if !projects[l] {
                continue;
            }
            let j = v[l] as usize * ref_width + u[l] as usize;
            let (Some(nn), Some(qq), Some(&vr)) = (
                reference.normals.get(j),
                reference.points.get(j),
                reference.variance_m2.get(j),
            ) else {
                continue;
            };
            if !nn.x.is_finite() {
                continue;
            }
            associated[l] = true;
            nr[0][l] = nn.x;
            nr[1][l] = nn.y;
            nr[2][l] = nn.z;
            q[0][l] = qq.x;
            q[1][l] = qq.y;
            q[2][l] = qq.z;
            var_ref[l] = vr;
        }
        // Stage 4 (vectorised): gates, weight, residual and Jacobian of every lane.
        let mut inlier = [false; LANES];
        let mut jac = [[0.0f32; LANES]; 6];
        let mut res = [0.0f32; LANES];
        let mut wgt = [0.0f32; LANES];
        let mut en2 = [0.0f32; LANES];
        let mut loss = [0.0f32; LANES];
        for l in 0..LANES {
            let pc = [p[0][l], p[1][l], p[2][l]];
            let n = [nr[0][l], nr[1][l], nr[2][l]];
            // The normal gate widens with the frame normals' own noise (precomputed per
            // point from the frame's focal length: `normal_gate_cos`), never tighter than
            // `min_cos`. The reference's resolution plays no part (a model rendered at half
            // resolution has smoother normals, not noisier ones).
            let cos_g = cos_gate[l].min(c.min_cos);
            let nw = rotate(&c.rot, &[nc[0][l], nc[1][l], nc[2][l]]);
            let normal_ok = !(dot(&nw, &n) < cos_g);
            // The world point, and the ray's direction `R·p` (the centre's offset).
            let ray = rotate(&c.rot, &pc);
            let xw = [ray[0] + c.tr[0], ray[1] + c.tr[1], ray[2] + c.tr[2]];
            let diff = [xw[0] - q[0][l], xw[1] - q[1][l], xw[2] - q[2][l]];
            let r = dot(&n, &diff);
            // The frame point's depth noise acts along its ray: σ_Z(z)·|n·ray|; against a
            // depth frame its lateral error acts across the ray.
            let cos = dot(&n, &ray) / ray_len[l];
            let var = variance_along_normal(cz2[l], lateral * p[2][l], cos) + var_ref[l];
            let sigma = var.sqrt();
            let gate = c.gate_sigmas * sigma + c.allowance;
            let gate2 = 2.0 * gate;
            let within = (r.abs() <= gate) & (dot(&diff, &diff) <= gate2 * gate2);
            inlier[l] = associated[l] & normal_ok & within;
            let scale = if c.inv_var { sigma } else { c.uniform_sigma };
            let e = (r / scale).abs();
            let hub = if e <= c.huber_k { 1.0 } else { c.huber_k / e };
            wgt[l] = hub / (scale * scale);
            let pl = [xw[0] - c.ctr[0], xw[1] - c.ctr[1], xw[2] - c.ctr[2]];
            jac[0][l] = pl[1] * n[2] - pl[2] * n[1];
            jac[1][l] = pl[2] * n[0] - pl[0] * n[2];
            jac[2][l] = pl[0] * n[1] - pl[1] * n[0];
            jac[3][l] = n[0];
            jac[4][l] = n[1];
            jac[5][l] = n[2];
            res[l] = r;
            let en = r / sigma;
            en2[l] = en * en;
            loss[l] = huber_loss(en, c.huber_k).min(c.cap) - c.cap;
        }
        // Stage 5 (in sample order): the sums.
        for l in 0..len {
            s.valid += u32::from(valid[l]);
            s.associated += u32::from(associated[l]);
            each(match (valid[l], inlier[l]) {
                (false, _) => 0.0,
                (true, false) => c.cap,
                (true, true) => c.cap + loss[l],
            });
            if !inlier[l] {
                continue;
            }
            let j = [
                jac[0][l], jac[1][l], jac[2][l], jac[3][l], jac[4][l], jac[5][l],
            ];
            s.accumulate(&j, res[l], wgt[l]);
            s.inliers += 1;
            s.chi2 += en2[l];
            s.loss_below_cap += loss[l];
            s.r2_m2 += res[l] * res[l];
        }
        start += len;
    }
    s
}

/// `m·p` for a row-major 3×3 `m`.
#[inline(always)]
fn rotate(m: &[f32; 9], p: &[f32; 3]) -> [f32; 3] {
    [
        m[0] * p[0] + m[1] * p[1] + m[2] * p[2],
        m[3] * p[0] + m[4] * p[1] + m[5] * p[2],
        m[6] * p[0] + m[7] * p[1] + m[8] * p[2],
    ]
}

/// `m·p + t`.
#[inline(always)]
fn affine(m: &[f32; 9], t: &[f32; 3], p: &[f32; 3]) -> [f32; 3] {
    let r = rotate(m, p);
    [r[0] + t[0], r[1] + t[1], r[2] + t[2]]
}

#[inline(always)]
fn dot(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Huber's loss of a normalised residual `e` with threshold `k`: `e²/2` within `±k`, linear
/// beyond.
#[inline(always)]
fn huber_loss(e: f32, k: f32) -> f32 {
    let a = e.abs();
    if a <= k {
        0.5 * a * a
    } else {
        k * a - 0.5 * k * k
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sl_core::{CameraToWorld, Intrinsics};

    /// The pass as a plain loop over the samples, one at a time, in row order.
    fn one_at_a_time(
        c: &PassConsts<'_>,
        prow: &[Point3<f32>],
        nrow: &[Vector3<f32>],
        arow: &[PointAux],
        stride: usize,
    ) -> RowSums {
        let mut s = RowSums::default();
        let kr = &c.reference.intrinsics;
        for ((pc, nc), aux) in prow.iter().zip(nrow).zip(arow).step_by(stride) {
            if !nc.x.is_finite() {
                continue;
            }
            s.valid += 1;
            let pc = [pc.x, pc.y, pc.z];
            let xr = affine(&c.m, &c.tm, &pc);
            if xr[2] <= 0.0 {
                continue;
            }
            let iz = 1.0 / xr[2];
            let x = c.fx * xr[0] * iz + c.cx;
            let y = c.fy * xr[1] * iz + c.cy;
            if !(x > -0.5 && x < c.rw - 0.5 && y > -0.5 && y < c.rh - 0.5) {
                continue;
            }
            let (u, v) = (x.round() as usize, y.round() as usize);
            let j = v * kr.width + u;
            let nr = c.reference.normals[j];
            if !nr.x.is_finite() {
                continue;
            }
            let n = [nr.x, nr.y, nr.z];
            s.associated += 1;
            let nw = rotate(&c.rot, &[nc.x, nc.y, nc.z]);
            if dot(&nw, &n) < aux.cos_gate.min(c.min_cos) {
                continue;
            }
            let q = c.reference.points[j];
            let ray = rotate(&c.rot, &pc);
            let xw = [ray[0] + c.tr[0], ray[1] + c.tr[1], ray[2] + c.tr[2]];
            let diff = [xw[0] - q.x, xw[1] - q.y, xw[2] - q.z];
            let r = dot(&n, &diff);
            let cos = dot(&n, &ray) / aux.ray_len;
            let lateral = c.reference.lateral_sigma_per_m * pc[2];
            let sigma =
                (variance_along_normal(aux.cz2, lateral, cos) + c.reference.variance_m2[j]).sqrt();
            let gate = c.gate_sigmas * sigma + c.allowance;
            if !(r.abs() <= gate && dot(&diff, &diff) <= (2.0 * gate) * (2.0 * gate)) {
                continue;
            }
            let scale = if c.inv_var { sigma } else { c.uniform_sigma };
            let e = (r / scale).abs();
            let hub = if e <= c.huber_k { 1.0 } else { c.huber_k / e };
            let pl = [xw[0] - c.ctr[0], xw[1] - c.ctr[1], xw[2] - c.ctr[2]];
            let j6 = [
                pl[1] * n[2] - pl[2] * n[1],
                pl[2] * n[0] - pl[0] * n[2],
                pl[0] * n[1] - pl[1] * n[0],
                n[0],
                n[1],
                n[2],
            ];
            s.accumulate(&j6, r, hub / (scale * scale));
            s.inliers += 1;
            let en = r / sigma;
            s.chi2 += en * en;
            s.loss_below_cap += huber_loss(en, c.huber_k).min(c.cap) - c.cap;
            s.r2_m2 += r * r;
        }
        s
    }

    fn bits(s: &RowSums) -> Vec<u32> {
        s.h.iter()
            .chain(&s.g)
            .chain([&s.chi2, &s.r2_m2, &s.loss_below_cap])
            .map(|v| v.to_bits())
            .chain([s.valid, s.associated, s.inliers])
            .collect()
    }

    /// A wavy wall 1–3 m away seen by a 64×48 reference, and rows of frame points near it
    /// (some invalid, some off the reference, some behind the camera, some far off the
    /// surface): the batched pass gives the plain loop's sums bit for bit, for every row
    /// length (full batches and a partial one), stride, weighting and instruction set.
    #[test]
    fn batches_sum_exactly_what_one_sample_at_a_time_sums() {
        let k = Intrinsics::new(64, 48, 60.0, 60.0, 31.5, 23.5).unwrap();
        let n = k.width * k.height;
        let surface = |px: f32, py: f32| {
            let z = 1.0 + 0.02 * px + 0.01 * (py * 0.7).sin();
            Point3::new((px - 31.5) * z / 60.0, (py - 23.5) * z / 60.0, z)
        };
        let mut reference = ReferenceMaps::empty(&k);
        for i in 0..n {
            let (x, y) = ((i % k.width) as f32, (i / k.width) as f32);
            if (i * 7) % 23 == 0 {
                continue;
            }
            reference.points[i] = surface(x, y);
            let nn = Vector3::new(-0.3 + 0.01 * y, 0.05, -1.0).normalize();
            reference.normals[i] = nn;
            reference.variance_m2[i] = 1e-6 * (1.0 + (i % 5) as f32);
        }
        reference.pose = CameraToWorld::identity();
        type Row = (Vec<Point3<f32>>, Vec<Vector3<f32>>, Vec<PointAux>);
        let rows: Vec<Row> = (0..12)
            .map(|r| {
                let len = 5 + 9 * r;
                let mut p = Vec::new();
                let mut nv = Vec::new();
                let mut a = Vec::new();
                for i in 0..len {
                    // Columns from −3 to 66: some project off the reference.
                    let px = ((i * 5 + r) % 70) as f32 - 3.0;
                    let py = (r * 4) as f32;
                    let mut q = surface(px, py);
                    q.z += 0.002 * (i as f32 * 0.9).sin();
                    match i % 11 {
                        3 => q.z = -0.5,
                        7 => q *= 1.5,
                        _ => {}
                    }
                    p.push(q);
                    nv.push(if i % 9 == 4 {
                        Vector3::new(f32::NAN, f32::NAN, f32::NAN)
                    } else {
                        Vector3::new(-0.3 + 0.01 * py + 0.002 * (i % 5) as f32, 0.05, -1.0)
                            .normalize()
                    });
                    a.push(PointAux {
                        ray_len: q.coords.norm(),
                        cz2: 0.0028 * q.z * q.z,
                        cos_gate: 0.8 + 0.01 * (i % 7) as f32,
                    });
                }
                (p, nv, a)
            })
            .collect();
        let (mut checked, mut associated, mut valid) = (0, 0, 0);
        // The lateral term of a depth-frame reference (0: a model's), with both weightings.
        for (inv_var, lateral) in [(true, 0.0), (false, 0.0), (true, 0.0014)] {
            reference.lateral_sigma_per_m = lateral;
            let c = PassConsts {
                rot: [1.0, -0.0017, 0.0, 0.0017, 1.0, 0.0, 0.0, 0.0, 1.0],
                tr: [0.003, -0.002, 0.001],
                m: [1.0, -0.0017, 0.0, 0.0017, 1.0, 0.0, 0.0, 0.0, 1.0],
                tm: [0.003, -0.002, 0.001],
                fx: k.fx as f32,
                fy: k.fy as f32,
                cx: k.cx as f32,
                cy: k.cy as f32,
                rw: k.width as f32,
                rh: k.height as f32,
                gate_sigmas: 3.0,
                huber_k: 2.0,
                uniform_sigma: 0.003,
                inv_var,
                ctr: [0.01, 0.0, 0.02],
                cap: 2.0 * 3.0 - 2.0,
                allowance: 0.01,
                min_cos: 0.85,
                reference: &reference,
            };
            for (p, nv, a) in &rows {
                for stride in [1, 2, 3] {
                    let plain = one_at_a_time(&c, p, nv, a, stride);
                    let batched = row_sums(&c, p, nv, a, stride);
                    assert_eq!(
                        bits(&batched),
                        bits(&plain),
                        "len {} stride {stride}",
                        p.len()
                    );
                    checked += plain.inliers;
                    associated += plain.associated;
                    valid += plain.valid;
                    for isa in sl_core::Isa::ALL {
                        let k = Kernel(&c, p, nv, a, stride);
                        assert_eq!(bits(&isa.run(k)), bits(&plain), "{isa}");
                    }
                }
            }
        }
        // Every gate is exercised: points off the reference, and associated points rejected.
        assert!(checked > 200, "only {checked} inliers summed");
        assert!(
            valid > associated && associated > checked + 50,
            "valid {valid}, associated {associated}, inliers {checked}"
        );
    }

    struct Kernel<'a>(
        &'a PassConsts<'a>,
        &'a [Point3<f32>],
        &'a [Vector3<f32>],
        &'a [PointAux],
        usize,
    );

    impl sl_core::IsaKernel for Kernel<'_> {
        type Output = RowSums;
        #[inline(always)]
        fn run(self) -> RowSums {
            row_sums(self.0, self.1, self.2, self.3, self.4)
        }
    }
}

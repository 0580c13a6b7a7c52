//! Least-squares affine fits of the disparity, `D(x, y) = a·x + b·y + c`, from running sums.
//!
//! [`AffineSums`] accumulates the ten moments `Σ1, Σx, Σy, ΣD, Σx², Σxy, Σy², ΣxD, ΣyD, ΣD²` in
//! `f64` (sums are additive, so regions merge by adding their sums). Solving uses the centred
//! normal equations (solved as nalgebra's LU would, see `lu_solve`), which are well conditioned
//! even for 640×480 coordinates.

use crate::plane::DisparityAffine;

/// The moments of a set of `(x, y, D)` samples.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AffineSums {
    /// Number of samples (Σ1, may be a weight sum).
    pub n: f64,
    /// Σx.
    pub sx: f64,
    /// Σy.
    pub sy: f64,
    /// ΣD.
    pub sd: f64,
    /// Σx².
    pub sxx: f64,
    /// Σxy.
    pub sxy: f64,
    /// Σy².
    pub syy: f64,
    /// ΣxD.
    pub sxd: f64,
    /// ΣyD.
    pub syd: f64,
    /// ΣD².
    pub sdd: f64,
}

impl AffineSums {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, x: f64, y: f64, d: f64) {
        self.n += 1.0;
        self.sx += x;
        self.sy += y;
        self.sd += d;
        self.sxx += x * x;
        self.sxy += x * y;
        self.syy += y * y;
        self.sxd += x * d;
        self.syd += y * d;
        self.sdd += d * d;
    }

    /// Removes one sample previously added.
    #[inline]
    pub fn remove(&mut self, x: f64, y: f64, d: f64) {
        self.n -= 1.0;
        self.sx -= x;
        self.sy -= y;
        self.sd -= d;
        self.sxx -= x * x;
        self.sxy -= x * y;
        self.syy -= y * y;
        self.sxd -= x * d;
        self.syd -= y * d;
        self.sdd -= d * d;
    }

    /// Adds a horizontal run of pixels `x0..x1` on row `y` whose disparity sums are
    /// `Σd = sd`, `Σx·d = sxd`, `Σd² = sdd` (the x moments are closed-form).
    #[inline]
    #[cfg(test)]
    pub fn add_run(&mut self, y: f64, x0: usize, x1: usize, sd: f64, sxd: f64, sdd: f64) {
        if x1 <= x0 {
            return;
        }
        let n = (x1 - x0) as f64;
        // Σ_{x0}^{x1-1} x and x².
        let s1 = |m: f64| m * (m - 1.0) / 2.0;
        let s2 = |m: f64| (m - 1.0) * m * (2.0 * m - 1.0) / 6.0;
        let sx = s1(x1 as f64) - s1(x0 as f64);
        let sxx = s2(x1 as f64) - s2(x0 as f64);
        self.n += n;
        self.sx += sx;
        self.sy += y * n;
        self.sd += sd;
        self.sxx += sxx;
        self.sxy += y * sx;
        self.syy += y * y * n;
        self.sxd += sxd;
        self.syd += y * sd;
        self.sdd += sdd;
    }

    /// Adds the samples of another set.
    pub fn merge(&mut self, o: &AffineSums) {
        self.n += o.n;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sd += o.sd;
        self.sxx += o.sxx;
        self.sxy += o.sxy;
        self.syy += o.syy;
        self.sxd += o.sxd;
        self.syd += o.syd;
        self.sdd += o.sdd;
    }

    /// Removes the sums of `o`, a subset of these samples.
    pub(crate) fn subtract(&mut self, o: &AffineSums) {
        self.n -= o.n;
        self.sx -= o.sx;
        self.sy -= o.sy;
        self.sd -= o.sd;
        self.sxx -= o.sxx;
        self.sxy -= o.sxy;
        self.syy -= o.syy;
        self.sxd -= o.sxd;
        self.syd -= o.syd;
        self.sdd -= o.sdd;
    }

    /// Centred second moments `(Cxx, Cxy, Cyy, Cxd, Cyd, Cdd)` and means `(mx, my, md)`.
    fn centred(&self) -> ([f64; 6], [f64; 3]) {
        let n = self.n;
        let (mx, my, md) = (self.sx / n, self.sy / n, self.sd / n);
        (
            [
                self.sxx / n - mx * mx,
                self.sxy / n - mx * my,
                self.syy / n - my * my,
                self.sxd / n - mx * md,
                self.syd / n - my * md,
                self.sdd / n - md * md,
            ],
            [mx, my, md],
        )
    }

    /// The slopes' information matrix for unit noise variance, `[Sxx, Sxy, Syy]` (the sums of
    /// centred squares): a fit's slopes `(a, b)` have covariance `σ²·S⁻¹` for independent
    /// samples of variance `σ²`.
    pub(crate) fn slope_information(&self) -> [f64; 3] {
        if self.n <= 0.0 {
            return [0.0; 3];
        }
        let ([cxx, cxy, cyy, ..], _) = self.centred();
        [cxx * self.n, cxy * self.n, cyy * self.n]
    }

    /// The least-squares affine fit; `None` for fewer than 3 samples or collinear pixels.
    pub fn solve(&self) -> Option<DisparityAffine> {
        if self.n < 3.0 {
            return None;
        }
        let ([cxx, cxy, cyy, cxd, cyd, _], [mx, my, md]) = self.centred();
        // Centred 3x3 normal equations in (a, b, c') with c' the value at the centroid; the
        // third row decouples (centred coordinates have zero mean).
        let det = cxx * cyy - cxy * cxy;
        let well_posed = det > 1e-9 * (cxx * cyy).max(1e-30) && cxx > 1e-12 && cyy > 1e-12;
        if !well_posed {
            return None;
        }
        let [a, b, z] = lu_solve([[cxx, cxy], [cxy, cyy]], [cxd, cyd, md])?;
        let c = z - a * mx - b * my;
        if !(a.is_finite() && b.is_finite() && c.is_finite()) {
            return None;
        }
        Some(DisparityAffine { a, b, c })
    }

    /// Residual sum of squares `Σ(D − a·x − b·y − c)²` of any affine function.
    pub fn rss(&self, f: &DisparityAffine) -> f64 {
        if self.n <= 0.0 {
            return 0.0;
        }
        let ([cxx, cxy, cyy, cxd, cyd, cdd], [mx, my, md]) = self.centred();
        let (a, b) = (f.a, f.b);
        let e = md - a * mx - b * my - f.c;
        let v = cdd + a * a * cxx + b * b * cyy + 2.0 * a * b * cxy - 2.0 * a * cxd - 2.0 * b * cyd
            + e * e;
        (v * self.n).max(0.0)
    }

    /// RMS residual of `f` over the samples, pixels of disparity.
    pub fn rms(&self, f: &DisparityAffine) -> f64 {
        if self.n <= 0.0 {
            0.0
        } else {
            (self.rss(f) / self.n).sqrt()
        }
    }
}

/// The solution of `[[m00, m01, 0], [m10, m11, 0], [0, 0, 1]] · x = r` by exactly the
/// floating-point operations of nalgebra's `Matrix3::lu().solve()` (partial pivoting; the
/// elimination and substitution steps with their products by the zero entries), so the result
/// is bit-identical to it at a tenth of the instructions (the extractor solves ~2000 of these
/// a frame). `None` where nalgebra's solve fails (a zero pivot).
#[inline]
fn lu_solve(m: [[f64; 2]; 2], r: [f64; 3]) -> Option<[f64; 3]> {
    // Column 0 is (m00, m10, 0): nalgebra's pivot is the first entry of largest magnitude.
    let swap = m[1][0].abs() > m[0][0].abs();
    let (p, q) = if swap { (1, 0) } else { (0, 1) };
    // `axpy` computes `y = (a·x)·1 + 1·y`: the products by one are exact, so `a·x + y`.
    let axpy = |a: f64, x: f64, y: f64| a * x + y;
    // Step 0: pivot row `p` (u00, u01, u02 = 0), multipliers of the rows below it.
    let (u00, u01, u02) = (m[p][0], m[p][1], 0.0f64);
    if u00 == 0.0 {
        // A zero column: the decomposition skips it and the back substitution fails.
        return None;
    }
    let inv0 = 1.0 / u00;
    let (l10, l20) = (m[q][0] * inv0, 0.0f64 * inv0);
    let (m11, m12) = (axpy(-u01, l10, m[q][1]), axpy(-u02, l10, 0.0));
    let (m21, m22) = (axpy(-u01, l20, 0.0), axpy(-u02, l20, 1.0));
    // Step 1: the pivot of column 1 is m11 (m21 is zero); a zero pivot is skipped by the
    // decomposition and fails the solve.
    if m11 == 0.0 {
        return None;
    }
    let inv1 = 1.0 / m11;
    let l21 = m21 * inv1;
    let m22 = axpy(-m12, l21, m22);
    // Forward substitution (unit diagonal; nalgebra divides by the diagonal 1).
    let (mut b0, mut b1, mut b2) = (r[p], r[q], r[2]);
    let c0 = b0 / 1.0;
    b1 = axpy(-c0, l10, b1);
    b2 = axpy(-c0, l20, b2);
    let c1 = b1 / 1.0;
    b2 = axpy(-c1, l21, b2);
    // Back substitution.
    if m22 == 0.0 {
        return None;
    }
    b2 /= m22;
    b0 = axpy(-b2, u02, b0);
    b1 = axpy(-b2, m12, b1);
    b1 /= m11;
    b0 = axpy(-b1, u01, b0);
    b0 /= u00;
    Some([b0, b1, b2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`lu_solve`] against nalgebra's LU solve, bit for bit (both pivot orders, signs, and
    /// near-singular and degenerate systems).
    #[test]
    fn lu_solve_matches_nalgebra_bits() {
        use nalgebra::{Matrix3, Vector3};
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let bits = |v: Option<[f64; 3]>| v.map(|a| a.map(f64::to_bits));
        for k in 0..20000 {
            let scale = [1e-6, 1.0, 1e3, 1e6][k % 4];
            let (a, b, c) = (next() * scale, next() * scale, next() * scale);
            // Symmetric systems as the fits make them, and some with m10 ≠ m01, exact zeros
            // and singular ones.
            let mut m = [[a.abs(), b], [b, c.abs()]];
            match k % 7 {
                0 => m[1][0] = next(),
                1 => m[0][1] = 0.0,
                2 => m[1] = m[0],
                3 => m[0][0] = 0.0,
                _ => {}
            }
            let r = [next() * 1e3, next() * 1e3, next() * 60.0];
            let want = Matrix3::new(m[0][0], m[0][1], 0.0, m[1][0], m[1][1], 0.0, 0.0, 0.0, 1.0)
                .lu()
                .solve(&Vector3::new(r[0], r[1], r[2]))
                .map(|v| [v.x, v.y, v.z]);
            assert_eq!(bits(lu_solve(m, r)), bits(want), "{m:?} {r:?}");
        }
    }

    #[test]
    fn exact_fit_and_runs() {
        let f = DisparityAffine {
            a: 0.013,
            b: -0.021,
            c: 40.0,
        };
        let mut s = AffineSums::default();
        let mut r = AffineSums::default();
        for y in 100..140 {
            let (mut sd, mut sxd, mut sdd) = (0.0, 0.0, 0.0);
            for x in 300..620 {
                let d = f.eval(x as f64, y as f64);
                s.add(x as f64, y as f64, d);
                sd += d;
                sxd += x as f64 * d;
                sdd += d * d;
            }
            r.add_run(y as f64, 300, 620, sd, sxd, sdd);
        }
        for (u, v) in [
            (s.n, r.n),
            (s.sx, r.sx),
            (s.sxx, r.sxx),
            (s.sxy, r.sxy),
            (s.syy, r.syy),
            (s.syd, r.syd),
        ] {
            assert!((u - v).abs() <= 1e-9 * u.abs().max(1.0));
        }
        let g = s.solve().unwrap();
        assert!((g.a - f.a).abs() < 1e-9 && (g.b - f.b).abs() < 1e-9 && (g.c - f.c).abs() < 1e-6);
        assert!(s.rms(&g) < 1e-5);
        let off = DisparityAffine { c: f.c + 0.5, ..f };
        assert!((s.rms(&off) - 0.5).abs() < 1e-5);
    }

    #[test]
    fn degenerate_inputs() {
        let mut s = AffineSums::default();
        assert!(s.solve().is_none());
        for x in 0..10 {
            s.add(x as f64, 5.0, 1.0);
        }
        assert!(s.solve().is_none(), "collinear pixels");
    }
}

//! Least-squares affine fits of the disparity, `D(x, y) = a·x + b·y + c`, from running sums.
//!
//! [`AffineSums`] accumulates the ten moments `Σ1, Σx, Σy, ΣD, Σx², Σxy, Σy², ΣxD, ΣyD, ΣD²` in
//! `f64` (sums are additive, so regions merge by adding their sums). Solving uses the centred
//! normal equations (nalgebra), which are well conditioned even for 640×480 coordinates.

use nalgebra::{Matrix3, Vector3};

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

    /// The least-squares affine fit; `None` for fewer than 3 samples or collinear pixels.
    pub fn solve(&self) -> Option<DisparityAffine> {
        if self.n < 3.0 {
            return None;
        }
        let ([cxx, cxy, cyy, cxd, cyd, _], [mx, my, md]) = self.centred();
        // Centred 3x3 normal equations in (a, b, c') with c' the value at the centroid; the
        // third row decouples (centred coordinates have zero mean).
        let m = Matrix3::new(cxx, cxy, 0.0, cxy, cyy, 0.0, 0.0, 0.0, 1.0);
        let rhs = Vector3::new(cxd, cyd, md);
        let det = cxx * cyy - cxy * cxy;
        let well_posed = det > 1e-9 * (cxx * cyy).max(1e-30) && cxx > 1e-12 && cyy > 1e-12;
        if !well_posed {
            return None;
        }
        let sol = m.lu().solve(&rhs)?;
        let (a, b) = (sol.x, sol.y);
        let c = sol.z - a * mx - b * my;
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

#[cfg(test)]
mod tests {
    use super::*;

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

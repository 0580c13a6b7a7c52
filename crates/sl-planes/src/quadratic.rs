//! Least-squares fits of a disparity residual by a quadratic surface and by a hinge (two
//! affine pieces meeting along a line), from running sums: the two models the crease test of
//! the extractor compares (`extract::crease`).
//!
//! Samples are the residuals `r` of a plane's pixels against its affine fit, at coordinates
//! `(u, v)` centred on the plane and scaled to order one, so the sums stay well conditioned in
//! `f64`. The quadratic's sums are accumulated a row at a time ([`RowMoments`]: nine sums per
//! sample instead of the 27 entries of the normal equations). The hinge is fitted at many
//! positions of its line at once from the sums of the samples binned along the line's normal
//! ([`HingeBins`]). Written by hand: a 6 × 6 and a 4 × 4 normal-equation fit, solved with
//! nalgebra's Cholesky decomposition.

use nalgebra::{Cholesky, SMatrix, SVector};

/// Basis of the quadratic model: `1, u, v, u², u·v, v²` (sample by sample; the extractor
/// adds whole rows, [`QuadraticSums::add_row`]).
#[cfg(test)]
#[inline]
fn quadratic_basis(u: f64, v: f64) -> SVector<f64, 6> {
    SVector::<f64, 6>::new(1.0, u, v, u * u, u * v, v * v)
}

/// Basis of the hinge model: `1, u, v, max(0, t − t₀)` (sample by sample; the extractor
/// bins the samples, [`HingeBins`]).
#[cfg(test)]
#[inline]
fn hinge_basis(u: f64, v: f64, hinge: f64) -> SVector<f64, 4> {
    SVector::<f64, 4>::new(1.0, u, v, hinge)
}

/// The normal equations of a linear least-squares fit with `N` basis functions.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NormalEquations<const N: usize> {
    m: SMatrix<f64, N, N>,
    rhs: SVector<f64, N>,
    srr: f64,
    n: usize,
}

impl<const N: usize> Default for NormalEquations<N> {
    fn default() -> Self {
        Self {
            m: SMatrix::zeros(),
            rhs: SVector::zeros(),
            srr: 0.0,
            n: 0,
        }
    }
}

/// A solved fit: its coefficients, residual sum of squares and the Cholesky factor of the
/// normal matrix (for the covariance of the coefficients).
pub(crate) struct Solved<const N: usize> {
    pub(crate) coef: SVector<f64, N>,
    pub(crate) rss: f64,
    pub(crate) n: usize,
    chol: Cholesky<f64, nalgebra::Const<N>>,
}

impl<const N: usize> NormalEquations<N> {
    #[inline]
    fn add_basis(&mut self, phi: &SVector<f64, N>, r: f64) {
        // Upper triangle only; mirrored when solving.
        for j in 0..N {
            let pj = phi[j];
            for i in 0..=j {
                self.m[(i, j)] += phi[i] * pj;
            }
            self.rhs[j] += pj * r;
        }
        self.srr += r * r;
        self.n += 1;
    }

    /// The least-squares fit; `None` when the samples do not determine it.
    pub(crate) fn solve(&self) -> Option<Solved<N>> {
        if self.n <= N {
            return None;
        }
        let mut m = self.m;
        for j in 0..N {
            for i in 0..j {
                m[(j, i)] = m[(i, j)];
            }
        }
        let chol = Cholesky::new(m)?;
        let coef = chol.solve(&self.rhs);
        // At the optimum, RSS = Σr² − coefᵀ·rhs.
        let rss = (self.srr - coef.dot(&self.rhs)).max(0.0);
        if !(rss.is_finite() && coef.iter().all(|c| c.is_finite())) {
            return None;
        }
        Some(Solved {
            coef,
            rss,
            n: self.n,
            chol,
        })
    }
}

/// The sums over the samples of one row (one `v`) that the quadratic model needs: powers of
/// `u` up to 4, and the residual times powers of `u` up to 2.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RowMoments {
    s: [f64; 5],
    r: [f64; 3],
    rr: f64,
}

impl RowMoments {
    /// Adds the residual `r` at `u`.
    #[inline]
    pub(crate) fn add(&mut self, u: f64, r: f64) {
        let u2 = u * u;
        self.s[0] += 1.0;
        self.s[1] += u;
        self.s[2] += u2;
        self.s[3] += u2 * u;
        self.s[4] += u2 * u2;
        self.r[0] += r;
        self.r[1] += u * r;
        self.r[2] += u2 * r;
        self.rr += r * r;
    }

    /// Whether no sample was added.
    #[inline]
    pub(crate) fn is_empty(&self) -> bool {
        self.s[0] == 0.0
    }
}

/// Sums of the quadratic model.
pub(crate) type QuadraticSums = NormalEquations<6>;

impl QuadraticSums {
    /// Adds the residual `r` at the scaled coordinates `(u, v)`.
    #[cfg(test)]
    #[inline]
    pub(crate) fn add(&mut self, u: f64, v: f64, r: f64) {
        self.add_basis(&quadratic_basis(u, v), r);
    }

    /// Adds the samples of one row at `v` (the same sums as adding them one by one).
    pub(crate) fn add_row(&mut self, v: f64, m: &RowMoments) {
        let [s0, s1, s2, s3, s4] = m.s;
        let [r0, r1, r2] = m.r;
        let (v2, v3) = (v * v, v * v * v);
        // Σ φ_i φ_j for φ = (1, u, v, u², uv, v²), upper triangle.
        let upper = [
            [s0, s1, v * s0, s2, v * s1, v2 * s0],
            [0.0, s2, v * s1, s3, v * s2, v2 * s1],
            [0.0, 0.0, v2 * s0, v * s2, v2 * s1, v3 * s0],
            [0.0, 0.0, 0.0, s4, v * s3, v2 * s2],
            [0.0, 0.0, 0.0, 0.0, v2 * s2, v3 * s1],
            [0.0, 0.0, 0.0, 0.0, 0.0, v2 * v2 * s0],
        ];
        for (i, row) in upper.iter().enumerate() {
            for (j, &x) in row.iter().enumerate().skip(i) {
                self.m[(i, j)] += x;
            }
        }
        let rhs = [r0, r1, v * r0, r2, v * r1, v2 * r0];
        for (t, x) in self.rhs.iter_mut().zip(rhs) {
            *t += x;
        }
        self.srr += m.rr;
        self.n += s0 as usize;
    }
}

/// The weighted moments of samples of the quadratic model: `Σw·uᵃvᵇ` for `a + b ≤ 4`,
/// `Σw·r·uᵃvᵇ` for `a + b ≤ 2` and `Σw·r²` (21 sums per sample instead of the 27 of the normal
/// equations), turned into [`QuadraticSums`] once ([`QuadraticMoments::sums`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct QuadraticMoments {
    /// `Σw·uᵃvᵇ` in the order 1, u, v, u², uv, v², u³, u²v, uv², v³, u⁴, u³v, u²v², uv³, v⁴.
    m: [f64; 15],
    /// `Σw·r·φ` for φ = 1, u, v, u², uv, v².
    r: [f64; 6],
    rr: f64,
    n: usize,
}

impl QuadraticMoments {
    /// Adds the residual `r` at the scaled coordinates `(u, v)` with weight `w`.
    #[inline]
    pub(crate) fn add(&mut self, u: f64, v: f64, r: f64, w: f64) {
        let (u2, uv, v2) = (u * u, u * v, v * v);
        let p = [
            1.0,
            u,
            v,
            u2,
            uv,
            v2,
            u2 * u,
            u2 * v,
            u * v2,
            v2 * v,
            u2 * u2,
            u2 * uv,
            u2 * v2,
            uv * v2,
            v2 * v2,
        ];
        for (m, x) in self.m.iter_mut().zip(p) {
            *m += w * x;
        }
        let wr = w * r;
        for (t, x) in self.r.iter_mut().zip(&p[..6]) {
            *t += wr * x;
        }
        self.rr += wr * r;
        self.n += 1;
    }

    /// The normal equations of the weighted fit.
    pub(crate) fn sums(&self) -> QuadraticSums {
        // Index of uᵃvᵇ in `m`, and the exponents of the basis 1, u, v, u², uv, v².
        let index = |a: usize, b: usize| -> usize {
            let degree = a + b;
            degree * (degree + 1) / 2 + b
        };
        const EXPONENTS: [(usize, usize); 6] = [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)];
        let mut out = QuadraticSums::default();
        for (i, &(ai, bi)) in EXPONENTS.iter().enumerate() {
            for (j, &(aj, bj)) in EXPONENTS.iter().enumerate().skip(i) {
                out.m[(i, j)] = self.m[index(ai + aj, bi + bj)];
            }
            out.rhs[i] = self.r[i];
        }
        out.srr = self.rr;
        out.n = self.n;
        out
    }
}

/// Sums of the hinge model along one line (the direct fit [`HingeBins`] is checked against).
#[cfg(test)]
pub(crate) type HingeSums = NormalEquations<4>;

#[cfg(test)]
impl HingeSums {
    /// Adds the residual `r` at `(u, v)` whose hinge term is `hinge = max(0, t − t₀)`.
    #[inline]
    pub(crate) fn add(&mut self, u: f64, v: f64, hinge: f64, r: f64) {
        self.add_basis(&hinge_basis(u, v, hinge), r);
    }
}

/// Number of bins along the hinge line's normal: the line is tried at the `HINGE_BINS − 1`
/// inner bin edges.
pub(crate) const HINGE_BINS: usize = 32;

/// Samples `(u, v, r)` binned by their position `t` along a direction, for fitting the hinge
/// `r ≈ c₀ + c₁u + c₂v + c₃·max(0, t − t₀)` at every inner bin edge `t₀` in one pass: the
/// hinge term's sums over the samples beyond `t₀` follow from the bins' sums of
/// `1, t, t², u, v, r, t·u, t·v, t·r`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct HingeBins {
    t_min: f64,
    width: f64,
    /// Per bin: `[1, t, t², u, v, r, t·u, t·v, t·r]`.
    bins: [[f64; 9]; HINGE_BINS],
    /// The affine part over all samples.
    affine: NormalEquations<4>,
}

impl HingeBins {
    /// Empty bins over `[t_min, t_max]`.
    pub(crate) fn new(t_min: f64, t_max: f64) -> Self {
        Self {
            t_min,
            width: ((t_max - t_min) / HINGE_BINS as f64).max(f64::MIN_POSITIVE),
            bins: [[0.0; 9]; HINGE_BINS],
            affine: NormalEquations::default(),
        }
    }

    /// Adds the residual `r` at `(u, v)`, at `t` along the direction.
    #[inline]
    pub(crate) fn add(&mut self, u: f64, v: f64, t: f64, r: f64) {
        let k = (((t - self.t_min) / self.width) as usize).min(HINGE_BINS - 1);
        let b = &mut self.bins[k];
        for (s, x) in b
            .iter_mut()
            .zip([1.0, t, t * t, u, v, r, t * u, t * v, t * r])
        {
            *s += x;
        }
        // The affine part (the hinge column is added per position).
        self.affine
            .add_basis(&SVector::<f64, 4>::new(1.0, u, v, 0.0), r);
    }

    /// The best hinge over the inner bin edges: `(rss, t₀)`, or `None` when no position
    /// gives a determined fit.
    pub(crate) fn best(&self) -> Option<(f64, f64)> {
        let mut tail = [0.0; 9];
        let mut best: Option<(f64, f64)> = None;
        for k in (1..HINGE_BINS).rev() {
            for (t, b) in tail.iter_mut().zip(&self.bins[k]) {
                *t += b;
            }
            let t0 = self.t_min + k as f64 * self.width;
            let [n, st, stt, su, sv, sr, stu, stv, str_] = tail;
            // Σh, Σh², Σh·u, Σh·v, Σh·r over the samples beyond t₀, h = t − t₀.
            let sh = st - t0 * n;
            let shh = stt - 2.0 * t0 * st + t0 * t0 * n;
            let (shu, shv, shr) = (stu - t0 * su, stv - t0 * sv, str_ - t0 * sr);
            let mut eq = self.affine;
            eq.m[(0, 3)] = sh;
            eq.m[(1, 3)] = shu;
            eq.m[(2, 3)] = shv;
            eq.m[(3, 3)] = shh;
            eq.rhs[3] = shr;
            if let Some(s) = eq.solve()
                && best.is_none_or(|b| s.rss < b.0)
            {
                best = Some((s.rss, t0));
            }
        }
        best
    }
}

/// The strongest curvature of a quadratic fit: the Hessian's eigenvalue of largest magnitude
/// (per squared unit of the scaled coordinates), its direction, and its variance per unit
/// sample variance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Curvature {
    /// Magnitude of the eigenvalue, residual units per squared coordinate unit.
    pub(crate) magnitude: f64,
    /// Unit direction `(du, dv)` of the curvature (across a crease).
    pub(crate) direction: (f64, f64),
    /// Variance of the eigenvalue for samples of unit variance (independent).
    pub(crate) unit_variance: f64,
}

impl Solved<6> {
    /// The Hessian's dominant eigenvalue and its variance (first order: `δλ = dᵀ·δH·d`).
    pub(crate) fn curvature(&self) -> Curvature {
        let c = &self.coef;
        let (h11, h12, h22) = (2.0 * c[3], c[4], 2.0 * c[5]);
        let h = nalgebra::Matrix2::new(h11, h12, h12, h22);
        let e = h.symmetric_eigen();
        let k = usize::from(e.eigenvalues[1].abs() > e.eigenvalues[0].abs());
        let (du, dv) = (e.eigenvectors[(0, k)], e.eigenvectors[(1, k)]);
        // λ = dᵀ H d with H from the coefficients c₃ (u²), c₄ (uv), c₅ (v²).
        let g = SVector::<f64, 6>::new(0.0, 0.0, 0.0, 2.0 * du * du, 2.0 * du * dv, 2.0 * dv * dv);
        let l = self.chol.l();
        let y = l.solve_lower_triangular(&g).unwrap_or_else(SVector::zeros);
        Curvature {
            magnitude: e.eigenvalues[k].abs(),
            direction: (du, dv),
            unit_variance: y.norm_squared(),
        }
    }
}

#[cfg(test)]
mod moments_tests {
    use super::*;

    /// The moments' normal equations are the weighted sample-by-sample ones.
    #[test]
    fn weighted_moments_match_the_samples() {
        let mut direct = QuadraticSums::default();
        let mut moments = QuadraticMoments::default();
        for k in 0..40 {
            let (u, v) = (0.1 * f64::from(k % 7) - 0.3, 0.07 * f64::from(k) - 1.2);
            let (r, w) = (
                0.5 * u - v * v + 0.01 * f64::from(k),
                1.0 + f64::from(k % 3),
            );
            let phi = quadratic_basis(u, v) * w.sqrt();
            direct.add_basis(&phi, r * w.sqrt());
            moments.add(u, v, r, w);
        }
        let (a, b) = (direct.solve().unwrap(), moments.sums().solve().unwrap());
        for (x, y) in a.coef.iter().zip(b.coef.iter()) {
            assert!((x - y).abs() < 1e-9 * (1.0 + x.abs()), "{x} {y}");
        }
        assert!((a.rss - b.rss).abs() < 1e-9 * (1.0 + a.rss));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quadratic_is_fitted_exactly_with_its_curvature() {
        let mut q = QuadraticSums::default();
        for j in -5..=5 {
            for i in -5..=5 {
                let (u, v) = (f64::from(i) * 0.2, f64::from(j) * 0.2);
                q.add(u, v, 0.3 + 0.1 * u - 0.2 * v + 1.5 * u * u);
            }
        }
        let s = q.solve().unwrap();
        assert!(s.rss < 1e-10, "{}", s.rss);
        let c = s.curvature();
        assert!((c.magnitude - 3.0).abs() < 1e-9, "{}", c.magnitude);
        assert!((c.direction.0.abs() - 1.0).abs() < 1e-9);
        assert!(c.unit_variance > 0.0);
    }

    #[test]
    fn the_curvature_variance_matches_monte_carlo_for_white_noise() {
        // Fit pure noise of unit variance many times: the scatter of the u²-curvature
        // must match the predicted variance.
        let mut state = 12345u64;
        let mut gauss = || {
            // Box-Muller on a small LCG: deterministic, good enough for a variance check.
            let mut uni = || {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (uni(), uni());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        };
        let (mut sum2, trials) = (0.0, 400);
        let mut predicted = 0.0;
        for _ in 0..trials {
            let mut q = QuadraticSums::default();
            for j in -6..=6 {
                for i in -6..=6 {
                    q.add(f64::from(i) / 6.0, f64::from(j) / 6.0, gauss());
                }
            }
            let s = q.solve().unwrap();
            // The u² curvature (2·c₃) and its variance along (1, 0).
            let h11 = 2.0 * s.coef[3];
            sum2 += h11 * h11;
            let g = SVector::<f64, 6>::new(0.0, 0.0, 0.0, 2.0, 0.0, 0.0);
            let y = s.chol.l().solve_lower_triangular(&g).unwrap();
            predicted = y.norm_squared();
        }
        let observed = sum2 / f64::from(trials);
        assert!(
            (observed / predicted - 1.0).abs() < 0.2,
            "observed {observed}, predicted {predicted}"
        );
    }

    #[test]
    fn a_hinge_fits_two_planes_meeting_along_a_line() {
        let mut h = HingeSums::default();
        let mut q = QuadraticSums::default();
        for j in -10..=10 {
            for i in -10..=10 {
                let (u, v) = (f64::from(i) * 0.1, f64::from(j) * 0.1);
                let t = u;
                let r = 0.2 * v + 0.5 * (t - 0.2).max(0.0);
                h.add(u, v, (t - 0.2).max(0.0), r);
                q.add(u, v, r);
            }
        }
        let (hs, qs) = (h.solve().unwrap(), q.solve().unwrap());
        assert!(hs.rss < 1e-10 && qs.rss > 1e-4, "{} {}", hs.rss, qs.rss);
    }

    #[test]
    fn sums_by_rows_equal_sums_by_samples() {
        let (mut by_sample, mut by_row) = (QuadraticSums::default(), QuadraticSums::default());
        for j in 0..7 {
            let v = f64::from(j) * 0.3 - 1.0;
            let mut row = RowMoments::default();
            for i in 0..9 {
                let u = f64::from(i) * 0.25 - 1.1;
                let r = (u * 3.0 + v).sin();
                by_sample.add(u, v, r);
                row.add(u, r);
            }
            by_row.add_row(v, &row);
        }
        let (a, b) = (by_sample.solve().unwrap(), by_row.solve().unwrap());
        assert!((a.coef - b.coef).norm() < 1e-9 && (a.rss - b.rss).abs() < 1e-9);
    }

    #[test]
    fn binned_hinges_equal_direct_fits() {
        let mut bins = HingeBins::new(-1.0, 1.0);
        let samples: Vec<(f64, f64, f64)> = (0..400)
            .map(|i| {
                let (u, v) = (
                    f64::from(i % 20) * 0.1 - 0.95,
                    f64::from(i / 20) * 0.1 - 0.95,
                );
                (
                    u,
                    v,
                    0.3 * v + 0.8 * (u - 0.3).max(0.0) + 0.01 * (f64::from(i) * 1.7).sin(),
                )
            })
            .collect();
        for &(u, v, r) in &samples {
            bins.add(u, v, u, r);
        }
        let (rss, t0) = bins.best().unwrap();
        // The best edge is the one nearest the true hinge, and its RSS is the direct fit's.
        assert!((t0 - 0.3).abs() <= 2.0 / HINGE_BINS as f64, "{t0}");
        let mut direct = HingeSums::default();
        for &(u, v, r) in &samples {
            direct.add(u, v, (u - t0).max(0.0), r);
        }
        let d = direct.solve().unwrap();
        assert!(
            (d.rss - rss).abs() < 1e-9 * (1.0 + d.rss),
            "{} {}",
            d.rss,
            rss
        );
    }

    #[test]
    fn too_few_or_degenerate_samples_do_not_solve() {
        let mut q = QuadraticSums::default();
        for i in 0..6 {
            q.add(f64::from(i), 0.0, 1.0);
        }
        assert!(q.solve().is_none());
        // Collinear samples: the v terms are undetermined.
        for i in 0..20 {
            q.add(f64::from(i) * 0.1, 0.0, 1.0);
        }
        assert!(q.solve().is_none());
    }
}

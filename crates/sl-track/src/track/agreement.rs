//! What a check's samples vouch for: the information matrices of samples that agree with a
//! pose, discounted by how far they disagree as a group ([`agreeing_information`]), and the
//! direction along which samples the pose leaves beyond the gates pin it better than those
//! that agree ([`disputed_direction`]). Dense 6×6 linear algebra by `nalgebra`'s symmetric
//! eigendecomposition; used by [`super::structure`].

use nalgebra::{Matrix6, SymmetricEigen, Vector6};

/// Eigenvalues below this fraction of the largest are a matrix's null space.
const RANK_TOLERANCE: f64 = 1e-9;

/// The positive semi-definite part of a symmetric matrix (its negative eigenvalues set to 0):
/// an unbiased estimate of a positive semi-definite matrix whose noise makes it indefinite has
/// negative eigenvalues that are noise, not information taken away.
pub(super) fn positive_part(m: Matrix6<f64>) -> Matrix6<f64> {
    let e = SymmetricEigen::new(m);
    e.eigenvectors
        * Matrix6::from_diagonal(&e.eigenvalues.map(|v| v.max(0.0)))
        * e.eigenvectors.transpose()
}

/// Along the direction where the samples beyond the gates (`beyond`) hold the most information
/// relative to the samples that agree with the pose (`agreeing`, given as its
/// eigendecomposition, positive definite): if there they hold more than the agreeing ones, the
/// pose's standard deviation along it from them alone, metres; else `None`.
///
/// The largest generalised eigenvalue `μ` of `beyond v = μ agreeing v`, through
/// `A^{-1/2} B A^{-1/2}`; `μ > 1` means some direction is measured better by the samples that
/// disagree with the pose than by those that agree.
pub(super) fn disputed_direction(
    agreeing: &SymmetricEigen<f64, nalgebra::U6>,
    beyond: &Matrix6<f64>,
) -> Option<f64> {
    let inv_sqrt = agreeing.eigenvectors
        * Matrix6::from_diagonal(&agreeing.eigenvalues.map(|v| 1.0 / v.sqrt()))
        * agreeing.eigenvectors.transpose();
    let m = SymmetricEigen::new(inv_sqrt * beyond * inv_sqrt);
    let (top, &mu) = m
        .eigenvalues
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))?;
    let more_than_agreeing = mu > 1.0;
    if !more_than_agreeing {
        return None;
    }
    let v = inv_sqrt * m.eigenvectors.column(top);
    let along = v.dot(&(beyond * v)) / v.norm_squared();
    (along > 0.0).then(|| 1.0 / along.sqrt())
}

/// The information `info` (positive semi-definite) of samples whose residuals may share an
/// error, when the rest of the frame's samples give `rest`: discounted along the pose change
/// their residuals ask for, by as much as it exceeds their noise (the rule of the planes in
/// [`super::structure::StructureCheck::weakest_sigma_m`], for six directions at once).
///
/// `score` is `g = Σ w r J` over the samples and `own` its covariance at the right pose
/// (`Σ w J Jᵀ` with the samples' own normals). At the right pose `q = gᵀ own⁺ g` follows a χ²
/// with as many degrees of freedom `k` as `own` has rank. At a pose off by `Δ` the samples'
/// residuals are `Jᵀ Δ` plus noise; the rest of the frame, which the alignment has satisfied,
/// pins the directions it constrains, so `δ = (rest + info)⁺ g` — the Gauss–Newton step these
/// residuals ask for with everything else held — estimates `Δ` (the samples alone, `info⁺ g`,
/// would put most of it on the rotations a small object hardly constrains). The shared error is
/// modelled as a pose error of covariance `c δ δᵀ`, `c = 1 − k/q` (0 when `q ≤ k`: within the
/// noise), added to the samples' own: by Sherman–Morrison their information becomes
/// `info − c u uᵀ / (1 + c δᵀ u)` with `u = info δ`, still positive semi-definite. Along `δ`
/// what is left is about one standard deviation of `δ`; across it, what they had.
pub(super) fn agreeing_information(
    info: &Matrix6<f64>,
    rest: &Matrix6<f64>,
    own: &Matrix6<f64>,
    score: &Vector6<f64>,
) -> Matrix6<f64> {
    let (_, q, k) = pseudo_solve(*own, score);
    if k == 0 || q <= k as f64 {
        return *info;
    }
    let c = 1.0 - k as f64 / q;
    let (delta, _, _) = pseudo_solve(rest + info, score);
    let u = info * delta;
    info - u * u.transpose() * (c / (1.0 + c * delta.dot(&u)))
}

/// For the positive semi-definite `a`: `x = a⁺ g`, `gᵀ a⁺ g` and the rank of `a` (its
/// eigenvalues above [`RANK_TOLERANCE`] of the largest).
fn pseudo_solve(a: Matrix6<f64>, g: &Vector6<f64>) -> (Vector6<f64>, f64, usize) {
    let a = SymmetricEigen::new(a);
    let largest = a.eigenvalues.max();
    let (mut x, mut q, mut rank) = (Vector6::zeros(), 0.0, 0);
    if largest.is_nan() || largest <= 0.0 {
        return (x, q, rank);
    }
    for (i, &e) in a.eigenvalues.iter().enumerate() {
        if e > largest * RANK_TOLERANCE {
            let v = a.eigenvectors.column(i);
            let along = v.dot(g);
            x += v * (along / e);
            q += along * along / e;
            rank += 1;
        }
    }
    (x, q, rank)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Agreeing samples that pin every direction to 0.1 (information 100) but the sixth to 1.
    fn weak_along_last() -> SymmetricEigen<f64, nalgebra::U6> {
        SymmetricEigen::new(Matrix6::from_diagonal(&Vector6::new(
            100.0, 100.0, 100.0, 100.0, 100.0, 1.0,
        )))
    }

    fn along(axis: usize, information: f64) -> Matrix6<f64> {
        let mut m = Matrix6::zeros();
        m[(axis, axis)] = information;
        m
    }

    #[test]
    fn samples_beyond_the_gates_dispute_only_a_direction_they_pin_better() {
        let agreeing = weak_along_last();
        // 50 against the agreeing samples' 1 along the weak direction: σ = 1/√50 from them.
        let s = disputed_direction(&agreeing, &along(5, 50.0)).unwrap();
        assert!((s - 50f64.sqrt().recip()).abs() < 1e-9, "{s}");
        // The same information along a direction the agreeing samples hold at 100: no dispute.
        assert_eq!(disputed_direction(&agreeing, &along(0, 50.0)), None);
        // Less than the agreeing samples along the weak direction: none either.
        assert_eq!(disputed_direction(&agreeing, &along(5, 0.5)), None);
        assert_eq!(disputed_direction(&agreeing, &Matrix6::zeros()), None);
    }

    #[test]
    fn a_dispute_across_the_axes_is_found_along_its_own_direction() {
        // Beyond the gates: information 200 along (e₀ + e₅)/√2. Relative to the agreeing
        // samples that direction is mostly the weak one, and it is disputed.
        let agreeing = weak_along_last();
        let mut v = Vector6::zeros();
        v[0] = 1.0;
        v[5] = 1.0;
        let v = v / 2f64.sqrt();
        let beyond = v * v.transpose() * 200.0;
        let s = disputed_direction(&agreeing, &beyond).unwrap();
        // Along the generalised eigenvector (nearly e₅ after the agreeing samples' scaling) the
        // beyond-gate information is at most the 200 along v, and more than the weak 1.
        assert!(s >= 200f64.sqrt().recip() - 1e-12 && s < 1.0, "{s}");
    }

    #[test]
    fn the_positive_part_drops_negative_eigenvalues_only() {
        let mut m = Matrix6::from_diagonal(&Vector6::new(3.0, -1.0, 2.0, 0.0, -0.5, 1.0));
        m = positive_part(m);
        let e = SymmetricEigen::new(m).eigenvalues;
        let mut e: Vec<f64> = e.iter().copied().collect();
        e.sort_by(f64::total_cmp);
        let want = [0.0, 0.0, 0.0, 1.0, 2.0, 3.0];
        for (a, b) in e.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{e:?}");
        }
    }
}

//! Rotation and translation from plane matches: weighted Kabsch on the normals (SVD of
//! `Σ w·n_b·n_aᵀ`) and the weighted least-squares translation from `n_a·t = d_b − d_a`.

use super::*;

/// The rotation `R` minimising `Σ w·|a − R·b|²` (weighted Kabsch/SVD); `None` when the
/// weighted vectors do not determine it (fewer than two non-parallel directions).
pub fn weighted_kabsch(pairs: &[(Vector3<f64>, Vector3<f64>, f64)]) -> Option<Rotation3<f64>> {
    let mut hm = Matrix3::zeros();
    for (a, b, w) in pairs {
        hm += *w * b * a.transpose();
    }
    let svd = hm.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut sv = svd.singular_values;
    sv.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    let rank2 = sv[1] > 1e-9 * sv[0].max(1e-300);
    if !rank2 {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let fix = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d));
    Some(Rotation3::from_matrix_unchecked(v * fix * u.transpose()))
}

/// Minimum-norm weighted least-squares `t` of `n·t = δ` over `(n, δ, w)` rows, restricted to
/// the eigen-directions of `Σw·n·nᵀ/Σw` above `min_eigen`; also whether all three are.
pub(super) fn partial_translation(
    rows: &[(Vector3<f64>, f64, f64)],
    min_eigen: f64,
) -> (Vector3<f64>, bool) {
    let mut m = Matrix3::zeros();
    let mut v = Vector3::zeros();
    let mut sw = 0.0;
    for (n, delta, w) in rows {
        m += *w * n * n.transpose();
        v += *w * n * *delta;
        sw += w;
    }
    if sw <= 0.0 {
        return (Vector3::zeros(), false);
    }
    let eig = SymmetricEigen::new(m / sw);
    let mut t = Vector3::zeros();
    let mut full = true;
    for i in 0..3 {
        let l = eig.eigenvalues[i];
        if l > min_eigen {
            let e = eig.eigenvectors.column(i).into_owned();
            t += e * (e.dot(&(v / sw)) / l);
        } else {
            full = false;
        }
    }
    (t, full)
}

/// The angle between two rotations, radians, robust near 180° (`Rotation3::angle_to` goes
/// through `acos` of the trace and turns NaN there).
pub(super) fn rotation_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    UnitQuaternion::from_rotation_matrix(a).angle_to(&UnitQuaternion::from_rotation_matrix(b))
}

pub(super) fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Weighted Kabsch over matches of A's and B's planes.
pub(super) fn kabsch_ab(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    matches: &[PlaneMatch],
) -> Option<Rotation3<f64>> {
    let pairs: Vec<_> = matches
        .iter()
        .map(|m| {
            (
                planes_a[m.a].plane.normal,
                planes_b[m.b].plane.normal,
                m.weight,
            )
        })
        .collect();
    weighted_kabsch(&pairs)
}

pub(super) fn solve_translation(
    planes_a: &[PlaneInfo],
    planes_b: &[PlaneInfo],
    rotation: &UnitQuaternion<f64>,
    matches: Vec<PlaneMatch>,
    cfg: &MotionConfig,
) -> (Option<Vector3<f64>>, Vector3<f64>, Vec<PlaneMatch>) {
    let solve = |ms: &[PlaneMatch]| {
        let rows: Vec<(Vector3<f64>, f64, f64)> = ms
            .iter()
            .map(|mt| {
                let (pa, pb) = (&planes_a[mt.a].plane, &planes_b[mt.b].plane);
                let n = (pa.normal + rotation * pb.normal).normalize();
                (n, pb.offset_m - pa.offset_m, mt.weight)
            })
            .collect();
        let (t, full) = partial_translation(&rows, cfg.min_translation_eigen);
        (full.then_some(t), t)
    };
    let (full, partial) = solve(&matches);
    // Drop matches whose offsets disagree with the translation by more than 10 cm (unless that
    // would leave fewer than two).
    let kept: Vec<PlaneMatch> = matches
        .iter()
        .copied()
        .filter(|mt| {
            let (pa, pb) = (&planes_a[mt.a].plane, &planes_b[mt.b].plane);
            let n = rotation * pb.normal;
            (pb.offset_m - n.dot(&partial) - pa.offset_m).abs() < 0.1
        })
        .collect();
    if kept.len() >= 2 && kept.len() < matches.len() {
        let (f2, p2) = solve(&kept);
        return (f2, p2, kept);
    }
    (full, partial, matches)
}

//! Nearest-timestamp association of two trajectories, as `evaluate_ate.py`'s `associate`:
//! every pair closer than the gap is a candidate, candidates are taken greedily by increasing
//! time difference, each timestamp at most once, and the matches are returned in time order.

use super::StampedPose;

/// Index pairs `(i_gt, i_est)` into `gt` and `est` (each sorted by timestamp, as
/// [`super::ate`] passes them) whose timestamps differ by less than `max_gap_s`, matched
/// greedily by increasing difference (ties by the ground-truth, then the estimated
/// timestamp), each pose at most once, in ground-truth time order.
pub fn associate(gt: &[StampedPose], est: &[StampedPose], max_gap_s: f64) -> Vec<(usize, usize)> {
    // Candidates: for each ground-truth stamp, the estimated stamps within the gap (a sliding
    // window over the sorted estimates instead of all n·m pairs).
    let mut cand: Vec<(f64, usize, usize)> = Vec::new();
    let mut lo = 0;
    for (i, (ta, _)) in gt.iter().enumerate() {
        while lo < est.len() && est[lo].0 <= ta - max_gap_s {
            lo += 1;
        }
        let mut j = lo;
        while j < est.len() && est[j].0 < ta + max_gap_s {
            let d = (ta - est[j].0).abs();
            if d < max_gap_s {
                cand.push((d, i, j));
            }
            j += 1;
        }
    }
    // Indices order like timestamps (both sorted), so (d, i, j) orders like TUM's (d, a, b).
    cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut used_gt = vec![false; gt.len()];
    let mut used_est = vec![false; est.len()];
    let mut out = Vec::new();
    for (_, i, j) in cand {
        if !used_gt[i] && !used_est[j] {
            used_gt[i] = true;
            used_est[j] = true;
            out.push((i, j));
        }
    }
    out.sort_unstable();
    out
}

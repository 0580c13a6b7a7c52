//! The marching-cubes case table, generated at first use from the cube's faces.
//!
//! Corner `c` of a cube has offset `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`; bit `c` of a case
//! index is set when corner `c` is *inside* (F < 0, behind the surface). Edge `4·a + j` runs
//! along axis `a` from the `j`-th corner (ascending) whose bit `a` is 0.
//!
//! **Disambiguation (Montani, Scateni & Scopigno 1994).** Lorensen & Cline's table reduces the
//! 256 cases to 15 using complementary symmetry, which resolves an ambiguous face (two inside
//! corners on one diagonal, two outside corners on the other) differently in a case and in its
//! complement, so two cubes sharing that face can disagree and leave a crack. Montani et al.
//! drop complementary symmetry and resolve *every* ambiguous face the same way. We do the same:
//! on an ambiguous face the inside corners are joined and the outside corners are cut off
//! (thin solid structures stay connected). The decision depends on the four face corners
//! only, so both cubes sharing a face make it identically: the mesh has no cracks.
//!
//! **Construction.** For every case we intersect the surface with each face (0, 1 or 2 line
//! segments between edge crossings, chosen by the rule above), orient each segment so that
//! inside corners lie on one fixed side when the face is seen from outside the cube, chain the
//! segments into closed loops (every crossing point starts exactly one segment and ends exactly
//! one) and triangulate each loop as a fan. The orientation makes every triangle face the
//! outside (F > 0), and a face shared by two cubes is traversed in opposite directions by the
//! two, so neighbouring cubes stitch into a consistently oriented manifold.

use std::sync::OnceLock;

/// Corner offsets.
pub const CORNERS: [[usize; 3]; 8] = {
    let mut c = [[0usize; 3]; 8];
    let mut i = 0;
    while i < 8 {
        c[i] = [i & 1, (i >> 1) & 1, (i >> 2) & 1];
        i += 1;
    }
    c
};

/// Edges as `(lower corner, upper corner, axis)`.
pub const EDGES: [(u8, u8, u8); 12] = {
    let mut e = [(0u8, 0u8, 0u8); 12];
    let mut a = 0;
    while a < 3 {
        let mut j = 0;
        let mut c = 0;
        while c < 8 {
            if (c >> a) & 1 == 0 {
                e[a * 4 + j] = (c as u8, (c | (1 << a)) as u8, a as u8);
                j += 1;
            }
            c += 1;
        }
        a += 1;
    }
    e
};

/// The edge joining two corners that differ in one bit.
fn edge_between(c0: usize, c1: usize) -> usize {
    let (lo, hi) = if c0 < c1 { (c0, c1) } else { (c1, c0) };
    let a = (hi ^ lo).trailing_zeros() as usize;
    let j = (0..8)
        .filter(|&c| (c >> a) & 1 == 0)
        .take_while(|&c| c != lo)
        .count();
    a * 4 + j
}

/// Corners of face `(axis, side)` in counter-clockwise order seen from outside the cube.
pub fn face_cycle(axis: usize, side: usize) -> [usize; 4] {
    let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
    let s = side << axis;
    let cyc = [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(cu, cv)| s | (cu << u) | (cv << v));
    if side == 1 {
        cyc
    } else {
        [cyc[0], cyc[3], cyc[2], cyc[1]]
    }
}

/// The oriented surface segments `(from edge, to edge)` on face `(axis, side)` for a case.
/// Depends only on the signs of the four face corners.
pub fn face_segments(case: u8, axis: usize, side: usize) -> Vec<(usize, usize)> {
    let cyc = face_cycle(axis, side);
    let inside = cyc.map(|c| (case >> c) & 1 == 1);
    let n_in = inside.iter().filter(|&&b| b).count();
    if n_in == 0 || n_in == 4 {
        return Vec::new();
    }
    let e = |i: usize, j: usize| edge_between(cyc[i % 4], cyc[j % 4]);
    let ambiguous = inside[0] == inside[2] && inside[1] == inside[3] && inside[0] != inside[1];
    if ambiguous {
        // Join the inside corners: cut off each outside corner i with a segment from the
        // edge after it (outside -> inside) to the edge before it (inside -> outside).
        (0..4)
            .filter(|&i| !inside[i])
            .map(|i| (e(i, i + 1), e(i + 3, i)))
            .collect()
    } else {
        // One inside run: from its entry edge (outside -> inside) to its exit edge.
        let mut entry = None;
        let mut exit = None;
        for i in 0..4 {
            let j = (i + 1) % 4;
            if !inside[i] && inside[j] {
                entry = Some(e(i, j));
            }
            if inside[i] && !inside[j] {
                exit = Some(e(i, j));
            }
        }
        match (entry, exit) {
            (Some(a), Some(b)) => vec![(a, b)],
            _ => Vec::new(),
        }
    }
}

/// The generated table: the triangles (as triples of edge indices) of each of the 256 cases.
#[derive(Debug)]
pub struct McTable {
    offsets: [u16; 257],
    tris: Vec<[u8; 3]>,
}

impl McTable {
    /// The triangles of a case, each a triple of edge indices, facing the outside (F > 0).
    #[inline]
    pub fn triangles(&self, case: u8) -> &[[u8; 3]] {
        let c = case as usize;
        &self.tris[self.offsets[c] as usize..self.offsets[c + 1] as usize]
    }

    /// The largest number of triangles of any case.
    #[cfg(test)]
    pub fn max_triangles(&self) -> usize {
        (0..256)
            .map(|c| (self.offsets[c + 1] - self.offsets[c]) as usize)
            .max()
            .unwrap_or(0)
    }
}

/// Builds the loops of a case: closed cycles of crossing edges.
pub fn case_loops(case: u8) -> Vec<Vec<usize>> {
    let mut next = [usize::MAX; 12];
    for axis in 0..3 {
        for side in 0..2 {
            for (a, b) in face_segments(case, axis, side) {
                next[a] = b;
            }
        }
    }
    let mut seen = [false; 12];
    let mut loops = Vec::new();
    for start in 0..12 {
        if next[start] == usize::MAX || seen[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !seen[e] && e != usize::MAX {
            seen[e] = true;
            lp.push(e);
            e = next[e];
        }
        loops.push(lp);
    }
    loops
}

/// Whether two cube edges lie on a common face.
fn share_face(e0: usize, e1: usize) -> bool {
    let (a0, b0, _) = EDGES[e0];
    let (a1, b1, _) = EDGES[e1];
    // A face is a set of corners with one coordinate fixed: both edges lie on it when all
    // four corners agree on some coordinate bit.
    (0..3).any(|bit| {
        let v = (a0 >> bit) & 1;
        [b0, a1, b1].iter().all(|&c| (c >> bit) & 1 == v)
    })
}

/// Triangulates a loop (polygon of crossing edges) without creating a diagonal between two
/// points on the same cube face: such a diagonal would lie in the face and could coincide
/// with one of the neighbouring cube, making that mesh edge non-manifold. Returns `None` if
/// no such triangulation exists.
fn triangulate(poly: &[usize]) -> Option<Vec<[usize; 3]>> {
    let n = poly.len();
    if n < 3 {
        return Some(Vec::new());
    }
    if n == 3 {
        return Some(vec![[poly[0], poly[1], poly[2]]]);
    }
    // The triangle on edge (0, 1) has apex k; diagonals (1, k) and (k, 0) must be allowed.
    for k in 2..n {
        let diag_ok = |i: usize, j: usize| {
            let adjacent = (i + 1) % n == j || (j + 1) % n == i;
            adjacent || !share_face(poly[i], poly[j])
        };
        if !diag_ok(1, k) || !diag_ok(k, 0) {
            continue;
        }
        let left: Vec<usize> = poly[1..=k].to_vec();
        let mut right: Vec<usize> = poly[k..].to_vec();
        right.push(poly[0]);
        if let (Some(mut l), Some(r)) = (triangulate(&left), triangulate(&right)) {
            l.push([poly[0], poly[1], poly[k]]);
            l.extend(r);
            return Some(l);
        }
    }
    None
}

fn build() -> McTable {
    let mut offsets = [0u16; 257];
    let mut tris = Vec::new();
    for case in 0..256usize {
        for lp in case_loops(case as u8) {
            match triangulate(&lp) {
                Some(t) => tris.extend(t.into_iter().map(|t| t.map(|e| e as u8))),
                None => {
                    // Not reached for any of the 256 cases (checked by a test); a fan keeps
                    // the table complete regardless.
                    for i in 1..lp.len().saturating_sub(1) {
                        tris.push([lp[0] as u8, lp[i] as u8, lp[i + 1] as u8]);
                    }
                }
            }
        }
        offsets[case + 1] = tris.len() as u16;
    }
    McTable { offsets, tris }
}

/// The table (built once).
pub fn table() -> &'static McTable {
    static TABLE: OnceLock<McTable> = OnceLock::new();
    TABLE.get_or_init(build)
}

/// The 24 rotations of the cube as corner permutations (`perm[c]` = image of corner `c`).
#[cfg(test)]
pub fn cube_rotations() -> Vec<[usize; 8]> {
    let rot_x = |c: usize| {
        // (x, y, z) -> (x, 1 - z, y)
        let [x, y, z] = CORNERS[c];
        x | ((1 - z) << 1) | (y << 2)
    };
    let rot_y = |c: usize| {
        // (x, y, z) -> (z, y, 1 - x)
        let [x, y, z] = CORNERS[c];
        z | (y << 1) | ((1 - x) << 2)
    };
    let id: [usize; 8] = [0, 1, 2, 3, 4, 5, 6, 7];
    let mut all = vec![id];
    let mut i = 0;
    while i < all.len() {
        let p = all[i];
        for g in [&rot_x as &dyn Fn(usize) -> usize, &rot_y] {
            let q = p.map(g);
            if !all.contains(&q) {
                all.push(q);
            }
        }
        i += 1;
    }
    all
}

/// Applies a corner permutation to a case index.
#[cfg(test)]
pub fn permute_case(case: u8, perm: &[usize; 8]) -> u8 {
    (0..8)
        .filter(|&c| (case >> c) & 1 == 1)
        .fold(0u8, |acc, c| acc | (1 << perm[c]))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn crossing(case: u8, e: usize) -> bool {
        let (a, b, _) = EDGES[e];
        ((case >> a) & 1) != ((case >> b) & 1)
    }

    #[test]
    fn every_loop_triangulates_without_face_diagonals() {
        for case in 0..=255u8 {
            for lp in case_loops(case) {
                assert!(triangulate(&lp).is_some(), "case {case} loop {lp:?}");
            }
            for t in table().triangles(case) {
                for i in 0..3 {
                    let (a, b) = (t[i] as usize, t[(i + 1) % 3] as usize);
                    // Any triangle edge on a face must be one of that face's segments.
                    if share_face(a, b) {
                        let on_segment = (0..3).any(|ax| {
                            (0..2).any(|side| {
                                face_segments(case, ax, side)
                                    .iter()
                                    .any(|&(x, y)| (x, y) == (a, b) || (x, y) == (b, a))
                            })
                        });
                        assert!(on_segment, "case {case}: edge {a}-{b} lies in a face");
                    }
                }
            }
        }
    }

    #[test]
    fn edges_are_consistent() {
        for (i, &(a, b, ax)) in EDGES.iter().enumerate() {
            assert_eq!(a ^ b, 1 << ax);
            assert_eq!(edge_between(a as usize, b as usize), i);
        }
    }

    #[test]
    fn fifteen_base_cases() {
        let rots = cube_rotations();
        assert_eq!(rots.len(), 24);
        let canon = |c: u8, complement: bool| {
            let mut best = u8::MAX;
            for r in &rots {
                let p = permute_case(c, r);
                best = best.min(p);
                if complement {
                    best = best.min(!p);
                }
            }
            best
        };
        let with_compl: std::collections::BTreeSet<u8> =
            (0..=255u8).map(|c| canon(c, true)).collect();
        let rot_only: std::collections::BTreeSet<u8> =
            (0..=255u8).map(|c| canon(c, false)).collect();
        // Lorensen & Cline's 15 classes (rotations + complement), 23 without complement.
        assert_eq!(with_compl.len(), 15);
        assert_eq!(rot_only.len(), 23);
        // Triangle counts are rotation invariant (the table is built from faces only).
        for c in 0..=255u8 {
            for r in &rots {
                assert_eq!(
                    table().triangles(c).len(),
                    table().triangles(permute_case(c, r)).len(),
                    "case {c}"
                );
            }
        }
        // The classic counts of the 15 base cases under the "join inside" rule: every base case
        // with at most four inside corners (the ones Lorensen lists) gets its classic number of
        // triangles when no face is ambiguous.
        let t = table();
        assert_eq!(t.triangles(0).len(), 0);
        assert_eq!(t.triangles(0b0000_0001).len(), 1); // case 1
        assert_eq!(t.triangles(0b0000_0011).len(), 2); // case 2
        assert_eq!(t.triangles(0b1000_0001).len(), 2); // case 4: opposite corners
        assert_eq!(t.triangles(0b0000_1110).len(), 3); // case 5
        assert_eq!(t.triangles(0b0000_1111).len(), 2); // case 8: a half
        assert_eq!(t.triangles(0b0111_0001).len(), 4); // case 9 / 11 family
        assert!(t.max_triangles() <= 12);
    }

    /// Every triangle uses crossing edges only, every crossing edge is used, the loop
    /// boundary of each case equals its face segments, and interior edges pair up with
    /// opposite orientation.
    #[test]
    fn all_256_cases_are_closed_within_the_cube() {
        for case in 0..=255u8 {
            let tris = table().triangles(case);
            let mut used = [false; 12];
            let mut directed: HashMap<(u8, u8), i32> = HashMap::new();
            for t in tris {
                for i in 0..3 {
                    assert!(
                        crossing(case, t[i] as usize),
                        "case {case} uses non-crossing edge"
                    );
                    used[t[i] as usize] = true;
                    *directed.entry((t[i], t[(i + 1) % 3])).or_default() += 1;
                }
            }
            for (e, &u) in used.iter().enumerate() {
                assert_eq!(u, crossing(case, e), "case {case} edge {e}");
            }
            let mut segs: Vec<(u8, u8)> = Vec::new();
            for axis in 0..3 {
                for side in 0..2 {
                    for (a, b) in face_segments(case, axis, side) {
                        segs.push((a as u8, b as u8));
                    }
                }
            }
            // Boundary of the triangle fan = directed edges without a reverse twin.
            let mut boundary: Vec<(u8, u8)> = directed
                .iter()
                .filter(|((a, b), _)| !directed.contains_key(&(*b, *a)))
                .map(|(&k, &n)| {
                    assert_eq!(n, 1, "case {case}: directed edge used twice");
                    k
                })
                .collect();
            boundary.sort_unstable();
            segs.sort_unstable();
            assert_eq!(boundary, segs, "case {case}");
        }
    }

    /// Triangles face the outside: their area-weighted normal agrees with the gradient of the
    /// trilinear interpolant of ±1 corner values.
    #[test]
    fn triangles_face_outside() {
        for case in 1..=254u8 {
            let val = |c: usize| if (case >> c) & 1 == 1 { -1.0 } else { 1.0 };
            let vert = |e: u8| {
                let (a, b, _) = EDGES[e as usize];
                let (pa, pb) = (CORNERS[a as usize], CORNERS[b as usize]);
                [0, 1, 2].map(|i| (pa[i] + pb[i]) as f64 / 2.0)
            };
            let grad = |p: [f64; 3]| {
                let mut g = [0.0; 3];
                for (c, o) in CORNERS.iter().enumerate() {
                    for ax in 0..3 {
                        let mut w = if o[ax] == 1 { 1.0 } else { -1.0 };
                        for bx in 0..3 {
                            if bx != ax {
                                w *= if o[bx] == 1 { p[bx] } else { 1.0 - p[bx] };
                            }
                        }
                        g[ax] += w * val(c);
                    }
                }
                g
            };
            let mut agree = 0.0;
            for t in table().triangles(case) {
                let [a, b, c] = t.map(vert);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let n = [
                    u[1] * v[2] - u[2] * v[1],
                    u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0],
                ];
                let m = [0, 1, 2].map(|i| (a[i] + b[i] + c[i]) / 3.0);
                let g = grad(m);
                agree += n[0] * g[0] + n[1] * g[1] + n[2] * g[2];
            }
            assert!(agree > 0.0, "case {case}: {agree}");
        }
    }

    #[test]
    fn ambiguous_face_is_resolved_identically_from_both_sides() {
        // Cube A's +x face and cube B's -x face are the same face. For every sign pattern on
        // it, the segments must be the same set of crossing points, traversed oppositely.
        for pattern in 0..16u8 {
            // Face x = 1 of A: corners 1, 3, 5, 7; face x = 0 of B: corners 0, 2, 4, 6.
            let mut a_case = 0u8;
            let mut b_case = 0u8;
            for (i, (&ca, &cb)) in [1usize, 3, 5, 7].iter().zip(&[0usize, 2, 4, 6]).enumerate() {
                if (pattern >> i) & 1 == 1 {
                    a_case |= 1 << ca;
                    b_case |= 1 << cb;
                }
            }
            // Fill the far corners both ways: the face decision must not depend on them.
            for far in [0u8, 0b0101_0101] {
                let sa: Vec<(usize, usize)> = face_segments(a_case | far, 0, 1);
                let sb: Vec<(usize, usize)> = face_segments(b_case | (far << 1), 0, 0);
                // Map A's x = 1 edges to B's x = 0 edges: same (y, z) edge, lower corner - 1.
                let to_b = |e: usize| {
                    let (lo, hi, ax) = EDGES[e];
                    let lo = if ax == 0 { lo } else { lo & !1 };
                    let hi = if ax == 0 { hi } else { hi & !1 };
                    edge_between(lo as usize, hi as usize)
                };
                let mut mapped: Vec<(usize, usize)> =
                    sa.iter().map(|&(x, y)| (to_b(y), to_b(x))).collect();
                let mut sb = sb;
                mapped.sort_unstable();
                sb.sort_unstable();
                assert_eq!(mapped, sb, "pattern {pattern:04b}");
            }
        }
    }
}

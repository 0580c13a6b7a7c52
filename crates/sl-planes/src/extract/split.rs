//! Pieces of one plane that the free space between them says are different surfaces
//! ([`PlaneExtractor::split_separated`]).

use super::*;

/// Cells sampled per piece for the lines between two pieces.
const SAMPLES_PER_PIECE: usize = 6;

/// One 4-connected piece of a plane's cells.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Piece {
    /// The plane's label.
    label: u16,
    /// Cells.
    cells: usize,
    /// Its runs in the labeller's runs, and how many of them the sampling has passed.
    runs: u32,
    seen: u32,
    /// Cells `(x, y)` spread over its runs (the middle of every `⌈runs / SAMPLES_PER_PIECE⌉`-th
    /// run; pieces of at least `min_q` cells only), the ends of the lines to other pieces.
    samples: [(f32, f32); SAMPLES_PER_PIECE],
    sampled: u8,
    /// Union-find parent among the pieces of its plane (index into the pieces).
    parent: u32,
    /// The label it takes (0 = keeps its plane's).
    new_label: u16,
}

impl PlaneExtractor {
    /// Splits a plane whose pieces (4-connected sets of its cells, each at least `min_q`
    /// cells) are separated by free space: two pieces stay one plane when at least one of the
    /// lines between sample cells of the two crosses no cell that lies **behind** the plane
    /// (its mean disparity below the plane's by more than `τ`), directly or through other
    /// pieces. Behind the plane means the camera sees through where the plane would be, so
    /// the plane has a hole there: two box tops at one height with the floor between them, two
    /// box faces side by side with the wall behind. A wall cut in two by a chair in front of it
    /// (an occluder, nearer than the plane) stays one plane. The merges join coplanar
    /// disconnected regions whatever lies between them; in the room benchmark most spurious
    /// planes were such unions of two boxes' faces.
    ///
    /// Each set of pieces that stays together becomes a plane with the same fit (the final
    /// pass refits each on its own pixels); the set of the largest piece keeps the label.
    /// Pieces smaller than `min_q` keep their plane's label.
    ///
    /// `labelled`: the components of the cell labels are already in `self.components` (from
    /// `drop_small_pieces`, whose dropped pieces are smaller than `min_q`).
    #[inline(never)]
    pub(super) fn split_separated(
        &mut self,
        wq: usize,
        hq: usize,
        tau: f64,
        min_q: usize,
        labelled: bool,
    ) {
        if !labelled {
            self.components.label(&self.cell_labels, wq, hq);
        }
        let comps = &self.components;
        let pieces = &mut self.split_pieces;
        pieces.clear();
        pieces.resize(comps.sizes.len(), Piece::default());
        for (ri, run) in comps.runs.iter().enumerate() {
            let c = comps.component[ri] as usize;
            let p = &mut pieces[c];
            if p.runs == 0 {
                p.label = run.key as u16;
                p.cells = comps.sizes[c];
                p.parent = c as u32;
            }
            p.runs += 1;
        }
        for run in comps.runs.iter().zip(&comps.component) {
            let p = &mut pieces[*run.1 as usize];
            if p.cells < min_q {
                continue;
            }
            let step = p.runs.div_ceil(SAMPLES_PER_PIECE as u32).max(1);
            if p.seen.is_multiple_of(step) && usize::from(p.sampled) < SAMPLES_PER_PIECE {
                let r = run.0;
                p.samples[usize::from(p.sampled)] = (0.5 * (r.x0 + r.x1 - 1) as f32, r.y as f32);
                p.sampled += 1;
            }
            p.seen += 1;
        }
        // The big pieces, by plane.
        let mut order = std::mem::take(&mut self.split_order);
        order.clear();
        order.extend((0..pieces.len() as u32).filter(|&c| pieces[c as usize].cells >= min_q));
        order.sort_by_key(|&c| {
            let p = &pieces[c as usize];
            (p.label, std::cmp::Reverse(p.cells), c)
        });
        let mut changed = false;
        let mut start = 0;
        while start < order.len() {
            let label = self.split_pieces[order[start] as usize].label;
            let end = start
                + order[start..]
                    .iter()
                    .take_while(|&&c| self.split_pieces[c as usize].label == label)
                    .count();
            if end - start >= 2
                && let Some(f) = self.planes.get(label as usize - 1).map(|p| p.f)
            {
                changed |= self.split_plane(&order[start..end], label, &f, wq, tau);
            }
            start = end;
        }
        self.split_order = order;
        if !changed {
            return;
        }
        // Relabel the moved pieces' runs, and refill the moment sums of the planes that were
        // split (the order by size reads them).
        let split_from = &mut self.split_affected;
        split_from.clear();
        split_from.resize(self.planes.len() + 1, 0);
        for p in self.split_pieces.iter().filter(|p| p.new_label != 0) {
            split_from[p.label as usize] = 1;
            split_from[p.new_label as usize] = 1;
        }
        for (l, p) in self.planes.iter_mut().enumerate() {
            if split_from[l + 1] != 0 {
                p.sums = AffineSums::default();
            }
        }
        let comps = &self.components;
        for (ri, run) in comps.runs.iter().enumerate() {
            let piece = &self.split_pieces[comps.component[ri] as usize];
            let y = run.y as usize;
            let (x0, x1) = (run.x0 as usize, run.x1 as usize);
            let l = match piece.new_label {
                0 => piece.label,
                l => {
                    self.cell_labels[y * wq + x0..y * wq + x1].fill(l);
                    l
                }
            };
            // (Runs of the pieces `drop_small_pieces` dropped are zero now.)
            if split_from[l as usize] != 0
                && self.cell_labels[y * wq + x0] == l
                && let Some(p) = self.planes.get_mut(l as usize - 1)
            {
                for (x, &d) in self.cell_disparity[y * wq + x0..y * wq + x1]
                    .iter()
                    .enumerate()
                {
                    if d.is_finite() {
                        p.sums.add((x0 + x) as f64, y as f64, f64::from(d));
                    }
                }
            }
        }
    }

    /// Joins the pieces `ids` (of plane `label`, largest first) along clear lines; every set
    /// but that of the largest piece gets a new plane. Returns whether any did.
    fn split_plane(
        &mut self,
        ids: &[u32],
        label: u16,
        f: &DisparityAffine,
        wq: usize,
        tau: f64,
    ) -> bool {
        let find = |pieces: &[Piece], mut c: u32| {
            while pieces[c as usize].parent != c {
                c = pieces[c as usize].parent;
            }
            c
        };
        for (a, &ca) in ids.iter().enumerate() {
            for &cb in &ids[a + 1..] {
                let (ra, rb) = (find(&self.split_pieces, ca), find(&self.split_pieces, cb));
                if ra == rb {
                    continue;
                }
                if self.clear_line_between(ca, cb, label, f, wq, tau) {
                    self.split_pieces[rb as usize].parent = ra;
                }
            }
        }
        let root0 = find(&self.split_pieces, ids[0]);
        let mut any = false;
        // New labels for the other sets, in the order of their largest piece.
        for &c in ids {
            let r = find(&self.split_pieces, c);
            if r == root0 {
                continue;
            }
            let l = if self.split_pieces[r as usize].new_label != 0 {
                self.split_pieces[r as usize].new_label
            } else {
                if self.planes.len() + 1 >= usize::from(u16::MAX) || self.planes.len() >= MAX_PLANES
                {
                    continue;
                }
                let mut cand = self.planes[label as usize - 1];
                cand.sums = AffineSums::default();
                self.planes.push(cand);
                let l = self.planes.len() as u16;
                self.split_pieces[r as usize].new_label = l;
                l
            };
            self.split_pieces[c as usize].new_label = l;
            any = true;
        }
        any
    }

    /// Whether some line between sample cells of pieces `ca` and `cb` crosses no valid cell
    /// behind the plane `f` by more than `tau` (cells of the plane itself, occluders in front
    /// of it and invalid cells do not block).
    fn clear_line_between(
        &self,
        ca: u32,
        cb: u32,
        label: u16,
        f: &DisparityAffine,
        wq: usize,
        tau: f64,
    ) -> bool {
        let (pa, pb) = (
            &self.split_pieces[ca as usize],
            &self.split_pieces[cb as usize],
        );
        let point = |&(x, y): &(f32, f32)| (f64::from(x), f64::from(y));
        let cells = &self.cell_disparity;
        let labels = &self.cell_labels;
        for (xa, ya) in pa.samples[..usize::from(pa.sampled)].iter().map(point) {
            'line: for (xb, yb) in pb.samples[..usize::from(pb.sampled)].iter().map(point) {
                let steps = (xb - xa).abs().max((yb - ya).abs()).ceil().max(1.0) as usize;
                let (dx, dy) = ((xb - xa) / steps as f64, (yb - ya) / steps as f64);
                for s in 1..steps {
                    // The cell nearest the point (coordinates are non-negative).
                    let (x, y) = (
                        (xa + s as f64 * dx + 0.5) as usize,
                        (ya + s as f64 * dy + 0.5) as usize,
                    );
                    let i = y * wq + x;
                    if labels.get(i) == Some(&label) {
                        continue;
                    }
                    let d = cells.get(i).copied().unwrap_or(f32::NAN);
                    if d.is_finite() && f64::from(d) < f.eval(x as f64, y as f64) - tau {
                        continue 'line;
                    }
                }
                return true;
            }
        }
        false
    }
}

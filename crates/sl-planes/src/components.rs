//! Connected components (4-connectivity) by run-length encoding and union-find over runs.
//!
//! Each row is split into maximal runs of equal non-background value; runs of consecutive rows
//! with the same value and overlapping columns are united. The work is proportional to the
//! number of runs, not pixels, after one scan of the image.

/// One horizontal run `x0..x1` on row `y` of pixels with the same value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Run {
    /// Row.
    pub y: u32,
    /// First column.
    pub x0: u32,
    /// One past the last column.
    pub x1: u32,
    /// The pixel value of the run (never the background value).
    pub key: u32,
}

/// Reusable run-based connected-component labeller.
#[derive(Debug, Default, Clone)]
pub struct RunLabeler {
    /// The runs, row by row.
    pub runs: Vec<Run>,
    parent: Vec<u32>,
    /// Component index per run after [`RunLabeler::label`].
    pub component: Vec<u32>,
    /// Pixel count per component after [`RunLabeler::label`].
    pub sizes: Vec<usize>,
}

impl RunLabeler {
    /// Labels the components of the non-zero values of a row-major `width × height` image.
    /// Afterwards `runs[i]` belongs to component `component[i]` (0-based, dense) of
    /// `sizes[component[i]]` pixels.
    pub fn label<T: Copy + PartialEq + Default + Into<u32>>(
        &mut self,
        data: &[T],
        width: usize,
        height: usize,
    ) {
        self.runs.clear();
        self.parent.clear();
        let zero = T::default();
        let mut prev_start = 0usize;
        for y in 0..height {
            let row = &data[y * width..(y + 1) * width];
            let row_start = self.runs.len();
            let mut x = 0usize;
            while x < width {
                let v = row[x];
                if v == zero {
                    x += 1;
                    continue;
                }
                let x0 = x;
                while x < width && row[x] == v {
                    x += 1;
                }
                let idx = self.runs.len() as u32;
                self.runs.push(Run {
                    y: y as u32,
                    x0: x0 as u32,
                    x1: x as u32,
                    key: v.into(),
                });
                self.parent.push(idx);
            }
            // Unite with overlapping runs of the previous row (two-pointer sweep).
            if y > 0 {
                let (mut i, mut j) = (prev_start, row_start);
                let end_prev = row_start;
                let end_cur = self.runs.len();
                while i < end_prev && j < end_cur {
                    let (a, b) = (self.runs[i], self.runs[j]);
                    if a.x0 < b.x1 && b.x0 < a.x1 && a.key == b.key {
                        self.union(i as u32, j as u32);
                    }
                    if a.x1 < b.x1 {
                        i += 1;
                    } else {
                        j += 1;
                    }
                }
            }
            prev_start = row_start;
        }
        self.finish();
    }

    fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let p = self.parent[i as usize];
            self.parent[i as usize] = self.parent[p as usize];
            i = p;
        }
        i
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Keep the smaller index as root: roots then precede their members.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }

    fn finish(&mut self) {
        self.component.clear();
        self.sizes.clear();
        self.component.resize(self.runs.len(), u32::MAX);
        for i in 0..self.runs.len() {
            let r = self.find(i as u32) as usize;
            let c = if r == i {
                self.sizes.push(0);
                (self.sizes.len() - 1) as u32
            } else {
                self.component[r]
            };
            self.component[i] = c;
            let run = self.runs[i];
            self.sizes[c as usize] += (run.x1 - run.x0) as usize;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn u_shape_is_one_component() {
        #[rustfmt::skip]
        let img: [u8; 30] = [
            1, 0, 0, 0, 1, 2,
            1, 0, 2, 0, 1, 2,
            1, 0, 2, 0, 1, 0,
            1, 1, 1, 1, 1, 0,
            0, 0, 0, 0, 0, 3,
        ];
        let mut l = RunLabeler::default();
        l.label(&img, 6, 5);
        let mut sizes = l.sizes.clone();
        sizes.sort_unstable();
        // U of 1s (11), the 2s at column 2 (2), the 2s at column 5 (2), the lone 3 (1).
        assert_eq!(sizes, vec![1, 2, 2, 11]);
        // Different values never join even when touching.
        let img2: [u8; 4] = [1, 2, 1, 2];
        l.label(&img2, 2, 2);
        assert_eq!(l.sizes.len(), 2);
    }
}

//! Connected components (4-connectivity) by run-length encoding and union-find over runs.
//!
//! Each row is split into maximal runs of equal non-background value; runs of consecutive rows
//! with the same value and overlapping columns are united. The work is proportional to the
//! number of runs, not pixels, after one scan of the image, which reads 64-bit words (8 mask
//! bytes or 4 labels at a time) to skip the background and to find the ends of runs.

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

/// A pixel value the labeller accepts (the default value is the background); scanning works
/// on 64-bit words.
pub trait RunValue: Copy + PartialEq + Default + Into<u32> {
    /// Values per 64-bit word.
    const PER_WORD: usize;
    /// Bits of one value.
    const BITS: u32;
    /// The values `row[x..x + PER_WORD]` as a little-endian word.
    fn word(row: &[Self], x: usize) -> u64;
    /// First `x' ≥ x` with a non-background value (or `row.len()`).
    #[inline]
    fn skip_zeros(row: &[Self], mut x: usize) -> usize {
        while x + Self::PER_WORD <= row.len() {
            let wd = Self::word(row, x);
            if wd != 0 {
                return x + (wd.trailing_zeros() / Self::BITS) as usize;
            }
            x += Self::PER_WORD;
        }
        while x < row.len() && row[x] == Self::default() {
            x += 1;
        }
        x
    }
    /// End of the run of values equal to `row[x]` that starts at `x`.
    #[inline]
    fn run_end(row: &[Self], mut x: usize) -> usize {
        let v = row[x];
        let mut vv = u64::from(v.into());
        let mut shift = Self::BITS;
        while shift < 64 {
            vv |= vv << shift;
            shift *= 2;
        }
        while x + Self::PER_WORD <= row.len() {
            let diff = Self::word(row, x) ^ vv;
            if diff != 0 {
                return x + (diff.trailing_zeros() / Self::BITS) as usize;
            }
            x += Self::PER_WORD;
        }
        while x < row.len() && row[x] == v {
            x += 1;
        }
        x
    }
}

impl RunValue for u8 {
    const PER_WORD: usize = 8;
    const BITS: u32 = 8;
    #[inline]
    fn word(row: &[u8], x: usize) -> u64 {
        match row.get(x..x + 8).map(<[u8; 8]>::try_from) {
            Some(Ok(a)) => u64::from_le_bytes(a),
            _ => 0,
        }
    }
}

impl RunValue for u16 {
    const PER_WORD: usize = 4;
    const BITS: u32 = 16;
    #[inline]
    fn word(row: &[u16], x: usize) -> u64 {
        match row.get(x..x + 4).map(<[u16; 4]>::try_from) {
            Some(Ok(a)) => {
                u64::from(a[0])
                    | (u64::from(a[1]) << 16)
                    | (u64::from(a[2]) << 32)
                    | (u64::from(a[3]) << 48)
            }
            _ => 0,
        }
    }
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
    pub fn label<T: RunValue>(&mut self, data: &[T], width: usize, height: usize) {
        self.runs.clear();
        self.parent.clear();
        let mut prev_start = 0usize;
        for y in 0..height {
            let row = &data[y * width..(y + 1) * width];
            let row_start = self.runs.len();
            let mut x = 0usize;
            while x < width {
                // Skip the background a word at a time, then find the end of the run.
                x = T::skip_zeros(row, x);
                if x >= width {
                    break;
                }
                let v = row[x];
                let x0 = x;
                x = T::run_end(row, x);
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

    /// Component sizes by a per-pixel flood fill.
    fn naive<T: RunValue>(img: &[T], w: usize, h: usize) -> Vec<usize> {
        let mut seen = vec![false; w * h];
        let mut sizes = Vec::new();
        for s in 0..w * h {
            if seen[s] || img[s] == T::default() {
                continue;
            }
            let (mut stack, mut n) = (vec![s], 0);
            seen[s] = true;
            while let Some(i) = stack.pop() {
                n += 1;
                let (x, y) = (i % w, i / w);
                let mut nb = Vec::new();
                if x > 0 {
                    nb.push(i - 1);
                }
                if x + 1 < w {
                    nb.push(i + 1);
                }
                if y > 0 {
                    nb.push(i - w);
                }
                if y + 1 < h {
                    nb.push(i + w);
                }
                for j in nb {
                    if !seen[j] && img[j] == img[i] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            sizes.push(n);
        }
        sizes.sort_unstable();
        sizes
    }

    #[test]
    fn word_scanning_matches_flood_fill() {
        let (w, h) = (45, 23);
        let mut l = RunLabeler::default();
        for seed in 0..20u32 {
            let v = |i: usize| (((i as u32).wrapping_mul(2654435761) ^ (seed * 40503)) >> 7) % 7;
            // Blocky values so that runs are long and cross word boundaries.
            let img8: Vec<u8> = (0..w * h)
                .map(|i| {
                    let r = v((i % w) / 5 + 31 * ((i / w) / 3));
                    if r < 3 { 0 } else { (r - 2) as u8 }
                })
                .collect();
            let img16: Vec<u16> = img8.iter().map(|&b| u16::from(b) * 300).collect();
            l.label(&img8, w, h);
            let mut s8 = l.sizes.clone();
            s8.sort_unstable();
            assert_eq!(s8, naive(&img8, w, h));
            l.label(&img16, w, h);
            let mut s16 = l.sizes.clone();
            s16.sort_unstable();
            assert_eq!(s16, naive(&img16, w, h));
        }
    }

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

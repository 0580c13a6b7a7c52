//! Extension of a disparity map across its holes and the image border, so that the LoG can
//! test the pixels next to them.
//!
//! The box-LoG needs a complete support: without this, every pixel within its reach (4
//! half-resolution pixels at the default scale, 8 full-resolution pixels) of an invalid pixel or
//! of the image border fails the planarity test. A surface seen as a strip less than about 30
//! pixels wide along the image border or between occlusion bands then has no planar cells at
//! all and is never seeded (the held-out rooms of the room benchmark lost most of their missed
//! planes this way: box faces and far ceilings cut by the border or by drop-outs).
//!
//! The extension is **exact for a plane**: the disparity of a plane is affine in the pixel, and
//! each missing value within `reach` of valid data is the least-squares line through the
//! nearest valid values of its row (then of its column), evaluated at the missing pixel. So the
//! LoG of an affine map stays exactly zero up to the hole or the border, and a jump between two
//! surfaces on both sides of a hole stays a jump (each side is extended from its own side, up
//! to the middle of the hole). Only the LoG sees the extended values: the extended pixels stay
//! invalid for everything else (cells, fits, labels).

use wide::{CmpNe, f32x4};

/// Most valid values a line is fitted through.
const FIT_LEN: usize = 6;

/// Fills the NaN values of `line` that lie within `reach` of a finite value, each from the
/// least-squares line through the (up to [`FIT_LEN`]) consecutive finite values on its side of
/// the gap; a gap between two finite runs is filled from the left up to its middle and from the
/// right beyond (ties from the left). `nan` holds one bit per value (set = NaN) on entry and
/// the NaN left on return. The fits read only values that were finite on entry.
fn extend_line(line: &mut [f32], nan: &mut [u64], reach: usize) {
    let n = line.len();
    // Start of the finite run before the current gap (values before it may have been filled).
    let mut run_start = 0;
    let mut i = 0;
    while i < n {
        i = next_bit(nan, i, n, true);
        if i == n {
            break;
        }
        let a = i;
        i = next_bit(nan, i, n, false);
        let b = i;
        // A side extends the gap when its finite run has at least two values (a line; one
        // value alone would extend as a constant, which is not exact for a tilted plane).
        let left = a >= 2 && run_start + 2 <= a;
        let right = b + 1 < n && (nan[(b + 1) / 64] >> ((b + 1) % 64)) & 1 == 0;
        let mid = if left && right {
            a + (b - a).div_ceil(2)
        } else {
            b
        };
        let right_fit = right.then(|| {
            let end = next_bit(nan, b, n.min(b + FIT_LEN), true);
            line_fit(&line[b..end])
        });
        if left {
            let start = run_start.max(a.saturating_sub(FIT_LEN));
            let (slope, mean, centre) = line_fit(&line[start..a]);
            let origin = start as f32 + centre;
            let to = mid.min(a + reach);
            for (x, v) in line.iter_mut().enumerate().take(to).skip(a) {
                *v = mean + slope * (x as f32 - origin);
            }
            clear_bits(nan, a, to);
        }
        if let Some((slope, mean, centre)) = right_fit {
            let origin = b as f32 + centre;
            let from = if left { mid } else { a }.max(b.saturating_sub(reach));
            for (x, v) in line.iter_mut().enumerate().take(b).skip(from) {
                *v = mean + slope * (x as f32 - origin);
            }
            clear_bits(nan, from, b);
        }
        run_start = b;
    }
}

/// The first index in `i..end` whose bit is `set` (or `end`).
fn next_bit(bits: &[u64], mut i: usize, end: usize, set: bool) -> usize {
    while i < end {
        let word = if set { bits[i / 64] } else { !bits[i / 64] } >> (i % 64);
        if word != 0 {
            return (i + word.trailing_zeros() as usize).min(end);
        }
        i = (i / 64 + 1) * 64;
    }
    end
}

/// Clears the bits `a..b`.
fn clear_bits(bits: &mut [u64], a: usize, b: usize) {
    for i in a..b {
        bits[i / 64] &= !(1u64 << (i % 64));
    }
}

/// One bit per value of `row` (set = NaN) into `out` (`row.len().div_ceil(64)` words); returns
/// whether any is set.
fn nan_bits(row: &[f32], out: &mut [u64]) -> bool {
    let mut any = 0u64;
    for (word, chunk) in out.iter_mut().zip(row.chunks(64)) {
        let mut bits = 0u64;
        let mut groups = chunk.chunks_exact(4);
        for (k, g) in (&mut groups).enumerate() {
            let v = f32x4::from([g[0], g[1], g[2], g[3]]);
            bits |= (v.cmp_ne(v).move_mask() as u64) << (4 * k);
        }
        let done = chunk.len() - groups.remainder().len();
        for (k, v) in groups.remainder().iter().enumerate() {
            bits |= u64::from(v.is_nan()) << (done + k);
        }
        *word = bits;
        any |= bits;
    }
    any != 0
}

/// Least-squares line through `v` at positions `0..v.len()`: (slope, mean value, mean
/// position); slope 0 for a single value.
fn line_fit(v: &[f32]) -> (f32, f32, f32) {
    let n = v.len() as f32;
    let centre = (n - 1.0) / 2.0;
    let mean = v.iter().sum::<f32>() / n;
    if v.len() < 2 {
        return (0.0, mean, centre);
    }
    let (mut sxy, mut sxx) = (0.0f32, 0.0f32);
    for (k, &y) in v.iter().enumerate() {
        let dx = k as f32 - centre;
        sxy += dx * (y - mean);
        sxx += dx * dx;
    }
    (sxy / sxx, mean, centre)
}

/// Reusable buffers of [`extend_map`].
#[derive(Debug, Default, Clone)]
pub(crate) struct ExtendBuffers {
    /// Per row, one bit per pixel: NaN after the row pass.
    nan: Vec<u64>,
    /// Per row, one bit per pixel: a finite pixel within `reach` rows in its column.
    near: Vec<u64>,
    /// The column pass's scratch, one per band of rows.
    bands: Vec<ColumnBand>,
}

/// The scratch of the column pass over one band of rows.
#[derive(Debug, Default, Clone)]
struct ColumnBand {
    /// Per column: the fit of the finite run ending at a row, cached as (row, slope per row
    /// away from the run, value at the row), for runs above and below.
    above: Vec<(usize, f32, f32)>,
    below: Vec<(usize, f32, f32)>,
    /// Values of one column run being fitted.
    values: Vec<f32>,
    /// Copies of the rows just above and below the band that its fits may read.
    halo_above: Vec<f32>,
    halo_below: Vec<f32>,
}

/// Extends the map `d` (`w × h`, NaN = invalid) across its holes within `reach` pixels of valid
/// data: along the rows ([`extend_line`]), then along the columns of the result, which reaches
/// the corners and the rows above and below wide holes. The column pass follows the same rule
/// (the nearer finite run of the column, ties from above, a line through up to [`FIT_LEN`] of
/// its values); it visits only the NaN pixels with a finite pixel within `reach` in their
/// column, found with one bit per pixel, and fits each column run once.
///
/// With `parallel`, both passes run in bands of rows on the caller's pool. Every value is
/// computed from the same finite values by the same operations in any band (the column pass
/// reads only values that were finite after the row pass, which it never writes), so the map
/// is the same on any number of threads.
pub(crate) fn extend_map(
    d: &mut [f32],
    w: usize,
    h: usize,
    reach: usize,
    buf: &mut ExtendBuffers,
    parallel: bool,
) {
    use rayon::prelude::*;
    if w == 0 || h == 0 || reach == 0 || d.len() < w * h {
        return;
    }
    let d = &mut d[..w * h];
    let words = w.div_ceil(64);
    let ExtendBuffers { nan, near, bands } = buf;
    let nbands = if parallel {
        rayon::current_num_threads().min(h / 16).max(1)
    } else {
        1
    };
    let rows_per = h.div_ceil(nbands);
    // Rows: the NaN bits of each row, its gaps filled, the bits of what is left.
    nan.clear();
    nan.resize(words * h, 0);
    let row_pass = |(row, bits): (&mut [f32], &mut [u64])| -> bool {
        if nan_bits(row, bits) {
            extend_line(row, bits, reach);
            bits.iter().any(|&b| b != 0)
        } else {
            false
        }
    };
    let nan_left = if nbands > 1 {
        d.par_chunks_exact_mut(w)
            .zip(nan.par_chunks_exact_mut(words))
            .map(row_pass)
            .reduce(|| false, |a, b| a | b)
    } else {
        d.chunks_exact_mut(w)
            .zip(nan.chunks_exact_mut(words))
            .map(row_pass)
            .fold(false, |a, b| a | b)
    };
    if !nan_left {
        return;
    }
    // Finite within `reach` rows: the OR of the finite bits of the rows around.
    near.clear();
    near.resize(words * h, 0);
    let nan: &[u64] = nan;
    let near_row = |(y, out): (usize, &mut [u64])| {
        let (lo, hi) = (y.saturating_sub(reach), (y + reach).min(h - 1));
        for (c, o) in out.iter_mut().enumerate() {
            let valid_bits = if c + 1 == words && !w.is_multiple_of(64) {
                (1u64 << (w % 64)) - 1
            } else {
                u64::MAX
            };
            let mut acc = 0u64;
            for yy in lo..=hi {
                acc |= !nan[yy * words + c];
            }
            *o = acc & valid_bits;
        }
    };
    if nbands > 1 {
        near.par_chunks_exact_mut(words)
            .enumerate()
            .for_each(near_row);
    } else {
        near.chunks_exact_mut(words).enumerate().for_each(near_row);
    }
    // Columns, band by band: a band's fits read at most `reach + FIT_LEN` rows beyond it.
    if bands.len() < nbands {
        bands.resize_with(nbands, ColumnBand::default);
    }
    let halo = reach + FIT_LEN;
    for (b, band) in bands[..nbands].iter_mut().enumerate() {
        let (y0, y1) = ((b * rows_per).min(h), ((b + 1) * rows_per).min(h));
        band.halo_above.clear();
        band.halo_below.clear();
        if nbands > 1 {
            band.halo_above
                .extend_from_slice(&d[y0.saturating_sub(halo) * w..y0 * w]);
            band.halo_below
                .extend_from_slice(&d[y1 * w..(y1 + halo).min(h) * w]);
        }
    }
    let near: &[u64] = near;
    let column_pass = |(b, (rows, band)): (usize, (&mut [f32], &mut ColumnBand))| {
        let y0 = b * rows_per;
        band.fill(rows, y0, w, h, reach, nan, near);
    };
    if nbands > 1 {
        d.par_chunks_mut(rows_per * w)
            .zip(bands[..nbands].par_iter_mut())
            .enumerate()
            .for_each(column_pass);
    } else {
        column_pass((0, (d, &mut bands[0])));
    }
}

impl ColumnBand {
    /// The column pass over the rows `y0..` of the map held in `rows` (the band), reading the
    /// rows beyond it from the halos.
    #[allow(clippy::too_many_arguments)]
    fn fill(
        &mut self,
        rows: &mut [f32],
        y0: usize,
        w: usize,
        h: usize,
        reach: usize,
        nan: &[u64],
        near: &[u64],
    ) {
        let words = w.div_ceil(64);
        let y1 = y0 + rows.len() / w;
        let above_start = y0 - self.halo_above.len() / w;
        let ColumnBand {
            above,
            below,
            values,
            halo_above,
            halo_below,
        } = self;
        // The value of pixel (x, r) of the map, `r` within the band or its halos.
        let at = |rows: &[f32], x: usize, r: usize| -> f32 {
            if r < y0 {
                halo_above[(r - above_start) * w + x]
            } else if r >= y1 {
                halo_below[(r - y1) * w + x]
            } else {
                rows[(r - y0) * w + x]
            }
        };
        let is_nan =
            |nan: &[u64], x: usize, y: usize| (nan[y * words + x / 64] >> (x % 64)) & 1 == 1;
        above.clear();
        above.resize(w, (usize::MAX, 0.0, 0.0));
        below.clear();
        below.resize(w, (usize::MAX, 0.0, 0.0));
        for y in y0..y1 {
            for c in 0..words {
                let mut todo = nan[y * words + c] & near[y * words + c];
                while todo != 0 {
                    let x = c * 64 + todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    // The nearest finite rows above and below within reach whose run in the
                    // column has at least two values (see `extend_line`).
                    let up = (1..=reach.min(y))
                        .find(|&t| !is_nan(nan, x, y - t))
                        .filter(|&t| y - t >= 1 && !is_nan(nan, x, y - t - 1));
                    let dn = (1..=reach.min(h - 1 - y))
                        .find(|&t| !is_nan(nan, x, y + t))
                        .filter(|&t| y + t + 1 < h && !is_nan(nan, x, y + t + 1));
                    let (t, from_above) = match (up, dn) {
                        (Some(u), Some(v)) if u <= v => (u, true),
                        (Some(u), None) => (u, true),
                        (_, Some(v)) => (v, false),
                        (None, None) => continue,
                    };
                    let (edge, cache) = if from_above {
                        (y - t, &mut above[x])
                    } else {
                        (y + t, &mut below[x])
                    };
                    if cache.0 != edge {
                        // The run's values from its far end to `edge`.
                        let mut len = 1;
                        while len < FIT_LEN {
                            let next = if from_above {
                                edge.checked_sub(len)
                            } else {
                                Some(edge + len).filter(|&r| r < h)
                            };
                            match next {
                                Some(r) if !is_nan(nan, x, r) => len += 1,
                                _ => break,
                            }
                        }
                        values.clear();
                        values.extend((0..len).rev().map(|k| {
                            let r = if from_above { edge - k } else { edge + k };
                            at(rows, x, r)
                        }));
                        let (slope, mean, centre) = line_fit(values);
                        // Value at `edge` (position len − 1 = 2·centre) and slope away from
                        // the run.
                        *cache = (edge, slope, mean + slope * centre);
                    }
                    let (_, slope, at_edge) = *cache;
                    rows[(y - y0) * w + x] = at_edge + slope * t as f32;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_is_extended_exactly_within_reach() {
        let (w, h) = (40, 30);
        let plane = |x: usize, y: usize| 20.0 + 0.125 * x as f32 - 0.0625 * y as f32;
        let mut d = vec![f32::NAN; w * h];
        // A valid block with a hole inside, NaN around it (an image border of 6 px).
        for y in 6..h - 6 {
            for x in 6..w - 6 {
                let hole = (15..20).contains(&x) && (12..14).contains(&y);
                d[y * w + x] = if hole { f32::NAN } else { plane(x, y) };
            }
        }
        extend_map(&mut d, w, h, 4, &mut ExtendBuffers::default(), false);
        for y in 0..h {
            for x in 0..w {
                let v = d[y * w + x];
                let near = (2..w - 2).contains(&x) && (2..h - 2).contains(&y);
                if near {
                    assert!((v - plane(x, y)).abs() < 1e-4, "({x}, {y}): {v}");
                } else {
                    assert!(v.is_nan(), "({x}, {y}) beyond reach: {v}");
                }
            }
        }
    }

    /// In bands of rows on pools of 1 to 5 threads, the map is the one-band map, bit for bit.
    #[test]
    fn banded_extension_matches_one_band() {
        let (w, h) = (47, 90);
        let d0: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                // Holes of every width and height, wide bands of NaN, tilted data.
                let hole = (x % 13 < 3 && y % 11 < 6) || (20..32).contains(&y) && x > 30 || y < 3;
                if hole || (i * 7919) % 61 == 0 {
                    f32::NAN
                } else {
                    10.0 + 0.07 * x as f32 - 0.11 * y as f32 + ((i * 104_729) % 7) as f32 * 0.01
                }
            })
            .collect();
        let mut want = d0.clone();
        extend_map(&mut want, w, h, 4, &mut ExtendBuffers::default(), false);
        assert!(
            want.iter().filter(|v| v.is_nan()).count() < d0.iter().filter(|v| v.is_nan()).count()
        );
        for threads in 1..=5 {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool");
            let mut got = d0.clone();
            let mut buf = ExtendBuffers::default();
            pool.install(|| extend_map(&mut got, w, h, 4, &mut buf, true));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&got), bits(&want), "{threads} threads");
        }
    }

    /// [`extend_line`] with the NaN bits computed here; checks the bits left.
    fn extend(line: &mut [f32], reach: usize) {
        let mut bits = vec![0u64; line.len().div_ceil(64)];
        nan_bits(line, &mut bits);
        extend_line(line, &mut bits, reach);
        for (i, v) in line.iter().enumerate() {
            assert_eq!(v.is_nan(), (bits[i / 64] >> (i % 64)) & 1 == 1, "bit {i}");
        }
    }

    #[test]
    fn each_side_of_a_gap_is_extended_from_its_own_side() {
        let mut line = vec![
            10.0,
            10.0,
            10.0,
            f32::NAN,
            f32::NAN,
            f32::NAN,
            f32::NAN,
            30.0,
            30.0,
        ];
        extend(&mut line, 8);
        assert_eq!(
            line,
            vec![10.0, 10.0, 10.0, 10.0, 10.0, 30.0, 30.0, 30.0, 30.0]
        );
        // All invalid, or nothing to fill: unchanged.
        let mut none = vec![f32::NAN; 5];
        extend(&mut none, 3);
        assert!(none.iter().all(|v| v.is_nan()));
        // One value alone is no line: nothing is extended from it.
        let mut one = vec![f32::NAN, 7.0, f32::NAN];
        extend(&mut one, 3);
        assert!(one[0].is_nan() && one[2].is_nan() && one[1] == 7.0);
        let mut two = vec![f32::NAN, 7.0, 8.0, f32::NAN];
        extend(&mut two, 3);
        assert_eq!(two, vec![6.0, 7.0, 8.0, 9.0]);
        // Longer than a word, gaps across word boundaries, a reach shorter than the gaps.
        let mut long: Vec<f32> = (0..200)
            .map(|i| {
                if (60..75).contains(&i) || (120..130).contains(&i) || i >= 190 {
                    f32::NAN
                } else {
                    0.5 * i as f32
                }
            })
            .collect();
        extend(&mut long, 4);
        for (i, v) in long.iter().enumerate() {
            let filled = (60..64).contains(&i)
                || (71..75).contains(&i)
                || (120..124).contains(&i)
                || (126..130).contains(&i)
                || (190..194).contains(&i);
            let gap = (60..75).contains(&i) || (120..130).contains(&i) || i >= 190;
            if !gap || filled {
                assert!((v - 0.5 * i as f32).abs() < 1e-3, "{i}: {v}");
            } else {
                assert!(v.is_nan(), "{i}: {v}");
            }
        }
    }

    proptest::proptest! {
        /// Any hole pattern on a plane: every value the extension writes lies on the plane
        /// (it is exact for affine maps), finite values are untouched, and every NaN within
        /// `reach` of a finite value along its row is filled.
        #[test]
        fn extension_of_a_plane_stays_on_the_plane(
            w in 3usize..90,
            h in 3usize..40,
            holes in proptest::collection::vec(proptest::bool::weighted(0.35), 3600),
            a in -0.2f32..0.2,
            b in -0.2f32..0.2,
            reach in 1usize..6,
        ) {
            let plane = |x: usize, y: usize| 30.0 + a * x as f32 + b * y as f32;
            let orig: Vec<f32> = (0..w * h)
                .map(|i| if holes[i] { f32::NAN } else { plane(i % w, i / w) })
                .collect();
            let mut d = orig.clone();
            extend_map(&mut d, w, h, reach, &mut ExtendBuffers::default(), false);
            for y in 0..h {
                for x in 0..w {
                    let (o, v) = (orig[y * w + x], d[y * w + x]);
                    if !o.is_nan() {
                        proptest::prop_assert_eq!(o.to_bits(), v.to_bits());
                    } else if !v.is_nan() {
                        proptest::prop_assert!((v - plane(x, y)).abs() < 1e-3, "({}, {}): {}", x, y, v);
                    }
                    // Two finite neighbours on one side within reach along the row: filled.
                    let pair = |xx: usize, yy: usize| {
                        xx + 1 < w && !orig[yy * w + xx].is_nan() && !orig[yy * w + xx + 1].is_nan()
                    };
                    let right_pair = (x + 1..(x + reach + 1).min(w)).find(|&xx| !orig[y * w + xx].is_nan())
                        .is_some_and(|xx| pair(xx, y));
                    if o.is_nan() && right_pair {
                        proptest::prop_assert!(!v.is_nan(), "({}, {}) left NaN", x, y);
                    }
                }
            }
        }
    }
}

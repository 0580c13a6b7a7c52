//! Row helpers of the label image: whether a chunk holds a label, run ends, relabelling
//! through a lookup table, the planes present in a 3-row neighbourhood, bit masks and bounding
//! boxes.

use super::*;

/// Whether `chunk` holds `label` (one branch-free pass, for skipping the chunks of a row
/// without it).
#[inline]
pub(super) fn holds_label(chunk: &[u16], label: u16) -> bool {
    chunk.iter().fold(false, |f, &l| f | (l == label))
}

/// End of the run of values equal to `row[i]` that starts at `i` (4 values per step).
#[inline]
pub(super) fn run_end(row: &[u16], i: usize) -> usize {
    let v = row[i];
    let vv = u64::from(v) * 0x0001_0001_0001_0001;
    let rest = &row[i..];
    let mut words = rest.chunks_exact(4);
    let mut base = i;
    for q in &mut words {
        let w = u64::from(q[0])
            | (u64::from(q[1]) << 16)
            | (u64::from(q[2]) << 32)
            | (u64::from(q[3]) << 48);
        let x = w ^ vv;
        if x != 0 {
            return base + (x.trailing_zeros() / 16) as usize;
        }
        base += 4;
    }
    words
        .remainder()
        .iter()
        .position(|&l| l != v)
        .map_or(row.len(), |n| base + n)
}

/// Replaces every label `l` by `lut[l]` (0 beyond the table), 8 labels (16 bytes) at a time:
/// a chunk equal to the previous one reuses its result (runs inside a plane), a chunk of one
/// label takes one lookup, and only the mixed chunks (plane borders, holes) look up every
/// label.
pub(super) fn relabel(labels: &mut [u16], lut: &[u16]) {
    // A chunk's 8 labels are one `u128` (native byte order: each 16-bit lane is one label);
    // `ONES` spreads one label over all lanes.
    const ONES: u128 = 0x0001_0001_0001_0001_0001_0001_0001_0001;
    let look = |l: u16| lut.get(l as usize).copied().unwrap_or(0);
    let map = |v: u128| -> u128 {
        if v == v.rotate_left(16) {
            u128::from(look(v as u16)) * ONES
        } else {
            (0..LANES).fold(0, |m, i| {
                m | (u128::from(look((v >> (16 * i)) as u16)) << (16 * i))
            })
        }
    };
    let (mut prev_in, mut prev_out) = (0u128, map(0));
    let bytes: &mut [u8] = bytemuck::cast_slice_mut(labels);
    let mut ch = bytes.chunks_exact_mut(2 * LANES);
    for c in &mut ch {
        let Ok(c16) = <&mut [u8; 2 * LANES]>::try_from(c) else {
            continue;
        };
        let v = u128::from_ne_bytes(*c16);
        if v != prev_in {
            prev_in = v;
            prev_out = map(v);
        }
        *c16 = prev_out.to_ne_bytes();
    }
    for l in ch.into_remainder().chunks_exact_mut(2) {
        let v = look(u16::from_ne_bytes([l[0], l[1]]));
        l.copy_from_slice(&v.to_ne_bytes());
    }
}

/// Bit `l − 1` of label `l` for labels 1..=64 (0 for 0 and larger labels).
static LABEL_BIT: [u64; 128] = {
    let mut t = [0u64; 128];
    let mut l = 1;
    while l <= 64 {
        t[l] = 1 << (l - 1);
        l += 1;
    }
    t
};

/// The distinct planes (label − 1) of the cells `i0..i1` of `rows` (rows may be shorter or
/// empty) into `out` (at most 16); returns their number.
#[inline(always)]
pub(super) fn neighbour_planes(
    rows: [&[u16]; 3],
    i0: usize,
    i1: usize,
    out: &mut [u16; 16],
) -> usize {
    // Labels up to 64 as bits, larger ones one by one.
    let mut bits = 0u64;
    let mut big = 0u16;
    for r in rows {
        for &l in r.get(i0.min(r.len())..i1.min(r.len())).unwrap_or(&[]) {
            bits |= LABEL_BIT.get(l as usize).copied().unwrap_or(0);
            big = big.max(l);
        }
    }
    let mut n = 0;
    while bits != 0 && n < out.len() {
        out[n] = bits.trailing_zeros() as u16;
        bits &= bits - 1;
        n += 1;
    }
    if big > 64 {
        for r in rows {
            for &l in r.get(i0.min(r.len())..i1.min(r.len())).unwrap_or(&[]) {
                if l > 64 && n < out.len() && !out[..n].contains(&(l - 1)) {
                    out[n] = l - 1;
                    n += 1;
                }
            }
        }
    }
    n
}

/// The candidate planes (label − 1) of the cells `a..b` of three cell-label rows (above, this
/// row, below; a row may be shorter or empty) into `out` (at most 16); returns their number.
/// The one neighbour-candidate search of the coarse and the final pass: with at most 64 planes
/// (`small`) the labels are OR-ed as bits, otherwise collected one by one.
#[inline(always)]
pub(super) fn candidate_planes_around(
    rows: [&[u16]; 3],
    a: usize,
    b: usize,
    small: bool,
    out: &mut [u16; 16],
) -> usize {
    if small {
        let bits = or_bits(rows[0], a, b) | or_bits(rows[1], a, b) | or_bits(rows[2], a, b);
        bits_to_planes(bits, out)
    } else {
        neighbour_planes(rows, a, b, out)
    }
}

/// The bits `l − 1` of the labels `l` of `row[a..b]` (labels ≤ 64; an empty or short row
/// contributes its part of the range).
#[inline(always)]
pub(super) fn or_bits(row: &[u16], a: usize, b: usize) -> u64 {
    // Callers have at most 64 planes: labels ≤ 64 < 128.
    row.get(a..b.min(row.len()))
        .unwrap_or(&[])
        .iter()
        .fold(0u64, |m, &l| m | LABEL_BIT[(l & 127) as usize])
}

/// The planes (label − 1) of a bit mask into `out` (at most 16); returns their number.
#[inline(always)]
pub(super) fn bits_to_planes(mut bits: u64, out: &mut [u16; 16]) -> usize {
    let mut n = 0;
    while bits != 0 && n < out.len() {
        out[n] = bits.trailing_zeros() as u16;
        bits &= bits - 1;
        n += 1;
    }
    n
}

/// `s` padded to 8 elements with `fill`.
#[inline]
pub(super) fn pad<T: Copy>(s: &[T], fill: T) -> [T; LANES] {
    let mut a = [fill; LANES];
    let n = s.len().min(LANES);
    a[..n].copy_from_slice(&s[..n]);
    a
}

/// Bit mask of the non-zero bytes of a word whose bytes are 0 or 1.
#[inline(always)]
pub(super) fn byte_mask(v: u64) -> u32 {
    (v.wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

/// Up to 8 bytes (0 or 1) as a little-endian word, zero-padded.
#[inline(always)]
pub(super) fn pad_word(s: &[u8]) -> u64 {
    u64::from_le_bytes(<[u8; LANES]>::try_from(s).unwrap_or_else(|_| pad(s, 0)))
}

/// Bit mask of the non-zero values among up to 8 labels.
#[inline(always)]
pub(super) fn nonzero_mask(s: &[u16]) -> u32 {
    let a = <[u16; LANES]>::try_from(s).unwrap_or_else(|_| pad(s, 0));
    let v = i16x8::from(a.map(|l| l as i16));
    (v.cmp_eq(i16x8::ZERO).move_mask() as u32 ^ 0xff) & 0xff
}

/// Keep bytes of 8 cells or pixels that all passed.
pub(super) const ALL_KEPT: u64 = 0x0101_0101_0101_0101;

/// `need[i]` = 1 for the unlabelled cells of `row` with a labelled 4-neighbour, else 0
/// (`up` and `dn` have the length of `row`).
pub(super) fn touching(row: &[u16], up: &[u16], dn: &[u16], need: &mut [u8]) {
    for ((o, &u), &d) in need.iter_mut().zip(up).zip(dn) {
        *o = u8::from((u | d) != 0);
    }
    if row.len() > 1 {
        for (o, &l) in need[1..].iter_mut().zip(row) {
            *o |= u8::from(l != 0);
        }
        for (o, &r) in need.iter_mut().zip(&row[1..]) {
            *o |= u8::from(r != 0);
        }
    }
    for (o, &c) in need.iter_mut().zip(row) {
        *o &= u8::from(c == 0);
    }
}

/// `out[i] = 1` for the labelled cells of `row` with a cell of another plane among their 8
/// neighbours (`up` and `dn` the rows above and below, empty or short at the grid's edges):
/// the cells at a border between two planes.
pub(super) fn plane_borders(row: &[u16], up: &[u16], dn: &[u16], out: &mut [u8]) {
    let n = row.len().min(out.len());
    if n >= 3 && up.len() >= n && dn.len() >= n {
        // Inside the grid (both neighbour rows present): one fused pass over the interior
        // cells, then the two end cells by the general rule.
        borders_interior(row, up, dn, &mut out[..n]);
        // The end cells: their two columns of neighbours.
        let end = |k: usize, nb: usize| {
            let v = row[k];
            let other = |x: u16| (x != 0) & (x != v);
            let any = other(up[k]) | other(up[nb]) | other(row[nb]) | other(dn[k]) | other(dn[nb]);
            u8::from(any & (v != 0))
        };
        out[0] = end(0, 1);
        out[n - 1] = end(n - 1, n - 2);
        return;
    }
    plane_borders_general(row, up, dn, out);
}

/// [`plane_borders`] for cells `1..n − 1` of `out` (`n = out.len()`; `row`, `up`, `dn` at
/// least as long): a cell is a border when it is labelled and one of its 8 neighbours carries
/// another label. One pass with the nine labels side by side (the coarse and final passes
/// call this for every cell row, ~500 times a frame; the general form makes seven passes).
#[allow(clippy::needless_range_loop)]
#[inline]
fn borders_interior(row: &[u16], up: &[u16], dn: &[u16], out: &mut [u8]) {
    let n = out.len();
    let m = n - 2;
    // Slices cut to the common length, so the loop has no bounds checks and vectorises.
    let (ul, uc, ur) = (&up[..m], &up[1..m + 1], &up[2..m + 2]);
    let (l, c, r) = (&row[..m], &row[1..m + 1], &row[2..m + 2]);
    let (dl, dc, dr) = (&dn[..m], &dn[1..m + 1], &dn[2..m + 2]);
    let o = &mut out[1..m + 1];
    for i in 0..m {
        let v = c[i];
        let other = |x: u16| (x != 0) & (x != v);
        let any = other(ul[i])
            | other(uc[i])
            | other(ur[i])
            | other(l[i])
            | other(r[i])
            | other(dl[i])
            | other(dc[i])
            | other(dr[i]);
        o[i] = u8::from(any & (v != 0));
    }
}

/// [`plane_borders`] for rows of any length (missing or short neighbour rows at the grid's
/// edges).
fn plane_borders_general(row: &[u16], up: &[u16], dn: &[u16], out: &mut [u8]) {
    let n = row.len().min(out.len());
    let (row, out) = (&row[..n], &mut out[..n]);
    out.fill(0);
    // `out[i] |= nb[i]` is another plane than `row[i]`, for a neighbour row shifted by −1, 0, +1
    // (a vectorisable loop each).
    fn mark(out: &mut [u8], row: &[u16], nb: &[u16]) {
        for ((o, &l), &m) in out.iter_mut().zip(row).zip(nb) {
            *o |= u8::from((m != 0) & (m != l));
        }
    }
    for (nb, centre) in [(up, true), (row, false), (dn, true)] {
        let m = nb.len().min(n);
        if m == 0 {
            continue;
        }
        if centre {
            mark(&mut out[..m], &row[..m], &nb[..m]);
        }
        // The neighbour to the left (`nb[i − 1]`) and to the right (`nb[i + 1]`).
        mark(&mut out[1..], &row[1..], &nb[..m.min(n - 1)]);
        if m > 1 {
            mark(out, row, &nb[1..m]);
        }
    }
    for (o, &l) in out.iter_mut().zip(row) {
        *o &= u8::from(l != 0);
    }
}

/// An empty support box.
pub(super) const EMPTY_BOX: [u32; 4] = [u32::MAX, u32::MAX, 0, 0];

pub(super) fn grow(bb: &mut [u32; 4], x0: usize, x1: usize, y: usize) {
    bb[0] = bb[0].min(x0 as u32);
    bb[1] = bb[1].min(y as u32);
    bb[2] = bb[2].max(x1 as u32);
    bb[3] = bb[3].max(y as u32);
}

pub(super) fn union_box(a: &[u32; 4], b: &[u32; 4]) -> [u32; 4] {
    [
        a[0].min(b[0]),
        a[1].min(b[1]),
        a[2].max(b[2]),
        a[3].max(b[3]),
    ]
}

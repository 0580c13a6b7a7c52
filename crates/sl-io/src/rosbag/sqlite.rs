//! A read-only reader of SQLite database files, as much of the file format
//! (<https://www.sqlite.org/fileformat2.html>) as a ROS 2 bag needs: the 100-byte file header,
//! table B-trees walked in rowid order, cells whose payload overflows into a chain of pages, and
//! records (varint serial types and their values). No SQL is run; indexes, the freelist and
//! the journal are not read.
//!
//! Written by hand: `rusqlite` would compile SQLite's C source into every build to read two
//! tables' rows, and SQLite sizes its own buffers. Here every page number is checked against
//! the file, a walk visits at most as many pages as the file has (so a cycle of pages ends in
//! an error), and a payload is read only after its size has been checked against the caller's
//! budget.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{IoError, Result};

/// The first 16 bytes of every SQLite 3 database file.
pub(super) const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The deepest table B-tree walked (a billion rows on 512-byte pages need far fewer levels).
const MAX_DEPTH: usize = 40;

/// Page kinds (the first byte of a B-tree page's header).
const INTERIOR_TABLE: u8 = 0x05;
const LEAF_TABLE: u8 = 0x0d;

/// An open database file: its page geometry.
#[derive(Debug, Clone, Copy)]
pub(super) struct Sqlite {
    page_size: usize,
    /// The usable bytes of a page (the page size less the reserved bytes at its end).
    usable: usize,
    /// Pages in the file.
    pages: u32,
}

/// Where one row of a table lies, and its rowid and payload size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct RowPlace {
    pub(super) rowid: i64,
    /// The leaf page holding its cell, and the cell's offset in that page.
    pub(super) page: u32,
    pub(super) offset: u16,
    /// The record's size in bytes.
    pub(super) payload: u64,
}

/// A column value of a record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Value<'a> {
    Null,
    Int(i64),
    Float(f64),
    Text(&'a [u8]),
    Blob(&'a [u8]),
}

/// A leaf cell of a table B-tree, parsed.
struct LeafCell {
    payload: u64,
    rowid: i64,
    /// Where its local part starts in the page, and how long it is.
    local_at: usize,
    local: usize,
    /// The first overflow page (0: none).
    overflow: u32,
}

fn bad(path: &Path, m: impl Into<String>) -> IoError {
    IoError::malformed(path, m)
}

fn be16(b: &[u8], at: usize) -> Option<usize> {
    Some(usize::from(u16::from_be_bytes(
        b.get(at..at + 2)?.try_into().ok()?,
    )))
}

fn be32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_be_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

/// The varint at `at` (1–9 bytes, big-endian groups of 7 bits, the ninth byte whole) and its
/// length.
pub(super) fn varint(b: &[u8], at: usize) -> Option<(u64, usize)> {
    let mut v = 0u64;
    for i in 0..9 {
        let c = *b.get(at + i)?;
        if i == 8 {
            return Some(((v << 8) | u64::from(c), 9));
        }
        v = (v << 7) | u64::from(c & 0x7f);
        if c & 0x80 == 0 {
            return Some((v, i + 1));
        }
    }
    None
}

impl Sqlite {
    /// Reads the file header.
    ///
    /// # Errors
    /// Not an SQLite 3 file, a page size the format does not allow, a text encoding other than
    /// UTF-8, or a file whose newest writes lie in a `-wal` file beside it.
    pub(super) fn open<R: Read + Seek>(path: &Path, r: &mut R, file_len: u64) -> Result<Self> {
        let mut h = [0u8; 100];
        r.seek(SeekFrom::Start(0))
            .map_err(|e| IoError::io(path, e))?;
        r.read_exact(&mut h)
            .map_err(|_| bad(path, "an SQLite file shorter than its 100-byte header"))?;
        if &h[..16] != MAGIC {
            return Err(bad(path, "not an SQLite 3 database"));
        }
        let page_size = match be16(&h, 16).unwrap_or(0) {
            1 => 65_536,
            n => n,
        };
        if !(512..=65_536).contains(&page_size) || !page_size.is_power_of_two() {
            return Err(bad(
                path,
                format!("an SQLite page size of {page_size} bytes"),
            ));
        }
        let usable = page_size - usize::from(h[20]);
        if usable < 480 {
            return Err(bad(
                path,
                format!("SQLite pages of {usable} usable bytes (at least 480)"),
            ));
        }
        let encoding = be32(&h, 56).unwrap_or(0);
        if encoding > 1 {
            return Err(bad(
                path,
                format!("an SQLite database in UTF-16 (text encoding {encoding}); bags use UTF-8"),
            ));
        }
        if h[18] == 2 {
            let mut wal = path.as_os_str().to_owned();
            wal.push("-wal");
            if std::fs::metadata(&wal).is_ok_and(|m| m.len() > 0) {
                return Err(bad(
                    path,
                    "its newest writes are still in its -wal file (a recording that was not \
                     closed): `sqlite3 FILE 'PRAGMA wal_checkpoint'` moves them into the file",
                ));
            }
        }
        let in_file = file_len / page_size as u64;
        let pages = u32::try_from(in_file).unwrap_or(u32::MAX);
        Ok(Self {
            page_size,
            usable,
            pages,
        })
    }

    /// Reads page `no` (1-based) into `buf`.
    fn read_page<R: Read + Seek>(
        &self,
        path: &Path,
        r: &mut R,
        no: u32,
        buf: &mut Vec<u8>,
    ) -> Result<()> {
        if no == 0 || no > self.pages {
            return Err(bad(
                path,
                format!(
                    "a reference to SQLite page {no}; the file has {} pages",
                    self.pages
                ),
            ));
        }
        buf.resize(self.page_size, 0);
        r.seek(SeekFrom::Start(u64::from(no - 1) * self.page_size as u64))
            .map_err(|e| IoError::io(path, e))?;
        r.read_exact(buf).map_err(|e| IoError::io(path, e))
    }

    /// Where the B-tree header of page `no` starts (page 1 holds the file header first).
    fn header_at(no: u32) -> usize {
        if no == 1 { 100 } else { 0 }
    }

    /// The local size of a table leaf cell's payload of `p` bytes (the format's rule: all of it
    /// up to `U − 35`, else `M + (P − M) mod (U − 4)` when that fits, else `M`).
    fn local_size(&self, p: u64) -> usize {
        let u = self.usable as u64;
        let x = u - 35;
        if p <= x {
            return p as usize;
        }
        let m = (u - 12) * 32 / 255 - 23;
        let k = m + (p - m) % (u - 4);
        (if k <= x { k } else { m }) as usize
    }

    /// The leaf cell at `offset` of a table leaf page.
    fn leaf_cell(&self, path: &Path, page: &[u8], no: u32, offset: usize) -> Result<LeafCell> {
        let cut = || {
            bad(
                path,
                format!("a cell of SQLite page {no} runs past its page"),
            )
        };
        let (payload, n1) = varint(page, offset).ok_or_else(cut)?;
        let (rowid, n2) = varint(page, offset + n1).ok_or_else(cut)?;
        let local = self.local_size(payload);
        let local_at = offset + n1 + n2;
        let end = local_at + local;
        let overflow = if (local as u64) < payload {
            be32(&page[..self.usable], end).ok_or_else(cut)?
        } else {
            0
        };
        if end > self.usable {
            return Err(cut());
        }
        Ok(LeafCell {
            payload,
            rowid: rowid as i64,
            local_at,
            local,
            overflow,
        })
    }

    /// Calls `row` for every row of the table whose B-tree has its root at page `root`, in rowid
    /// order, with its place and the local part of its payload (the whole record when it does
    /// not overflow). At most `max_rows` rows.
    ///
    /// # Errors
    /// A page that is not part of a table B-tree, a tree deeper than [`MAX_DEPTH`] or visiting
    /// more pages than the file has (a cycle), more rows than `max_rows`, or an error of `row`.
    pub(super) fn scan<R: Read + Seek>(
        &self,
        path: &Path,
        r: &mut R,
        root: u32,
        max_rows: usize,
        row: &mut dyn FnMut(RowPlace, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let mut walk = Walk {
            db: self,
            path,
            visited: 0,
            rows: 0,
            max_rows,
        };
        walk.page(r, root, 0, row)
    }

    /// The first `want` bytes (at most its size) of the payload of the row whose cell lies at
    /// `offset` of leaf page `page`, reading its overflow pages as needed; more than `budget`
    /// bytes is an error, found before anything is allocated.
    pub(super) fn payload<R: Read + Seek>(
        &self,
        path: &Path,
        r: &mut R,
        (page_no, offset): (u32, u16),
        want: u64,
        budget: u64,
    ) -> Result<Vec<u8>> {
        let mut page = Vec::new();
        self.read_page(path, r, page_no, &mut page)?;
        if page[Self::header_at(page_no)] != LEAF_TABLE {
            return Err(bad(
                path,
                format!("SQLite page {page_no} is not a table leaf"),
            ));
        }
        let cell = self.leaf_cell(path, &page, page_no, usize::from(offset))?;
        if want.min(cell.payload) > budget {
            return Err(IoError::too_large(
                path,
                format!(
                    "a row of {} bytes is beyond the {budget}-byte budget of one decoded buffer \
                     (raise --max-memory)",
                    cell.payload
                ),
            ));
        }
        let want = want.min(cell.payload);
        let mut out = Vec::with_capacity(usize::try_from(want).unwrap_or(0));
        let local = cell.local.min(want as usize);
        out.extend_from_slice(&page[cell.local_at..cell.local_at + local]);
        let mut next = cell.overflow;
        while (out.len() as u64) < want {
            if next == 0 {
                return Err(bad(
                    path,
                    format!(
                        "the overflow chain of row {} ends after {} of its {} bytes",
                        cell.rowid,
                        out.len(),
                        cell.payload
                    ),
                ));
            }
            self.read_page(path, r, next, &mut page)?;
            next = be32(&page, 0).unwrap_or(0);
            let take = (self.usable - 4).min((want - out.len() as u64) as usize);
            out.extend_from_slice(&page[4..4 + take]);
        }
        Ok(out)
    }
}

/// One walk of a table B-tree.
struct Walk<'a> {
    db: &'a Sqlite,
    path: &'a Path,
    visited: u32,
    rows: usize,
    max_rows: usize,
}

impl Walk<'_> {
    fn page<R: Read + Seek>(
        &mut self,
        r: &mut R,
        no: u32,
        depth: usize,
        row: &mut dyn FnMut(RowPlace, &[u8]) -> Result<()>,
    ) -> Result<()> {
        let path = self.path;
        self.visited += 1;
        if depth > MAX_DEPTH || self.visited > self.db.pages {
            return Err(bad(
                path,
                "a table B-tree that visits a page twice or is deeper than any real one",
            ));
        }
        let mut page = Vec::new();
        self.db.read_page(path, r, no, &mut page)?;
        let h = Sqlite::header_at(no);
        let kind = page[h];
        let cells = be16(&page, h + 3).unwrap_or(0);
        let ptrs = h + if kind == INTERIOR_TABLE { 12 } else { 8 };
        if ptrs + 2 * cells > self.db.usable {
            return Err(bad(
                path,
                format!("SQLite page {no} lists {cells} cells, more than fit"),
            ));
        }
        let cell_at = |i: usize| be16(&page, ptrs + 2 * i).unwrap_or(0);
        match kind {
            LEAF_TABLE => {
                for i in 0..cells {
                    let c = self.db.leaf_cell(path, &page, no, cell_at(i))?;
                    self.rows += 1;
                    if self.rows > self.max_rows {
                        return Err(IoError::too_large(
                            path,
                            format!(
                                "a table of more than {} rows, the limit (raise --max-memory)",
                                self.max_rows
                            ),
                        ));
                    }
                    let place = RowPlace {
                        rowid: c.rowid,
                        page: no,
                        offset: cell_at(i) as u16,
                        payload: c.payload,
                    };
                    row(place, &page[c.local_at..c.local_at + c.local])?;
                }
                Ok(())
            }
            INTERIOR_TABLE => {
                for i in 0..cells {
                    let child = be32(&page, cell_at(i)).ok_or_else(|| {
                        bad(
                            path,
                            format!("a cell of SQLite page {no} runs past its page"),
                        )
                    })?;
                    self.page(r, child, depth + 1, row)?;
                }
                let right = be32(&page, h + 8).unwrap_or(0);
                self.page(r, right, depth + 1, row)
            }
            other => Err(bad(
                path,
                format!("SQLite page {no} (kind {other:#04x}) is not part of a table B-tree"),
            )),
        }
    }
}

/// A record: its columns' serial types and where its body starts.
#[derive(Debug)]
pub(super) struct Record<'a> {
    bytes: &'a [u8],
    types: Vec<u64>,
    body_at: usize,
}

impl<'a> Record<'a> {
    /// Parses the record header of `bytes` (a whole record, or a prefix holding its header).
    pub(super) fn parse(path: &Path, bytes: &'a [u8]) -> Result<Self> {
        let cut = || bad(path, "an SQLite record header runs past its record");
        let (header_len, mut at) = varint(bytes, 0).ok_or_else(cut)?;
        let header_len = usize::try_from(header_len).map_err(|_| cut())?;
        if header_len > bytes.len() || header_len < at {
            return Err(cut());
        }
        let mut types = Vec::new();
        while at < header_len {
            let (t, n) = varint(&bytes[..header_len], at).ok_or_else(cut)?;
            types.push(t);
            at += n;
        }
        Ok(Self {
            bytes,
            types,
            body_at: header_len,
        })
    }

    /// The byte range of column `i` in the record (its serial type's size).
    pub(super) fn range(&self, i: usize) -> Option<std::ops::Range<u64>> {
        let mut at = self.body_at as u64;
        for (j, &t) in self.types.iter().enumerate() {
            let n = serial_size(t)?;
            if j == i {
                return Some(at..at + n);
            }
            at += n;
        }
        None
    }

    /// Column `i` (`None` when the record has fewer columns or its bytes are not in `bytes`;
    /// a column past the record's end reads as NULL, as SQLite reads a row written before a
    /// column was added).
    pub(super) fn value(&self, i: usize) -> Option<Value<'a>> {
        let Some(&t) = self.types.get(i) else {
            return Some(Value::Null);
        };
        let range = self.range(i)?;
        let b = self
            .bytes
            .get(usize::try_from(range.start).ok()?..usize::try_from(range.end).ok()?)?;
        let int = |b: &[u8]| {
            let neg = b.first().is_some_and(|c| c & 0x80 != 0);
            b.iter()
                .fold(if neg { -1i64 } else { 0 }, |v, &c| (v << 8) | i64::from(c))
        };
        Some(match t {
            0 => Value::Null,
            1..=6 => Value::Int(int(b)),
            7 => Value::Float(f64::from_bits(u64::from_be_bytes(b.try_into().ok()?))),
            8 => Value::Int(0),
            9 => Value::Int(1),
            t if t >= 12 && t % 2 == 0 => Value::Blob(b),
            t if t >= 13 => Value::Text(b),
            _ => return None,
        })
    }
}

/// The size of a value of serial type `t` (`None` for the reserved types 10 and 11).
fn serial_size(t: u64) -> Option<u64> {
    Some(match t {
        0 | 8 | 9 => 0,
        1 => 1,
        2 => 2,
        3 => 3,
        4 => 4,
        5 => 6,
        6 | 7 => 8,
        10 | 11 => return None,
        t => (t - 12) / 2,
    })
}

/// The column names of a `CREATE TABLE name (col type …, …)` statement, and which is an
/// `INTEGER PRIMARY KEY` (an alias of the rowid, stored as NULL in the record).
pub(super) fn table_columns(sql: &str) -> (Vec<String>, Option<usize>) {
    let (Some(open), Some(close)) = (sql.find('('), sql.rfind(')')) else {
        return (Vec::new(), None);
    };
    let mut defs = Vec::new();
    let (mut depth, mut start) = (0usize, open + 1);
    for (i, c) in sql
        .char_indices()
        .take_while(|&(i, _)| i < close)
        .skip(open + 1)
    {
        match c {
            '(' => depth += 1,
            ')' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                defs.push(&sql[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    if close > start {
        defs.push(&sql[start..close]);
    }
    let mut names = Vec::new();
    let mut rowid = None;
    for d in defs {
        let d = d.trim();
        let upper = d.to_ascii_uppercase();
        if ["PRIMARY ", "UNIQUE", "CHECK", "FOREIGN ", "CONSTRAINT "]
            .iter()
            .any(|k| upper.starts_with(k))
        {
            continue;
        }
        let name = d
            .split_whitespace()
            .next()
            .unwrap_or("")
            .trim_matches(|c| matches!(c, '"' | '`' | '[' | ']'));
        let words: Vec<&str> = upper.split_whitespace().collect();
        if words.get(1) == Some(&"INTEGER") && words.get(2..4) == Some(&["PRIMARY", "KEY"]) {
            rowid = Some(names.len());
        }
        names.push(name.to_string());
    }
    (names, rowid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_read_as_the_format_says() {
        assert_eq!(varint(&[0x05], 0), Some((5, 1)));
        assert_eq!(varint(&[0x81, 0x00], 0), Some((128, 2)));
        assert_eq!(varint(&[0xff; 9], 0), Some((u64::MAX, 9)));
        assert_eq!(varint(&[0x81], 0), None);
    }

    #[test]
    fn columns_of_rosbag2_tables() {
        let (c, id) = table_columns(
            "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,\
             timestamp INTEGER NOT NULL, data BLOB NOT NULL)",
        );
        assert_eq!(c, ["id", "topic_id", "timestamp", "data"]);
        assert_eq!(id, Some(0));
        let (c, id) = table_columns(
            "CREATE TABLE \"t\" (a TEXT, \"b c\" BLOB, d NUMERIC(10, 2), PRIMARY KEY (a))",
        );
        assert_eq!(c, ["a", "b", "d"]);
        assert_eq!(id, None);
    }

    #[test]
    fn record_values_of_every_serial_type() {
        // Header: size 7, types NULL, int8 -2, int16 300, float 1.5, text "ab", blob [9].
        let mut r = vec![7u8, 0, 1, 2, 7, 17, 14];
        r.push(0xfe);
        r.extend_from_slice(&300i16.to_be_bytes());
        r.extend_from_slice(&1.5f64.to_bits().to_be_bytes());
        r.extend_from_slice(b"ab");
        r.push(9);
        let rec = Record::parse(Path::new("x"), &r).unwrap();
        assert_eq!(rec.value(0), Some(Value::Null));
        assert_eq!(rec.value(1), Some(Value::Int(-2)));
        assert_eq!(rec.value(2), Some(Value::Int(300)));
        assert_eq!(rec.value(3), Some(Value::Float(1.5)));
        assert_eq!(rec.value(4), Some(Value::Text(b"ab")));
        assert_eq!(rec.value(5), Some(Value::Blob(&[9])));
        assert_eq!(rec.value(6), Some(Value::Null));
        // A prefix holding the header but not the blob.
        let rec = Record::parse(Path::new("x"), &r[..12]).unwrap();
        assert_eq!(rec.value(5), None);
        assert!(Record::parse(Path::new("x"), &[9, 1]).is_err());
    }
}

//! A ROS 2 bag in SQLite (`.db3`) for tests, written as the SQLite file format lays it out
//! (<https://www.sqlite.org/fileformat2.html>): the 100-byte header, the schema on page 1, the
//! `topics` and `messages` tables of `rosbag2_storage_sqlite3` as table B-trees (leaf pages,
//! interior pages above them when one page does not hold the rows, payloads that do not fit
//! spilled into overflow chains). A small page size makes a few messages exercise every part.
//! `sl-io` reads it; nothing in the product writes SQLite.

use std::path::Path;

use crate::rosbag_writer::{Conn, Msg};

/// A column value of a record.
enum Val<'a> {
    Null,
    Int(i64),
    Text(&'a str),
    Blob(&'a [u8]),
}

fn varint(out: &mut Vec<u8>, v: u64) {
    if v > 0x00ff_ffff_ffff_ffff {
        // Nine bytes: eight of seven bits, then a whole byte.
        let hi = v >> 8;
        for i in (0..8).rev() {
            out.push(((hi >> (7 * i)) & 0x7f) as u8 | 0x80);
        }
        out.push(v as u8);
        return;
    }
    let mut groups = Vec::new();
    let mut x = v;
    loop {
        groups.push((x & 0x7f) as u8);
        x >>= 7;
        if x == 0 {
            break;
        }
    }
    for (i, g) in groups.iter().rev().enumerate() {
        out.push(if i + 1 < groups.len() { g | 0x80 } else { *g });
    }
}

/// A record: the header (its size, then each column's serial type) and the body.
fn record(values: &[Val<'_>]) -> Vec<u8> {
    let mut types = Vec::new();
    let mut body = Vec::new();
    for v in values {
        match v {
            Val::Null => varint(&mut types, 0),
            Val::Int(i) => {
                let (t, n) = match *i {
                    -128..=127 => (1, 1),
                    -32_768..=32_767 => (2, 2),
                    -8_388_608..=8_388_607 => (3, 3),
                    -2_147_483_648..=2_147_483_647 => (4, 4),
                    -140_737_488_355_328..=140_737_488_355_327 => (5, 6),
                    _ => (6, 8),
                };
                varint(&mut types, t);
                body.extend_from_slice(&i.to_be_bytes()[8 - n..]);
            }
            Val::Text(s) => {
                varint(&mut types, 13 + 2 * s.len() as u64);
                body.extend_from_slice(s.as_bytes());
            }
            Val::Blob(b) => {
                varint(&mut types, 12 + 2 * b.len() as u64);
                body.extend_from_slice(b);
            }
        }
    }
    // The header size counts itself (one byte for the headers written here).
    let mut out = Vec::new();
    varint(&mut out, types.len() as u64 + 1);
    out.extend_from_slice(&types);
    out.extend_from_slice(&body);
    out
}

/// The file's pages, numbered from 1 (page 1, the schema's, is written last).
struct Pages {
    size: usize,
    pages: Vec<Vec<u8>>,
}

impl Pages {
    fn push(&mut self, page: Vec<u8>) -> u32 {
        self.pages.push(page);
        self.pages.len() as u32
    }

    /// The local size of a payload of `p` bytes in a table leaf cell.
    fn local(&self, p: usize) -> usize {
        let u = self.size;
        let x = u - 35;
        if p <= x {
            return p;
        }
        let m = (u - 12) * 32 / 255 - 23;
        let k = m + (p - m) % (u - 4);
        if k <= x { k } else { m }
    }

    /// A leaf cell for `payload`, its overflow (if any) written to pages of its own.
    fn leaf_cell(&mut self, rowid: i64, payload: &[u8]) -> Vec<u8> {
        let mut cell = Vec::new();
        varint(&mut cell, payload.len() as u64);
        varint(&mut cell, rowid as u64);
        let local = self.local(payload.len());
        cell.extend_from_slice(&payload[..local]);
        if local < payload.len() {
            let rest: Vec<&[u8]> = payload[local..].chunks(self.size - 4).collect();
            let first = self.pages.len() as u32 + 1;
            for (i, part) in rest.iter().enumerate() {
                let next = if i + 1 < rest.len() {
                    first + i as u32 + 1
                } else {
                    0
                };
                let mut page = next.to_be_bytes().to_vec();
                page.extend_from_slice(part);
                page.resize(self.size, 0);
                self.push(page);
            }
            cell.extend_from_slice(&first.to_be_bytes());
        }
        cell
    }

    /// A B-tree page of `kind` holding `cells` (content from the page's end), its header at
    /// `at` (100 on page 1).
    fn btree_page(&self, kind: u8, cells: &[Vec<u8>], right: Option<u32>, at: usize) -> Vec<u8> {
        let mut page = vec![0u8; self.size];
        let header = if right.is_some() { 12 } else { 8 };
        let mut end = self.size;
        for (i, c) in cells.iter().enumerate() {
            end -= c.len();
            page[end..end + c.len()].copy_from_slice(c);
            let p = at + header + 2 * i;
            page[p..p + 2].copy_from_slice(&(end as u16).to_be_bytes());
        }
        page[at] = kind;
        page[at + 3..at + 5].copy_from_slice(&(cells.len() as u16).to_be_bytes());
        page[at + 5..at + 7].copy_from_slice(&((end % 65_536) as u16).to_be_bytes());
        if let Some(r) = right {
            page[at + 8..at + 12].copy_from_slice(&r.to_be_bytes());
        }
        page
    }

    /// Writes a table of `rows` (rowid, record) and returns its root page.
    fn table(&mut self, rows: &[(i64, Vec<u8>)]) -> u32 {
        let cells: Vec<(i64, Vec<u8>)> = rows
            .iter()
            .map(|(id, rec)| (*id, self.leaf_cell(*id, rec)))
            .collect();
        // Leaves: as many cells as fit.
        let mut level: Vec<(u32, i64)> = Vec::new();
        let mut group: Vec<Vec<u8>> = Vec::new();
        let mut used = 8;
        let mut last = 0;
        let flush =
            |s: &mut Self, group: &mut Vec<Vec<u8>>, last: i64, level: &mut Vec<(u32, i64)>| {
                let page = s.btree_page(0x0d, group, None, 0);
                level.push((s.push(page), last));
                group.clear();
            };
        for (id, c) in cells {
            if used + c.len() + 2 > self.size && !group.is_empty() {
                flush(self, &mut group, last, &mut level);
                used = 8;
            }
            used += c.len() + 2;
            group.push(c);
            last = id;
        }
        if !group.is_empty() || level.is_empty() {
            flush(self, &mut group, last, &mut level);
        }
        // Interior levels until one page is the root.
        while level.len() > 1 {
            let mut up = Vec::new();
            let mut group: Vec<Vec<u8>> = Vec::new();
            let mut used = 12;
            let mut i = 0;
            while i < level.len() {
                let (child, key) = level[i];
                let mut cell = child.to_be_bytes().to_vec();
                varint(&mut cell, key as u64);
                let is_last = i + 1 == level.len();
                if is_last || (used + cell.len() + 2 > self.size && !group.is_empty()) {
                    // This child closes the page as its right-most pointer.
                    let page = self.btree_page(0x05, &group, Some(child), 0);
                    up.push((self.push(page), key));
                    group.clear();
                    used = 12;
                } else {
                    used += cell.len() + 2;
                    group.push(cell);
                }
                i += 1;
            }
            level = up;
        }
        level[0].0
    }
}

/// The `CREATE TABLE` statements of `rosbag2_storage_sqlite3` (Humble).
const TOPICS_SQL: &str = "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,\
    type TEXT NOT NULL,serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL)";
const MESSAGES_SQL: &str = "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT \
    NULL,timestamp INTEGER NOT NULL, data BLOB NOT NULL)";

/// Writes a ROS 2 bag in SQLite with pages of `page_size` bytes (512–65536): `conns` as the
/// `topics` rows (ROS 2 type names, `cdr`), `msgs` as the `messages` rows in the given order
/// (their time as the receive time in nanoseconds).
pub fn write_db3(
    path: &Path,
    page_size: usize,
    conns: &[Conn],
    msgs: &[Msg],
) -> std::io::Result<()> {
    let mut p = Pages {
        size: page_size,
        pages: vec![Vec::new()],
    };
    let topics: Vec<(i64, Vec<u8>)> = conns
        .iter()
        .map(|c| {
            let rec = record(&[
                Val::Null,
                Val::Text(c.1),
                Val::Text(c.2),
                Val::Text("cdr"),
                Val::Text(""),
            ]);
            (i64::from(c.0), rec)
        })
        .collect();
    let topics_root = p.table(&topics);
    let messages: Vec<(i64, Vec<u8>)> = msgs
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let t = i64::from(m.time.0) * 1_000_000_000 + i64::from(m.time.1);
            let rec = record(&[
                Val::Null,
                Val::Int(i64::from(m.conn)),
                Val::Int(t),
                Val::Blob(&m.data),
            ]);
            (i as i64 + 1, rec)
        })
        .collect();
    let messages_root = p.table(&messages);
    let schema = [
        ("topics", topics_root, TOPICS_SQL),
        ("messages", messages_root, MESSAGES_SQL),
    ];
    let cells: Vec<Vec<u8>> = schema
        .iter()
        .enumerate()
        .map(|(i, (name, root, sql))| {
            let rec = record(&[
                Val::Text("table"),
                Val::Text(name),
                Val::Text(name),
                Val::Int(i64::from(*root)),
                Val::Text(sql),
            ]);
            let mut cell = Vec::new();
            varint(&mut cell, rec.len() as u64);
            varint(&mut cell, i as u64 + 1);
            cell.extend_from_slice(&rec);
            cell
        })
        .collect();
    let mut first = p.btree_page(0x0d, &cells, None, 100);
    let n = p.pages.len() as u32;
    let mut h = b"SQLite format 3\0".to_vec();
    let size_field = if page_size == 65_536 {
        1
    } else {
        page_size as u16
    };
    h.extend_from_slice(&size_field.to_be_bytes());
    h.extend_from_slice(&[1, 1, 0, 64, 32, 32]);
    for v in [1u32, n, 0, 0, 1, 4, 0, 0, 1, 0, 0, 0] {
        h.extend_from_slice(&v.to_be_bytes());
    }
    h.resize(92, 0);
    h.extend_from_slice(&1u32.to_be_bytes());
    h.extend_from_slice(&3_045_000u32.to_be_bytes());
    first[..100].copy_from_slice(&h);
    p.pages[0] = first;
    std::fs::write(path, p.pages.concat())
}

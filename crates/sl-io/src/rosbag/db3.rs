//! ROS 2 bags in SQLite (`.db3`: what `ros2 bag record` writes by default up to Humble, and what
//! librealsense records since 2.56): the `topics` table (id, name, type, serialization format)
//! and the `messages` table (topic id, receive time in nanoseconds, the CDR message), read
//! through the file-format reader of `sqlite.rs`. The messages table is walked once when the bag
//! is opened, keeping each row's topic, time and place (not its data); a message's data is read
//! when it is asked for.

use std::io::{Read, Seek};
use std::path::Path;

use super::messages::Encoding;
use super::sqlite::{RowPlace, Sqlite, Value, table_columns};
use super::{ChunkInfo, Connection};
use crate::error::{IoError, Result};

/// Bytes kept per message of the index.
const ENTRY_BYTES: u64 = std::mem::size_of::<Entry>() as u64;
/// Largest row of the schema or topics table read (a topic's QoS profile text is the longest:
/// a few kilobytes).
const MAX_META_ROW: u64 = 1 << 20;

/// One message of the bag: its topic, receive time and place.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub(super) topic_id: i64,
    pub(super) time_ns: i64,
    pub(super) place: RowPlace,
}

/// An open `.db3` bag.
#[derive(Debug)]
pub(super) struct Db3 {
    db: Sqlite,
    /// Column of the message data in the `messages` table.
    data_col: usize,
    pub(super) entries: Vec<Entry>,
}

fn bad(path: &Path, m: impl Into<String>) -> IoError {
    IoError::malformed(path, m)
}

/// A table of the schema: its root page and its columns (`rowid`: the column that is the
/// rowid's alias).
struct Table {
    root: u32,
    columns: Vec<String>,
    rowid: Option<usize>,
}

impl Table {
    fn column(&self, path: &Path, table: &str, name: &str) -> Result<usize> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| {
            bad(
                path,
                format!("its {table} table has no column {name} (a ROS 2 bag's has)"),
            )
        })
    }
}

/// Every row of the table at `root`, read whole: each at most [`MAX_META_ROW`] bytes, all
/// together at most `budget` (cells may share an overflow chain, so the file's size does not
/// bound what its rows add up to).
fn small_rows<R: Read + Seek>(
    db: &Sqlite,
    path: &Path,
    r: &mut R,
    root: u32,
    max_rows: usize,
    budget: u64,
) -> Result<Vec<(i64, Vec<u8>)>> {
    let mut places = Vec::new();
    db.scan(path, r, root, max_rows, &mut |p, _| {
        places.push(p);
        Ok(())
    })?;
    let total: u64 = places.iter().map(|p| p.payload).sum();
    if total > budget {
        return Err(IoError::too_large(
            path,
            format!(
                "schema or topic rows of {total} bytes, beyond the {budget}-byte budget of one \
                 decoded buffer"
            ),
        ));
    }
    places
        .into_iter()
        .map(|p| {
            Ok((
                p.rowid,
                db.payload(path, r, (p.page, p.offset), u64::MAX, MAX_META_ROW)?,
            ))
        })
        .collect()
}

fn text(v: Option<Value<'_>>) -> Option<String> {
    match v {
        Some(Value::Text(t)) => Some(String::from_utf8_lossy(t).into_owned()),
        _ => None,
    }
}

fn int(v: Option<Value<'_>>, rowid: i64, is_rowid: bool) -> Option<i64> {
    match v {
        Some(Value::Int(i)) => Some(i),
        Some(Value::Null) if is_rowid => Some(rowid),
        _ => None,
    }
}

/// The tables `topics` and `messages` of the schema (page 1).
fn tables<R: Read + Seek>(
    db: &Sqlite,
    path: &Path,
    r: &mut R,
    budget: u64,
) -> Result<(Table, Table)> {
    let mut topics = None;
    let mut messages = None;
    for (_, row) in small_rows(db, path, r, 1, 10_000, budget)? {
        let rec = super::sqlite::Record::parse(path, &row)?;
        // sqlite_schema: type, name, tbl_name, rootpage, sql.
        if text(rec.value(0)).as_deref() != Some("table") {
            continue;
        }
        let name = text(rec.value(1)).unwrap_or_default();
        let root = int(rec.value(3), 0, false).unwrap_or(0);
        let (columns, rowid) = table_columns(&text(rec.value(4)).unwrap_or_default());
        let t = Table {
            root: u32::try_from(root).unwrap_or(0),
            columns,
            rowid,
        };
        match name.as_str() {
            "topics" => topics = Some(t),
            "messages" => messages = Some(t),
            _ => {}
        }
    }
    match (topics, messages) {
        (Some(t), Some(m)) => Ok((t, m)),
        _ => Err(bad(
            path,
            "an SQLite database without the topics and messages tables of a ROS 2 bag",
        )),
    }
}

impl Db3 {
    /// Reads the schema, the topics and the index of every message.
    pub(super) fn open<R: Read + Seek>(
        path: &Path,
        r: &mut R,
        file_len: u64,
        budget: u64,
    ) -> Result<(Self, Vec<Connection>, ChunkInfo)> {
        let db = Sqlite::open(path, r, file_len)?;
        let (topics_t, messages_t) = tables(&db, path, r, budget)?;
        let name = topics_t.column(path, "topics", "name")?;
        let ty = topics_t.column(path, "topics", "type")?;
        let format = topics_t.column(path, "topics", "serialization_format")?;
        let id_col = topics_t.column(path, "topics", "id")?;
        let mut connections = Vec::new();
        for (rowid, row) in small_rows(&db, path, r, topics_t.root, 100_000, budget)? {
            let rec = super::sqlite::Record::parse(path, &row)?;
            let id = int(rec.value(id_col), rowid, topics_t.rowid == Some(id_col))
                .and_then(|i| u32::try_from(i).ok())
                .ok_or_else(|| bad(path, "a topic row without an id"))?;
            let topic = text(rec.value(name)).ok_or_else(|| bad(path, "a topic without a name"))?;
            let message_type = text(rec.value(ty)).unwrap_or_default();
            let serialization = text(rec.value(format)).unwrap_or_default();
            if serialization != "cdr" {
                return Err(bad(
                    path,
                    format!("{topic} is serialised as {serialization:?}; ROS 2 bags use cdr"),
                ));
            }
            connections.push(Connection {
                id,
                topic,
                message_type: message_type.replacen("/msg/", "/", 1),
                encoding: Encoding::Cdr,
            });
        }
        let topic_col = messages_t.column(path, "messages", "topic_id")?;
        let time_col = messages_t.column(path, "messages", "timestamp")?;
        let data_col = messages_t.column(path, "messages", "data")?;
        let max_rows = usize::try_from(budget / ENTRY_BYTES).unwrap_or(usize::MAX);
        let mut entries = Vec::new();
        let mut short = Vec::new();
        db.scan(path, r, messages_t.root, max_rows, &mut |place, local| {
            let rec = super::sqlite::Record::parse(path, local);
            let pair = |rec: &super::sqlite::Record<'_>| {
                Some((
                    int(rec.value(topic_col), 0, false)?,
                    int(rec.value(time_col), 0, false)?,
                ))
            };
            match rec.ok().as_ref().and_then(pair) {
                Some((topic_id, time_ns)) => entries.push(Entry {
                    topic_id,
                    time_ns,
                    place,
                }),
                // Its header or first columns overflow (pages too small for them): read later.
                None => short.push(place),
            }
            Ok(())
        })?;
        for place in short {
            let head = db.payload(path, r, (place.page, place.offset), 1024, budget)?;
            let rec = super::sqlite::Record::parse(path, &head)?;
            let topic_id = int(rec.value(topic_col), 0, false);
            let time_ns = int(rec.value(time_col), 0, false);
            let (Some(topic_id), Some(time_ns)) = (topic_id, time_ns) else {
                return Err(bad(
                    path,
                    format!("message row {} has no topic id or timestamp", place.rowid),
                ));
            };
            entries.push(Entry {
                topic_id,
                time_ns,
                place,
            });
        }
        // Recorded in time order; a stable sort keeps the rowid order among equal times.
        entries.sort_by_key(|e| e.time_ns);
        let mut counts: Vec<(u32, u32)> = connections.iter().map(|c| (c.id, 0)).collect();
        for e in &entries {
            if let Some(c) = counts
                .iter_mut()
                .find(|(id, _)| i64::from(*id) == e.topic_id)
            {
                c.1 = c.1.saturating_add(1);
            }
        }
        let chunk = ChunkInfo {
            pos: 0,
            counts,
            index_at: Vec::new(),
        };
        Ok((
            Self {
                db,
                data_col,
                entries,
            },
            connections,
            chunk,
        ))
    }

    /// The data of the message whose row lies at `place` (leaf page, cell offset): its CDR
    /// bytes, within `budget` bytes.
    pub(super) fn data<R: Read + Seek>(
        &self,
        path: &Path,
        r: &mut R,
        place: (u32, u16),
        budget: u64,
    ) -> Result<Vec<u8>> {
        let mut row = self.db.payload(path, r, place, u64::MAX, budget)?;
        let rec = super::sqlite::Record::parse(path, &row)?;
        let range = rec
            .range(self.data_col)
            .filter(|g| g.end <= row.len() as u64)
            .ok_or_else(|| {
                bad(
                    path,
                    format!(
                        "the message row at SQLite page {} has no data column",
                        place.0
                    ),
                )
            })?;
        row.truncate(range.end as usize);
        row.drain(..range.start as usize);
        Ok(row)
    }
}

//! One file of a recording — a ROS 1 bag, an MCAP file or a `.db3` — with its index: opened,
//! its topics and a topic's messages listed from the index, a message read by decompressing
//! its chunk (kept for the next) or reading its SQLite row. A recording split into several
//! files (a ROS 2 bag's folder) is one `Part` each, merged by [`super::RosBag`].

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use super::messages::Encoding;
use super::records::{Header, MAGIC, MAX_HEADER_BYTES, op, read_at, read_record, record_in};
use super::{
    BagMessage, BagTopic, COMPRESSED_IMAGE_TYPE, ChunkInfo, Connection, Format, db3, mcap, records,
    sqlite,
};
use crate::error::{IoError, Result};
use crate::limits::Limits;

/// One file of a recording: its index, and the chunk (or SQLite message) read last.
#[derive(Debug)]
pub(super) struct Part {
    path: PathBuf,
    file: BufReader<File>,
    file_len: u64,
    limits: Limits,
    format: Format,
    connections: Vec<Connection>,
    chunks: Vec<ChunkInfo>,
    /// The chunk decompressed last: its place and records (SQLite: the message read last).
    cache: Option<(u64, Vec<u8>)>,
    /// The index of a `.db3` bag.
    db3: Option<db3::Db3>,
}

/// `data` decompressed by `compression` (ROS 1: `none`, `bz2`, `lz4`; MCAP: empty, `zstd`,
/// `lz4`) into exactly `size` bytes: the decoder is stopped one byte past `size` (checked
/// against the budget by the caller), so a chunk whose header lies allocates no more.
fn inflate(
    path: &Path,
    pos: u64,
    compression: &str,
    data: Vec<u8>,
    size: u64,
    budget: u64,
) -> Result<Vec<u8>> {
    let mut out = Vec::with_capacity(usize::try_from(size).unwrap_or(0));
    let take = size + 1;
    let got = match compression {
        "none" | "" => {
            out = data;
            Ok(out.len())
        }
        "bz2" => bzip2::read::BzDecoder::new(&data[..])
            .take(take)
            .read_to_end(&mut out),
        "lz4" => lz4_flex::frame::FrameDecoder::new(&data[..])
            .take(take)
            .read_to_end(&mut out),
        "zstd" => {
            // The window a frame may ask for is bounded by the budget too (an encoder may
            // declare a window larger than its content).
            match ruzstd::decoding::StreamingDecoder::new_with_max_window_size(&data[..], budget) {
                Ok(d) => d.take(take).read_to_end(&mut out),
                Err(e) => Err(std::io::Error::other(e.to_string())),
            }
        }
        other => {
            return Err(IoError::malformed(
                path,
                format!(
                    "a chunk compressed as {other:?} (bags use none, bz2 or lz4; MCAP zstd or lz4)"
                ),
            ));
        }
    };
    match got {
        Ok(n) if n as u64 == size => Ok(out),
        Ok(n) => Err(IoError::malformed(
            path,
            format!(
                "the chunk at byte {pos} decompresses to {n}{} bytes, its header says {size}",
                if n as u64 > size { "+" } else { "" }
            ),
        )),
        Err(e) => Err(IoError::malformed(
            path,
            format!("the {compression} chunk at byte {pos} does not decompress: {e}"),
        )),
    }
}

/// The messages of `topic` the index records of the chunk at `pos` list (`found`) against
/// those its chunk info or summary counts (`expected`).
fn check_count(path: &Path, pos: u64, topic: &str, found: u64, expected: u64) -> Result<()> {
    if found == expected {
        return Ok(());
    }
    Err(IoError::malformed(
        path,
        format!(
            "the index records of the chunk at byte {pos} list {found} messages of {topic}, \
             its chunk info {expected}"
        ),
    ))
}

impl Part {
    /// Opens one file of a recording and reads its index (connections and chunk places; of a
    /// `.db3`, its topics and every message's topic, time and place).
    ///
    /// # Errors
    /// A file that is not a bag (ROS 1 of format 2.0, MCAP or SQLite), a bag without an index
    /// (a recording that was not closed: `rosbag reindex` or `mcap recover` writes one; a
    /// `.db3` whose newest writes are still in its `-wal` file), or a malformed or truncated
    /// record or page.
    pub(super) fn open(path: &Path, limits: &Limits) -> Result<Self> {
        let path = path.to_path_buf();
        let f = File::open(&path).map_err(|e| IoError::io(&path, e))?;
        let file_len = f.metadata().map_err(|e| IoError::io(&path, e))?.len();
        let mut file = BufReader::new(f);
        let mut magic = [0u8; 16];
        let got = file
            .read(&mut magic)
            .and_then(|n| {
                if n < magic.len() {
                    file.read_exact(&mut magic[n..]).map(|()| magic.len())
                } else {
                    Ok(n)
                }
            })
            .unwrap_or(0);
        if got >= mcap::MAGIC.len() && magic.starts_with(mcap::MAGIC) {
            let (connections, chunks) = mcap::read_summary(&path, &mut file, file_len)?;
            return Ok(Self {
                path,
                file,
                file_len,
                limits: *limits,
                format: Format::Mcap,
                connections,
                chunks,
                cache: None,
                db3: None,
            });
        }
        if got >= magic.len() && magic == *sqlite::MAGIC {
            let budget = limits.max_decoded_bytes;
            let (db, connections, chunk) = db3::Db3::open(&path, &mut file, file_len, budget)?;
            return Ok(Self {
                path,
                file,
                file_len,
                limits: *limits,
                format: Format::Sqlite,
                connections,
                chunks: vec![chunk],
                cache: None,
                db3: Some(db),
            });
        }
        if got < MAGIC.len() || magic[..MAGIC.len()] != *MAGIC {
            let v1 = magic.starts_with(b"#ROSBAG V1");
            return Err(IoError::malformed(
                &path,
                if v1 {
                    "a ROS bag of format 1.x, which is not read (ROS since 2010 writes 2.0)"
                } else {
                    "not a ROS 1 bag (it does not start with `#ROSBAG V2.0`), an MCAP file nor \
                     an SQLite one"
                },
            ));
        }
        {
            use std::io::Seek;
            file.seek(std::io::SeekFrom::Start(MAGIC.len() as u64))
                .map_err(|e| IoError::io(&path, e))?;
        }
        let header = read_record(&path, &mut file, file_len)?;
        if header.header.op(&path)? != op::BAG_HEADER {
            return Err(IoError::malformed(
                &path,
                "the first record is not the bag header",
            ));
        }
        let index_pos = header.header.u64(&path, "index_pos")?;
        if index_pos == 0 || index_pos >= file_len {
            return Err(IoError::malformed(
                &path,
                "the bag has no index (its recording was not closed): `rosbag reindex` writes one",
            ));
        }
        let mut bag = Self {
            path,
            file,
            file_len,
            limits: *limits,
            format: Format::Ros1,
            connections: Vec::new(),
            chunks: Vec::new(),
            cache: None,
            db3: None,
        };
        bag.read_index(index_pos)?;
        // A bag cut short inside its index (at a record's end) would otherwise lose chunks
        // without a word.
        let conns = header.header.u32(&bag.path, "conn_count")?;
        let chunks = header.header.u32(&bag.path, "chunk_count")?;
        if (bag.connections.len(), bag.chunks.len()) != (conns as usize, chunks as usize) {
            return Err(IoError::malformed(
                &bag.path,
                format!(
                    "the index holds {} connections and {} chunks, the bag header says {conns} \
                     and {chunks} (a bag cut short)",
                    bag.connections.len(),
                    bag.chunks.len()
                ),
            ));
        }
        Ok(bag)
    }

    /// The bag's file (a ROS 2 bag folder's `.mcap` or `.db3`).
    pub(super) fn path(&self) -> &Path {
        &self.path
    }

    /// What holds the recording: `"ROS 1 bag"`, `"MCAP (ROS 2 bag)"` or `"SQLite (ROS 2 bag)"`.
    pub(super) fn container(&self) -> &'static str {
        match self.format {
            Format::Ros1 => "ROS 1 bag",
            Format::Mcap => "MCAP (ROS 2 bag)",
            Format::Sqlite => "SQLite (ROS 2 bag)",
        }
    }

    /// Connections and chunk infos, from `index_pos` to the end of the file.
    fn read_index(&mut self, index_pos: u64) -> Result<()> {
        use std::io::Seek;
        let path = self.path.clone();
        self.file
            .seek(std::io::SeekFrom::Start(index_pos))
            .map_err(|e| IoError::io(&path, e))?;
        while self
            .file
            .stream_position()
            .map_err(|e| IoError::io(&path, e))?
            < self.file_len
        {
            let r = read_record(&path, &mut self.file, self.file_len)?;
            match r.header.op(&path)? {
                op::CONNECTION => {
                    if r.data_len > MAX_HEADER_BYTES {
                        return Err(IoError::malformed(
                            &path,
                            format!("a connection record of {} bytes", r.data_len),
                        ));
                    }
                    let id = r.header.u32(&path, "conn")?;
                    let topic = r.header.text(&path, "topic")?;
                    let data = read_at(&path, &mut self.file, r.data_pos, r.data_len)?;
                    let fields = Header::parse(&path, &data)?;
                    let message_type = fields.text(&path, "type")?;
                    self.connections.push(Connection {
                        id,
                        topic,
                        message_type,
                        encoding: Encoding::Ros1,
                    });
                }
                op::CHUNK_INFO => {
                    let pos = r.header.u64(&path, "chunk_pos")?;
                    let n = r.header.u32(&path, "count")?;
                    if u64::from(n) * 8 != u64::from(r.data_len) {
                        return Err(IoError::malformed(
                            &path,
                            format!("a chunk info of {n} connections has {} bytes", r.data_len),
                        ));
                    }
                    let data = read_at(&path, &mut self.file, r.data_pos, r.data_len)?;
                    let counts = data
                        .chunks_exact(8)
                        .map(|c| {
                            let w =
                                |i: usize| u32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
                            (w(0), w(4))
                        })
                        .collect();
                    self.chunks.push(ChunkInfo {
                        pos,
                        counts,
                        index_at: Vec::new(),
                    });
                }
                _ => {}
            }
            self.file
                .seek(std::io::SeekFrom::Start(r.data_pos + u64::from(r.data_len)))
                .map_err(|e| IoError::io(&path, e))?;
        }
        Ok(())
    }

    /// The bag's topics, by name, with their message types and counts.
    pub(super) fn topics(&self) -> Vec<BagTopic> {
        let mut out: Vec<BagTopic> = Vec::new();
        for c in &self.connections {
            let n: u64 = self
                .chunks
                .iter()
                .flat_map(|k| &k.counts)
                .filter(|(id, _)| *id == c.id)
                .map(|(_, n)| u64::from(*n))
                .sum();
            match out.iter_mut().find(|t| t.topic == c.topic) {
                Some(t) => t.messages += n,
                None => out.push(BagTopic {
                    topic: c.topic.clone(),
                    message_type: c.message_type.clone(),
                    messages: n,
                }),
            }
        }
        out.sort_by(|a, b| a.topic.cmp(&b.topic));
        out
    }

    /// The messages of `topic` in this file (none when it has no such topic), in the order
    /// they were recorded and marked as file `part`'s (at most [`Limits::max_frames`]).
    ///
    /// # Errors
    /// More messages than the limit, or a malformed index.
    pub(super) fn messages(&mut self, topic: &str, part: u32) -> Result<Vec<BagMessage>> {
        let ids: Vec<u32> = self
            .connections
            .iter()
            .filter(|c| c.topic == topic)
            .map(|c| c.id)
            .collect();
        // A topic this file does not have lists no messages ([`super::RosBag::messages`] says
        // which topics the recording has).
        let path = self.path.clone();
        let compressed = self.message_type(topic) == Some(COMPRESSED_IMAGE_TYPE);
        let encoding = self
            .connections
            .iter()
            .find(|c| c.topic == topic)
            .map_or(Encoding::Ros1, |c| c.encoding);
        let max_frames = self.limits.max_frames;
        let too_many = |path: &Path| {
            IoError::too_large(
                path,
                format!(
                    "{topic} has more than {max_frames} messages, the limit of frames a sequence \
                     may have (raise --max-memory)"
                ),
            )
        };
        if let Some(db) = &self.db3 {
            let out: Vec<BagMessage> = db
                .entries
                .iter()
                .filter(|e| ids.iter().any(|&id| i64::from(id) == e.topic_id))
                .map(|e| BagMessage {
                    part,
                    chunk_pos: u64::from(e.place.page),
                    offset: u64::from(e.place.offset),
                    compressed,
                    encoding,
                    record_time_s: e.time_ns as f64 * 1e-9,
                })
                .take(max_frames.saturating_add(1))
                .collect();
            if out.len() > max_frames {
                return Err(too_many(&path));
            }
            return Ok(out);
        }
        let mut out = Vec::new();
        let chunks: Vec<ChunkInfo> = self
            .chunks
            .iter()
            .filter(|c| c.counts.iter().any(|(id, _)| ids.contains(id)))
            .cloned()
            .collect();
        for chunk in &chunks {
            use std::io::Seek;
            let expected: u64 = chunk
                .counts
                .iter()
                .filter(|(id, _)| ids.contains(id))
                .map(|(_, n)| u64::from(*n))
                .sum();
            let before = out.len();
            if self.format == Format::Mcap {
                for (channel, at) in &chunk.index_at {
                    if !ids.contains(channel) {
                        continue;
                    }
                    let entries =
                        mcap::message_index(&path, &mut self.file, self.file_len, *at, max_frames)?;
                    if out.len() + entries.len() > max_frames {
                        return Err(too_many(&path));
                    }
                    out.extend(entries.into_iter().map(|(t, offset)| BagMessage {
                        part,
                        chunk_pos: chunk.pos,
                        offset,
                        compressed,
                        encoding,
                        record_time_s: records::time_s(
                            (t / 1_000_000_000) as u32,
                            (t % 1_000_000_000) as u32,
                        ),
                    }));
                }
                check_count(
                    &path,
                    chunk.pos,
                    topic,
                    (out.len() - before) as u64,
                    expected,
                )?;
                continue;
            }
            self.file
                .seek(std::io::SeekFrom::Start(chunk.pos))
                .map_err(|e| IoError::io(&path, e))?;
            let c = read_record(&path, &mut self.file, self.file_len)?;
            if c.header.op(&path)? != op::CHUNK {
                return Err(IoError::malformed(
                    &path,
                    format!(
                        "the index points at byte {} for a chunk, which is none",
                        chunk.pos
                    ),
                ));
            }
            // One index record per connection of the chunk follows it; together they list as
            // many messages of the topic as the chunk info says.
            for _ in 0..chunk.counts.len() {
                let r = read_record(&path, &mut self.file, self.file_len)?;
                if r.header.op(&path)? != op::INDEX_DATA {
                    break;
                }
                let conn = r.header.u32(&path, "conn")?;
                if !ids.contains(&conn) {
                    continue;
                }
                let n = r.header.u32(&path, "count")?;
                if u64::from(n) * 12 != u64::from(r.data_len) {
                    return Err(IoError::malformed(
                        &path,
                        format!("an index record of {n} messages has {} bytes", r.data_len),
                    ));
                }
                if out.len() + n as usize > max_frames {
                    return Err(too_many(&path));
                }
                let data = read_at(&path, &mut self.file, r.data_pos, r.data_len)?;
                for e in data.chunks_exact(12) {
                    let w = |i: usize| u32::from_le_bytes([e[i], e[i + 1], e[i + 2], e[i + 3]]);
                    out.push(BagMessage {
                        part,
                        chunk_pos: chunk.pos,
                        offset: u64::from(w(8)),
                        compressed,
                        encoding,
                        record_time_s: records::time_s(w(0), w(4)),
                    });
                }
                self.file
                    .seek(std::io::SeekFrom::Start(r.data_pos + u64::from(r.data_len)))
                    .map_err(|e| IoError::io(&path, e))?;
            }
            check_count(
                &path,
                chunk.pos,
                topic,
                (out.len() - before) as u64,
                expected,
            )?;
        }
        // Chunks are written in time order, and a chunk's index too; a stable sort keeps that
        // order among equal times.
        out.sort_by(|a, b| a.record_time_s.total_cmp(&b.record_time_s));
        Ok(out)
    }

    /// The serialised message `m` (its chunk decompressed, or kept from the last call).
    pub(super) fn message(&mut self, m: &BagMessage) -> Result<&[u8]> {
        let path = self.path.clone();
        if let Some(db) = &self.db3 {
            // The message itself is cached, keyed by its page and cell.
            let key = (m.chunk_pos << 16) | m.offset;
            if self.cache.as_ref().is_none_or(|(k, _)| *k != key) {
                self.cache = None;
                let place = (
                    u32::try_from(m.chunk_pos).unwrap_or(0),
                    u16::try_from(m.offset).unwrap_or(0),
                );
                let data = db.data(&path, &mut self.file, place, self.limits.max_decoded_bytes)?;
                self.cache = Some((key, data));
            }
            return Ok(self.cache.as_ref().map_or(&[][..], |(_, d)| d.as_slice()));
        }
        if self
            .cache
            .as_ref()
            .is_none_or(|(pos, _)| *pos != m.chunk_pos)
        {
            self.cache = None;
            let records = self.decompress_chunk(m.chunk_pos)?;
            self.cache = Some((m.chunk_pos, records));
        }
        let Some((_, records)) = &self.cache else {
            return Err(IoError::malformed(&path, "no chunk"));
        };
        if self.format == Format::Mcap {
            return mcap::message_in(&path, records, m.offset);
        }
        let offset = usize::try_from(m.offset).unwrap_or(usize::MAX);
        let (h, data, _) = record_in(&path, records, offset)?;
        if h.op(&path)? != op::MESSAGE {
            return Err(IoError::malformed(
                &path,
                format!(
                    "the index points at offset {} of the chunk at byte {} for a message, \
                     which is none",
                    m.offset, m.chunk_pos
                ),
            ));
        }
        Ok(data)
    }

    /// The records of the chunk at `pos`, decompressed within the budget.
    fn decompress_chunk(&mut self, pos: u64) -> Result<Vec<u8>> {
        use std::io::Seek;
        let path = self.path.clone();
        let budget = self.limits.max_decoded_bytes;
        let (compression, size, data) = if self.format == Format::Mcap {
            mcap::read_chunk(&path, &mut self.file, self.file_len, pos, budget)?
        } else {
            self.file
                .seek(std::io::SeekFrom::Start(pos))
                .map_err(|e| IoError::io(&path, e))?;
            let c = read_record(&path, &mut self.file, self.file_len)?;
            let compression = c.header.text(&path, "compression")?;
            let size = u64::from(c.header.u32(&path, "size")?);
            if size > budget || u64::from(c.data_len) > budget {
                return Err(IoError::too_large(
                    &path,
                    format!(
                        "a chunk of {} bytes ({size} decompressed) is beyond the {budget}-byte \
                         budget of one decoded buffer (raise --max-memory)",
                        c.data_len
                    ),
                ));
            }
            let data = read_at(&path, &mut self.file, c.data_pos, c.data_len)?;
            (compression, size, data)
        };
        inflate(&path, pos, &compression, data, size, budget)
    }

    /// The type of the messages of `topic`, if the bag has it.
    pub(super) fn message_type(&self, topic: &str) -> Option<&str> {
        self.connections
            .iter()
            .find(|c| c.topic == topic)
            .map(|c| c.message_type.as_str())
    }
}

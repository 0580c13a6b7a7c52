//! Robot recordings: ROS 1 bags (`.bag`, format 2.0) and ROS 2 bags in MCAP (`.mcap`) or in
//! SQLite (`.db3`, the default storage up to Humble), or a ROS 2 bag's folder holding
//! `metadata.yaml` and one such file — the depth images and camera calibration a robot
//! recorded, read straight from the recording. TUM RGB-D ships every sequence as a ROS 1 bag;
//! a Kinect, Xtion, RealSense or OAK-D driver under ROS records its depth as
//! `sensor_msgs/Image`; librealsense's own recorder (the RealSense Viewer) writes a ROS 1 bag,
//! or a `.db3` since 2.56, whose sensor options (`realsense.rs`: depth units, stereo
//! baseline, the device) choose the depth scale and noise model (`camera.rs`).
//!
//! Written by hand (no crate reads bags within a memory budget): the index (ROS 1: connections
//! and chunk places at the end of the file; MCAP: the summary section the footer points at) is
//! read first; a topic's messages are then found from the index records of each chunk, without
//! decompressing anything; a message is read by decompressing its chunk (`none`; ROS 1 `bz2`
//! through the `bzip2` crate; `lz4` frames through `lz4_flex`; MCAP `zstd` through `ruzstd`),
//! which is kept for the next message. Every length is checked against the file and
//! [`Limits::max_decoded_bytes`] before a buffer is sized from it. A `.db3` is read through
//! a read-only reader of the SQLite file format (`sqlite.rs`, `db3.rs`): its `messages` table
//! walked once for each row's topic, time and place, a message's data read when asked for.
//!
//! Messages: ROS 1's serialisation, or ROS 2's CDR (`messages.rs`). Depth: `16UC1` and
//! `mono16` are units (millimetres by ROS's REP 118, 0 = none), `32FC1` metres (NaN = none;
//! TUM's bags store `/camera/depth/image` so); `image_transport`'s `compressedDepth`
//! (`sensor_msgs/CompressedImage`, what a robot records over a network) is read in its PNG
//! form, `16UC1` millimetres or `32FC1` as quantised inverse depth (its RVL form is refused by
//! name). The frame's time is its message header's stamp (the sensor's), not the time the
//! recorder received it.
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use sl_io::Limits;
//! use sl_io::rosbag::RosBag;
//!
//! // A file that is not a bag is an error that says what was expected.
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("not.bag");
//! std::fs::write(&path, b"hello")?;
//! let err = RosBag::open(&path, &Limits::default()).unwrap_err();
//! assert!(err.to_string().contains("not a ROS 1 bag"));
//! # Ok(())
//! # }
//! ```

mod camera;
mod db3;
mod mcap;
mod messages;
mod realsense;
mod records;
mod sqlite;

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use sl_core::DepthImage;

pub use camera::BagCamera;
pub use messages::DepthEncodingKind;
use messages::Encoding;
pub use realsense::RealSenseInfo;
use records::{Header, MAGIC, MAX_HEADER_BYTES, op, read_at, read_record, record_in};

use crate::error::{IoError, Result};
use crate::limits::Limits;
use crate::ros_camera::{RosCamera, camera_info_to_camera};

/// The message type of a depth or colour image.
pub const IMAGE_TYPE: &str = "sensor_msgs/Image";
/// The message type of a compressed image (`image_transport`'s `compressedDepth` for depth).
pub const COMPRESSED_IMAGE_TYPE: &str = "sensor_msgs/CompressedImage";
/// The message type of a camera calibration.
pub const CAMERA_INFO_TYPE: &str = "sensor_msgs/CameraInfo";

/// One topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagTopic {
    /// Its name (`/camera/depth/image`).
    pub topic: String,
    /// Its message type (`sensor_msgs/Image`).
    pub message_type: String,
    /// How many messages the bag holds on it (from the index).
    pub messages: u64,
}

/// Where one message lies (found by [`RosBag::messages`], read by [`RosBag::read_depth`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BagMessage {
    chunk_pos: u64,
    /// Where its record lies in the chunk's decompressed records.
    offset: u64,
    /// A `sensor_msgs/CompressedImage` rather than an `Image`.
    compressed: bool,
    /// How it is serialised (ROS 1, or ROS 2's CDR).
    encoding: Encoding,
    /// When the recorder received it, seconds (the message's own stamp is read with it).
    pub record_time_s: f64,
}

/// A depth frame read from a bag.
#[derive(Debug, Clone)]
pub struct BagDepth {
    /// The image header's stamp, seconds (the record time when the stamp is 0).
    pub stamp_s: f64,
    /// Depth in metres, 0 = none.
    pub depth: DepthImage,
    /// How the message stored it.
    pub kind: DepthEncodingKind,
}

/// A topic's connection (ROS 1) or channel (MCAP).
#[derive(Debug, Clone)]
struct Connection {
    id: u32,
    topic: String,
    /// As ROS 1 names it (`sensor_msgs/Image`; MCAP's `sensor_msgs/msg/Image` so renamed).
    message_type: String,
    encoding: Encoding,
}

/// A chunk: where it lies and what it holds.
#[derive(Debug, Clone)]
struct ChunkInfo {
    pos: u64,
    /// `(connection, messages)` in the chunk.
    counts: Vec<(u32, u32)>,
    /// MCAP: where each channel's message index record lies (ROS 1's follow the chunk).
    index_at: Vec<(u32, u64)>,
}

/// The container of the recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    /// ROS 1 bag, format 2.0.
    Ros1,
    /// MCAP (ROS 2).
    Mcap,
    /// SQLite (ROS 2, `.db3`).
    Sqlite,
}

/// An open recording (see the module docs).
#[derive(Debug)]
pub struct RosBag {
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

/// Whether `path` names a recording [`RosBag::open`] takes: a `.bag` (ROS 1) or `.mcap` file,
/// or a ROS 2 bag's folder (`metadata.yaml` beside its `.mcap` or `.db3` files).
pub fn is_bag_file(path: &Path) -> bool {
    let ext = |p: &Path, e: &str| p.extension().is_some_and(|x| x.eq_ignore_ascii_case(e));
    if path.is_dir() {
        return path.join("metadata.yaml").is_file()
            && std::fs::read_dir(path).is_ok_and(|d| {
                d.flatten()
                    .any(|e| ext(&e.path(), "mcap") || ext(&e.path(), "db3"))
            });
    }
    ext(path, "bag") || ext(path, "mcap") || ext(path, "db3")
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

/// The file of a recording: `path` itself, or a ROS 2 bag folder's one `.mcap` or `.db3` file.
fn bag_file_of(path: &Path) -> Result<PathBuf> {
    if !path.is_dir() {
        return Ok(path.to_path_buf());
    }
    let mut files = Vec::new();
    for e in std::fs::read_dir(path).map_err(|e| IoError::io(path, e))? {
        let p = e.map_err(|e| IoError::io(path, e))?.path();
        if p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("db3"))
        {
            files.push(p);
        }
    }
    files.sort();
    match files.len() {
        1 => Ok(files.swap_remove(0)),
        0 => Err(IoError::malformed(
            path,
            "a folder without an .mcap or .db3 file",
        )),
        n => Err(IoError::malformed(
            path,
            format!("a bag split into {n} files: give one of them"),
        )),
    }
}

impl RosBag {
    /// Opens a bag and reads its index (connections and chunk places; of a `.db3`, its topics
    /// and every message's topic, time and place).
    ///
    /// # Errors
    /// A file that is not a bag (ROS 1 of format 2.0, MCAP or SQLite), a bag without an index
    /// (a recording that was not closed: `rosbag reindex` or `mcap recover` writes one; a
    /// `.db3` whose newest writes are still in its `-wal` file), a bag split into several
    /// files, or a malformed or truncated record or page.
    pub fn open(path: impl AsRef<Path>, limits: &Limits) -> Result<Self> {
        let path = bag_file_of(path.as_ref())?;
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
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What holds the recording: `"ROS 1 bag"`, `"MCAP (ROS 2 bag)"` or `"SQLite (ROS 2 bag)"`.
    pub fn container(&self) -> &'static str {
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
    pub fn topics(&self) -> Vec<BagTopic> {
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

    /// The messages of `topic`, in the order they were recorded (at most
    /// [`Limits::max_frames`]).
    ///
    /// # Errors
    /// A topic the bag does not have (the error lists those it has), more messages than the
    /// limit, or a malformed index.
    pub fn messages(&mut self, topic: &str) -> Result<Vec<BagMessage>> {
        let ids: Vec<u32> = self
            .connections
            .iter()
            .filter(|c| c.topic == topic)
            .map(|c| c.id)
            .collect();
        if ids.is_empty() {
            let have: Vec<String> = self.topics().into_iter().map(|t| t.topic).collect();
            return Err(IoError::malformed(
                &self.path,
                format!("no topic {topic:?} (the bag has {})", have.join(", ")),
            ));
        }
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
    fn message(&mut self, m: &BagMessage) -> Result<&[u8]> {
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
    pub fn message_type(&self, topic: &str) -> Option<&str> {
        self.connections
            .iter()
            .find(|c| c.topic == topic)
            .map(|c| c.message_type.as_str())
    }

    /// How the image message `m` stores depth (`None`: an image that is not depth).
    ///
    /// # Errors
    /// As [`RosBag::read_depth`], but for the pixels.
    pub fn depth_kind(&mut self, m: &BagMessage) -> Result<Option<DepthEncodingKind>> {
        Ok(self
            .image_encoding(m)?
            .as_deref()
            .and_then(DepthEncodingKind::of))
    }

    /// The depth image of message `m` (of a `sensor_msgs/Image` topic): 16-bit values divided by
    /// `units_per_m` (ROS's millimetres: 1000), floats by `float_units_per_m` (metres: 1).
    ///
    /// # Errors
    /// A message that is not a depth image, pixels beyond the limits, or a malformed chunk.
    pub fn read_depth(
        &mut self,
        m: &BagMessage,
        units_per_m: f64,
        float_units_per_m: f64,
    ) -> Result<BagDepth> {
        let path = self.path.clone();
        let limits = self.limits;
        let (compressed, cdr) = (m.compressed, m.encoding);
        let b = self.message(m)?;
        let (stamp_s, depth, encoding) = if compressed {
            let c = messages::compressed_image(&path, b, cdr)?;
            let depth =
                messages::compressed_depth_of(&path, &c, units_per_m, float_units_per_m, &limits)?;
            let encoding = messages::compressed_depth_encoding(&c.format)
                .unwrap_or_default()
                .to_string();
            (c.stamp_s, depth, encoding)
        } else {
            let img = messages::image(&path, b, cdr)?;
            let depth = messages::depth_of(&path, &img, units_per_m, float_units_per_m, &limits)?;
            (img.stamp_s, depth, img.encoding)
        };
        let kind = DepthEncodingKind::of(&encoding).unwrap_or(DepthEncodingKind::U16);
        let stamp_s = if stamp_s > 0.0 {
            stamp_s
        } else {
            m.record_time_s
        };
        Ok(BagDepth {
            stamp_s,
            depth,
            kind,
        })
    }

    /// The camera of the first message on the `sensor_msgs/CameraInfo` topic `topic`.
    ///
    /// # Errors
    /// No such topic or message, or a calibration [`crate::ros_camera::read_ros_camera`] would
    /// refuse (binning, a region of interest, a distortion other than `plumb_bob`).
    pub fn camera(&mut self, topic: &str) -> Result<RosCamera> {
        let path = self.path.clone();
        let first = self
            .messages(topic)?
            .into_iter()
            .next()
            .ok_or_else(|| IoError::malformed(&path, format!("{topic} has no message")))?;
        let b = self.message(&first)?;
        let info = messages::camera_info(&path, b, first.encoding)?;
        self.limits
            .check_pixels(info.width as u64, info.height as u64)
            .map_err(|e| IoError::too_large(&path, e))?;
        camera_info_to_camera(&path, &info)
    }

    /// The depth topic to read: `requested` when given (it must be an image topic), else the one
    /// image topic whose first message holds depth (`16UC1`, `32FC1`, or `mono16` on a topic
    /// named for depth; an infrared `mono16` stream is not depth), a `compressedDepth` topic
    /// counting as one.
    ///
    /// # Errors
    /// No depth topic, or several (the error lists them: name one).
    pub fn depth_topic(&mut self, requested: Option<&str>) -> Result<String> {
        let path = self.path.clone();
        if let Some(t) = requested {
            return match self.message_type(t) {
                Some(IMAGE_TYPE | COMPRESSED_IMAGE_TYPE) => Ok(t.to_string()),
                Some(other) => Err(IoError::malformed(
                    &path,
                    format!("{t} carries {other}, not {IMAGE_TYPE}"),
                )),
                None => self.messages(t).map(|_| t.to_string()),
            };
        }
        let images: Vec<String> = self
            .topics()
            .into_iter()
            .filter(|t| {
                (t.message_type == IMAGE_TYPE || t.message_type == COMPRESSED_IMAGE_TYPE)
                    && t.messages > 0
            })
            .map(|t| t.topic)
            .collect();
        let mut depth = Vec::new();
        for t in &images {
            let Some(first) = self.messages(t)?.into_iter().next() else {
                continue;
            };
            let named = t.to_ascii_lowercase().contains("depth");
            // `mono16` is depth only on a topic named for it (an infrared stream is not).
            let is_depth = match self.image_encoding(&first)?.as_deref() {
                Some("mono16") => named,
                Some(e) => DepthEncodingKind::of(e).is_some(),
                None => false,
            };
            if is_depth {
                depth.push(t.clone());
            }
        }
        match depth.len() {
            1 => Ok(depth.swap_remove(0)),
            0 => Err(IoError::malformed(
                &path,
                format!(
                    "no depth image topic (16UC1, 32FC1, or mono16 named for depth) among its \
                     image topics: {}",
                    if images.is_empty() {
                        "none".to_string()
                    } else {
                        images.join(", ")
                    }
                ),
            )),
            _ => Err(IoError::malformed(
                &path,
                format!(
                    "several depth image topics: {}; name one (--topic)",
                    depth.join(", ")
                ),
            )),
        }
    }

    /// The encoding of image message `m` (of a `compressedDepth` image, the encoding its format
    /// names; `None` for another compressed image).
    fn image_encoding(&mut self, m: &BagMessage) -> Result<Option<String>> {
        let path = self.path.clone();
        let (compressed, cdr) = (m.compressed, m.encoding);
        let b = self.message(m)?;
        if compressed {
            let c = messages::compressed_image(&path, b, cdr)?;
            return Ok(messages::compressed_depth_encoding(&c.format).map(str::to_string));
        }
        Ok(Some(messages::image(&path, b, cdr)?.encoding))
    }

    /// The `sensor_msgs/CameraInfo` topic beside the image topic `image_topic`
    /// (`/camera/depth/image` → `/camera/depth/camera_info`; a transport's topic
    /// `/camera/depth/image_raw/compressedDepth` → the same; a RealSense recording's
    /// `/device_0/sensor_0/Depth_0/image/data` → `/device_0/sensor_0/Depth_0/info/camera_info`),
    /// if the bag has it.
    pub fn camera_info_topic(&self, image_topic: &str) -> Option<String> {
        let ns = image_topic.rsplit_once('/').map_or("", |(ns, _)| ns);
        let parent = ns.rsplit_once('/').map_or("", |(p, _)| p);
        [
            format!("{ns}/camera_info"),
            format!("{parent}/camera_info"),
            format!("{parent}/info/camera_info"),
        ]
        .into_iter()
        .find(|t| self.message_type(t) == Some(CAMERA_INFO_TYPE))
    }
}

//! ROS 2 bags in MCAP (`.mcap`, what `ros2 bag record` writes since Iron): the summary section
//! (schemas, channels, chunk indexes) found from the footer, each chunk's message index records,
//! and the message records in a decompressed chunk. Every length is checked against the file or
//! the chunk before a buffer is sized from it.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use super::messages::Encoding;
use super::{ChunkInfo, Connection};
use crate::error::{IoError, Result};

/// The first and last bytes of an MCAP file.
pub(super) const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

mod op {
    pub(super) const FOOTER: u8 = 0x02;
    pub(super) const SCHEMA: u8 = 0x03;
    pub(super) const CHANNEL: u8 = 0x04;
    pub(super) const MESSAGE: u8 = 0x05;
    pub(super) const CHUNK: u8 = 0x06;
    pub(super) const MESSAGE_INDEX: u8 = 0x07;
    pub(super) const CHUNK_INDEX: u8 = 0x08;
}

/// Largest summary record read (a schema's text is the longest: a few kilobytes).
const MAX_SUMMARY_RECORD: u64 = 1 << 20;

/// Reads little-endian fields off a record's content, every read bounds-checked.
struct Content<'a> {
    path: &'a Path,
    b: &'a [u8],
    at: usize,
}

impl<'a> Content<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        let s = super::records::slice_at(self.b, self.at, n).ok_or_else(|| {
            IoError::malformed(
                self.path,
                format!("an MCAP record is cut off at its {what}"),
            )
        })?;
        self.at += n;
        Ok(s)
    }
    fn u16(&mut self, what: &str) -> Result<u16> {
        let b = self.take(2, what)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
    fn string(&mut self, what: &str) -> Result<String> {
        let n = self.u32(what)? as usize;
        Ok(String::from_utf8_lossy(self.take(n, what)?).into_owned())
    }
    /// A `u32`-byte-length-prefixed map or array, as its bytes.
    fn prefixed(&mut self, what: &str) -> Result<&'a [u8]> {
        let n = self.u32(what)? as usize;
        self.take(n, what)
    }
}

/// The opcode and content length of the record at `pos` (the reader left at its content).
fn read_head<R: Read + Seek>(path: &Path, r: &mut R, pos: u64) -> Result<(u8, u64)> {
    r.seek(SeekFrom::Start(pos))
        .map_err(|e| IoError::io(path, e))?;
    let mut head = [0u8; 9];
    r.read_exact(&mut head).map_err(|e| truncated(path, e))?;
    let mut len = [0u8; 8];
    len.copy_from_slice(&head[1..]);
    Ok((head[0], u64::from_le_bytes(len)))
}

/// Reads the record at `pos`: its opcode and content (at most `max` bytes).
fn read_record<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    file_len: u64,
    pos: u64,
    max: u64,
) -> Result<(u8, Vec<u8>)> {
    let (code, len) = read_head(path, r, pos)?;
    if len > max || pos + 9 + len > file_len {
        return Err(IoError::malformed(
            path,
            format!(
                "the MCAP record at byte {pos} claims {len} bytes, beyond the file's {file_len} \
                 or the {max}-byte limit of such a record"
            ),
        ));
    }
    let mut content = vec![0u8; len as usize];
    r.read_exact(&mut content).map_err(|e| truncated(path, e))?;
    Ok((code, content))
}

fn truncated(path: &Path, e: std::io::Error) -> IoError {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        IoError::malformed(path, "truncated: an MCAP record is cut off")
    } else {
        IoError::io(path, e)
    }
}

/// A schema name as ROS 1 spells it (`sensor_msgs/msg/Image` → `sensor_msgs/Image`).
fn ros1_name(name: &str) -> String {
    name.replacen("/msg/", "/", 1)
}

/// The channels and chunks of an MCAP file, from its summary section.
pub(super) fn read_summary<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    file_len: u64,
) -> Result<(Vec<Connection>, Vec<ChunkInfo>)> {
    // Footer: opcode, length 20, summary_start, summary_offset_start, summary_crc; then the magic.
    let footer_at = file_len
        .checked_sub(8 + 9 + 20)
        .ok_or_else(|| IoError::malformed(path, "an MCAP file too short for its footer"))?;
    r.seek(SeekFrom::Start(footer_at))
        .map_err(|e| IoError::io(path, e))?;
    let mut end = [0u8; 9 + 20 + 8];
    r.read_exact(&mut end).map_err(|e| truncated(path, e))?;
    let footer = &end[9..29];
    if end[0] != op::FOOTER || end[1..9] != 20u64.to_le_bytes() || &end[29..] != MAGIC {
        return Err(IoError::malformed(
            path,
            "an MCAP file without its footer (a recording that was not closed: `mcap recover` \
             writes one)",
        ));
    }
    let mut f = Content {
        path,
        b: footer,
        at: 0,
    };
    let summary_start = f.u64("summary_start")?;
    let summary_end = match f.u64("summary_offset_start")? {
        0 => footer_at,
        s => s,
    };
    if summary_start == 0 || summary_start > summary_end || summary_end > footer_at {
        return Err(IoError::malformed(
            path,
            "an MCAP file without a summary section (no index of its chunks: `mcap recover` \
             writes one)",
        ));
    }
    let mut schemas: Vec<(u16, String)> = Vec::new();
    let mut channels: Vec<(u16, u16, String, String)> = Vec::new();
    let mut chunk_offsets: Vec<(u64, Vec<(u16, u64)>)> = Vec::new();
    let mut pos = summary_start;
    while pos < summary_end {
        let (code, content) = read_record(path, r, file_len, pos, MAX_SUMMARY_RECORD)?;
        pos += 9 + content.len() as u64;
        let mut c = Content {
            path,
            b: &content,
            at: 0,
        };
        match code {
            op::SCHEMA => {
                let id = c.u16("schema id")?;
                let name = c.string("schema name")?;
                schemas.push((id, name));
            }
            op::CHANNEL => {
                let id = c.u16("channel id")?;
                let schema = c.u16("channel schema")?;
                let topic = c.string("channel topic")?;
                let encoding = c.string("channel message encoding")?;
                channels.push((id, schema, topic, encoding));
            }
            op::CHUNK_INDEX => {
                c.u64("message_start_time")?;
                c.u64("message_end_time")?;
                let chunk_at = c.u64("chunk_start_offset")?;
                c.u64("chunk_length")?;
                let map = c.prefixed("message_index_offsets")?;
                if map.len() % 10 != 0 {
                    return Err(IoError::malformed(
                        path,
                        format!("a chunk index's offsets map of {} bytes", map.len()),
                    ));
                }
                let offsets = map
                    .chunks_exact(10)
                    .map(|e| {
                        let mut a = [0u8; 8];
                        a.copy_from_slice(&e[2..]);
                        (u16::from_le_bytes([e[0], e[1]]), u64::from_le_bytes(a))
                    })
                    .collect();
                chunk_offsets.push((chunk_at, offsets));
            }
            _ => {}
        }
    }
    let connections = channels
        .into_iter()
        .map(|(id, schema, topic, encoding)| {
            let name = schemas
                .iter()
                .find(|(s, _)| *s == schema)
                .map(|(_, n)| ros1_name(n))
                .unwrap_or_default();
            Connection {
                id: u32::from(id),
                topic,
                message_type: name,
                encoding: if encoding == "ros1" {
                    Encoding::Ros1
                } else {
                    Encoding::Cdr
                },
            }
        })
        .collect();
    // Each channel's message count: its message index record's length (16 bytes an entry).
    let mut chunks = Vec::with_capacity(chunk_offsets.len());
    for (at, offsets) in chunk_offsets {
        let mut counts = Vec::with_capacity(offsets.len());
        let mut index_at = Vec::with_capacity(offsets.len());
        for (channel, off) in offsets {
            let (code, len) = read_head(path, r, off)?;
            if code != op::MESSAGE_INDEX || len < 6 || (len - 6) % 16 != 0 {
                return Err(IoError::malformed(
                    path,
                    format!("no message index record at byte {off}, where the summary says"),
                ));
            }
            let n = u32::try_from((len - 6) / 16).unwrap_or(u32::MAX);
            counts.push((u32::from(channel), n));
            index_at.push((u32::from(channel), off));
        }
        chunks.push(ChunkInfo {
            pos: at,
            counts,
            index_at,
        });
    }
    Ok((connections, chunks))
}

/// The `(log time, offset in the chunk's records)` of the messages listed by the message index
/// record at `at`.
pub(super) fn message_index<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    file_len: u64,
    at: u64,
    max_entries: usize,
) -> Result<Vec<(u64, u64)>> {
    let max = 6 + 16 * max_entries as u64;
    let (code, content) = read_record(path, r, file_len, at, max)?;
    if code != op::MESSAGE_INDEX {
        return Err(IoError::malformed(
            path,
            format!("no message index record at byte {at}"),
        ));
    }
    let mut c = Content {
        path,
        b: &content,
        at: 0,
    };
    c.u16("message index channel")?;
    let entries = c.prefixed("message index records")?;
    Ok(entries
        .chunks_exact(16)
        .map(|e| {
            let (mut t, mut o) = ([0u8; 8], [0u8; 8]);
            t.copy_from_slice(&e[..8]);
            o.copy_from_slice(&e[8..]);
            (u64::from_le_bytes(t), u64::from_le_bytes(o))
        })
        .collect())
}

/// The chunk at `pos`: its compression, uncompressed size and compressed records (the sizes
/// checked against `budget` before the records are read).
pub(super) fn read_chunk<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    file_len: u64,
    pos: u64,
    budget: u64,
) -> Result<(String, u64, Vec<u8>)> {
    r.seek(SeekFrom::Start(pos))
        .map_err(|e| IoError::io(path, e))?;
    let mut head = [0u8; 9 + 8 + 8 + 8 + 4 + 4];
    r.read_exact(&mut head).map_err(|e| truncated(path, e))?;
    if head[0] != op::CHUNK {
        return Err(IoError::malformed(
            path,
            format!("the summary points at byte {pos} for a chunk, which is none"),
        ));
    }
    let u64_at = |i: usize| {
        let mut a = [0u8; 8];
        a.copy_from_slice(&head[i..i + 8]);
        u64::from_le_bytes(a)
    };
    let size = u64_at(9 + 16);
    let name_len = u64::from(u32::from_le_bytes([head[37], head[38], head[39], head[40]]));
    if name_len > 64 {
        return Err(IoError::malformed(
            path,
            "a chunk's compression name of more than 64 bytes",
        ));
    }
    let mut name = vec![0u8; name_len as usize];
    r.read_exact(&mut name).map_err(|e| truncated(path, e))?;
    let mut len = [0u8; 8];
    r.read_exact(&mut len).map_err(|e| truncated(path, e))?;
    let records_len = u64::from_le_bytes(len);
    let records_at = pos + 41 + name_len + 8;
    if size > budget || records_len > budget || records_at + records_len > file_len {
        return Err(IoError::too_large(
            path,
            format!(
                "a chunk of {records_len} bytes ({size} decompressed) is beyond the file or the \
                 {budget}-byte budget of one decoded buffer (raise --max-memory)"
            ),
        ));
    }
    let mut records = vec![0u8; records_len as usize];
    r.read_exact(&mut records).map_err(|e| truncated(path, e))?;
    Ok((String::from_utf8_lossy(&name).into_owned(), size, records))
}

/// The data of the message record at `offset` of a chunk's decompressed `records`.
pub(super) fn message_in<'a>(path: &Path, records: &'a [u8], offset: u64) -> Result<&'a [u8]> {
    let at = usize::try_from(offset).unwrap_or(usize::MAX);
    let head = at
        .checked_add(9)
        .and_then(|end| records.get(at..end))
        .ok_or_else(|| IoError::malformed(path, "a message index points past its chunk"))?;
    let mut len = [0u8; 8];
    len.copy_from_slice(&head[1..]);
    let len = usize::try_from(u64::from_le_bytes(len)).unwrap_or(usize::MAX);
    if head[0] != op::MESSAGE || len < 22 {
        return Err(IoError::malformed(
            path,
            format!(
                "the message index points at offset {offset} of a chunk for a message, which is none"
            ),
        ));
    }
    at.checked_add(9 + 22)
        .zip(at.checked_add(9).and_then(|a| a.checked_add(len)))
        .and_then(|(from, to)| records.get(from..to))
        .ok_or_else(|| IoError::malformed(path, "a message record runs past its chunk"))
}

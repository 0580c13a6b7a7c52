//! The record layer of a ROS 1 bag (format 2.0): `<header length><header><data length><data>`,
//! a header being `<field length><name>=<value>` fields. Every length is checked against what
//! is left of the file or buffer before anything is allocated for it.

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::{IoError, Result};

/// The first line of a bag of format 2.0.
pub(super) const MAGIC: &[u8; 13] = b"#ROSBAG V2.0\n";

/// Record kinds (the header's `op` field).
pub(super) mod op {
    /// A message (`conn`, `time`; data: the serialised message).
    pub(crate) const MESSAGE: u8 = 0x02;
    /// The bag header (`index_pos`, `conn_count`, `chunk_count`).
    pub(crate) const BAG_HEADER: u8 = 0x03;
    /// Where the messages of one connection lie in the chunk before it.
    pub(crate) const INDEX_DATA: u8 = 0x04;
    /// A chunk of records (`compression`, `size`).
    pub(crate) const CHUNK: u8 = 0x05;
    /// A chunk's place and the connections in it.
    pub(crate) const CHUNK_INFO: u8 = 0x06;
    /// A connection: a topic and its message type.
    pub(crate) const CONNECTION: u8 = 0x07;
}

/// Largest record header read: a header holds a few short fields (a connection's topic is the
/// longest); a larger one is a corrupt length.
pub(super) const MAX_HEADER_BYTES: u32 = 1 << 20;

/// The fields of a record header, as name and value bytes.
#[derive(Debug, Default)]
pub(super) struct Header {
    fields: Vec<(String, Vec<u8>)>,
}

impl Header {
    /// Parses the header bytes `b` (errors name `path`).
    pub(super) fn parse(path: &Path, mut b: &[u8]) -> Result<Self> {
        let mut fields = Vec::new();
        while !b.is_empty() {
            let len = u32_at(path, b, 0, "a header field's length")? as usize;
            let Some(field) = b.get(4..4 + len) else {
                return Err(IoError::malformed(
                    path,
                    format!(
                        "a record header field of {len} bytes overruns its header ({} left)",
                        b.len() - 4
                    ),
                ));
            };
            let Some(eq) = field.iter().position(|&c| c == b'=') else {
                return Err(IoError::malformed(
                    path,
                    "a record header field without `=`",
                ));
            };
            let name = String::from_utf8_lossy(&field[..eq]).into_owned();
            fields.push((name, field[eq + 1..].to_vec()));
            b = &b[4 + len..];
        }
        Ok(Self { fields })
    }

    /// The value of field `name`, if present.
    pub(super) fn get(&self, name: &str) -> Option<&[u8]> {
        self.fields
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// The value of field `name`, which must be present.
    pub(super) fn field(&self, path: &Path, name: &str) -> Result<&[u8]> {
        self.get(name).ok_or_else(|| {
            IoError::malformed(path, format!("a record header has no `{name}` field"))
        })
    }

    /// The record kind.
    pub(super) fn op(&self, path: &Path) -> Result<u8> {
        match self.field(path, "op")? {
            [op] => Ok(*op),
            v => Err(IoError::malformed(
                path,
                format!("a record's `op` has {} bytes, not 1", v.len()),
            )),
        }
    }

    /// Field `name` as a little-endian `u32`.
    pub(super) fn u32(&self, path: &Path, name: &str) -> Result<u32> {
        let v = self.field(path, name)?;
        let b: [u8; 4] = v.try_into().map_err(|_| {
            IoError::malformed(path, format!("`{name}` has {} bytes, not 4", v.len()))
        })?;
        Ok(u32::from_le_bytes(b))
    }

    /// Field `name` as a little-endian `u64`.
    pub(super) fn u64(&self, path: &Path, name: &str) -> Result<u64> {
        let v = self.field(path, name)?;
        let b: [u8; 8] = v.try_into().map_err(|_| {
            IoError::malformed(path, format!("`{name}` has {} bytes, not 8", v.len()))
        })?;
        Ok(u64::from_le_bytes(b))
    }

    /// Field `name` as text.
    pub(super) fn text(&self, path: &Path, name: &str) -> Result<String> {
        Ok(String::from_utf8_lossy(self.field(path, name)?).into_owned())
    }
}

/// A ROS time (`secs`, `nsecs`, both little-endian `u32`) as seconds.
pub(super) fn time_s(secs: u32, nsecs: u32) -> f64 {
    f64::from(secs) + f64::from(nsecs) * 1e-9
}

/// The `n` bytes of `b` from `at`, if `b` holds them.
pub(super) fn slice_at(b: &[u8], at: usize, n: usize) -> Option<&[u8]> {
    at.checked_add(n).and_then(|end| b.get(at..end))
}

/// The little-endian `u32` at `at` in `b`, or an error saying what was expected there.
pub(super) fn u32_at(path: &Path, b: &[u8], at: usize, what: &str) -> Result<u32> {
    b.get(at..at + 4)
        .and_then(|s| <[u8; 4]>::try_from(s).ok())
        .map(u32::from_le_bytes)
        .ok_or_else(|| IoError::malformed(path, format!("truncated: {what} is cut off")))
}

/// A record read from the file: its header, and where its data lie (not read).
pub(super) struct FileRecord {
    pub(super) header: Header,
    /// File offset of the data.
    pub(super) data_pos: u64,
    /// Length of the data, bytes (within the file).
    pub(super) data_len: u32,
}

/// Reads the record at the reader's position: its header, leaving the reader after the data.
/// `file_len` bounds every length.
pub(super) fn read_record<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    file_len: u64,
) -> Result<FileRecord> {
    let at = r.stream_position().map_err(|e| IoError::io(path, e))?;
    let header_len = read_u32(path, r, "a record's header length")?;
    if header_len > MAX_HEADER_BYTES || u64::from(header_len) + at + 8 > file_len {
        return Err(IoError::malformed(
            path,
            format!(
                "the record at byte {at} claims a {header_len}-byte header, beyond the file's \
                 {file_len} bytes or the {MAX_HEADER_BYTES}-byte limit of a header"
            ),
        ));
    }
    let mut hb = vec![0u8; header_len as usize];
    r.read_exact(&mut hb).map_err(|e| IoError::io(path, e))?;
    let header = Header::parse(path, &hb)?;
    let data_len = read_u32(path, r, "a record's data length")?;
    let data_pos = at + 8 + u64::from(header_len);
    if data_pos + u64::from(data_len) > file_len {
        return Err(IoError::malformed(
            path,
            format!(
                "the record at byte {at} claims {data_len} bytes of data, beyond the file's \
                 {file_len} bytes (a bag cut short: `rosbag reindex` cannot mend a lost end)"
            ),
        ));
    }
    r.seek(SeekFrom::Start(data_pos + u64::from(data_len)))
        .map_err(|e| IoError::io(path, e))?;
    Ok(FileRecord {
        header,
        data_pos,
        data_len,
    })
}

/// Reads `len` bytes at `pos` (the caller checked them against the file and its budget).
pub(super) fn read_at<R: Read + Seek>(
    path: &Path,
    r: &mut R,
    pos: u64,
    len: u32,
) -> Result<Vec<u8>> {
    r.seek(SeekFrom::Start(pos))
        .map_err(|e| IoError::io(path, e))?;
    let mut b = vec![0u8; len as usize];
    r.read_exact(&mut b).map_err(|e| IoError::io(path, e))?;
    Ok(b)
}

fn read_u32<R: Read>(path: &Path, r: &mut R, what: &str) -> Result<u32> {
    let mut b = [0u8; 4];
    r.read_exact(&mut b).map_err(|e| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            IoError::malformed(path, format!("truncated: {what} is cut off"))
        } else {
            IoError::io(path, e)
        }
    })?;
    Ok(u32::from_le_bytes(b))
}

/// A record inside a decompressed chunk, at `at`: its header and data.
pub(super) fn record_in<'a>(
    path: &Path,
    b: &'a [u8],
    at: usize,
) -> Result<(Header, &'a [u8], usize)> {
    let header_len = u32_at(path, b, at, "a record's header length")? as usize;
    let hb = b.get(at + 4..at + 4 + header_len).ok_or_else(|| {
        IoError::malformed(path, "truncated: a record header runs past its chunk")
    })?;
    let header = Header::parse(path, hb)?;
    let data_at = at + 4 + header_len;
    let data_len = u32_at(path, b, data_at, "a record's data length")? as usize;
    let data = b
        .get(data_at + 4..data_at + 4 + data_len)
        .ok_or_else(|| IoError::malformed(path, "truncated: a record's data run past its chunk"))?;
    Ok((header, data, data_at + 4 + data_len))
}

//! A ROS 1 bag writer (format 2.0) for tests: records as the format's specification lays them
//! out (chunks of `none`, `bz2` or `lz4`, each followed by its index records; connections and
//! chunk infos at the end), and the two messages a depth recording needs. `sl-io` reads bags;
//! nothing in the product writes them.

use std::io::Write;
use std::path::Path;

/// One record: `<header length><header fields><data length><data>`.
fn record(fields: &[(&str, &[u8])], data: &[u8]) -> Vec<u8> {
    let mut h = Vec::new();
    for (name, value) in fields {
        h.extend_from_slice(&((name.len() + 1 + value.len()) as u32).to_le_bytes());
        h.extend_from_slice(name.as_bytes());
        h.push(b'=');
        h.extend_from_slice(value);
    }
    let mut r = Vec::new();
    r.extend_from_slice(&(h.len() as u32).to_le_bytes());
    r.extend_from_slice(&h);
    r.extend_from_slice(&(data.len() as u32).to_le_bytes());
    r.extend_from_slice(data);
    r
}

fn time(secs: u32, nsecs: u32) -> [u8; 8] {
    (u64::from(secs) | (u64::from(nsecs) << 32)).to_le_bytes()
}

/// A connection: id, topic, message type.
pub type Conn = (u32, &'static str, &'static str);

/// A message on a connection.
#[derive(Debug, Clone)]
pub struct Msg {
    /// Its connection.
    pub conn: u32,
    /// Record time: seconds, nanoseconds.
    pub time: (u32, u32),
    /// The serialised message.
    pub data: Vec<u8>,
}

fn compress(kind: &str, b: &[u8]) -> std::io::Result<Vec<u8>> {
    match kind {
        "none" => Ok(b.to_vec()),
        "bz2" => {
            let mut e = bzip2::write::BzEncoder::new(Vec::new(), bzip2::Compression::fast());
            e.write_all(b)?;
            e.finish()
        }
        "lz4" => {
            let mut e = lz4_flex::frame::FrameEncoder::new(Vec::new());
            e.write_all(b)?;
            e.finish().map_err(std::io::Error::other)
        }
        other => Err(std::io::Error::other(format!("compression {other:?}"))),
    }
}

/// Writes a bag of format 2.0: the messages in chunks of `per_chunk`, each chunk followed by
/// its index records, then the connections and chunk infos, the header pointing at them.
pub fn write_bag(
    path: &Path,
    conns: &[Conn],
    msgs: &[Msg],
    compression: &str,
    per_chunk: usize,
) -> std::io::Result<()> {
    let mut out = b"#ROSBAG V2.0\n".to_vec();
    let header_at = out.len();
    let mut chunk_infos = Vec::new();
    // The bag header, rewritten below with the index position; padded to 4096 bytes.
    let bag_header = |index_pos: u64, n_chunks: u32| {
        let fields: [(&str, &[u8]); 4] = [
            ("op", &[0x03]),
            ("index_pos", &index_pos.to_le_bytes()),
            ("conn_count", &(conns.len() as u32).to_le_bytes()),
            ("chunk_count", &n_chunks.to_le_bytes()),
        ];
        let bare = record(&fields, &[]);
        record(&fields, &vec![b' '; 4096 - bare.len()])
    };
    out.extend(bag_header(0, 0));
    let conn_data = |c: &Conn| {
        let mut d = Vec::new();
        for (n, v) in [
            ("topic", c.1),
            ("type", c.2),
            ("md5sum", "*"),
            ("message_definition", ""),
        ] {
            d.extend_from_slice(&((n.len() + 1 + v.len()) as u32).to_le_bytes());
            d.extend_from_slice(n.as_bytes());
            d.push(b'=');
            d.extend_from_slice(v.as_bytes());
        }
        d
    };
    for group in msgs.chunks(per_chunk) {
        let mut inner = Vec::new();
        let mut index: Vec<(u32, Vec<u8>)> = Vec::new();
        for c in conns {
            inner.extend(record(
                &[
                    ("op", &[0x07]),
                    ("conn", &c.0.to_le_bytes()),
                    ("topic", c.1.as_bytes()),
                ],
                &conn_data(c),
            ));
        }
        for m in group {
            let offset = inner.len() as u32;
            let t = time(m.time.0, m.time.1);
            inner.extend(record(
                &[
                    ("op", &[0x02]),
                    ("conn", &m.conn.to_le_bytes()),
                    ("time", &t),
                ],
                &m.data,
            ));
            let entry = match index.iter_mut().find(|(c, _)| *c == m.conn) {
                Some(e) => e,
                None => {
                    index.push((m.conn, Vec::new()));
                    let last = index.len() - 1;
                    &mut index[last]
                }
            };
            entry.1.extend_from_slice(&t);
            entry.1.extend_from_slice(&offset.to_le_bytes());
        }
        let chunk_pos = out.len() as u64;
        out.extend(record(
            &[
                ("op", &[0x05]),
                ("compression", compression.as_bytes()),
                ("size", &(inner.len() as u32).to_le_bytes()),
            ],
            &compress(compression, &inner)?,
        ));
        let mut counts = Vec::new();
        for (conn, entries) in &index {
            let n = (entries.len() / 12) as u32;
            out.extend(record(
                &[
                    ("op", &[0x04]),
                    ("ver", &1u32.to_le_bytes()),
                    ("conn", &conn.to_le_bytes()),
                    ("count", &n.to_le_bytes()),
                ],
                entries,
            ));
            counts.extend_from_slice(&conn.to_le_bytes());
            counts.extend_from_slice(&n.to_le_bytes());
        }
        let (first, last) = match (group.first(), group.last()) {
            (Some(f), Some(l)) => (f.time, l.time),
            _ => continue,
        };
        chunk_infos.push(record(
            &[
                ("op", &[0x06]),
                ("ver", &1u32.to_le_bytes()),
                ("chunk_pos", &chunk_pos.to_le_bytes()),
                ("start_time", &time(first.0, first.1)),
                ("end_time", &time(last.0, last.1)),
                ("count", &(index.len() as u32).to_le_bytes()),
            ],
            &counts,
        ));
    }
    let index_pos = out.len() as u64;
    for c in conns {
        out.extend(record(
            &[
                ("op", &[0x07]),
                ("conn", &c.0.to_le_bytes()),
                ("topic", c.1.as_bytes()),
            ],
            &conn_data(c),
        ));
    }
    for ci in &chunk_infos {
        out.extend_from_slice(ci);
    }
    let h = bag_header(index_pos, chunk_infos.len() as u32);
    out[header_at..header_at + h.len()].copy_from_slice(&h);
    std::fs::write(path, out)
}

fn string(b: &mut Vec<u8>, s: &str) {
    b.extend_from_slice(&(s.len() as u32).to_le_bytes());
    b.extend_from_slice(s.as_bytes());
}

fn header(b: &mut Vec<u8>, stamp: (u32, u32)) {
    b.extend_from_slice(&7u32.to_le_bytes());
    b.extend_from_slice(&stamp.0.to_le_bytes());
    b.extend_from_slice(&stamp.1.to_le_bytes());
    string(b, "camera_depth_optical_frame");
}

/// A `sensor_msgs/Image` of `w`×`h` pixels of `bpp` bytes, rows `pad` bytes longer than needed.
pub fn image(
    stamp: (u32, u32),
    w: u32,
    h: u32,
    encoding: &str,
    big: bool,
    pixels: &[u8],
    pad: u32,
) -> Vec<u8> {
    let bpp = pixels.len() as u32 / (w * h);
    let step = w * bpp + pad;
    let mut data = Vec::new();
    for row in pixels.chunks((w * bpp) as usize) {
        data.extend_from_slice(row);
        data.extend(std::iter::repeat_n(0xee, pad as usize));
    }
    let mut b = Vec::new();
    header(&mut b, stamp);
    b.extend_from_slice(&h.to_le_bytes());
    b.extend_from_slice(&w.to_le_bytes());
    string(&mut b, encoding);
    b.push(u8::from(big));
    b.extend_from_slice(&step.to_le_bytes());
    b.extend_from_slice(&(data.len() as u32).to_le_bytes());
    b.extend_from_slice(&data);
    b
}

/// A `sensor_msgs/CameraInfo` of a `w`×`h` pinhole camera with `fx = fy = f` and `d`.
pub fn camera_info(w: u32, h: u32, f: f64, model: &str, d: &[f64], binning: u32) -> Vec<u8> {
    let mut b = Vec::new();
    header(&mut b, (1, 0));
    b.extend_from_slice(&h.to_le_bytes());
    b.extend_from_slice(&w.to_le_bytes());
    string(&mut b, model);
    b.extend_from_slice(&(d.len() as u32).to_le_bytes());
    let (cx, cy) = (f64::from(w) / 2.0 - 0.5, f64::from(h) / 2.0 - 0.5);
    let k = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [f, 0.0, cx, 0.0, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    for v in d.iter().chain(&k).chain(&r).chain(&p) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&binning.to_le_bytes());
    b.extend_from_slice(&binning.to_le_bytes());
    for v in [0u32; 4] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.push(0);
    b
}

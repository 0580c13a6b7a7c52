//! ROS bag writers for tests: a ROS 1 bag (format 2.0) as the format's specification lays it
//! out (chunks of `none`, `bz2` or `lz4`, each followed by its index records; connections and
//! chunk infos at the end), an MCAP file as `ros2 bag record` writes one (chunks of none,
//! `zstd` or `lz4`, message indexes, the summary and footer), and the messages a depth
//! recording needs, in ROS 1 and in CDR. `sl-io` reads bags; nothing in the product writes them.

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
    let conn_record = |c: &Conn| {
        record(
            &[
                ("op", &[0x07]),
                ("conn", &c.0.to_le_bytes()),
                ("topic", c.1.as_bytes()),
            ],
            &conn_data(c),
        )
    };
    for group in msgs.chunks(per_chunk) {
        let mut inner = Vec::new();
        let mut index: Vec<(u32, Vec<u8>)> = Vec::new();
        for c in conns {
            inner.extend(conn_record(c));
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
        out.extend(conn_record(c));
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
    camera_info_tx(w, h, f, model, d, binning, 0.0)
}

/// As [`camera_info`], with `tx` in `P[3]` (`−f·B` for the right camera of a stereo pair).
pub fn camera_info_tx(
    w: u32,
    h: u32,
    f: f64,
    model: &str,
    d: &[f64],
    binning: u32,
    tx: f64,
) -> Vec<u8> {
    let mut b = Vec::new();
    header(&mut b, (1, 0));
    b.extend_from_slice(&h.to_le_bytes());
    b.extend_from_slice(&w.to_le_bytes());
    string(&mut b, model);
    b.extend_from_slice(&(d.len() as u32).to_le_bytes());
    let (cx, cy) = (f64::from(w) / 2.0 - 0.5, f64::from(h) / 2.0 - 0.5);
    let k = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
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

/// A CDR serialiser (little-endian encapsulation, primitives aligned from after its header).
struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Self {
        Self(vec![0, 1, 0, 0])
    }
    fn align(&mut self, n: usize) {
        while !(self.0.len() - 4).is_multiple_of(n) {
            self.0.push(0);
        }
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }
    fn header(&mut self, stamp: (u32, u32)) {
        self.u32(stamp.0);
        self.u32(stamp.1);
        self.string("camera_depth_optical_frame");
    }
}

/// A ROS 2 `sensor_msgs/msg/Image` in CDR (`w`×`h`, rows as `pixels` holds them).
pub fn image_cdr(stamp: (u32, u32), w: u32, h: u32, encoding: &str, pixels: &[u8]) -> Vec<u8> {
    let mut c = Cdr::new();
    c.header(stamp);
    c.u32(h);
    c.u32(w);
    c.string(encoding);
    c.0.push(0);
    c.u32(pixels.len() as u32 / h.max(1));
    c.u32(pixels.len() as u32);
    c.0.extend_from_slice(pixels);
    c.0
}

/// A ROS 2 `sensor_msgs/msg/CameraInfo` in CDR (a `w`×`h` pinhole camera, `fx = fy = f`).
pub fn camera_info_cdr(w: u32, h: u32, f: f64, model: &str, d: &[f64]) -> Vec<u8> {
    camera_info_cdr_tx(w, h, f, model, d, 0.0)
}

/// As [`camera_info_cdr`], with `tx` in `P[3]` (`−f·B` for the right camera of a stereo pair).
pub fn camera_info_cdr_tx(w: u32, h: u32, f: f64, model: &str, d: &[f64], tx: f64) -> Vec<u8> {
    let mut c = Cdr::new();
    c.header((1, 0));
    c.u32(h);
    c.u32(w);
    c.string(model);
    c.u32(d.len() as u32);
    for v in d {
        c.f64(*v);
    }
    let (cx, cy) = (f64::from(w) / 2.0 - 0.5, f64::from(h) / 2.0 - 0.5);
    let k = [f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0];
    let r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let p = [f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
    for v in k.iter().chain(&r).chain(&p) {
        c.f64(*v);
    }
    for v in [0u32; 6] {
        c.u32(v);
    }
    c.0.push(0);
    c.0
}

fn mcap_record(out: &mut Vec<u8>, op: u8, content: &[u8]) {
    out.push(op);
    out.extend_from_slice(&(content.len() as u64).to_le_bytes());
    out.extend_from_slice(content);
}

fn mcap_string(b: &mut Vec<u8>, s: &str) {
    b.extend_from_slice(&(s.len() as u32).to_le_bytes());
    b.extend_from_slice(s.as_bytes());
}

/// Writes an MCAP file as `ros2 bag record` does: the messages (CDR) in chunks of
/// `per_chunk`, compressed as `compression` (`""`, `"zstd"` or `"lz4"`), each followed by its
/// message index records; then the summary (schemas, channels, chunk indexes) and the footer.
/// `conns` name the ROS 2 types (`sensor_msgs/msg/Image`).
pub fn write_mcap(
    path: &Path,
    conns: &[Conn],
    msgs: &[Msg],
    compression: &str,
    per_chunk: usize,
) -> std::io::Result<()> {
    let mut out = b"\x89MCAP0\r\n".to_vec();
    let mut header = Vec::new();
    mcap_string(&mut header, "ros2");
    mcap_string(&mut header, "sl-testkit");
    mcap_record(&mut out, 0x01, &header);
    let mut chunk_indexes = Vec::new();
    for group in msgs.chunks(per_chunk.max(1)) {
        let mut records = Vec::new();
        let mut index: Vec<(u32, Vec<u8>)> = Vec::new();
        for (seq, m) in group.iter().enumerate() {
            let t = u64::from(m.time.0) * 1_000_000_000 + u64::from(m.time.1);
            let offset = records.len() as u64;
            let mut content = Vec::new();
            content.extend_from_slice(&(m.conn as u16).to_le_bytes());
            content.extend_from_slice(&(seq as u32).to_le_bytes());
            content.extend_from_slice(&t.to_le_bytes());
            content.extend_from_slice(&t.to_le_bytes());
            content.extend_from_slice(&m.data);
            mcap_record(&mut records, 0x05, &content);
            let entry = match index.iter().position(|(c, _)| *c == m.conn) {
                Some(i) => &mut index[i].1,
                None => {
                    index.push((m.conn, Vec::new()));
                    let last = index.len() - 1;
                    &mut index[last].1
                }
            };
            entry.extend_from_slice(&t.to_le_bytes());
            entry.extend_from_slice(&offset.to_le_bytes());
        }
        let compressed = match compression {
            "" => records.clone(),
            "zstd" => ruzstd::encoding::compress_to_vec(
                &records[..],
                ruzstd::encoding::CompressionLevel::Fastest,
            ),
            other => compress(other, &records)?,
        };
        let chunk_at = out.len() as u64;
        let mut chunk = Vec::new();
        chunk.extend_from_slice(&0u64.to_le_bytes());
        chunk.extend_from_slice(&u64::MAX.to_le_bytes());
        chunk.extend_from_slice(&(records.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&0u32.to_le_bytes());
        mcap_string(&mut chunk, compression);
        chunk.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
        chunk.extend_from_slice(&compressed);
        mcap_record(&mut out, 0x06, &chunk);
        let chunk_len = out.len() as u64 - chunk_at;
        let index_start = out.len() as u64;
        let mut offsets = Vec::new();
        for (conn, entries) in &index {
            offsets.extend_from_slice(&(*conn as u16).to_le_bytes());
            offsets.extend_from_slice(&(out.len() as u64).to_le_bytes());
            let mut content = (*conn as u16).to_le_bytes().to_vec();
            content.extend_from_slice(&(entries.len() as u32).to_le_bytes());
            content.extend_from_slice(entries);
            mcap_record(&mut out, 0x07, &content);
        }
        let mut ci = Vec::new();
        ci.extend_from_slice(&0u64.to_le_bytes());
        ci.extend_from_slice(&u64::MAX.to_le_bytes());
        ci.extend_from_slice(&chunk_at.to_le_bytes());
        ci.extend_from_slice(&chunk_len.to_le_bytes());
        ci.extend_from_slice(&(offsets.len() as u32).to_le_bytes());
        ci.extend_from_slice(&offsets);
        ci.extend_from_slice(&(out.len() as u64 - index_start).to_le_bytes());
        mcap_string(&mut ci, compression);
        ci.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
        ci.extend_from_slice(&(records.len() as u64).to_le_bytes());
        chunk_indexes.push(ci);
    }
    mcap_record(&mut out, 0x0F, &0u32.to_le_bytes());
    let summary_start = out.len() as u64;
    for (i, c) in conns.iter().enumerate() {
        let mut schema = ((i + 1) as u16).to_le_bytes().to_vec();
        mcap_string(&mut schema, c.2);
        mcap_string(&mut schema, "ros2msg");
        mcap_string(&mut schema, "");
        mcap_record(&mut out, 0x03, &schema);
        let mut channel = (c.0 as u16).to_le_bytes().to_vec();
        channel.extend_from_slice(&((i + 1) as u16).to_le_bytes());
        mcap_string(&mut channel, c.1);
        mcap_string(&mut channel, "cdr");
        channel.extend_from_slice(&0u32.to_le_bytes());
        mcap_record(&mut out, 0x04, &channel);
    }
    for ci in &chunk_indexes {
        mcap_record(&mut out, 0x08, ci);
    }
    let mut footer = summary_start.to_le_bytes().to_vec();
    footer.extend_from_slice(&0u64.to_le_bytes());
    footer.extend_from_slice(&0u32.to_le_bytes());
    mcap_record(&mut out, 0x02, &footer);
    out.extend_from_slice(b"\x89MCAP0\r\n");
    std::fs::write(path, out)
}

/// A `std_msgs/String` holding `text`, in CDR (`cdr`) or ROS 1.
pub fn string_msg(text: &str, cdr: bool) -> Vec<u8> {
    if cdr {
        let mut c = Cdr::new();
        c.string(text);
        return c.0;
    }
    let mut b = Vec::new();
    string(&mut b, text);
    b
}

/// A `std_msgs/Float32` holding `v`, in ROS 1.
pub fn float32_msg(v: f32) -> Vec<u8> {
    v.to_le_bytes().to_vec()
}

/// A `diagnostic_msgs/KeyValue`, in ROS 1.
pub fn key_value_msg(key: &str, value: &str) -> Vec<u8> {
    let mut b = Vec::new();
    string(&mut b, key);
    string(&mut b, value);
    b
}

/// A ROS 2 `sensor_msgs/msg/CompressedImage` in CDR: `format` and `data`.
pub fn compressed_image_cdr(stamp: (u32, u32), format: &str, data: &[u8]) -> Vec<u8> {
    let mut c = Cdr::new();
    c.header(stamp);
    c.string(format);
    c.u32(data.len() as u32);
    c.0.extend_from_slice(data);
    c.0
}

/// `values` as the `compressedDepth` plugin's RVL codec writes them (Wilson 2017): width and
/// height as little-endian `u32`, then little-endian 32-bit words of nibbles filled from the
/// most significant end; runs of zeros and of non-zero values alternate, each run's length a
/// number of 3-bit nibbles (least significant first, bit 3 = more follow), each non-zero
/// value its zig-zag coded difference from the previous one. Written from the format's
/// description, independently of sl-io's decoder.
pub fn rvl_encode(values: &sl_core::Image<u16>) -> Vec<u8> {
    let px = values.data();
    let mut nibbles: Vec<u8> = Vec::new();
    let mut put = |mut v: u64| {
        loop {
            let more = v >> 3 != 0;
            nibbles.push((v & 7) as u8 | if more { 8 } else { 0 });
            v >>= 3;
            if !more {
                break;
            }
        }
    };
    let (mut i, mut previous) = (0, 0i64);
    while i < px.len() {
        let zeros = px[i..].iter().take_while(|&&v| v == 0).count();
        put(zeros as u64);
        i += zeros;
        let run = px[i..].iter().take_while(|&&v| v != 0).count();
        put(run as u64);
        for &v in &px[i..i + run] {
            let d = i64::from(v) - previous;
            put(if d >= 0 { 2 * d } else { -2 * d - 1 } as u64);
            previous = i64::from(v);
        }
        i += run;
    }
    let mut out = (values.width() as u32).to_le_bytes().to_vec();
    out.extend_from_slice(&(values.height() as u32).to_le_bytes());
    for word in nibbles.chunks(8) {
        let w = (0..8).fold(0u32, |w, k| {
            (w << 4) | u32::from(word.get(k).copied().unwrap_or(0))
        });
        out.extend_from_slice(&w.to_le_bytes());
    }
    out
}

/// The data of `image_transport`'s `compressedDepth` with its RVL codec: the 12-byte
/// configuration header (format 0, depth quantisation `a`, `b`), then [`rvl_encode`].
pub fn compressed_depth_rvl_data(a: f32, b: f32, values: &sl_core::Image<u16>) -> Vec<u8> {
    let mut data = 0i32.to_le_bytes().to_vec();
    data.extend_from_slice(&a.to_le_bytes());
    data.extend_from_slice(&b.to_le_bytes());
    data.extend_from_slice(&rvl_encode(values));
    data
}

/// The data of `image_transport`'s `compressedDepth` for the 16-bit `values`: its 12-byte
/// configuration header (format 0, depth quantisation `a`, `b`), then the values as a 16-bit
/// PNG, written by sl-io through the file `scratch`.
pub fn compressed_depth_data(
    scratch: &Path,
    a: f32,
    b: f32,
    values: &sl_core::Image<u16>,
) -> std::io::Result<Vec<u8>> {
    let raw = sl_io::depth::RawDepth {
        values: values.clone(),
        encoding: sl_io::DepthEncoding::png(1000.0),
    };
    sl_io::depth::write_raw_depth(scratch, &raw).map_err(std::io::Error::other)?;
    let mut data = 0i32.to_le_bytes().to_vec();
    data.extend_from_slice(&a.to_le_bytes());
    data.extend_from_slice(&b.to_le_bytes());
    data.extend_from_slice(&std::fs::read(scratch)?);
    Ok(data)
}

/// One transform of a [`tf_message`]: the pose of `child` in `parent` at `stamp`
/// (translation, quaternion `x, y, z, w`).
#[derive(Debug, Clone)]
pub struct TfEntry {
    /// Seconds, nanoseconds.
    pub stamp: (u32, u32),
    /// The parent frame (`header.frame_id`).
    pub parent: String,
    /// The child frame (`child_frame_id`).
    pub child: String,
    /// Metres.
    pub translation: [f64; 3],
    /// `x, y, z, w`.
    pub rotation: [f64; 4],
}

/// A `tf2_msgs/TFMessage` of `entries`, in ROS 1 (`cdr` false) or CDR.
pub fn tf_message(entries: &[TfEntry], cdr: bool) -> Vec<u8> {
    if cdr {
        let mut c = Cdr::new();
        c.u32(entries.len() as u32);
        for e in entries {
            c.u32(e.stamp.0);
            c.u32(e.stamp.1);
            c.string(&e.parent);
            c.string(&e.child);
            for v in e.translation.iter().chain(&e.rotation) {
                c.f64(*v);
            }
        }
        return c.0;
    }
    let mut b = Vec::new();
    b.extend_from_slice(&(entries.len() as u32).to_le_bytes());
    for e in entries {
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&e.stamp.0.to_le_bytes());
        b.extend_from_slice(&e.stamp.1.to_le_bytes());
        string(&mut b, &e.parent);
        string(&mut b, &e.child);
        for v in e.translation.iter().chain(&e.rotation) {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

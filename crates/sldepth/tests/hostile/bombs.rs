//! Bombs: a PNG whose header promises a huge image, candidate blocks past the budget, endless
//! text inputs and line and frame counts past their caps.

use super::*;

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

struct Bits {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl Bits {
    fn put(&mut self, value: u64, bits: u32) {
        self.acc |= value << self.n;
        self.n += bits;
        while self.n >= 8 {
            self.out.push(self.acc as u8);
            self.acc >>= 8;
            self.n -= 8;
        }
    }
    /// A Huffman code, most significant bit first.
    fn code(&mut self, code: u32, bits: u32) {
        let rev = code.reverse_bits() >> (32 - bits);
        self.put(u64::from(rev), bits);
    }
}

/// zlib stream of `len` zero bytes: a literal 0, then copies of 258 bytes at distance 1.
fn zlib_zeros(len: u64) -> Vec<u8> {
    let mut b = Bits {
        out: vec![0x78, 0x01],
        acc: 0,
        n: 0,
    };
    b.put(1, 1); // final block
    b.put(1, 2); // fixed Huffman
    b.code(0x30, 8); // literal 0
    let mut left = len - 1;
    while left >= 258 + 3 || left == 258 {
        b.code(0b1100_0101, 8); // length code 285 = 258
        b.code(0, 5); // distance code 0 = 1
        left -= 258;
    }
    for _ in 0..left {
        b.code(0x30, 8);
    }
    b.code(0, 7); // end of block
    if b.n > 0 {
        b.put(0, 8 - b.n);
    }
    // Adler-32 of `len` zeros: a = 1, b = len (mod 65521).
    let adler = (((len % 65521) as u32) << 16) | 1;
    b.out.extend_from_slice(&adler.to_be_bytes());
    b.out
}

fn png_chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend_from_slice(&(data.len() as u32).to_be_bytes());
    let mut c = kind.to_vec();
    c.extend_from_slice(data);
    out.extend_from_slice(&c);
    out.extend_from_slice(&crc32(&c).to_be_bytes());
}

fn png_bomb(side: u32) -> Vec<u8> {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&[16, 0, 0, 0, 0]); // 16-bit grey
    png_chunk(&mut png, b"IHDR", &ihdr);
    let raw = u64::from(side) * (1 + 2 * u64::from(side));
    png_chunk(&mut png, b"IDAT", &zlib_zeros(raw));
    png_chunk(&mut png, b"IEND", &[]);
    png
}

#[test]
fn png_bomb_is_refused_from_its_header_by_every_reading_command() {
    let dir = tempfile::tempdir().unwrap();
    let bomb = dir.path().join("bomb.png");
    std::fs::write(&bomb, png_bomb(16384)).unwrap();
    let out = dir.path().join("out.ply");
    for args in [
        vec!["info", s(&bomb)],
        vec!["cloud", s(&bomb), "-o", s(&out)],
        vec!["filter", s(&bomb), s(&dir.path().join("f.png"))],
        vec!["planes", s(&bomb), "-o", s(&dir.path().join("l.png"))],
        vec!["analyze", s(&bomb)],
        vec!["motion", s(&bomb), s(&bomb)],
    ] {
        let o = run_bounded(&args);
        assert_typed_error(&o, &["bomb.png", "too large", "16384x16384"]);
    }
    assert_eq!(entries(dir.path()), vec!["bomb.png"]);
    // The same file is a valid PNG: with the limits raised past it, the header passes.
    let small = dir.path().join("small.png");
    std::fs::write(&small, png_bomb(64)).unwrap();
    let o = run(&[
        "info",
        s(&small),
        "--camera",
        s(&camera_json(dir.path(), 64, 64, 50.0)),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn fuse_counts_candidate_blocks_against_the_budget_as_they_are_found() {
    let dir = tempfile::tempdir().unwrap();
    let (list, cam) = small_sequence(dir.path());
    let mesh = dir.path().join("m.ply");
    let o = run_bounded(&[
        "fuse",
        "--frames",
        s(&list),
        "--camera",
        s(&cam),
        "--voxel-m",
        "0.0001",
        "--trunc-m",
        "1",
        "-o",
        s(&mesh),
    ]);
    assert_typed_error(&o, &["memory budget exceeded", "candidate voxel blocks"]);
    assert!(!mesh.exists());
    // Within the budget the same sequence fuses (with the former fixed 2 cm band: the default
    // sensor-adaptive band, up to 7.7 cm at 4 m, needs 14 159 blocks = 56 MiB here, over the
    // 21 MiB TSDF share of 64M), and a budget over the TSDF share is refused.
    let ok = run_bounded(&[
        "fuse",
        "--frames",
        s(&list),
        "--camera",
        s(&cam),
        "--trunc-m",
        "0.02",
        "-o",
        s(&mesh),
    ]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(mesh.exists());
    let o = run_bounded(&[
        "fuse",
        "--frames",
        s(&list),
        "--camera",
        s(&cam),
        "--memory-budget-bytes",
        "1073741824",
    ]);
    assert_typed_error(&o, &["--memory-budget-bytes", "raise --max-memory"]);
}

#[test]
fn text_inputs_are_counted_while_streaming_through_a_fifo() {
    let dir = tempfile::tempdir().unwrap();
    let (_, cam) = small_sequence(dir.path());
    let fifo = dir.path().join("frames.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("skipping: cannot create a FIFO here");
        return;
    }
    // A writer that would send 1 GiB in a single line; the reader must stop at its limit.
    let writer = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let Ok(mut f) = std::fs::OpenOptions::new().write(true).open(&fifo) else {
                return 0u64;
            };
            let chunk = vec![b'x'; 1 << 20];
            let mut sent = 0u64;
            while sent < 1 << 30 {
                if f.write_all(&chunk).is_err() {
                    break;
                }
                sent += chunk.len() as u64;
            }
            sent
        })
    };
    let o = run_bounded(&["fuse", "--frames", s(&fifo), "--camera", s(&cam)]);
    assert_typed_error(&o, &["frames.fifo", "too large", "bytes"]);
    let sent = writer.join().unwrap();
    assert!(sent < 1 << 30, "the reader consumed all {sent} bytes");
}

#[test]
fn text_line_and_frame_counts_are_capped() {
    let dir = tempfile::tempdir().unwrap();
    let (_, cam) = small_sequence(dir.path());
    let limits = sl_io::Limits::for_memory(BUDGET_BYTES);
    // More frames than the limit (each a valid line).
    let list = dir.path().join("many.txt");
    let line = "d.png 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n";
    std::fs::write(&list, line.repeat(limits.max_frames + 1)).unwrap();
    let o = run_bounded(&["fuse", "--frames", s(&list), "--camera", s(&cam)]);
    assert_typed_error(&o, &["many.txt", "too large", "frames"]);
    // A TUM sequence whose associations.txt has more lines than the limit.
    let tum = dir.path().join("tum");
    std::fs::create_dir(&tum).unwrap();
    std::fs::write(tum.join("groundtruth.txt"), "1.0 0 0 0 0 0 0 1\n").unwrap();
    std::fs::write(
        tum.join("associations.txt"),
        "#\n".repeat(limits.max_text_lines as usize + 1),
    )
    .unwrap();
    let o = run_bounded(&["fuse", "--tum", s(&tum), "--camera", s(&cam)]);
    assert_typed_error(&o, &["associations.txt", "too large", "lines"]);
}

/// A ROS bag whose one chunk holds a 4000×4000 16-bit depth image of zeros (32 MB; 1.6 KB as
/// bz2): refused from the chunk's header, beyond the 2 MiB decoded-bytes share of the 64 MiB
/// budget, by `track` (`info` lists the topic and says why it chose none); the same chunk with its header claiming 1000 bytes is
/// refused when the decompressor passes them, not after inflating all of it.
#[test]
fn bag_bombs_are_refused_within_the_budget() {
    use sl_testkit::rosbag_writer::{Msg, image, write_bag};
    let dir = tempfile::tempdir().unwrap();
    let bomb = dir.path().join("bomb.bag");
    let zeros = vec![0u8; 4000 * 4000 * 2];
    let msgs = vec![Msg {
        conn: 0,
        time: (1, 0),
        data: image((1, 0), 4000, 4000, "16UC1", false, &zeros, 0),
    }];
    let conns = [(0, "/camera/depth/image_raw", "sensor_msgs/Image")];
    write_bag(&bomb, &conns, &msgs, "bz2", 1).unwrap();
    assert!(std::fs::metadata(&bomb).unwrap().len() < 64 << 10);
    let o = run_bounded(&["track", s(&bomb), "--camera", "kinect-v1"]);
    assert_typed_error(&o, &["bomb.bag", "budget"]);
    let o = run_bounded(&["info", s(&bomb)]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("/camera/depth/image_raw  sensor_msgs/Image  1 messages")
            && stdout.contains("none chosen")
            && stdout.contains("budget"),
        "{stdout}"
    );
    // The header lies: 1000 bytes.
    let mut bytes = std::fs::read(&bomb).unwrap();
    let at = bytes.windows(5).position(|w| w == b"size=").unwrap() + 5;
    bytes[at..at + 4].copy_from_slice(&1000u32.to_le_bytes());
    let liar = dir.path().join("liar.bag");
    std::fs::write(&liar, bytes).unwrap();
    let o = run_bounded(&["track", s(&liar), "--camera", "kinect-v1"]);
    assert_typed_error(
        &o,
        &[
            "liar.bag",
            "decompresses to 1001+ bytes, its header says 1000",
        ],
    );
}

//! Fuzz-style robustness: random bytes, truncations and byte flips of valid files go into every
//! reader, which must return (usually `Err`), never panic or allocate by an unchecked header.

use std::path::Path;

use proptest::prelude::*;
use sl_core::{DepthImage, Image};
use sl_io::depth::DepthFormat;
use sl_io::ply::{PlyData, PlyFormat};
use sl_io::trajectory::{
    read_open3d_log, read_pose_txt, read_tum_associations, read_tum_trajectory,
};
use sl_io::{
    DepthEncoding, ReadConfig, read_camera_json, read_depth, read_intrinsics_txt, read_ply,
    read_rgb, write_depth, write_ply,
};

/// Runs every reader on `path`; returns how many succeeded.
fn run_all_readers(path: &Path) -> usize {
    let mut ok = 0;
    for f in DepthFormat::ALL {
        ok += usize::from(read_depth(path, &ReadConfig::default().with_format(f)).is_ok());
    }
    ok += usize::from(read_rgb(path).is_ok());
    ok += usize::from(read_camera_json(path).is_ok());
    ok += usize::from(read_intrinsics_txt(path, 640, 480).is_ok());
    ok += usize::from(read_ply(path).is_ok());
    ok += usize::from(read_tum_trajectory(path).is_ok());
    ok += usize::from(read_tum_associations(path).is_ok());
    ok += usize::from(read_open3d_log(path).is_ok());
    ok += usize::from(read_pose_txt(path).is_ok());
    ok
}

/// Valid files of each binary format, as bytes.
fn valid_files() -> Vec<(&'static str, Vec<u8>)> {
    let dir = tempfile::tempdir().unwrap();
    let depth = DepthImage::from_image(Image::from_fn(9, 7, |x, y| {
        if x == y {
            0.0
        } else {
            0.5 + 0.1 * (x + y) as f32
        }
    }));
    let mut out = Vec::new();
    for (name, enc) in [
        ("d.png", DepthEncoding::default()),
        ("d.tiff", DepthEncoding::tiff(1000.0)),
        ("f.tiff", DepthEncoding::tiff_f32(1.0)),
        ("d.pgm", DepthEncoding::nyu_raw()),
    ] {
        let p = dir.path().join(name);
        write_depth(&p, &depth, &enc).unwrap();
        out.push((name, std::fs::read(&p).unwrap()));
    }
    let mesh = PlyData::mesh(
        vec![
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 1.0],
        ],
        vec![[0, 1, 2], [1, 3, 2]],
    )
    .with_normals(vec![[0.0, 0.0, 1.0]; 4])
    .with_scalar("confidence", vec![0.5; 4]);
    for (name, fmt) in [
        ("m.ply", PlyFormat::BinaryLittleEndian),
        ("a.ply", PlyFormat::Ascii),
    ] {
        let p = dir.path().join(name);
        write_ply(&p, &mesh, fmt).unwrap();
        out.push((name, std::fs::read(&p).unwrap()));
    }
    out
}

#[test]
fn truncated_binary_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in valid_files() {
        let p = dir.path().join(name);
        // Every prefix that cuts into the data is an error for its own reader. (A PNG cut
        // inside its final, empty IEND chunk, or an ASCII PLY without its last newline, still
        // holds every value.)
        let slack = match name {
            "d.png" => 12,
            "a.ply" => 1,
            _ => 0,
        };
        let step = (bytes.len() / 60).max(1);
        for len in (0..bytes.len() - slack).step_by(step) {
            std::fs::write(&p, &bytes[..len]).unwrap();
            let r = match name {
                "m.ply" | "a.ply" => read_ply(&p).map(|_| ()),
                _ => read_depth(&p, &ReadConfig::default()).map(|_| ()),
            };
            let e = r.expect_err(&format!(
                "{name} truncated to {len} of {} bytes must be an error",
                bytes.len()
            ));
            assert!(e.to_string().contains(name), "{e}");
            run_all_readers(&p);
        }
    }
}

#[test]
fn oversized_headers_do_not_allocate() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.pgm");
    // 65536 x 65536 x 2 bytes = 8 GiB declared, 4 bytes present.
    std::fs::write(&p, b"P5 65536 65536 65535\n\x00\x00\x00\x00").unwrap();
    let e = read_depth(&p, &ReadConfig::default()).unwrap_err();
    assert!(e.to_string().contains("huge.pgm"), "{e}");
    // 4000 x 4000 (32 MB declared, within the default limits) but truncated: rejected before
    // allocating.
    std::fs::write(&p, b"P5 4000 4000 65535\n\x00\x00").unwrap();
    assert!(
        read_depth(&p, &ReadConfig::default())
            .unwrap_err()
            .to_string()
            .contains("truncated")
    );
    // A PNG whose IHDR claims 65536 x 65536: the decoder limits refuse it.
    let png = dir.path().join("huge.png");
    let mut bytes = b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR".to_vec();
    let ihdr = [0u8, 1, 0, 0, 0, 1, 0, 0, 16, 0, 0, 0, 0];
    bytes.extend_from_slice(&ihdr);
    let mut crc_input = b"IHDR".to_vec();
    crc_input.extend_from_slice(&ihdr);
    bytes.extend_from_slice(&crc32(&crc_input).to_be_bytes());
    std::fs::write(&png, &bytes).unwrap();
    assert!(read_depth(&png, &ReadConfig::default()).is_err());
    // A PLY declaring 10^9 binary vertices in a tiny file.
    let ply = dir.path().join("huge.ply");
    std::fs::write(
        &ply,
        "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
    )
    .unwrap();
    assert!(read_ply(&ply).unwrap_err().to_string().contains("huge.ply"));
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in data {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xedb8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Random bytes: no reader panics, and a binary image reader never accepts them.
    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("random.bin");
        std::fs::write(&p, &bytes).unwrap();
        run_all_readers(&p);
        for f in [DepthFormat::Png, DepthFormat::Tiff, DepthFormat::Sun] {
            prop_assert!(read_depth(&p, &ReadConfig::default().with_format(f)).is_err());
        }
    }

    /// Random bytes behind a plausible header (magic + sizes) still never panic.
    #[test]
    fn random_payload_behind_headers(which in 0usize..4, w in 0u32..70000, h in 0u32..70000,
                                      body in prop::collection::vec(any::<u8>(), 0..300)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.bin");
        let mut bytes = match which {
            0 => format!("P5 {w} {h} 65535\n").into_bytes(),
            1 => format!("P6\n{w} {h}\n255\n").into_bytes(),
            2 => format!("ply\nformat binary_little_endian 1.0\nelement vertex {w}\nproperty float x\nproperty float y\nproperty float z\nelement face {h}\nproperty list uchar int vertex_indices\nend_header\n").into_bytes(),
            _ => format!("ply\nformat ascii 1.0\nelement vertex {w}\nproperty float x\nproperty float y\nproperty float z\nend_header\n").into_bytes(),
        };
        bytes.extend_from_slice(&body);
        std::fs::write(&p, &bytes).unwrap();
        run_all_readers(&p);
    }

    /// Byte flips in valid files never panic any reader.
    #[test]
    fn flipped_bytes_never_panic(file in 0usize..6, flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8)) {
        let files = valid_files();
        let (name, mut bytes) = files[file].clone();
        for (i, b) in flips {
            let k = i.index(bytes.len());
            bytes[k] ^= b | 1;
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::write(&p, &bytes).unwrap();
        run_all_readers(&p);
    }

    /// Random text lines never panic the text readers.
    #[test]
    fn random_text_never_panics(lines in prop::collection::vec("[-0-9.e# a-z\t]{0,40}", 0..12)) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.txt");
        std::fs::write(&p, lines.join("\n")).unwrap();
        run_all_readers(&p);
    }
}

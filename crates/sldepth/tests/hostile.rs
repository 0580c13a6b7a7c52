//! The hostile-input suite (issue 15): generated bombs and malformed inputs through the
//! `sldepth` binary, each asserting a typed error (exit 1 with a message naming the problem),
//! never a panic (101) or an abort (134), and — where `prlimit` exists — peak memory within
//! the `--max-memory` budget plus [`CONSTANT_BYTES`]: the command runs with its address space
//! limited to that sum, so an allocation past it fails (and would abort the process).
//!
//! Every test here failed before the limits, the output checks and the range checks existed.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

mod common;
use common::{s, testdata};

/// The budget the bomb tests give `--max-memory`.
const BUDGET: &str = "64M";
const BUDGET_BYTES: u64 = 64 << 20;
/// What the program needs beyond its budget, in address space: code, thread stacks and
/// allocator arenas (measured: every command runs on 640x480 frames within 96 MiB of address
/// space in total; see docs/ARCHITECTURE.md, "Limits").
const CONSTANT_BYTES: u64 = 128 << 20;

/// The binary under test: this build's `sldepth`, or the one named by `SLDEPTH_HOSTILE_BIN`
/// (to show that an older build fails these tests; see docs/ARCHITECTURE.md, "Limits").
fn bin() -> String {
    std::env::var("SLDEPTH_HOSTILE_BIN").unwrap_or_else(|_| env!("CARGO_BIN_EXE_sldepth").into())
}

/// Whether the binary under test predates `--max-memory` (`SLDEPTH_HOSTILE_LEGACY=1`): the
/// bounded runs then give it the same inputs and address-space limit without the option.
fn legacy() -> bool {
    std::env::var_os("SLDEPTH_HOSTILE_LEGACY").is_some_and(|v| v == "1")
}

fn have_prlimit() -> bool {
    Command::new("prlimit")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `sldepth --max-memory BUDGET args` with its address space limited to the budget plus
/// the constant (without the limit, and saying so, where `prlimit` is missing).
fn run_bounded(args: &[&str]) -> Output {
    let mut full = if legacy() {
        vec![]
    } else {
        vec!["--max-memory", BUDGET]
    };
    full.extend_from_slice(args);
    let mut cmd = if have_prlimit() {
        let mut c = Command::new("prlimit");
        c.arg(format!("--as={}", BUDGET_BYTES + CONSTANT_BYTES))
            .arg("--")
            .arg(bin());
        c
    } else {
        eprintln!("note: no prlimit on this system: memory is not bounded in this run");
        Command::new(bin())
    };
    // No backtrace capture: symbolising one maps the binary's debug information, which is not
    // part of what the budget bounds. One malloc arena: glibc reserves 64 MiB of address space
    // for each extra arena it creates when threads contend, which depends on timing; under a
    // loaded CI machine that once failed a 512-byte allocation of a run well within its budget
    // (`fuse` of one 64×48 frame). Reserved address space is not memory the program uses.
    cmd.args(&full)
        .env("RUST_BACKTRACE", "0")
        .env("RUST_LIB_BACKTRACE", "0")
        .env("MALLOC_ARENA_MAX", "1")
        .output()
        .expect("sldepth runs")
}

fn run(args: &[&str]) -> Output {
    Command::new(bin())
        .args(args)
        .output()
        .expect("sldepth runs")
}

/// A clean, typed failure: exit code 1 (not 101 = panic, not 134 = abort on allocation
/// failure, not a signal) with a message containing every one of `needles`.
fn assert_typed_error(out: &Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_eq!(
        out.status.code(),
        Some(1),
        "status {:?}: {stderr}",
        out.status
    );
    for n in needles {
        assert!(stderr.contains(n), "expected {n:?} in: {stderr}");
    }
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

// ---------------------------------------------------------------------------------------------
// A real PNG bomb: 16384 x 16384 16-bit grey pixels, all zero, compressed with fixed-Huffman
// deflate copies of 258 bytes (about 3.4 MB on disk, 512 MiB decoded).

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

fn camera_json(dir: &Path, w: u64, h: u64, f: f64) -> PathBuf {
    let p = dir.join(format!("cam-{w}x{h}-{f:e}.json"));
    std::fs::write(
        &p,
        format!(
            r#"{{"width": {w}, "height": {h}, "intrinsic_matrix": [{f}, 0, 0, 0, {f}, 0, {}, {}, 1]}}"#,
            w as f64 / 2.0,
            h as f64 / 2.0
        ),
    )
    .unwrap();
    p
}

#[test]
fn huge_camera_is_refused_at_load_before_simulate_allocates() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim.png");
    for side in [65536, 16384] {
        let cam = camera_json(dir.path(), side, side, 500.0);
        let o = run_bounded(&[
            "simulate",
            "--scene",
            "floor",
            "--camera",
            s(&cam),
            "-o",
            s(&out),
        ]);
        assert_typed_error(&o, &["too large", &format!("{side}x{side}")]);
        assert!(!out.exists());
    }
}

#[test]
fn absurd_camera_numbers_are_refused_with_the_valid_range() {
    let dir = tempfile::tempdir().unwrap();
    let cam = camera_json(dir.path(), 640, 480, 1e308);
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&cam),
    ]);
    assert_typed_error(&o, &["fx", "must be in [1, 1e7] pixels"]);
}

/// A camera file that misspells a sensor key is refused by every command that reads it, naming
/// the key: `"baseline": 0.2` used to be ignored and the Kinect's 75 mm used without a word.
#[test]
fn a_misspelt_camera_sensor_key_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let cam = dir.path().join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [580, 0, 0, 0, 580, 0, 319.5, 239.5, 1], "baseline": 0.2}"#,
    )
    .unwrap();
    let depth = testdata("floor-seed1-depth.png");
    for cmd in ["info", "analyze", "noise-stats"] {
        let o = run(&[cmd, s(&depth), "--camera", s(&cam)]);
        assert_typed_error(
            &o,
            &["cam.json", "unknown key \"baseline\"", "`baseline_m`"],
        );
    }
}

/// A camera the prefilter cannot serve is named with its numbers compact: a 1e-300 m baseline
/// was printed as a 300-digit decimal.
#[test]
fn track_names_an_absurd_camera_compactly() {
    let dir = tempfile::tempdir().unwrap();
    let cam = dir.path().join("cam.json");
    std::fs::write(
        &cam,
        r#"{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 32, 24, 1], "baseline_m": 1e-300}"#,
    )
    .unwrap();
    let seq = dir.path().join("seq");
    std::fs::create_dir_all(seq.join("depth")).unwrap();
    let depth = sl_core::DepthImage::from_vec(64, 48, vec![1.5; 64 * 48]).unwrap();
    sl_io::write_depth(
        seq.join("depth/0.png"),
        &depth,
        &sl_io::DepthEncoding::default(),
    )
    .unwrap();
    let o = run(&["track", "--o3d", s(&seq), "--camera", s(&cam)]);
    assert_typed_error(&o, &["B = 1e-300 m", "--prefilter none skips it"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("0000000000"), "{stderr}");
}

/// A small frame (64x48 at 1.5 m) with its camera and a one-line frame list.
fn small_sequence(dir: &Path) -> (PathBuf, PathBuf) {
    let depth = sl_core::DepthImage::from_vec(64, 48, vec![1.5; 64 * 48]).unwrap();
    let png = dir.join("d.png");
    sl_io::write_depth(&png, &depth, &sl_io::DepthEncoding::default()).unwrap();
    let cam = camera_json(dir, 64, 48, 60.0);
    let list = dir.join("frames.txt");
    std::fs::write(&list, "d.png 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n").unwrap();
    (list, cam)
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

#[cfg(unix)]
#[test]
fn outputs_never_replace_links_fifos_or_directories() {
    let dir = tempfile::tempdir().unwrap();
    let input = testdata("floor-seed1-depth.png");
    let target = dir.path().join("target.png");
    std::fs::write(&target, b"keep").unwrap();
    let link = dir.path().join("link.png");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let sub = dir.path().join("sub.png");
    std::fs::create_dir(&sub).unwrap();
    let fifo = dir.path().join("fifo.png");
    let have_fifo = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    let mut outs = vec![(link.clone(), "symbolic link"), (sub.clone(), "directory")];
    if have_fifo {
        outs.push((fifo.clone(), "FIFO"));
    }
    for (out, what) in &outs {
        let o = run(&["filter", s(&input), s(out)]);
        assert_typed_error(&o, &["refusing to write", what]);
        let o = run(&["planes", s(&input), "-o", s(out)]);
        assert_typed_error(&o, &["refusing to write", what]);
    }
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"keep");
    assert!(sub.is_dir());
    if have_fifo {
        use std::os::unix::fs::FileTypeExt;
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
    }
    // No temporary file is left behind either.
    let left: Vec<String> = entries(dir.path())
        .into_iter()
        .filter(|n| n.contains("sldepth-tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn the_output_extension_decides_the_format_and_an_unknown_one_does_no_work() {
    let dir = tempfile::tempdir().unwrap();
    let input = testdata("floor-seed1-depth.png");
    let tif = dir.path().join("out.tif");
    let o = run(&["filter", s(&input), s(&tif)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&tif).unwrap();
    assert!(
        bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*"),
        "not a TIFF: {:?}",
        &bytes[..8.min(bytes.len())]
    );
    // It reads back as TIFF with the input's scale, and matches the PNG output.
    let png = dir.path().join("out.png");
    assert!(run(&["filter", s(&input), s(&png)]).status.success());
    let a = sl_io::read_depth(&tif, &sl_io::ReadConfig::default()).unwrap();
    let b = sl_io::read_depth(&png, &sl_io::ReadConfig::default()).unwrap();
    assert_eq!(a.depth, b.depth);
    for (cmd, out) in [
        (vec!["filter", s(&input)], dir.path().join("out.jpg")),
        (vec!["cloud", s(&input), "-o"], dir.path().join("cloud.xyz")),
        (vec!["planes", s(&input), "-o"], dir.path().join("labels")),
        (
            vec!["simulate", "--scene", "floor", "-o"],
            dir.path().join("sim.exr"),
        ),
    ] {
        let mut args = cmd.clone();
        args.push(s(&out));
        let o = run(&args);
        assert_typed_error(&o, &["unknown output format"]);
        assert!(!out.exists());
    }
}

#[test]
fn a_failing_argument_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (list, cam) = small_sequence(dir.path());
    let mesh = dir.path().join("m.ply");
    for (opt, value) in [
        ("--slice-m", "NaN"),
        ("--min-weight", "NaN"),
        ("--min-weight", "-1"),
        ("--depth-scale", "1e-300"),
    ] {
        let opt_value = format!("{opt}={value}");
        let o = run(&[
            "fuse",
            "--frames",
            s(&list),
            "--camera",
            s(&cam),
            "-o",
            s(&mesh),
            "--slice-png",
            s(&dir.path().join("slice.png")),
            &opt_value,
        ]);
        assert_typed_error(&o, &[opt, "must be"]);
        assert!(!mesh.exists(), "{opt} {value}: the mesh was written");
    }
    // A planes overlay whose colour image is missing: the label image is not written either.
    let labels = dir.path().join("labels.png");
    let o = run(&[
        "planes",
        s(&testdata("floor-seed1-depth.png")),
        "-o",
        s(&labels),
        "--overlay",
        s(&dir.path().join("ov.png")),
        "--color",
        s(&dir.path().join("missing.png")),
    ]);
    assert_typed_error(&o, &["missing.png"]);
    assert!(!labels.exists());
    // Two outputs naming one file (however spelled): refused before anything is written.
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let depth = sub.join("d.png");
    let same = dir.path().join("sub/../sub/d.png");
    let o = run(&[
        "simulate",
        "--scene",
        "floor",
        "-o",
        s(&depth),
        "--truth",
        s(&same),
    ]);
    assert_typed_error(&o, &["--output and --truth both name"]);
    assert!(!depth.exists());
    let o = run(&[
        "filter",
        s(&testdata("floor-seed1-depth.png")),
        s(&depth),
        "--normals",
        s(&depth),
    ]);
    assert_typed_error(&o, &["OUT and --normals both name"]);
    assert!(!depth.exists());
}

#[test]
fn meaningless_numbers_are_refused_with_their_range() {
    let input = testdata("floor-seed1-depth.png");
    // Outputs in a directory that exists (one that does not is refused first), never written:
    // every command below stops at its meaningless number.
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (l_png, x_png, f_png) = (out("l.png"), out("x.png"), out("f.png"));
    for (args, needles) in [
        (
            vec!["info", s(&input), "--depth-scale", "1e-300"],
            vec!["--depth-scale", "must be between 1 and 1e6"],
        ),
        (
            vec!["info", s(&input), "--depth-scale", "inf"],
            vec!["--depth-scale"],
        ),
        (
            vec!["planes", s(&input), "-o", &l_png, "--threshold-px", "NaN"],
            vec!["--threshold-px", "must be a number from"],
        ),
        (
            vec!["motion", s(&input), s(&input), "--threshold-px=-3"],
            vec!["--threshold-px"],
        ),
        (
            vec![
                "simulate",
                "--scene",
                "floor",
                "-o",
                &x_png,
                "--depth-scale",
                "NaN",
            ],
            vec!["--depth-scale"],
        ),
        (
            vec!["filter", s(&input), &f_png, "--repeat", "1000000000"],
            vec!["--repeat"],
        ),
        (
            vec!["--max-memory", "lots", "cameras"],
            vec!["--max-memory"],
        ),
    ] {
        let o = run(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "{args:?} wrote an output"
        );
        assert!(
            matches!(o.status.code(), Some(1) | Some(2)),
            "{args:?}: {:?} {stderr}",
            o.status
        );
        for n in needles {
            assert!(stderr.contains(n), "{args:?}: expected {n:?} in {stderr}");
        }
    }
}

/// A number far out of range is printed as it was meant, `1e300` (or `-1e300`, `1e-300`), not as
/// a 301-digit decimal, in every range error of the command line; the valid range alike.
#[test]
fn absurd_numbers_are_printed_compactly_in_range_errors() {
    let input = testdata("floor-seed1-depth.png");
    let dir = tempfile::tempdir().unwrap();
    let out = |name: &str| dir.path().join(name).to_string_lossy().into_owned();
    let (l_png, x_png, m_ply) = (out("l.png"), out("x.png"), out("m.ply"));
    let missing = dir.path().join("no-such-sequence");
    let simulate = |extra: &[&'static str]| {
        let mut v = vec!["simulate", "--scene", "floor", "-o", x_png.as_str()];
        v.extend_from_slice(extra);
        v
    };
    for (args, needles) in [
        (
            vec!["info", s(&input), "--depth-scale", "1e300"],
            vec!["--depth-scale 1e300: must be between 1 and 1e6"],
        ),
        (
            vec!["planes", s(&input), "-o", &l_png, "--threshold-px", "1e300"],
            vec!["--threshold-px 1e300: must be a number from 1e-6 to 1000"],
        ),
        (
            vec!["motion", s(&input), s(&input), "--threshold-px", "1e-300"],
            vec!["--threshold-px 1e-300: must be a number from 1e-6 to 1000"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--slice-m=-1e300",
            ],
            vec!["--slice-m -1e300: must be a number from -1e6 to 1e6"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--voxel-m",
                "1e300",
            ],
            vec!["--voxel-m 1e300: must be a number from 0.0001 to 1"],
        ),
        (
            vec![
                "fuse",
                "--7scenes",
                s(&missing),
                "-o",
                &m_ply,
                "--trunc-m",
                "1e300",
            ],
            vec!["--trunc-m 1e300: must be a number from 0.0001 to 10"],
        ),
        (
            vec!["track", "--7scenes", s(&missing), "--model-scale", "1e300"],
            vec!["--model-scale 1e300: must be a number from 0.001 to 1"],
        ),
        (
            vec!["track", "--7scenes", s(&missing), "--voxel-m", "1e-300"],
            vec!["--voxel-m 1e-300: must be a number from 0.0001 to 1"],
        ),
        (
            simulate(&["--sigma-d-px", "1e300"]),
            vec!["--sigma-d-px 1e300: must be a number from 0 to 100"],
        ),
        (
            simulate(&["--min-return=-1e300"]),
            vec!["--min-return -1e300: must be a finite number >= 0"],
        ),
        (
            simulate(&["--min-return", "0.04", "--reflectance", "1=1e300"]),
            vec![
                "--reflectance 1=1e300",
                "reflectance 1e300 of surface 1 must be in [0, 1]",
            ],
        ),
    ] {
        let o = run(&args);
        assert_typed_error(&o, &needles);
        let stderr = String::from_utf8_lossy(&o.stderr);
        let longest_digits = stderr
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(longest_digits < 20, "{args:?}: {stderr}");
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "{args:?} wrote an output"
        );
    }
}

#[test]
fn stale_temporary_files_of_killed_runs_are_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cloud.ply");
    // Left by a process that no longer runs (no PID can be 4294967295).
    let stale = dir.path().join(".cloud.ply.sldepth-tmp.4294967295.3");
    std::fs::write(&stale, vec![0u8; 4096]).unwrap();
    let o = run(&[
        "cloud",
        s(&testdata("floor-seed1-depth.png")),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!stale.exists());
    assert_eq!(entries(dir.path()), vec!["cloud.ply"]);
}

#[cfg(unix)]
#[test]
fn sigterm_and_sigint_during_a_write_remove_the_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    // A 2048x1536 frame: its ASCII cloud takes long enough to write to catch it mid-way.
    let (w, h) = (2048usize, 1536usize);
    let depth = sl_core::DepthImage::from_vec(w, h, vec![1.25; w * h]).unwrap();
    let png = dir.path().join("big.png");
    sl_io::write_depth(&png, &depth, &sl_io::DepthEncoding::default()).unwrap();
    let cam = camera_json(dir.path(), w as u64, h as u64, 1500.0);
    // Any entry beyond these is a temporary file, whatever its naming scheme.
    let before = entries(dir.path());
    let extra = |dir: &Path| -> Vec<String> {
        entries(dir)
            .into_iter()
            .filter(|n| !before.contains(n) && n != "cloud.ply")
            .collect()
    };
    let mut interrupted = 0;
    for signal in ["TERM", "INT"] {
        let out = dir.path().join("cloud.ply");
        let mut child = Command::new(bin())
            .args([
                "cloud",
                s(&png),
                "--camera",
                s(&cam),
                "--ascii",
                "-o",
                s(&out),
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait for the temporary file to appear, then interrupt.
        let start = std::time::Instant::now();
        let mut seen = false;
        while start.elapsed().as_secs() < 60 {
            if !extra(dir.path()).is_empty() {
                seen = true;
                break;
            }
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        if !seen {
            let _ = child.kill();
            let _ = child.wait();
            eprintln!("skipping SIG{signal}: the write finished before it could be interrupted");
            let _ = std::fs::remove_file(&out);
            continue;
        }
        let killed = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status()
            .unwrap();
        assert!(killed.success());
        let status = child.wait().unwrap();
        let left = extra(dir.path());
        if status.success() {
            // The write won the race; the temp was renamed into place.
            let _ = std::fs::remove_file(&out);
        } else {
            let code = if signal == "TERM" { 143 } else { 130 };
            assert_eq!(status.code(), Some(code), "SIG{signal}: {status:?}");
            assert!(!out.exists(), "SIG{signal}: a partial destination");
        }
        assert!(left.is_empty(), "SIG{signal} left {left:?}");
        interrupted += 1;
    }
    if interrupted == 0 {
        eprintln!("note: no write could be interrupted on this machine; nothing was checked");
    }
}

#[test]
fn a_closed_or_full_stderr_is_not_a_panic() {
    // Closed stderr: the error cannot be told, but the exit code still says it failed.
    let mut child = Command::new(bin())
        .args(["info", "/nonexistent/depth.png"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(1), "{status:?}");
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("skipping the full-stderr case: no /dev/full on this system");
        return;
    };
    // Full stderr, on an error and on a success that reports to stderr.
    let o = Command::new(bin())
        .args(["info", "/nonexistent/depth.png"])
        .stderr(full.try_clone().unwrap())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{:?}", o.status);
    let dir = tempfile::tempdir().unwrap();
    let o = Command::new(bin())
        .args([
            "cloud",
            s(&testdata("floor-seed1-depth.png")),
            "-o",
            s(&dir.path().join("c.ply")),
        ])
        .stderr(full)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{:?}", o.status);
}

/// An output that is the input under its own name or a hard link is refused, and the input
/// stays as it was (written atomically, it was replaced).
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in.png");
    std::fs::copy(testdata("floor-seed1-depth.png"), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let link = dir.path().join("link.png");
    std::fs::hard_link(&input, &link).unwrap();
    for out in [&input, &link] {
        let o = run(&["filter", s(&input), s(out)]);
        assert_typed_error(&o, &["is an input of this command"]);
    }
    let o = run(&["planes", s(&input), "-o", s(&link)]);
    assert_typed_error(&o, &["is an input of this command"]);
    assert_eq!(std::fs::read(&input).unwrap(), before);
}

/// A camera file that is a directory is an error, not a silent fall-back to the default
/// camera; a focal length below one pixel, a sub-pixel count beyond any matcher's and an
/// absurd trajectory position are refused with their range.
#[test]
fn a_camera_that_is_no_file_and_absurd_sensor_numbers_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // Its frame `d.png` (64x48 at 1.5 m).
    small_sequence(dir.path());
    let log_dir = dir.path().join("o3d");
    std::fs::create_dir_all(log_dir.join("camera.json")).unwrap();
    std::fs::create_dir_all(log_dir.join("depth")).unwrap();
    std::fs::copy(dir.path().join("d.png"), log_dir.join("depth/0.png")).unwrap();
    std::fs::write(
        log_dir.join("traj.log"),
        "0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )
    .unwrap();
    let mesh = dir.path().join("m.ply");
    let o = run(&[
        "fuse",
        "--o3d-log",
        s(&log_dir.join("traj.log")),
        "--depth-dir",
        s(&log_dir.join("depth")),
        "-o",
        s(&mesh),
    ]);
    assert_typed_error(&o, &["camera.json", "not a regular file"]);
    assert!(!mesh.exists());
    // A folder named like a preset does not hide the preset.
    std::fs::create_dir(dir.path().join("kinect-v1")).unwrap();
    let o = Command::new(bin())
        .current_dir(dir.path())
        .args([
            "info",
            s(&testdata("floor-seed1-depth.png")),
            "--camera",
            "kinect-v1",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tiny = camera_json(dir.path(), 640, 480, 1e-300);
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&tiny),
    ]);
    assert_typed_error(&o, &["fx", "must be in [1, 1e7] pixels"]);
    let q = dir.path().join("q.json");
    std::fs::write(
        &q,
        r#"{"width": 640, "height": 480, "intrinsic_matrix": [525, 0, 0, 0, 525, 0, 320, 240, 1], "subpixel": 4294967295}"#,
    )
    .unwrap();
    let o = run(&[
        "info",
        s(&testdata("floor-seed1-depth.png")),
        "--camera",
        s(&q),
    ]);
    assert_typed_error(&o, &["sub-pixel steps", "1..=256"]);
    let far = dir.path().join("far.txt");
    let near = dir.path().join("near.txt");
    let pose = |t: f64, x: f64| format!("{t} {x} 0 0 0 0 0 1\n");
    std::fs::write(
        &far,
        pose(1.0, 1e200) + &pose(2.0, 2e200) + &pose(3.0, 3e200),
    )
    .unwrap();
    std::fs::write(&near, pose(1.0, 0.0) + &pose(2.0, 0.1) + &pose(3.0, 0.2)).unwrap();
    let o = run(&["eval-traj", s(&far), s(&near)]);
    assert_typed_error(&o, &["from the origin", "beyond 1e9 m"]);
}

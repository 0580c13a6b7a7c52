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

#[path = "../common/mod.rs"]
mod common;
use common::{s, testdata};

mod bombs;
mod cameras;
mod numbers;
mod outputs;

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

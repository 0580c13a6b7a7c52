//! A mutation fuzzer on the stable toolchain, for machines without cargo-fuzz (no nightly, or
//! no network to install it): each target's committed seeds (`fuzz/corpus/<target>/`) are
//! mutated at random — bit flips, bytes set to boundary values, insertions, deletions,
//! truncation, splices of two seeds — and run through the target body under `catch_unwind`.
//! Seeded and deterministic; no coverage feedback, so it finds less than libFuzzer per
//! execution, but it exercises every target on any machine.
//!
//! ```sh
//! cargo run --release -p sl-fuzz --example mutate -- [TARGET|all] [EXECUTIONS] [SEED]
//! ```
//!
//! A panicking input is written to `target/fuzz-mutate/<target>/crash-<n>` and counted; the
//! slowest input of each target is written as `slowest` (a hang shows up there). Exit status 1
//! when any input panicked.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Longest mutated input, bytes (the readers' `-max_len` of docs/FUZZING.md).
const MAX_LEN: usize = 4096;

/// xorshift64*: a tiny deterministic generator (no dependency).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            0
        } else {
            (self.next() % n as u64) as usize
        }
    }
}

/// Byte values at the edges of the encodings the targets decode.
const INTERESTING: [u8; 8] = [0, 1, 0x7f, 0x80, 0xfe, 0xff, b'\n', b' '];

fn mutate(rng: &mut Rng, seeds: &[Vec<u8>], out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&seeds[rng.below(seeds.len())]);
    for _ in 0..1 + rng.below(8) {
        let len = out.len();
        match rng.below(7) {
            0 if len > 0 => {
                let i = rng.below(len);
                out[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                out[i] = INTERESTING[rng.below(INTERESTING.len())];
            }
            2 if len > 0 => {
                let i = rng.below(len);
                out[i] = rng.next() as u8;
            }
            3 if len < MAX_LEN => {
                let i = rng.below(len + 1);
                let n = 1 + rng.below(16);
                for _ in 0..n {
                    out.insert(i, rng.next() as u8);
                }
            }
            4 if len > 1 => {
                let i = rng.below(len);
                let n = (1 + rng.below(16)).min(len - i);
                out.drain(i..i + n);
            }
            5 if len > 0 => out.truncate(rng.below(len)),
            6 => {
                let other = &seeds[rng.below(seeds.len())];
                let cut = rng.below(out.len() + 1);
                let from = rng.below(other.len() + 1);
                out.truncate(cut);
                out.extend_from_slice(&other[from..]);
            }
            _ => {}
        }
    }
    out.truncate(MAX_LEN);
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let which = args.first().map_or("all", String::as_str);
    let executions: usize = args
        .get(1)
        .map_or(10_000, |s| s.parse().expect("EXECUTIONS"));
    let seed: u64 = args.get(2).map_or(1, |s| s.parse().expect("SEED"));
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus");
    let crashes = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/fuzz-mutate");
    // Panics are counted, not printed one by one.
    std::panic::set_hook(Box::new(|_| {}));
    let mut any = false;
    for (name, target) in sl_fuzz::TARGETS {
        if which != "all" && which != *name {
            continue;
        }
        let mut seeds: Vec<Vec<u8>> = std::fs::read_dir(root.join(name))
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .filter_map(|e| std::fs::read(e.path()).ok())
                    .collect()
            })
            .unwrap_or_default();
        seeds.sort();
        if seeds.is_empty() {
            seeds.push(Vec::new());
        }
        let mut rng = Rng(seed ^ 0x9E37_79B9_7F4A_7C15 ^ name.len() as u64);
        let mut input = Vec::new();
        let (mut panics, mut slowest) = (0usize, (Duration::ZERO, Vec::new()));
        let dir = crashes.join(name);
        let t0 = Instant::now();
        for _ in 0..executions {
            mutate(&mut rng, &seeds, &mut input);
            let t = Instant::now();
            let r = std::panic::catch_unwind(|| target(&input));
            let dt = t.elapsed();
            if dt > slowest.0 {
                slowest = (dt, input.clone());
            }
            if let Err(payload) = r {
                let msg = payload
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| payload.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                std::fs::create_dir_all(&dir).unwrap();
                let path = dir.join(format!("crash-{panics}"));
                std::fs::write(&path, &input).unwrap();
                if panics < 5 {
                    eprintln!("{name}: panic: {msg} ({})", path.display());
                }
                panics += 1;
            }
        }
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("slowest"), &slowest.1).unwrap();
        let secs = t0.elapsed().as_secs_f64();
        println!(
            "{name}: {executions} executions, {:.0}/s, {panics} panics, slowest {:.1} ms",
            executions as f64 / secs.max(1e-9),
            slowest.0.as_secs_f64() * 1e3
        );
        any |= panics > 0;
    }
    std::process::exit(i32::from(any));
}

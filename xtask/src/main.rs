//! Project automation for the sldepth workspace.
//!
//! - `cargo xtask validate` reproduces the paper's experiments on the real data in
//!   `../shared/data` (or `--data DIR`; simulated frames when absent), writes
//!   `target/validate/REPORT.md` with plots, prints a table, and exits non-zero on a regression.
//! - `cargo xtask gen-testdata` regenerates the seeded synthetic frames in `testdata/`
//!   (`--check` verifies the committed files instead of writing them).

mod testdata;
mod tidy;
mod validate;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "sldepth project automation")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Reproduce the paper's experiments and write target/validate/REPORT.md.
    Validate(validate::Args),
    /// Check the architecture invariants of docs/ARCHITECTURE.md (also run by `cargo test`).
    Tidy,
    /// Regenerate the seeded synthetic frames in testdata/ (or verify them with --check; the
    /// check also runs in `cargo test`).
    GenTestdata {
        /// Verify that the committed files equal freshly generated ones; write nothing.
        #[arg(long)]
        check: bool,
        /// Output directory (default: testdata/ at the workspace root).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Validate(args) => validate::main(args),
        Command::Tidy => tidy::run(&workspace_root()),
        Command::GenTestdata { check, out } => {
            let dir = out.unwrap_or_else(|| workspace_root().join("testdata"));
            testdata::run(&dir, check)
        }
    }
}

/// The workspace root (the parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    manifest.parent().map(PathBuf::from).unwrap_or(manifest)
}

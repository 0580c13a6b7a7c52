//! `cargo xtask validate`: every experiment of the paper, one module each, sharing a
//! [`Context`] that collects report sections, a table of numbers and pass/fail checks.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, Result, bail};
use serde::Serialize;

mod filter;
mod noise;
mod planes;
mod realism;
mod track;
mod tsdf;
mod tsdf_trunc;

/// One experiment: a name (for `--only`) and its entry point.
type Experiment = (&'static str, fn(&mut Context) -> Result<()>);

/// Every experiment, in report order.
const EXPERIMENTS: &[Experiment] = &[
    ("noise", noise::run),
    ("tsdf", tsdf::run),
    ("filter", filter::run),
    ("planes", planes::run),
    ("realism", realism::run),
    ("track", track::run),
];

/// Options of `cargo xtask validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory with the real frames (default: ../shared/data beside the workspace).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Behave as on a machine without the real data (simulated frames only).
    #[arg(long, conflicts_with = "data")]
    no_data: bool,
    /// Output directory for REPORT.md, results.json and images (default: target/validate).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print the results as JSON on standard output instead of a table.
    #[arg(long)]
    json: bool,
    /// Fewer frames and smaller sweeps (for CI smoke runs).
    #[arg(long)]
    quick: bool,
    /// Run only these experiments (repeatable), e.g. `--only noise`.
    #[arg(long, value_name = "NAME")]
    only: Vec<String>,
}

/// A number in the results table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Experiment that produced it.
    pub experiment: String,
    /// What was measured.
    pub metric: String,
    /// The value.
    pub value: f64,
    /// Its unit ("" when dimensionless).
    pub unit: String,
}

/// A pass/fail check; any failure makes `validate` exit non-zero.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What was checked.
    pub name: String,
    /// Whether it held.
    pub ok: bool,
    /// The measured values behind the verdict.
    pub detail: String,
}

/// What experiments see: where the data is, where to write, and where results go.
#[derive(Debug)]
pub struct Context {
    data_dir: Option<PathBuf>,
    out_dir: PathBuf,
    quick: bool,
    current: String,
    sections: Vec<(String, String)>,
    rows: Vec<Row>,
    checks: Vec<Check>,
}

impl Context {
    /// The real data directory, or `None` when it is absent (experiments then use simulated
    /// frames and say so).
    pub fn data_dir(&self) -> Option<&Path> {
        self.data_dir.as_deref()
    }

    /// Directory for images and plots; paths inside it can be linked from sections relatively.
    pub fn out_dir(&self) -> &Path {
        &self.out_dir
    }

    /// Whether `--quick` was given.
    pub fn quick(&self) -> bool {
        self.quick
    }

    /// Adds a Markdown section to REPORT.md.
    pub fn section(&mut self, title: impl Into<String>, markdown: impl Into<String>) {
        self.sections.push((title.into(), markdown.into()));
    }

    /// Adds a number to the results table.
    pub fn row(&mut self, experiment: &str, metric: &str, value: f64, unit: &str) {
        self.rows.push(Row {
            experiment: experiment.into(),
            metric: metric.into(),
            value,
            unit: unit.into(),
        });
    }

    /// Records a check; a failed one makes the run exit non-zero.
    pub fn check(&mut self, name: impl Into<String>, ok: bool, detail: impl Into<String>) {
        self.checks.push(Check {
            name: format!("{}: {}", self.current, name.into()),
            ok,
            detail: detail.into(),
        });
    }
}

/// Entry point of `cargo xtask validate`.
pub fn main(args: Args) -> Result<()> {
    let root = crate::workspace_root();
    let data_dir = match args.data {
        _ if args.no_data => None,
        Some(d) => {
            if !d.is_dir() {
                bail!("--data {}: not a directory", d.display());
            }
            Some(d)
        }
        None => sl_testkit::data_dir().ok(),
    };
    if data_dir.is_none() {
        eprintln!(
            "note: ../shared/data not found; real-frame experiments are skipped and simulated frames are used"
        );
    }
    let out_dir = args
        .out
        .unwrap_or_else(|| root.join("target").join("validate"));
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    for name in &args.only {
        if !EXPERIMENTS.iter().any(|(n, _)| n == name) {
            let known: Vec<&str> = EXPERIMENTS.iter().map(|(n, _)| *n).collect();
            bail!("unknown experiment {name:?}; known: {}", known.join(", "));
        }
    }
    let mut ctx = Context {
        data_dir,
        out_dir,
        quick: args.quick,
        current: String::new(),
        sections: Vec::new(),
        rows: Vec::new(),
        checks: Vec::new(),
    };
    let mut timings = Vec::new();
    for (name, run) in EXPERIMENTS {
        if !args.only.is_empty() && !args.only.iter().any(|o| o == name) {
            continue;
        }
        ctx.current = (*name).to_string();
        eprintln!("running experiment {name} ...");
        let t = Instant::now();
        if let Err(e) = run(&mut ctx) {
            ctx.check("experiment ran to completion", false, format!("{e:#}"));
        }
        timings.push((*name, t.elapsed().as_secs_f64()));
    }
    write_report(&ctx, &timings)?;
    if args.json {
        let v = serde_json::json!({
            "rows": ctx.rows,
            "checks": ctx.checks,
            "data_dir": ctx.data_dir.as_ref().map(|d| d.display().to_string()),
            "report": ctx.out_dir.join("REPORT.md").display().to_string(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_table(&ctx);
    }
    let failed: Vec<&Check> = ctx.checks.iter().filter(|c| !c.ok).collect();
    if !failed.is_empty() {
        for c in &failed {
            eprintln!("REGRESSION: {} ({})", c.name, c.detail);
        }
        bail!("{} of {} checks failed", failed.len(), ctx.checks.len());
    }
    eprintln!(
        "all {} checks passed; report: {}",
        ctx.checks.len(),
        ctx.out_dir.join("REPORT.md").display()
    );
    Ok(())
}

fn print_table(ctx: &Context) {
    let w = ctx
        .rows
        .iter()
        .map(|r| r.metric.len())
        .max()
        .unwrap_or(6)
        .max(6);
    println!("{:<10} {:<w$} {:>14} unit", "experiment", "metric", "value");
    for r in &ctx.rows {
        println!(
            "{:<10} {:<w$} {:>14} {}",
            r.experiment,
            r.metric,
            fmt_value(r.value),
            r.unit
        );
    }
    println!();
    for c in &ctx.checks {
        println!(
            "[{}] {} — {}",
            if c.ok { "ok" } else { "FAIL" },
            c.name,
            c.detail
        );
    }
}

fn fmt_value(v: f64) -> String {
    if v == 0.0 || (v.abs() >= 0.01 && v.abs() < 1e6) {
        format!("{v:.4}")
    } else {
        format!("{v:.4e}")
    }
}

fn write_report(ctx: &Context, timings: &[(&str, f64)]) -> Result<()> {
    let mut md = String::new();
    let _ = writeln!(md, "# sldepth validation report\n");
    let _ =
        writeln!(
            md,
            "Generated by `cargo xtask validate`. Real data: {}.\n",
            ctx.data_dir.as_ref().map_or(
                "absent (simulated frames only)".to_string(),
                |d| format!("`{}`", d.display())
            )
        );
    let _ = writeln!(
        md,
        "## Checks\n\n| check | result | detail |\n|---|---|---|"
    );
    for c in &ctx.checks {
        let _ = writeln!(
            md,
            "| {} | {} | {} |",
            c.name,
            if c.ok { "ok" } else { "**FAIL**" },
            c.detail
        );
    }
    let _ = writeln!(md);
    for (title, body) in &ctx.sections {
        let _ = writeln!(md, "## {title}\n\n{body}\n");
    }
    let _ = writeln!(
        md,
        "## All numbers\n\n| experiment | metric | value | unit |\n|---|---|---|---|"
    );
    for r in &ctx.rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} |",
            r.experiment,
            r.metric,
            fmt_value(r.value),
            r.unit
        );
    }
    let _ = writeln!(md, "\n## Run time\n");
    for (name, s) in timings {
        let _ = writeln!(md, "- {name}: {s:.1} s");
    }
    sl_io::atomic::write_atomic(ctx.out_dir.join("REPORT.md"), |w| {
        w.write_all(md.as_bytes())
    })?;
    let json =
        serde_json::to_vec_pretty(&serde_json::json!({ "rows": ctx.rows, "checks": ctx.checks }))?;
    sl_io::atomic::write_atomic(ctx.out_dir.join("results.json"), |w| w.write_all(&json))?;
    Ok(())
}

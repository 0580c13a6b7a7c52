//! `sldepth`: command-line tools for structured-light depth cameras (Kinect v1, PrimeSense,
//! Xtion). Run `sldepth --help` for the list of commands; every option names its unit.

/// `println!` that returns the write error (a closed pipe, a full disk) instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($arg)*)
    }};
}

/// `eprintln!` that never panics: a message to a closed or full stderr is dropped (there is
/// nobody to tell; the exit code still reports failures).
macro_rules! errln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

mod cmd;
mod common;
mod recording;

use std::process::ExitCode;

use std::io::Write as _;

use clap::{Parser, Subcommand};

/// Structured-light depth camera toolkit: noise analysis, simulation, filtering, fusion and
/// plane extraction for Kinect-class depth maps.
#[derive(Debug, Parser)]
#[command(name = "sldepth", version, about, long_about = None)]
struct Cli {
    /// Memory budget, bytes (suffixes K, M, G: powers of 1024). Every input is checked
    /// against limits derived from it before anything is allocated: pixels per image (budget /
    /// 256: 4096x4096 at the default), text input size and lines, frames per sequence, PLY
    /// elements, and the TSDF of `fuse` and `track` (1/3 of it for the blocks, 3/4 for the blocks
    /// and their mesh: extracting a mesh takes about as much memory as its volume). A full
    /// volume ends `fuse` with the mesh of the frames before; in `track` its fragment is meshed
    /// and the run goes on in a fresh volume in the same world frame (`--when-model-full`).
    /// Default 4G; at least 16M (a smaller
    /// budget is refused).
    #[arg(long, value_name = "BYTES", global = true, value_parser = common::parse_memory)]
    max_memory: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Size and depth statistics of a depth map.
    Info(cmd::info::Args),
    /// Depth resolution analysis (the paper's Figure 2): unique depths, log-log slope, quantum,
    /// implied f·B, disparity sub-pixel steps.
    Analyze(cmd::analyze::Args),
    /// Noise statistics of a depth map with planar regions: σ_D per depth band, residual
    /// autocorrelation, terrace widths, occlusion-band widths.
    NoiseStats(cmd::noise_stats::Args),
    /// Render a seeded synthetic scene through the Kinect noise model.
    Simulate(cmd::simulate::Args),
    /// Back-project a depth map to a PLY point cloud.
    Cloud(cmd::cloud::Args),
    /// Merge registered depth frames into a mesh: sparse TSDF with 1/Z^4 noise weights and
    /// crack-free marching cubes (paper section 3.3).
    Fuse(cmd::fuse::Args),
    /// Smooth a depth map: Gaussian, bilateral, the paper's adaptive bilateral (σ_d = k·Z², tuned
    /// from the sensor model) or a disparity-domain bilateral (section 3.2); by default the
    /// adaptive filter followed by coarse disparity passes for real sensors' correlated error.
    Filter(cmd::filter::Args),
    /// Extract planes with a fixed threshold in disparity (paper section 3.4), or with the
    /// fixed-metric-threshold RANSAC baseline; writes a 16-bit label image.
    Planes(cmd::planes::Args),
    /// Camera motion between two depth frames from matched planes (section 3.5), optionally
    /// refined by point-to-plane ICP.
    Motion(cmd::motion::Args),
    /// Track the camera through a raw depth recording (no poses given): noise-weighted
    /// point-to-plane tracking, fusion of every tracked frame, trajectory and mesh output.
    /// Frames of a whole fraction of the camera's size (320x240 for a 640x480 camera) are
    /// tracked as that sensor decimated, as every command reads them.
    Track(cmd::track::Args),
    /// Trajectory accuracy against ground truth (TUM benchmark definitions): ATE after rigid
    /// alignment and RPE per frame or per second, from two trajectory files (TUM format, or an
    /// Open3D `.log` stamped with its frame numbers).
    EvalTraj(cmd::eval_traj::Args),
    /// List the camera presets `--camera NAME` accepts: intrinsics, baseline, disparity
    /// sub-pixel steps, noise, range and the source of the numbers.
    Cameras(cmd::cameras::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    common::set_limits(
        cli.max_memory
            .map_or_else(sl_io::Limits::default, sl_io::Limits::for_memory),
    );
    install_signal_handler();
    match on_worker_thread(move || run(cli)) {
        Ok(()) => ExitCode::SUCCESS,
        // A reader that closed the pipe (`sldepth info x | head -c1`) wants no more output: stop
        // quietly, as ripgrep does.
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            // If even stderr is gone there is nobody to tell, but the exit code still says it
            // failed.
            let _ = writeln!(std::io::stderr(), "{}", report(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error report of `fn main() -> anyhow::Result<()>` (the message, then its causes, numbered
/// when there are several), without the causes a message already quotes: the library errors
/// name their cause in their own message ("x.png: No such file or directory") and also chain
/// it, which anyhow would print twice.
fn report(e: &anyhow::Error) -> String {
    let mut shown = e.to_string();
    let mut causes = Vec::new();
    for cause in e.chain().skip(1).map(|c| c.to_string()) {
        if !shown.contains(&cause) {
            shown.push('\n');
            shown.push_str(&cause);
            causes.push(cause);
        }
    }
    let mut out = format!("Error: {e}");
    match causes.as_slice() {
        [] => {}
        [one] => out.push_str(&format!("\n\nCaused by:\n    {one}")),
        many => {
            out.push_str("\n\nCaused by:");
            for (i, c) in many.iter().enumerate() {
                out.push_str(&format!("\n    {i}: {c}"));
            }
        }
    }
    out
}

/// Stack of the rayon worker threads, bytes: the command runs on one of them, so it gets a main
/// thread's usual 8 MiB rather than a spawned thread's default 2 MiB.
const WORKER_STACK_BYTES: usize = 8 << 20;

/// Runs the command on a worker thread of rayon's global pool (`RAYON_NUM_THREADS` threads, one
/// per core by default). A parallel phase started from a thread outside the pool puts its work
/// in the pool's queue and blocks that thread until a worker has done it, a sleep and a wake-up
/// per phase; started from a worker, it splits on the spot. A tracking step has about forty
/// phases: on a 2-core Intel Xeon VM (TUM fr1/rpy-200) this is 33 → 28 ms per step and 160,000 →
/// 13,000 context switches, with the same trajectory bit for bit.
fn on_worker_thread<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    // Fails only when the global pool already exists, which then serves as it is.
    let _ = rayon::ThreadPoolBuilder::new()
        .stack_size(WORKER_STACK_BYTES)
        .build_global();
    rayon::scope(|_| f())
}

/// On SIGINT / SIGTERM: remove the temporary files being written (the destinations are never
/// partial anyway) and exit with 128 + the signal number, as a shell reports it.
#[cfg(unix)]
fn install_signal_handler() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        errln!(
            "warning: cannot install the signal handler; an interrupted write may leave a temporary file"
        );
        return;
    };
    let spawned = std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(sig) = signals.forever().next() {
                sl_io::atomic::remove_live_temps();
                std::process::exit(128 + sig);
            }
        });
    if spawned.is_err() {
        errln!(
            "warning: cannot start the signal thread; an interrupted write may leave a temporary file"
        );
    }
}

#[cfg(not(unix))]
fn install_signal_handler() {}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Info(a) => cmd::info::run(a),
        Command::Analyze(a) => cmd::analyze::run(a),
        Command::NoiseStats(a) => cmd::noise_stats::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Cloud(a) => cmd::cloud::run(a),
        Command::Fuse(a) => cmd::fuse::run(a),
        Command::Filter(a) => cmd::filter::run(a),
        Command::Planes(a) => cmd::planes::run(a),
        Command::Motion(a) => cmd::motion::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::EvalTraj(a) => cmd::eval_traj::run(a),
        Command::Cameras(a) => cmd::cameras::run(a),
    }
}

#[cfg(test)]
mod tests {
    use super::report;
    use anyhow::Context as _;

    #[test]
    fn a_cause_the_message_quotes_is_not_repeated() {
        let missing = sl_io::read_depth(
            std::path::Path::new("/no/such/dir/x.png"),
            &sl_io::ReadConfig::default(),
        )
        .unwrap_err();
        let quoted = missing.to_string();
        let r = report(&anyhow::Error::from(missing));
        assert_eq!(r.matches("No such file or directory").count(), 1, "{r}");
        assert!(!r.contains("Caused by"), "{r}");
        // A context that does not quote its cause keeps it, once.
        let e = Err::<(), _>(anyhow::anyhow!("{quoted}"))
            .context("reading the frames")
            .unwrap_err();
        let r = report(&e);
        assert!(
            r.starts_with("Error: reading the frames\n\nCaused by:\n    "),
            "{r}"
        );
        assert_eq!(r.matches("No such file or directory").count(), 1, "{r}");
    }
}

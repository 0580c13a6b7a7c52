"""The cost of calling sldepth from Python, in instructions (never needed by tests).

    python docs/bench/python_overhead_callgrind.py [--data ../shared/data] [--n 10 20]

Wall-clock comparisons of a Python call with the Rust-internal timing (python_peers.py
--only overhead) need a quiet machine: on a guest whose speed drifts by more than the overhead
they measure nothing. This counts instructions instead, with ``valgrind --tool=callgrind``,
which repeats to within 0.01 % for the same binary and input whatever else the machine does.

For each function (``sldepth.extract_planes`` on TUM fr1/rpy frame 4, ``sldepth.filter`` single
scale on person-depth.png), one thread on both sides:
- Python: a process that makes one warm-up call and then N calls, for two values of N; the
  difference of the two totals over the difference of N is the instructions of one call as a
  Python program makes it (argument parsing, the input borrowed from NumPy, the computation,
  the output arrays and plane objects, freeing the previous results, the interpreter's loop);
- Rust: the same difference for ``planes_timing repeat N tum-fr1-rpy/04`` and for
  ``sldepth filter --repeat N --single-scale --model-noise-only`` (the computation alone, as
  the Rust-internal timings measure it).
Every fixed cost (start-up, imports, reading the frame) cancels in the differences.

Needs valgrind, the wheel of crates/sl-py installed in the running interpreter's environment
(with numpy), and ``cargo build --release -p sldepth`` and ``cargo build --release -p sl-planes
--example planes_timing``. OPENBLAS_NUM_THREADS=1 is set for the Python processes: NumPy's
OpenBLAS otherwise keeps worker threads polling, whose instructions callgrind counts (1.6 M per
call of ours in one run, a different amount in the next) although they are NumPy's, not ours.
valgrind has no AVX-512: both sides run their AVX2 paths.
"""

import argparse
import os
import pathlib
import re
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]


def calls(what, n, data):
    """The measured loop (run in the child process)."""
    import sldepth

    sldepth.set_num_threads(1)
    if what == "planes":
        tum = sorted((data / "tum-fr1-rpy/depth").glob("*.png"))[4]
        z = sldepth.read_depth(tum, 5000)
        cam = sldepth.Camera.preset("tum-fr1")
        call = lambda: sldepth.extract_planes(z, cam)  # noqa: E731
    else:
        z = sldepth.read_depth(data / "open3d-testdata/person-depth.png", 1000)
        cam = sldepth.Camera.preset("kinect-v1")
        call = lambda: sldepth.filter(z, cam, multiscale=False)  # noqa: E731
    call()  # warm-up: the pool, the extractor's buffers, NumPy's C API
    for _ in range(n):
        call()


def collected(cmd, env):
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg.out", *cmd],
                             capture_output=True, text=True, env=env, cwd=tmp)
        m = re.search(r"Collected : (\d+)", out.stderr)
        if out.returncode != 0 or not m:
            sys.exit(f"{' '.join(map(str, cmd))} failed:\n{out.stderr[-2000:]}")
        return int(m.group(1))


def per_call(cmd_for, ns, env):
    lo, hi = ns
    return (collected(cmd_for(hi), env) - collected(cmd_for(lo), env)) / (hi - lo)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=pathlib.Path, default=ROOT.parent / "shared/data")
    ap.add_argument("--n", type=int, nargs=2, default=[10, 20], help="the two call counts")
    ap.add_argument("--calls", nargs=2, metavar=("WHAT", "N"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.calls:
        calls(a.calls[0], int(a.calls[1]), a.data)
        return
    timing = ROOT / "target/release/examples/planes_timing"
    binary = ROOT / "target/release/sldepth"
    person = a.data / "open3d-testdata/person-depth.png"
    for p in (timing, binary, person):
        if not p.exists():
            sys.exit(f"missing {p}")
    env = {**os.environ, "RAYON_NUM_THREADS": "1", "SLDEPTH_DATA": str(a.data)}
    py_env = {**env, "OPENBLAS_NUM_THREADS": "1", "PYTHONHASHSEED": "0"}
    me = pathlib.Path(__file__).resolve()
    rows = [
        ("extract_planes, TUM fr1/rpy frame 4",
         lambda n: [sys.executable, me, "--data", a.data, "--calls", "planes", str(n)],
         lambda n: [timing, "repeat", str(n), "tum-fr1-rpy/04"]),
        ("filter 7x7 adaptive single scale, person",
         lambda n: [sys.executable, me, "--data", a.data, "--calls", "filter", str(n)],
         lambda n: [binary, "filter", person, "out.png", "--repeat", str(n), "--single-scale",
                    "--model-noise-only"]),
    ]
    print("| call | Python, M instructions per call | Rust, M per call | overhead |")
    print("|---|---|---|---|")
    for name, py_cmd, rust_cmd in rows:
        py = per_call(py_cmd, a.n, py_env)
        rust = per_call(rust_cmd, a.n, env)
        print(f"| {name} | {py / 1e6:.3f} | {rust / 1e6:.3f} | {100 * (py / rust - 1):+.2f} % |", flush=True)


if __name__ == "__main__":
    main()

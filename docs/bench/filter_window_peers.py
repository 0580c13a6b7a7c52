#!/usr/bin/env python3
"""sldepth's adaptive filter (square and disc window) beside cv2.bilateralFilter, interleaved,
on real 640x480 frames, for this CPU's best instruction set and for AVX2 only.

Measurement only -- no test needs this script. Needs ``opencv-python-headless`` (5.1.0.95 in
session 60; 5.0.0.93 before, a much slower wheel: compare ratios only at one OpenCV version) and
numpy, and ``target/release/sldepth`` (``cargo build --release -p sldepth``). Run from the
workspace root:

    python3 docs/bench/filter_window_peers.py [--rounds 5] [--reps 30] [--isa native|avx2]

Each round times ours (``sldepth filter --repeat N --json``: the filtering alone, no I/O, its
minimum of N) and OpenCV (minimum of N calls on the same float32 frame) back to back, and the
ratio ours / OpenCV is taken per round, so load on a shared machine moves both. ``--isa avx2``
emulates an AVX2-only CPU on an AVX-512 machine: ours runs ``--isa avx2`` and OpenCV is started
with ``OPENCV_CPU_DISABLE`` naming every AVX-512 feature (OpenCV reads it at import, so the script
re-executes itself with it set). OpenCV's window is the disc ``dx² + dy² ≤ r²`` (13 taps at
d = 5, 29 at d = 7); sldepth's is the full square unless ``--window-shape disc``. sigmaColor is
the adaptive filter's range sigma at the frame's median depth, ``k·Z²``; sigmaSpace = r/2 as ours.
"""
import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

AVX512 = "AVX512F,AVX512_COMMON,AVX512_SKX,AVX512_KNL,AVX512_KNM,AVX512_CNL,AVX512_CLX,AVX512_ICL"

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
DATA = os.path.normpath(os.path.join(ROOT, "..", "shared", "data"))
FRAMES = [
    ("person", "open3d-testdata/person-depth.png", 1000.0, "kinect-v1"),
    ("tum-fr1", "tum-fr1-rpy/depth/1305031229.528784.png", 5000.0, "tum-fr1"),
    ("7-scenes", "7scenes-redkitchen/frame-000150.depth.png", 1000.0, "7-scenes"),
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=30)
    ap.add_argument("--isa", choices=["native", "avx2"], default="native")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--json")
    args = ap.parse_args()
    if args.isa == "avx2" and os.environ.get("OPENCV_CPU_DISABLE") != AVX512:
        env = dict(os.environ, OPENCV_CPU_DISABLE=AVX512)
        return subprocess.call([sys.executable] + sys.argv, env=env)

    import cv2
    import numpy as np

    sldepth = os.path.join(ROOT, "target", "release", "sldepth")
    help_text = subprocess.run([sldepth, "filter", "--help"], capture_output=True, text=True).stdout
    rows = []
    print(f"OpenCV {cv2.__version__}, {platform.machine()}, {os.cpu_count()} cpus, isa {args.isa}, "
          f"OPENCV_CPU_DISABLE={os.environ.get('OPENCV_CPU_DISABLE', '')!r}")
    for name, rel, scale, camera in FRAMES:
        path = os.path.join(DATA, rel)
        if not os.path.exists(path):
            print(f"skipping {name}: {path} not found")
            continue
        raw = cv2.imread(path, cv2.IMREAD_UNCHANGED)
        z = raw.astype(np.float32) / np.float32(scale)
        z[raw == 65535] = 0.0
        for r in (2, 3):
            d = 2 * r + 1
            for threads in [int(t) for t in args.threads.split(",")]:
                for window in ("square", "disc"):
                    ratios, ours_ms, cv_ms, isa_used = [], [], [], None
                    for _ in range(args.rounds):
                        cmd = [sldepth, "filter", path, "/tmp/filter_window_peers.png",
                               "--camera", camera, "--depth-scale", str(scale), "--radius", str(r),
                               "--window-shape", window, "--repeat", str(args.reps), "--json"]
                        if "--single-scale" in help_text:
                            cmd += ["--single-scale"]  # the one pass, as OpenCV's
                        if args.isa == "avx2":
                            cmd += ["--isa", "avx2"]
                        out = subprocess.run(cmd, capture_output=True, text=True,
                                             env=dict(os.environ, RAYON_NUM_THREADS=str(threads)))
                        if out.returncode != 0:
                            print(out.stderr, file=sys.stderr)
                            return 1
                        j = json.loads(out.stdout)
                        isa_used = j["isa"]
                        k = j["k_per_m"]
                        ours = j["ms_min"]
                        zmed = float(np.median(z[z > 0]))
                        sigma_color = k * zmed * zmed
                        cv2.setNumThreads(threads)
                        cv2.bilateralFilter(z, d, sigma_color, r / 2.0)
                        times = []
                        for _ in range(args.reps):
                            t0 = time.perf_counter()
                            cv2.bilateralFilter(z, d, sigma_color, r / 2.0)
                            times.append((time.perf_counter() - t0) * 1e3)
                        theirs = min(times)
                        ours_ms.append(ours)
                        cv_ms.append(theirs)
                        ratios.append(ours / theirs)
                    row = {
                        "frame": name, "window_px": d, "threads": threads, "ours_window": window,
                        "ours_isa": isa_used, "opencv_avx512_disabled": args.isa == "avx2",
                        "ours_ms_min": min(ours_ms), "opencv_ms_min": min(cv_ms),
                        "ratio_min": min(ratios), "ratio_median": statistics.median(ratios),
                        "ratio_max": max(ratios),
                    }
                    rows.append(row)
                    print(f"{name:9s} {d}x{d} {threads}t ours {window:6s} {isa_used:8s} "
                          f"{row['ours_ms_min']:.3f} ms  opencv {row['opencv_ms_min']:.3f} ms  "
                          f"ratio min {row['ratio_min']:.2f} median {row['ratio_median']:.2f} "
                          f"max {row['ratio_max']:.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

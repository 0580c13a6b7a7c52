#!/usr/bin/env python3
"""Peer measurement for `sl-filter`: OpenCV's cv2.bilateralFilter on a real 640x480 Kinect frame.

Measurement only -- no test needs this script. Install the peer with
    pip install opencv-python-headless==5.1.0.95
(the wheel of session 60; 5.0.0.93, used before, is 2-5x slower at d = 5 and 7 on float32)
and run from the workspace root:
    python3 docs/bench/opencv_bilateral.py [DEPTH.png] [--reps N] [--depth-scale S]

The frame is converted to float32 metres (0 = invalid), as `sldepth filter` sees it. The filter is
the fixed-sigma bilateral (sigmaColor = 0.03 m, sigmaSpace = d / 4 px, i.e. 1.0 px at d = 5 and
1.5 px at d = 7 -- the same spatial sigmas as sldepth's default for radius 2 and 3), at d = 5 and
d = 7, with 1 thread and with OpenCV's default thread count. Prints the median and minimum
milliseconds of N repetitions per configuration and one JSON line per configuration.
"""
import argparse
import json
import os
import statistics
import sys
import time

import cv2
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_FRAME = os.path.normpath(
    os.path.join(HERE, "..", "..", "..", "shared", "data", "open3d-testdata", "person-depth.png")
)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("frame", nargs="?", default=DEFAULT_FRAME)
    ap.add_argument("--reps", type=int, default=200)
    ap.add_argument("--depth-scale", type=float, default=1000.0, help="raw units per metre (TUM: 5000)")
    ap.add_argument("--sigma-color", type=float, default=0.03, help="range sigma, metres")
    ap.add_argument("--diameters", default="5,7")
    args = ap.parse_args()

    raw = cv2.imread(args.frame, cv2.IMREAD_UNCHANGED)
    if raw is None:
        print(f"cannot read {args.frame}", file=sys.stderr)
        return 1
    depth = raw.astype(np.float32) / np.float32(args.depth_scale)
    if raw.dtype == np.uint16:
        depth[raw == 65535] = 0.0
    h, w = depth.shape
    default_threads = cv2.getNumThreads()
    print(f"OpenCV {cv2.__version__}, frame {args.frame} ({w}x{h}), default threads {default_threads}, "
          f"cpus {os.cpu_count()}, reps {args.reps}")
    for d in [int(x) for x in args.diameters.split(",")]:
        for threads in (1, default_threads):
            cv2.setNumThreads(threads)
            sigma_space = d / 4.0
            out = cv2.bilateralFilter(depth, d, args.sigma_color, sigma_space)  # warm-up
            times = []
            for _ in range(args.reps):
                t0 = time.perf_counter()
                out = cv2.bilateralFilter(depth, d, args.sigma_color, sigma_space)
                times.append((time.perf_counter() - t0) * 1e3)
            assert out.dtype == np.float32 and out.shape == depth.shape
            med, mn = statistics.median(times), min(times)
            print(f"d={d} threads={threads}: median {med:.3f} ms, min {mn:.3f} ms")
            print(json.dumps({"impl": "opencv", "version": cv2.__version__, "d": d, "threads": threads,
                              "ms_median": med, "ms_min": mn, "reps": args.reps}))
    cv2.setNumThreads(default_threads)
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Extraction time of sl-planes beside OpenCV's ``cv2.findPlanes`` without the Python wheel.

Interleaved rounds on the first TUM fr1/rpy frame and 7-Scenes frame-000150 (the frames of
``python_peers.py``): each round runs every given ``planes_timing`` binary (``time REPS FRAME``:
the minimum of REPS extractions in Rust, no Python call; ``RAYON_NUM_THREADS=THREADS``) and then
``cv2.findPlanes`` REPS times on the ``cv2.depthTo3d`` cloud (made outside the timing,
``cv2.setNumThreads(THREADS)``, Kinect ``sensor_error_a = 0.0075``). Ratios are per round.

    python docs/bench/planes_vs_findplanes.py BIN[,BIN...] THREADS ROUNDS REPS

Tests never need this script.
"""
import os, subprocess, sys, time
from pathlib import Path
import cv2, numpy as np
data = Path(os.environ.get("SLDEPTH_DATA", Path(__file__).resolve().parents[3] / "shared/data"))
tum = sorted((data / "tum-fr1-rpy/depth").glob("*.png"))[0]
seven = data / "7scenes-redkitchen/frame-000150.depth.png"
frames = {"tum-fr1-rpy": (tum, 5000.0, np.array([[517.3,0,318.6],[0,516.5,255.3],[0,0,1]], np.float32)),
          "7scenes": (seven, 1000.0, np.array([[585,0,320],[0,585,240],[0,0,1]], np.float32))}
bins = sys.argv[1].split(",")
threads = int(sys.argv[2]); rounds = int(sys.argv[3]); reps = int(sys.argv[4])
cv2.setNumThreads(threads)
pts = {k: cv2.depthTo3d(cv2.imread(str(f), cv2.IMREAD_UNCHANGED).astype(np.float32) / s, K) for k, (f, s, K) in frames.items()}
res = {}
for r in range(rounds):
    for name in frames:
        for b in bins:
            out = subprocess.run([b, "time", str(reps), name], capture_output=True, text=True,
                                 env={**os.environ, "RAYON_NUM_THREADS": str(threads)}).stdout
            line = [l for l in out.splitlines() if l.startswith(name)][0]
            ours = float(line.split("min ")[1].split(" ms")[0])
            res.setdefault((name, b), []).append(ours)
        t = []
        for _ in range(reps):
            t0 = time.perf_counter(); cv2.findPlanes(pts[name], None, sensor_error_a=0.0075); t.append((time.perf_counter() - t0) * 1e3)
        res.setdefault((name, "cv"), []).append(min(t))
    print("round", r, os.getloadavg(), flush=True)
for name in frames:
    cvs = res[(name, "cv")]
    for b in bins:
        o = res[(name, b)]
        ratios = [a / c for a, c in zip(o, cvs)]
        print(f"{name} threads={threads} {b}: ours min {min(o):.3f} ms, cv min {min(cvs):.3f} ms, ratio(min/min) {min(o)/min(cvs):.3f}, per-round ratios {' '.join(f'{x:.3f}' for x in ratios)}, median {sorted(ratios)[len(ratios)//2]:.3f}")

"""sldepth from Python beside OpenCV and Open3D, in one process, on the real frames of
../shared/data (never needed by tests).

    python docs/bench/python_peers.py [--rounds 5] [--data ../shared/data] [--json out.json]

Needs sldepth (the wheel of crates/sl-py), numpy, opencv-python(-headless) >= 5 and open3d in
the environment, and target/release/sldepth for the Rust-internal timings (cargo build
--release -p sldepth). Every comparison is interleaved: each round times ours and the peer
back to back on the same frame, and the ratio is taken per round, so a noisy machine moves both.

Compared:
- filter: ``sldepth.filter(method="adaptive", radius=r)`` vs ``cv2.bilateralFilter`` on float32
  with the same diameter 2r+1 (sigmaColor from the paper's k at the frame's median depth,
  sigmaSpace as ours), one thread and all threads;
- TSDF: ``TsdfVolume.integrate`` and ``extract_mesh`` vs Open3D's ``ScalableTSDFVolume``
  (same voxel, truncation and depth range) on the ICL living-room frames;
- planes: ``sldepth.extract_planes`` vs ``cv2.findPlanes`` (its Kinect ``sensor_error_a =
  0.0075``; points from the depth map computed outside the timing, normals left to it);
- call overhead: ``sldepth.filter`` / ``extract_planes`` against the Rust-internal timing the
  CLI reports for the same frame (``sldepth filter --repeat``, ``sldepth planes --json``).
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import open3d as o3d

import sldepth

ROOT = Path(__file__).resolve().parents[2]


def isa():
    flags = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    if "avx512f" in flags:
        return "avx512"
    return "avx2" if "avx2" in flags else "baseline"


def timed(fn, reps):
    """Minimum and median wall time of `reps` calls, milliseconds."""
    t = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        t.append((time.perf_counter() - t0) * 1e3)
    return min(t), statistics.median(t)


def frames(data):
    out = []
    person = data / "open3d-testdata/person-depth.png"
    if person.exists():
        out.append(("person", sldepth.read_depth(person, 1000), sldepth.Camera(640, 480, 525, 525, 319.5, 239.5)))
    tum = sorted((data / "tum-fr1-rpy/depth").glob("*.png")) if (data / "tum-fr1-rpy/depth").exists() else []
    if tum:
        out.append(("tum-fr1", sldepth.read_depth(tum[0], 5000), sldepth.Camera.preset("tum-fr1")))
    seven = data / "7scenes-redkitchen/frame-000150.depth.png"
    if seven.exists():
        out.append(("7-scenes", sldepth.read_depth(seven, 1000), sldepth.Camera.preset("7-scenes")))
    return out


def bench_filter(name, z, cam, rounds, reps, threads):
    rows = []
    med = float(np.median(z[z > 0]))
    for r in (2, 3):
        k = 10.0 * cam.sigma_d_px / cam.fb  # the default k of the adaptive filter (multiplier 10)
        sigma_color = k * med * med
        sigma_space = r / 1.5 if r else 1.0
        ours_cfg = dict(method="adaptive", radius=r)
        for nt in threads:
            sldepth.set_num_threads(nt)
            cv2.setNumThreads(nt)
            ratios, ours_t, cv_t = [], [], []
            for _ in range(rounds):
                o = timed(lambda: sldepth.filter(z, cam, **ours_cfg), reps)
                c = timed(lambda: cv2.bilateralFilter(z, 2 * r + 1, sigma_color, sigma_space), reps)
                ours_t.append(o)
                cv_t.append(c)
                ratios.append(o[0] / c[0])
            rows.append(dict(frame=name, window=f"{2*r+1}x{2*r+1}", threads=nt,
                             ours_min_ms=min(t[0] for t in ours_t), ours_median_ms=statistics.median(t[1] for t in ours_t),
                             peer_min_ms=min(t[0] for t in cv_t), peer_median_ms=statistics.median(t[1] for t in cv_t),
                             ratio_min=min(ratios), ratio_median=statistics.median(ratios)))
    sldepth.set_num_threads(None)
    return rows


def bench_planes(name, z, cam, rounds, reps):
    K = np.array(cam.intrinsic_matrix())
    h, w = z.shape
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    pts = np.dstack([(xs - K[0, 2]) * z / K[0, 0], (ys - K[1, 2]) * z / K[1, 1], z]).astype(np.float32)
    pts[z <= 0] = np.nan
    ratios, ours_t, cv_t = [], [], []
    sldepth.set_num_threads(1)
    cv2.setNumThreads(1)
    for _ in range(rounds):
        o = timed(lambda: sldepth.extract_planes(z, cam), reps)
        c = timed(lambda: cv2.findPlanes(pts, None, sensor_error_a=0.0075), reps)
        ours_t.append(o)
        cv_t.append(c)
        ratios.append(o[0] / c[0])
    sldepth.set_num_threads(None)
    _, planes = sldepth.extract_planes(z, cam)
    mask, coeffs = cv2.findPlanes(pts, None, sensor_error_a=0.0075)
    return dict(frame=name, threads=1, ours_min_ms=min(t[0] for t in ours_t), peer_min_ms=min(t[0] for t in cv_t),
                ratio_min=min(ratios), ratio_median=statistics.median(ratios),
                ours_planes=len(planes), peer_planes=0 if coeffs is None else len(coeffs))


def bench_tsdf(data, rounds):
    icl = data / "open3d-testdata/icl-livingroom"
    if not icl.exists():
        return []
    depth_files = sorted((icl / "depth").glob("*.png"))
    lines = (icl / "odometry.log").read_text().split("\n")
    poses = []
    for i in range(0, len(lines) - 4, 5):
        if lines[i].strip():
            poses.append(np.array([[float(v) for v in lines[i + j].split()] for j in range(1, 5)]))
    n = min(len(depth_files), len(poses))
    cam = sldepth.Camera.preset("icl-nuim")
    zs = [sldepth.read_depth(f, 1000) for f in depth_files[:n]]
    intr = o3d.camera.PinholeCameraIntrinsic(640, 480, 525.0, 525.0, 319.5, 239.5)
    o3d_depths = [o3d.geometry.Image((z * 1000).astype(np.uint16)) for z in zs]
    colors = [o3d.geometry.Image(np.zeros((480, 640, 3), np.uint8)) for _ in zs]
    rows = []
    for _ in range(rounds):
        vol = sldepth.TsdfVolume(voxel_m=0.004, trunc_m=0.02, weight="inv-z4", max_depth_m=4.0)
        t = []
        for z, p in zip(zs, poses):
            t0 = time.perf_counter()
            vol.integrate(z, cam, p)
            t.append((time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        mesh = vol.extract_mesh()
        ours_mc = (time.perf_counter() - t0) * 1e3
        ovol = o3d.pipelines.integration.ScalableTSDFVolume(
            voxel_length=0.004, sdf_trunc=0.02, color_type=o3d.pipelines.integration.TSDFVolumeColorType.NoColor)
        ot = []
        for d, c, p in zip(o3d_depths, colors, poses):
            rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(c, d, depth_scale=1000.0, depth_trunc=4.0, convert_rgb_to_intensity=False)
            t0 = time.perf_counter()
            ovol.integrate(rgbd, intr, np.linalg.inv(p))
            ot.append((time.perf_counter() - t0) * 1e3)
        t0 = time.perf_counter()
        omesh = ovol.extract_triangle_mesh()
        o3d_mc = (time.perf_counter() - t0) * 1e3
        rows.append(dict(frames=n, ours_integrate_ms=statistics.median(t), peer_integrate_ms=statistics.median(ot),
                         integrate_ratio=statistics.median(t) / statistics.median(ot),
                         ours_mesh_ms=ours_mc, peer_mesh_ms=o3d_mc, mesh_ratio=ours_mc / o3d_mc,
                         ours_vertices=len(mesh), peer_vertices=len(omesh.vertices)))
    return rows


def bench_overhead(data, rounds, reps):
    """Python call vs the Rust-internal time the CLI measures (same frame, camera, threads)."""
    binary = ROOT / "target/release/sldepth"
    person = data / "open3d-testdata/person-depth.png"
    if not (binary.exists() and person.exists()):
        return []
    cam = sldepth.Camera.preset("kinect-v1")  # the CLI's default camera
    z = sldepth.read_depth(person, 1000)
    rows = []
    for _ in range(rounds):
        out = subprocess.run([str(binary), "filter", str(person), "/tmp/_sl_bench.png", "--repeat", str(reps), "--json"],
                             capture_output=True, text=True, check=True)
        rust = json.loads(out.stdout)
        py = timed(lambda: sldepth.filter(z, cam), reps)
        rows.append(dict(stage="filter 7x7 adaptive", rust_min_ms=rust["ms_min"], python_min_ms=py[0],
                         rust_median_ms=rust["ms_median"], python_median_ms=py[1],
                         overhead_min=py[0] / rust["ms_min"] - 1.0))
        planes_rust = min(
            json.loads(subprocess.run([str(binary), "planes", str(person), "-o", "/tmp/_sl_bench.png", "--json"],
                                      capture_output=True, text=True, check=True).stdout)["ms"]
            for _ in range(reps // 5 or 1))
        sldepth.set_num_threads(1)
        py = timed(lambda: sldepth.extract_planes(z, cam), reps)
        sldepth.set_num_threads(None)
        rows.append(dict(stage="planes", rust_min_ms=planes_rust, python_min_ms=py[0],
                         overhead_min=py[0] / planes_rust - 1.0))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=50)
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared/data")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    info = dict(isa=isa(), cpu=platform.processor() or platform.machine(), cores=os.cpu_count(),
                loadavg=os.getloadavg(), opencv=cv2.__version__, open3d=o3d.__version__, sldepth=sldepth.__version__,
                python=sys.version.split()[0])
    print(json.dumps(info))
    res = dict(info=info, filter=[], planes=[], tsdf=[], overhead=[])
    for name, z, cam in frames(a.data):
        res["filter"] += bench_filter(name, z, cam, a.rounds, a.reps, [1, os.cpu_count()])
        res["planes"].append(bench_planes(name, z, cam, a.rounds, a.reps))
    res["tsdf"] = bench_tsdf(a.data, a.rounds)
    res["overhead"] = bench_overhead(a.data, a.rounds, a.reps)
    res["info"]["loadavg_end"] = os.getloadavg()
    for k in ("filter", "planes", "tsdf", "overhead"):
        for row in res[k]:
            print(k, json.dumps({x: (round(v, 4) if isinstance(v, float) else v) for x, v in row.items()}))
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()

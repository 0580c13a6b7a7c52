"""sldepth from Python beside OpenCV and Open3D, in one process, on the real frames of
../shared/data (never needed by tests).

    python docs/bench/python_peers.py [--rounds 5] [--data ../shared/data] [--json out.json]
        [--only filter planes tsdf overhead]

Needs sldepth (the wheel of crates/sl-py), numpy, opencv-python(-headless) >= 5 and open3d in
the environment, and target/release/sldepth for the Rust-internal timings (cargo build
--release -p sldepth). Every comparison is interleaved: each round times ours and the peer
back to back on the same frame, and the ratio is taken per round, so a noisy machine moves both.

Compared:
- filter: ``sldepth.filter(method="adaptive", radius=r, multiscale=False)`` (the single pass) vs ``cv2.bilateralFilter`` on float32
  with the same diameter 2r+1 (sigmaColor from the paper's k at the frame's median depth,
  sigmaSpace as ours), one thread and all threads;
- TSDF: ``TsdfVolume.integrate`` and ``extract_mesh`` vs Open3D's ``ScalableTSDFVolume``
  (same voxel, truncation and depth range) on the ICL living-room frames;
- planes: ``sldepth.extract_planes`` vs ``cv2.findPlanes`` (its Kinect ``sensor_error_a =
  0.0075``; points from the depth map computed outside the timing, normals left to it), one
  thread and all threads (our final pass runs in bands on the pool; findPlanes is sequential);
- call overhead, one thread and all threads: ``sldepth.filter`` against the Rust-internal
  timing the CLI reports for the same frame (``sldepth filter --repeat``), and
  ``extract_planes`` against the extractor's own minimum on a pool worker
  (``target/release/examples/planes_timing time-pool``); each Python measurement in a new
  thread that sets its count first, as a program that sets it once does.

Open3D: use ``open3d-cpu==0.19.0``. The PyPI ``open3d==0.20.0`` wheel's legacy
``ScalableTSDFVolume`` integrates nothing on our machines (0 vertices, ~2 ms per frame), so its
times would be meaningless.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import threading
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


def timed_paced(fn, reps, pause_s=0.002):
    """Median wall time of `reps` calls with a pause between them, milliseconds: a program that
    does other work between calls (a camera loop), so the pool's workers are asleep at each
    call and every hand-over to one costs a wake-up."""
    t = []
    for _ in range(reps):
        time.sleep(pause_s)
        t0 = time.perf_counter()
        fn()
        t.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(t)


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
        sigma_space = r / 2.0  # sldepth's default sigma_s for radius r
        ours_cfg = dict(method="adaptive", radius=r, multiscale=False)
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


def bench_planes(name, z, cam, rounds, reps, threads):
    # findPlanes wants the 4-channel organised cloud of cv2.depthTo3d (made outside the timing;
    # its normals are left to findPlanes, whose time includes them).
    pts = cv2.depthTo3d(z, np.array(cam.intrinsic_matrix(), dtype=np.float32))
    rows = []
    for nt in threads:
        ratios, ours_t, cv_t = [], [], []
        sldepth.set_num_threads(nt)
        cv2.setNumThreads(nt)
        for _ in range(rounds):
            o = timed(lambda: sldepth.extract_planes(z, cam), reps)
            c = timed(lambda: cv2.findPlanes(pts, None, sensor_error_a=0.0075), reps)
            ours_t.append(o)
            cv_t.append(c)
            ratios.append(o[0] / c[0])
        sldepth.set_num_threads(None)
        _, planes = sldepth.extract_planes(z, cam)
        mask, coeffs = cv2.findPlanes(pts, None, sensor_error_a=0.0075)
        rows.append(dict(frame=name, threads=nt, ours_min_ms=min(t[0] for t in ours_t),
                         peer_min_ms=min(t[0] for t in cv_t), ratio_min=min(ratios),
                         ratio_median=statistics.median(ratios), ours_planes=len(planes),
                         peer_planes=0 if coeffs is None else len(coeffs)))
    return rows


def read_log(path):
    lines = [l for l in path.read_text().split("\n") if l.strip()]
    return [np.array([[float(v) for v in lines[i + j].split()] for j in range(1, 5)])
            for i in range(0, len(lines) - 4, 5)]


def tsdf_sequences(data, max_frames):
    icl = data / "open3d-testdata/icl-livingroom"
    if icl.exists():
        files = sorted((icl / "depth").glob("*.png"))
        poses = read_log(icl / "odometry.log")
        yield "icl", sldepth.Camera.preset("icl-nuim"), files[:len(poses)], poses
    seven = data / "7scenes-redkitchen"
    if seven.exists():
        files = sorted(seven.glob("frame-*.depth.png"))[:max_frames]
        poses = [np.loadtxt(str(f).replace(".depth.png", ".pose.txt")) for f in files]
        yield "7-scenes", sldepth.Camera.preset("7-scenes"), files, poses


def bench_tsdf(data, rounds, max_frames=20):
    """Open3D's legacy ScalableTSDFVolume (NoColor), as in docs/bench/open3d_tsdf.py."""
    rows = []
    for name, cam, files, poses in tsdf_sequences(data, max_frames):
        zs = [sldepth.read_depth(f, 1000) for f in files]
        intr = o3d.camera.PinholeCameraIntrinsic(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
        black = o3d.geometry.Image(np.zeros((cam.height, cam.width, 3), np.uint8))
        rgbds = [o3d.geometry.RGBDImage.create_from_color_and_depth(
            black, o3d.geometry.Image(np.round(z * 1000).astype(np.uint16)), depth_scale=1000.0,
            depth_trunc=4.0, convert_rgb_to_intensity=False) for z in zs]
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
                voxel_length=0.004, sdf_trunc=0.02,
                color_type=o3d.pipelines.integration.TSDFVolumeColorType.NoColor)
            ot = []
            for rgbd, p in zip(rgbds, poses):
                t0 = time.perf_counter()
                ovol.integrate(rgbd, intr, np.linalg.inv(p))
                ot.append((time.perf_counter() - t0) * 1e3)
            t0 = time.perf_counter()
            omesh = ovol.extract_triangle_mesh()
            o3d_mc = (time.perf_counter() - t0) * 1e3
            if len(omesh.vertices) == 0:
                # A peer that fused nothing (the PyPI open3d 0.20 wheel, see above) has no time
                # worth comparing: say so instead of printing a ratio.
                sys.exit(f"Open3D {o3d.__version__} integrated nothing on {name} (0 vertices): "
                         "install open3d-cpu==0.19.0 to compare TSDF times")
            rows.append(dict(sequence=name, frames=len(zs), ours_integrate_ms=statistics.median(t),
                             peer_integrate_ms=statistics.median(ot),
                             integrate_ratio=statistics.median(t) / statistics.median(ot),
                             ours_mesh_ms=ours_mc, peer_mesh_ms=o3d_mc, mesh_ratio=ours_mc / o3d_mc,
                             ours_vertices=len(mesh), peer_vertices=len(omesh.vertices)))
    return rows


def in_fresh_thread(n, fn):
    """Runs `fn` in a new Python thread whose first sldepth call uses `n` threads, as a program
    that sets its thread count once does: the thread then computes as worker 0 of a pool of its
    own (a call with another count than a thread's first goes through a shared pool instead)."""
    out = []

    def run():
        sldepth.set_num_threads(n)
        try:
            out.append(fn())
        finally:
            sldepth.set_num_threads(None)

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out[0]


def bench_overhead(data, rounds, reps):
    """Python call vs the Rust-internal time (same frame, camera, threads), interleaved rounds.

    References: `sldepth filter --repeat` (every command runs on a worker of the global pool)
    and `planes_timing time-pool` (the extractor on a worker of the global pool), each with
    RAYON_NUM_THREADS set to the row's thread count."""
    binary = ROOT / "target/release/sldepth"
    timing = ROOT / "target/release/examples/planes_timing"
    person = data / "open3d-testdata/person-depth.png"
    if not (binary.exists() and person.exists()):
        return []
    cam = sldepth.Camera.preset("kinect-v1")  # the CLI's default camera
    z = sldepth.read_depth(person, 1000)
    named = {"tum-fr1": "tum-fr1-rpy", "7-scenes": "7scenes"}
    planes = [(name, zz, c) for name, zz, c in frames(data) if name in named] if timing.exists() else []
    best = {}

    def keep(key, rust_ms, py_ms, paced_ms):
        r, p, m = best.get(key, (float("inf"), float("inf"), []))
        best[key] = (min(r, rust_ms), min(p, py_ms), m + [paced_ms])

    for _ in range(rounds):
        for n in (1, os.cpu_count()):
            env = {**os.environ, "RAYON_NUM_THREADS": str(n)}
            out = subprocess.run([str(binary), "filter", str(person), "/tmp/_sl_bench.png", "--repeat", str(reps),
                                  "--json", "--single-scale"], capture_output=True, text=True, env=env, check=True)
            call = lambda: sldepth.filter(z, cam, multiscale=False)  # noqa: E731
            py = in_fresh_thread(n, lambda: (timed(call, reps)[0], timed_paced(call, reps)))
            keep(("filter 7x7 adaptive, person", n), json.loads(out.stdout)["ms_min"], *py)
            if planes:
                out = subprocess.run([str(timing), "time-pool", str(reps)], capture_output=True, text=True,
                                     env=env, check=True).stdout
                rust = {l.split(":")[0]: float(l.split("min ")[1].split(" ms")[0])
                        for l in out.splitlines() if " min " in l and not l.startswith(" ")}
                for name, zz, c in planes:
                    if named[name] in rust:
                        call = lambda: sldepth.extract_planes(zz, c)  # noqa: E731
                        py = in_fresh_thread(n, lambda: (timed(call, reps)[0], timed_paced(call, reps)))
                        keep((f"planes {name}", n), rust[named[name]], *py)
    # python_paced_median_ms: the median over rounds of timed_paced's medians (workers asleep
    # at each call), beside the back-to-back minimum the overhead is computed from.
    return [dict(stage=stage, threads=n, rust_min_ms=r, python_min_ms=p, overhead_min=p / r - 1.0,
                 python_paced_median_ms=statistics.median(m), rounds=rounds)
            for (stage, n), (r, p, m) in best.items()]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=50)
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared/data")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--only", nargs="*", default=["filter", "planes", "tsdf", "overhead"],
                    help="sections to run (filter planes tsdf overhead)")
    a = ap.parse_args()
    info = dict(isa=isa(), cpu=platform.processor() or platform.machine(), cores=os.cpu_count(),
                loadavg=os.getloadavg(), opencv=cv2.__version__, open3d=o3d.__version__, sldepth=sldepth.__version__,
                python=sys.version.split()[0])
    print(json.dumps(info))
    res = dict(info=info, filter=[], planes=[], tsdf=[], overhead=[])
    for name, z, cam in frames(a.data):
        if "filter" in a.only:
            res["filter"] += bench_filter(name, z, cam, a.rounds, a.reps, [1, os.cpu_count()])
        if "planes" in a.only:
            res["planes"] += bench_planes(name, z, cam, a.rounds, a.reps, [1, os.cpu_count()])
    if "tsdf" in a.only:
        res["tsdf"] = bench_tsdf(a.data, a.rounds)
    if "overhead" in a.only:
        res["overhead"] = bench_overhead(a.data, a.rounds, a.reps)
    res["info"]["loadavg_end"] = os.getloadavg()
    for k in ("filter", "planes", "tsdf", "overhead"):
        for row in res[k]:
            print(k, json.dumps({x: (round(v, 4) if isinstance(v, float) else v) for x, v in row.items()}))
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()

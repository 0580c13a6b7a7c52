"""Open3D's camera trackers on the real sequences of ../shared/data, for the side-by-side
trajectory table of issue 13 (never needed by tests).

    python docs/bench/track_peers.py [--data ../shared/data] [--out /tmp/track-peers] [--json out.json]
                                     [--voxel-m 0.008] [--only tum|7scenes|icl ...] [--undistort-tum]

Needs numpy and ``open3d-cpu==0.19.0`` (the PyPI ``open3d==0.20.0`` wheel's volumes integrate
nothing on our machines; see python_peers.py). Runs, on the depth frames alone (no colour: the
200-frame TUM sequence ships without RGB, so Open3D's Hybrid odometry, which needs intensity, is
not run):

- ``frame-to-frame``: ``o3d.t.pipelines.odometry.rgbd_odometry_multi_scale`` (PointToPlane,
  three levels with 20/10/5 iterations, as Open3D's defaults), each frame against the previous
  one, chained;
- ``dense-slam``: ``o3d.t.pipelines.slam.Model`` (frame to model: track against the raycast of
  the fused volume, then integrate), as Open3D's ``examples/python/t_reconstruction_system/
  dense_slam.py`` does, with the voxel size given (8 mm by default) and the same depth range as
  ours (0.1 to 4 m).

Every trajectory is written in TUM format (``timestamp tx ty tz qx qy qz qw``, camera-to-world,
first frame at the identity) to ``--out``, so that ``sldepth eval-traj EST GT`` can score it the
same way as ours; the script also prints its own ATE (RMSE after Horn's closed-form rigid
alignment, the TUM benchmark's definition) and ms per frame. Timestamps: TUM's own; 7-Scenes and
ICL number their frames, so the frame index / 30 s is used for both the estimate and the
reference written beside it (``*-gt.txt``).
"""

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np
import open3d as o3d

DEPTH_MIN_M = 0.1
DEPTH_MAX_M = 4.0


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(r):
    # Shepperd's method, returns (x, y, z, w) with w >= 0.
    t = np.trace(r)
    if t > 0:
        s = np.sqrt(t + 1.0) * 2
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        q = [0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
    elif r[1, 1] > r[2, 2]:
        s = np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        q = [(r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
    else:
        s = np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
        q = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s, (r[1, 0] - r[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[3] >= 0 else -q


def write_tum(path, stamps, poses):
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw (camera-to-world)\n")
        for t, p in zip(stamps, poses):
            q = matrix_to_quat(p[:3, :3])
            f.write(
                f"{t:.6f} {p[0, 3]:.6f} {p[1, 3]:.6f} {p[2, 3]:.6f} "
                f"{q[0]:.6f} {q[1]:.6f} {q[2]:.6f} {q[3]:.6f}\n"
            )


def read_tum(path):
    out = []
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        m = np.eye(4)
        m[:3, :3] = quat_to_matrix(v[4:8])
        m[:3, 3] = v[1:4]
        out.append((v[0], m))
    return out


def associate(stamps, gt, max_gap_s=0.02):
    """Nearest ground-truth pose for each stamp within max_gap_s (TUM's associate.py rule,
    each reference used once)."""
    gt_t = np.array([t for t, _ in gt])
    pairs, used = [], set()
    for i, t in enumerate(stamps):
        j = int(np.argmin(np.abs(gt_t - t)))
        if abs(gt_t[j] - t) <= max_gap_s and j not in used:
            used.add(j)
            pairs.append((i, j))
    return pairs


def ate_rmse(est_xyz, gt_xyz):
    """RMSE of the translations after Horn's closed-form rigid alignment (no scale)."""
    mu_e, mu_g = est_xyz.mean(0), gt_xyz.mean(0)
    h = (est_xyz - mu_e).T @ (gt_xyz - mu_g)
    u, _, vt = np.linalg.svd(h)
    d = np.eye(3)
    d[2, 2] = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ d @ u.T
    aligned = (r @ (est_xyz - mu_e).T).T + mu_g
    return float(np.sqrt(np.mean(np.sum((aligned - gt_xyz) ** 2, axis=1))))


def sequences(data, only):
    seqs = []
    tum = data / "tum-fr1-rpy-200"
    if tum.is_dir() and (not only or "tum" in only):
        files, stamps = [], []
        for line in open(tum / "depth.txt"):
            if line.startswith("#") or not line.strip():
                continue
            t, f = line.split()[:2]
            stamps.append(float(t))
            files.append(tum / f)
        k = [[517.3, 0, 318.6], [0, 516.5, 255.3], [0, 0, 1]]
        seqs.append(("tum-fr1-rpy-200", files, stamps, k, 5000.0, read_tum(tum / "groundtruth.txt")))
    sc = data / "7scenes-redkitchen"
    if sc.is_dir() and (not only or "7scenes" in only):
        files = sorted(sc.glob("frame-*.depth.png"))
        stamps = [i / 30.0 for i in range(len(files))]
        gt = []
        for t, f in zip(stamps, files):
            m = np.loadtxt(str(f).replace(".depth.png", ".pose.txt"))
            gt.append((t, m))
        k = [[585.0, 0, 320.0], [0, 585.0, 240.0], [0, 0, 1]]
        seqs.append(("7scenes-redkitchen", files, stamps, k, 1000.0, gt))
    icl = data / "open3d-testdata" / "icl-livingroom"
    if icl.is_dir() and (not only or "icl" in only):
        files = sorted((icl / "depth").glob("*.png"))
        stamps = [i / 30.0 for i in range(len(files))]
        lines = [l.split() for l in open(icl / "odometry.log") if l.strip()]
        gt = []
        for i in range(len(files)):
            rows = lines[5 * i + 1 : 5 * i + 5]
            gt.append((stamps[i], np.array([[float(x) for x in r] for r in rows])))
        k = [[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]]
        seqs.append(("icl-livingroom", files, stamps, k, 1000.0, gt))
    return seqs


# TUM fr1's published lens (k1, k2, p1, p2, k3), as the `tum-fr1` preset carries it.
TUM_FR1_LENS = (0.2624, -0.9531, -0.0054, 0.0026, 1.1633)


def nearest_undistort_map(k, lens, w, h):
    """Per pixel of the ideal pinhole image, the index of the distorted image's pixel it
    comes from (nearest neighbour), or -1 where the ray leaves the image: what
    ``sl_core::Undistorter`` and ``sldepth track --lens auto`` use."""
    k1, k2, p1, p2, k3 = lens
    fx, fy, cx, cy = k[0][0], k[1][1], k[0][2], k[1][2]
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    x, y = (u - cx) / fx, (v - cy) / fy
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    ud, vd = np.round(fx * xd + cx), np.round(fy * yd + cy)
    inside = (ud >= 0) & (vd >= 0) & (ud < w) & (vd < h)
    return np.where(inside, vd * w + ud, -1).astype(np.int64)


def read_depth(path, undistort=None):
    img = o3d.t.io.read_image(str(path))
    if undistort is None:
        return img
    z = np.asarray(img).reshape(-1)
    out = np.where(undistort >= 0, z[np.maximum(undistort, 0)], 0).astype(z.dtype)
    return o3d.t.geometry.Image(out.reshape(img.rows, img.columns, 1))


def frame_to_frame(files, k, scale, undistort=None):
    intr = o3d.core.Tensor(k, o3d.core.Dtype.Float64)
    criteria = [
        o3d.t.pipelines.odometry.OdometryConvergenceCriteria(n)
        for n in (20, 10, 5)
    ]
    poses = [np.eye(4)]
    times = []
    prev = None
    for f in files:
        depth = read_depth(f, undistort)
        h, w = depth.rows, depth.columns
        color = o3d.t.geometry.Image(np.zeros((h, w, 3), np.uint8))
        cur = o3d.t.geometry.RGBDImage(color, depth)
        if prev is not None:
            t0 = time.perf_counter()
            res = o3d.t.pipelines.odometry.rgbd_odometry_multi_scale(
                cur,
                prev,
                intr,
                o3d.core.Tensor(np.eye(4)),
                scale,
                DEPTH_MAX_M,
                criteria,
                o3d.t.pipelines.odometry.Method.PointToPlane,
            )
            times.append((time.perf_counter() - t0) * 1e3)
            poses.append(poses[-1] @ res.transformation.numpy())
        prev = cur
    return poses, times


def dense_slam(files, k, scale, voxel_m, undistort=None):
    device = o3d.core.Device("CPU:0")
    intr = o3d.core.Tensor(k, o3d.core.Dtype.Float64)
    t_frame_to_model = o3d.core.Tensor(np.identity(4))
    model = o3d.t.pipelines.slam.Model(voxel_m, 16, 50000, t_frame_to_model, device)
    first = read_depth(files[0], undistort)
    inp = o3d.t.pipelines.slam.Frame(first.rows, first.columns, intr, device)
    ray = o3d.t.pipelines.slam.Frame(first.rows, first.columns, intr, device)
    color = o3d.t.geometry.Image(np.zeros((first.rows, first.columns, 3), np.uint8))
    poses, times = [], []
    trunc_mult = 8.0
    for i, f in enumerate(files):
        depth = read_depth(f, undistort)
        inp.set_data_from_image("depth", depth)
        inp.set_data_from_image("color", color)
        t0 = time.perf_counter()
        if i > 0:
            res = model.track_frame_to_model(inp, ray, scale, DEPTH_MAX_M, 0.07)
            t_frame_to_model = t_frame_to_model @ res.transformation
        poses.append(t_frame_to_model.cpu().numpy())
        model.update_frame_pose(i, t_frame_to_model)
        model.integrate(inp, scale, DEPTH_MAX_M, trunc_mult)
        model.synthesize_model_frame(ray, scale, DEPTH_MIN_M, DEPTH_MAX_M, trunc_mult, False)
        times.append((time.perf_counter() - t0) * 1e3)
    return poses, times


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[3] / "shared" / "data"))
    ap.add_argument("--out", default="/tmp/track-peers")
    ap.add_argument("--json")
    ap.add_argument("--voxel-m", type=float, default=0.008)
    ap.add_argument("--only", action="append")
    ap.add_argument("--undistort-tum", action="store_true",
                    help="resample the TUM frames with the tum-fr1 lens model first (nearest "
                         "neighbour, as sldepth track --lens auto does)")
    args = ap.parse_args()
    data = Path(args.data)
    if not data.is_dir():
        data = Path("../shared/data")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    o3d.core.Device("CPU:0")
    print(f"open3d {o3d.__version__}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cpus")
    rows = []
    for name, files, stamps, k, scale, gt in sequences(data, args.only):
        # The reference in TUM format beside the estimates.
        write_tum(out / f"{name}-gt.txt", [t for t, _ in gt], [m for _, m in gt])
        undistort = None
        if args.undistort_tum and name.startswith("tum"):
            first = o3d.t.io.read_image(str(files[0]))
            undistort = nearest_undistort_map(k, TUM_FR1_LENS, first.columns, first.rows)
        tag = "-undistorted" if undistort is not None else ""
        for method in ("frame-to-frame", "dense-slam"):
            if method == "frame-to-frame":
                poses, times = frame_to_frame(files, k, scale, undistort)
            else:
                poses, times = dense_slam(files, k, scale, args.voxel_m, undistort)
            path = out / f"{name}-open3d-{method}{tag}.txt"
            write_tum(path, stamps, poses)
            pairs = associate(stamps, gt)
            est = np.array([poses[i][:3, 3] for i, _ in pairs])
            ref = np.array([gt[j][1][:3, 3] for _, j in pairs])
            ate = ate_rmse(est, ref)
            row = {
                "sequence": name,
                "method": f"open3d {method}{tag}",
                "frames": len(files),
                "associated": len(pairs),
                "ate_rmse_m": ate,
                "ms_per_frame_median": float(np.median(times)) if times else None,
                "trajectory": str(path),
            }
            rows.append(row)
            print(f"{name:20s} {method:15s} ATE {ate * 100:6.2f} cm  "
                  f"{row['ms_per_frame_median']:.1f} ms/frame  -> {path}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=2)


if __name__ == "__main__":
    main()

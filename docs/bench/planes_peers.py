"""Plane-extraction peers on the real-frame repeatability benchmark of issue 12.

The same metric as ``cargo xtask validate --only planes`` (xtask/src/validate/planes/repeat.rs):
planes of at least 5,000 pixels in frame i, moved to world coordinates with the ground-truth
poses, count as found again in frame i + k (k = 1, 5, 10) when a plane of frame i + k has its
normal within 3 degrees and passes within 3 cm of the centroid of frame i's plane.

Peer: OpenCV 5 ``cv2.findPlanes`` (RgbdPlane) on ``cv2.depthTo3d`` clouds, with its Kinect
``sensor_error_a = 0.0075``. On the rooms also Open3D ``detect_planar_patches`` (oriented boxes,
turned into labels by box containment; not on the repeatability benchmark). Any other
program's label images (CAPE, run by a driver described in docs/bench/README.md) are scored by
``--rooms-labels`` and ``--labels-root``. TUM frames are resampled with the ``tum-fr1`` lens model
(nearest neighbour, as ``sl_core::Undistorter``) unless ``--raw-tum`` is given, as validate does.

Rooms: ``--rooms DIR`` scores the peer on the randomised room benchmark instead, the frames
written by ``cargo run --release -p sl-planes --example export_rooms -- DIR``, with the rules of
the validate experiment (xtask/src/validate/planes/rooms.rs): SegComp (Hoover et al.) at 80 %
overlap for ground-truth planes of at least 2,000 valid pixels, spurious = noise regions of at
least 2,000 pixels that detect no surface (not even one below the 2,000-pixel cut).

Usage (a venv with opencv-python-headless 5 and numpy)::

    python docs/bench/planes_peers.py [DATA_DIR]    # default ../shared/data
    python docs/bench/planes_peers.py --rooms DIR
    python docs/bench/planes_peers.py --rooms-open3d DIR   # needs open3d (slow: seconds a frame)
    python docs/bench/planes_peers.py --rooms-labels DIR LABEL_DIR NAME   # score NN-labels.png files
    python docs/bench/planes_peers.py DATA_DIR --export-frames OUT        # frames + list for a driver
    python docs/bench/planes_peers.py DATA_DIR --labels-root OUT --method NAME   # score its output

Tests never need this script.
"""

import sys
import time
from pathlib import Path

import cv2
import numpy as np

MIN_PIXELS = 5000
MAX_DEG = 3.0
MAX_OFFSET_M = 0.03
GAPS = (1, 5, 10)


def quat_pose(tx, ty, tz, qx, qy, qz, qw):
    x, y, z, w = qx, qy, qz, qw
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = (tx, ty, tz)
    return t


# TUM fr1's published lens (OpenCV order k1, k2, p1, p2, k3), as the `tum-fr1` preset carries it.
TUM_FR1_LENS = np.array([0.2624, -0.9531, -0.0054, 0.0026, 1.1633])


def nearest_undistorter(k, dist, size):
    """The nearest-neighbour resampling into the pinhole image of the same intrinsics
    (``sl_core::Undistorter``): depth values unchanged, 0 where the ray leaves the image."""
    mx, my = cv2.initUndistortRectifyMap(k, dist, None, k, size, cv2.CV_32FC1)
    return lambda z: cv2.remap(z, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def tum200(data):
    d = data / "tum-fr1-rpy-200"
    if not (d / "depth.txt").exists():
        return None
    gt = np.array([[float(v) for v in l.split()] for l in (d / "groundtruth.txt").read_text().splitlines()
                   if l and not l.startswith("#")])
    frames = []
    for l in (d / "depth.txt").read_text().splitlines():
        if not l or l.startswith("#"):
            continue
        ts, name = l.split()[:2]
        i = np.argmin(np.abs(gt[:, 0] - float(ts)))
        if abs(gt[i, 0] - float(ts)) <= 0.02:
            frames.append((d / name, quat_pose(*gt[i, 1:8])))
    k = np.array([[517.3, 0, 318.6], [0, 516.5, 255.3], [0, 0, 1]], dtype=np.float32)
    return "tum-fr1-rpy-200", frames, k, 5000.0, TUM_FR1_LENS


def seven_scenes(data):
    d = data / "7scenes-redkitchen"
    if not d.exists():
        return None
    frames = []
    for p in sorted(d.glob("frame-*.depth.png")):
        pose = np.loadtxt(str(p).replace(".depth.png", ".pose.txt"))
        frames.append((p, pose))
    k = np.array([[585, 0, 320], [0, 585, 240], [0, 0, 1]], dtype=np.float32)
    return "7scenes-redkitchen", frames, k, 1000.0, None


def planes_cv(z, k):
    """World-independent planes of one frame: (unit normal, offset, centroid, pixels)."""
    pts = cv2.depthTo3d(z, k)
    mask, coeffs = cv2.findPlanes(pts, None, sensor_error_a=0.0075)
    out = []
    if coeffs is None:
        return out
    coeffs = np.asarray(coeffs).reshape(-1, 4)
    for i, c in enumerate(coeffs):
        sel = mask == i
        n = int(sel.sum())
        if n == 0:
            continue
        p = pts[sel][:, :3]
        p = p[np.isfinite(p).all(axis=1)]
        if len(p) == 0:
            continue
        nrm = np.linalg.norm(c[:3])
        out.append((c[:3] / nrm, c[3] / nrm, p.mean(axis=0), n))
    return out


def planes_from_labels(z, k, labels, params):
    """Planes of an external segmentation: ``params`` maps a label to (unit normal, offset m)
    of ``n·p + d = 0``; centroid and pixel count come from the label image."""
    pts = cv2.depthTo3d(z, k)
    out = []
    for lab, (n, d) in params.items():
        sel = (labels == lab) & (z > 0)
        px = int(sel.sum())
        if px == 0:
            continue
        out.append((n, d, pts[sel][:, :3].mean(axis=0), px))
    return out


def read_plane_params(path):
    params = {}
    for line in Path(path).read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        v = line.split()
        n = np.array([float(x) for x in v[1:4]])
        params[int(v[0])] = (n / np.linalg.norm(n), float(v[4]) / np.linalg.norm(n))
    return params


def to_world(planes, pose):
    r, t = pose[:3, :3], pose[:3, 3]
    out = []
    for n, d, cen, px in planes:
        nw = r @ n
        out.append((nw, d - nw @ t, r @ cen + t, px))
    return out


def same(a, b):
    cos = abs(float(a[0] @ b[0]))
    dist = abs(float(b[0] @ a[2] + b[1]))
    return np.degrees(np.arccos(min(1.0, cos))) <= MAX_DEG and dist <= MAX_OFFSET_M


def segcomp(gt, seg, valid, t=0.8, min_gt=2000):
    """Hoover et al. SegComp, as sl_eval::planes::segcomp_detail: counts and noise-region sizes."""
    g = gt[valid].astype(np.int64)
    m = seg[valid].astype(np.int64)
    gl, gc = np.unique(g[g != 0], return_counts=True)
    gsize = {int(a): int(b) for a, b in zip(gl, gc) if b >= min_gt}
    ml, mc = np.unique(m[m != 0], return_counts=True)
    msize = {int(a): int(b) for a, b in zip(ml, mc)}
    keep = (m != 0) & np.isin(g, list(gsize)) if gsize else np.zeros_like(m, bool)
    pairs, cnt = np.unique(np.stack([m[keep], g[keep]]), axis=1, return_counts=True)
    ov = {(int(a), int(b)): int(c) for (a, b), c in zip(pairs.T, cnt)}
    o = lambda a, b: ov.get((a, b), 0)
    gk, mk = sorted(gsize), sorted(msize)
    gu = {x: False for x in gk}
    mu = {x: False for x in mk}
    res = dict(gt=len(gk), correct=0, over=0, under=0)
    for gg in gk:
        for mm in mk:
            if not mu[mm] and o(mm, gg) >= t * msize[mm] and o(mm, gg) >= t * gsize[gg]:
                res["correct"] += 1
                gu[gg] = mu[mm] = True
                break
    for gg in gk:
        if gu[gg]:
            continue
        parts = [mm for mm in mk if not mu[mm] and o(mm, gg) > 0 and o(mm, gg) >= t * msize[mm]]
        if len(parts) >= 2 and sum(o(mm, gg) for mm in parts) >= t * gsize[gg]:
            res["over"] += 1
            gu[gg] = True
            for mm in parts:
                mu[mm] = True
    for mm in mk:
        if mu[mm]:
            continue
        parts = [gg for gg in gk if not gu[gg] and o(mm, gg) > 0 and o(mm, gg) >= t * gsize[gg]]
        if len(parts) >= 2 and sum(o(mm, gg) for mm in parts) >= t * msize[mm]:
            res["under"] += 1
            mu[mm] = True
            for gg in parts:
                gu[gg] = True
    res["missed"] = sum(1 for v in gu.values() if not v)
    noise = [mm for mm in mk if not mu[mm]]
    res["noise"] = len(noise)
    # A noise region that correctly detects a surface too small to be scored is not spurious.
    small = {int(a): int(b) for a, b in zip(gl, gc) if b < min_gt}
    sk = (m != 0) & np.isin(g, list(small)) if small else np.zeros_like(m, bool)
    sp, sc = np.unique(np.stack([m[sk], g[sk]]), axis=1, return_counts=True)
    on_small = {int(a) for (a, b), c in zip(sp.T, sc) if c >= t * msize[int(a)] and c >= t * small[int(b)]}
    res["spurious"] = sum(1 for mm in noise if msize[mm] >= min_gt and mm not in on_small)
    return res


def rooms(d):
    cams = {l.split()[0]: [float(v) for v in l.split()[1:]] for l in (d / "cameras.txt").read_text().splitlines()}
    total = dict(gt=0, correct=0, over=0, under=0, missed=0, noise=0, spurious=0)
    worst = 0.0
    for name, (fx, fy, cx, cy) in sorted(cams.items()):
        z = cv2.imread(str(d / f"{name}-depth.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 1000.0
        gt = cv2.imread(str(d / f"{name}-labels.png"), cv2.IMREAD_UNCHANGED)
        k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dtype=np.float32)
        pts = cv2.depthTo3d(z, k)
        t0 = time.perf_counter()
        mask, _ = cv2.findPlanes(pts, None, sensor_error_a=0.0075)
        worst = max(worst, (time.perf_counter() - t0) * 1e3)
        seg = np.where(mask == 255, 0, mask.astype(np.int64) + 1)
        r = segcomp(gt, seg, z > 0)
        for key in total:
            total[key] += r[key]
    print("| method | GT planes | correct | over | under | missed | noise | spurious >= 2000 px | worst ms |")
    print("|---|---|---|---|---|---|---|---|---|")
    print(f"| cv2.findPlanes | {total['gt']} | {total['correct']} ({100 * total['correct'] / max(total['gt'], 1):.1f} %) | "
          f"{total['over']} | {total['under']} | {total['missed']} | {total['noise']} | {total['spurious']} | {worst:.0f} |")


def rooms_labels(d, labels_dir, method):
    """Scores label images made by another program (e.g. CAPE, see docs/bench/README.md): for
    every room ``NN``, ``labels_dir/NN-labels.png`` (16-bit, 0 = no plane)."""
    cams = {l.split()[0]: [float(v) for v in l.split()[1:]] for l in (d / "cameras.txt").read_text().splitlines()}
    total = dict(gt=0, correct=0, over=0, under=0, missed=0, noise=0, spurious=0)
    for name in sorted(cams):
        z = cv2.imread(str(d / f"{name}-depth.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 1000.0
        gt = cv2.imread(str(d / f"{name}-labels.png"), cv2.IMREAD_UNCHANGED)
        seg = cv2.imread(str(labels_dir / f"{name}-labels.png"), cv2.IMREAD_UNCHANGED).astype(np.int64)
        r = segcomp(gt, seg, z > 0)
        for key in total:
            total[key] += r[key]
    print(f"| {method} | {total['gt']} | {total['correct']} ({100 * total['correct'] / max(total['gt'], 1):.1f} %) | "
          f"{total['over']} | {total['under']} | {total['missed']} | {total['noise']} | {total['spurious']} | – |")


def planes_open3d(z, fx, fy, cx, cy):
    """Open3D ``detect_planar_patches`` (default parameters, normals from 30 neighbours) as a
    label image: a pixel takes the smallest oriented box that contains its point."""
    import open3d as o3d

    h, w = z.shape
    u, v = np.meshgrid(np.arange(w), np.arange(h))
    valid = z > 0
    pts = np.stack([(u - cx) * z / fx, (v - cy) * z / fy, z], -1)[valid].astype(np.float64)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(30))
    boxes = pc.detect_planar_patches(search_param=o3d.geometry.KDTreeSearchParamKNN(30))
    flat = np.zeros(len(pts), np.int64)
    best = np.full(len(pts), np.inf)
    for i, b in enumerate(boxes):
        idx = np.asarray(b.get_point_indices_within_bounding_box(pc.points), np.int64)
        vol = b.volume()
        sel = idx[vol < best[idx]]
        flat[sel] = i + 1
        best[sel] = vol
    seg = np.zeros((h, w), np.int64)
    seg[valid] = flat
    return seg


def rooms_open3d(d):
    cams = {l.split()[0]: [float(v) for v in l.split()[1:]] for l in (d / "cameras.txt").read_text().splitlines()}
    total = dict(gt=0, correct=0, over=0, under=0, missed=0, noise=0, spurious=0)
    worst = 0.0
    for name, (fx, fy, cx, cy) in sorted(cams.items()):
        z = cv2.imread(str(d / f"{name}-depth.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 1000.0
        gt = cv2.imread(str(d / f"{name}-labels.png"), cv2.IMREAD_UNCHANGED)
        t0 = time.perf_counter()
        seg = planes_open3d(z, fx, fy, cx, cy)
        worst = max(worst, (time.perf_counter() - t0) * 1e3)
        r = segcomp(gt, seg, z > 0)
        for key in total:
            total[key] += r[key]
    print(f"| open3d detect_planar_patches | {total['gt']} | {total['correct']} ({100 * total['correct'] / max(total['gt'], 1):.1f} %) | "
          f"{total['over']} | {total['under']} | {total['missed']} | {total['noise']} | {total['spurious']} | {worst:.0f} |")


def option(name):
    """The value after ``name`` on the command line (removed from it), or None."""
    if name not in sys.argv:
        return None
    i = sys.argv.index(name)
    value = sys.argv[i + 1]
    del sys.argv[i:i + 2]
    return value


def flag(name):
    if name in sys.argv:
        sys.argv.remove(name)
        return True
    return False


def main():
    if len(sys.argv) > 4 and sys.argv[1] == "--rooms-labels":
        rooms_labels(Path(sys.argv[2]), Path(sys.argv[3]), sys.argv[4])
        return
    if len(sys.argv) > 2 and sys.argv[1] == "--rooms-open3d":
        rooms_open3d(Path(sys.argv[2]))
        return
    if len(sys.argv) > 2 and sys.argv[1] == "--rooms":
        cv2.setNumThreads(1)
        rooms(Path(sys.argv[2]))
        return
    raw_tum = flag("--raw-tum")
    export = option("--export-frames")
    labels_root = option("--labels-root")
    method = option("--method") or ("external" if labels_root else "cv2.findPlanes")
    data = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[3] / "shared/data"
    cv2.setNumThreads(1)
    if not export:
        print("| sequence | method | k | planes tested | found again | planes | pixels |")
        print("|---|---|---|---|---|---|---|")
    summary = []
    for seq in (tum200(data), seven_scenes(data)):
        if seq is None:
            continue
        name, frames, k, scale, lens = seq
        undistort = None
        if lens is not None and not raw_tum:
            undistort = nearest_undistorter(k, lens, (640, 480))
        if export:
            out = Path(export) / name
            (out / "ext").mkdir(parents=True, exist_ok=True)
            lines = []
            for i, (path, _) in enumerate(frames):
                raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
                if undistort is not None:
                    raw = undistort(raw)
                cv2.imwrite(str(out / f"{i:04}-depth.png"), raw)
                lines.append(f"{out / f'{i:04}-depth.png'} {k[0, 0]} {k[1, 1]} {k[0, 2]} {k[1, 2]} {scale} {out / 'ext' / f'{i:04}'}")
            (out / "list.txt").write_text("\n".join(lines) + "\n")
            print(f"wrote {len(lines)} frames and {out / 'list.txt'}")
            continue
        world, times, counts = [], [], []
        for i, (path, pose) in enumerate(frames):
            z = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if undistort is not None:
                z = undistort(z)
            z = z.astype(np.float32) / scale
            if labels_root:
                base = Path(labels_root) / name / "ext" / f"{i:04}"
                labels = cv2.imread(f"{base}-labels.png", cv2.IMREAD_UNCHANGED)
                text = Path(f"{base}-planes.txt").read_text()
                times.append(float(text.split()[2]))
                planes = planes_from_labels(z, k, labels, read_plane_params(f"{base}-planes.txt"))
            else:
                t0 = time.perf_counter()
                planes = planes_cv(z, k)
                times.append((time.perf_counter() - t0) * 1e3)
            counts.append(len(planes))
            world.append(to_world(planes, pose))
        for gap in GAPS:
            tested = found = px = fpx = 0
            for i in range(len(world) - gap):
                for p in world[i]:
                    if p[3] < MIN_PIXELS:
                        continue
                    tested += 1
                    px += p[3]
                    if any(same(p, q) for q in world[i + gap]):
                        found += 1
                        fpx += p[3]
            print(f"| {name} | {method} | {gap} | {tested} | {found} | "
                  f"{100 * found / max(tested, 1):.1f} % | {100 * fpx / max(px, 1):.1f} % |")
        summary.append((name, np.mean(counts), max(times), np.median(times)))
    if export:
        return
    print()
    print("| sequence | method | planes per frame | worst ms | median ms |")
    print("|---|---|---|---|---|")
    for name, c, worst, med in summary:
        print(f"| {name} | {method} | {c:.2f} | {worst:.1f} | {med:.1f} |")


if __name__ == "__main__":
    main()

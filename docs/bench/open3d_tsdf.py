#!/usr/bin/env python3
"""Open3D reference timing for `sldepth fuse` (issue 4): ScalableTSDFVolume on the same frames.

Measurement only -- no test needs this script or Open3D.

    pip install open3d-cpu==0.19.0        # or open3d==0.19.0
    python docs/bench/open3d_tsdf.py --dataset icl     [--data ../shared/data] [--threads 2]
    python docs/bench/open3d_tsdf.py --dataset 7scenes --frames 50

Parameters match `sldepth fuse` defaults used in the benchmark: 4 mm voxels, 2 cm truncation
(`sdf_trunc`), depth scale 1000 (both datasets store millimetres), max depth 4 m, no colour
(`TSDFVolumeColorType.NoColor`). Prints one JSON object with the per-frame integration times
(median, excluding file I/O: images are decoded before the timer starts), the marching-cubes
time of `extract_triangle_mesh`, and the mesh size. Run it interleaved with our runs and take
medians (see docs/bench/README or the issue report).
"""
import argparse
import json
import os
import statistics
import time

import numpy as np
import open3d as o3d


def read_log(path):
    lines = [l for l in open(path) if l.strip()]
    poses = []
    for i in range(0, len(lines), 5):
        m = np.array([[float(x) for x in l.split()] for l in lines[i + 1:i + 5]])
        poses.append(m)
    return poses


def load(dataset, data, nframes):
    if dataset == "icl":
        d = os.path.join(data, "open3d-testdata", "icl-livingroom")
        k = o3d.camera.PinholeCameraIntrinsic(640, 480, 525.0, 525.0, 319.5, 239.5)
        poses = read_log(os.path.join(d, "odometry.log"))
        files = [os.path.join(d, "depth", "%05d.png" % i) for i in range(len(poses))]
    else:
        d = os.path.join(data, "7scenes-redkitchen")
        k = o3d.camera.PinholeCameraIntrinsic(640, 480, 585.0, 585.0, 320.0, 240.0)
        files, poses = [], []
        for i in range(150, 150 + nframes):
            files.append(os.path.join(d, "frame-%06d.depth.png" % i))
            poses.append(np.loadtxt(os.path.join(d, "frame-%06d.pose.txt" % i)))
    frames = []
    for f, p in list(zip(files, poses))[:nframes]:
        depth = np.asarray(o3d.io.read_image(f)).copy()
        depth[depth == 65535] = 0  # 7-Scenes marks invalid pixels with 65535
        depth_img = o3d.geometry.Image(depth)
        color = o3d.geometry.Image(np.zeros((480, 640, 3), dtype=np.uint8))
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(
            color, depth_img, depth_scale=1000.0, depth_trunc=4.0, convert_rgb_to_intensity=False)
        # Open3D wants world-to-camera extrinsics.
        frames.append((rgbd, np.linalg.inv(p)))
    return k, frames


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dataset", choices=["icl", "7scenes"], default="icl")
    ap.add_argument("--data", default=os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data"))
    ap.add_argument("--frames", type=int, default=50)
    ap.add_argument("--voxel-m", type=float, default=0.004)
    ap.add_argument("--trunc-m", type=float, default=0.02)
    ap.add_argument("--output", default=None, help="write the mesh here (PLY)")
    args = ap.parse_args()
    k, frames = load(args.dataset, args.data, args.frames)
    vol = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=args.voxel_m, sdf_trunc=args.trunc_m,
        color_type=o3d.pipelines.integration.TSDFVolumeColorType.NoColor)
    times = []
    for rgbd, extr in frames:
        t0 = time.perf_counter()
        vol.integrate(rgbd, k, extr)
        times.append((time.perf_counter() - t0) * 1e3)
    t0 = time.perf_counter()
    mesh = vol.extract_triangle_mesh()
    extract_ms = (time.perf_counter() - t0) * 1e3
    if args.output:
        o3d.io.write_triangle_mesh(args.output, mesh)
    print(json.dumps({
        "tool": "open3d " + o3d.__version__,
        "dataset": args.dataset,
        "frames": len(frames),
        "integrate_ms_median": statistics.median(times),
        "integrate_ms": [round(t, 2) for t in times],
        "extract_ms": extract_ms,
        "vertices": len(mesh.vertices),
        "triangles": len(mesh.triangles),
    }))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Open3D peers of `sldepth track` on the same depth frames (issue 13), ATE/RPE side by side.

    /work/peers-venv/bin/python docs/bench/track_peers_quick.py tum DIR      # depth.txt + groundtruth.txt
    /work/peers-venv/bin/python docs/bench/track_peers_quick.py 7scenes DIR  # frame-*.depth.png + .pose.txt
    /work/peers-venv/bin/python docs/bench/track_peers_quick.py icl DIR      # depth/*.png + odometry.log

Runs Open3D's tensor `rgbd_odometry_multi_scale` (PointToPlane, frame to frame; Hybrid needs
colour and is skipped: the comparison is depth only) and the dense SLAM `o3d.t.pipelines.slam.Model`
(frame to model, 8 mm voxels like the issue's reference run) with a constant grey colour image,
and prints ATE RMSE (Horn alignment) and RPE per frame. Optional `--ours TRAJ.txt` evaluates a
`sldepth track --output` trajectory the same way. `--reference-model` (7scenes, icl) also
tracks every frame against a model Open3D fused with the reference poses, the peer of
`cargo run --release -p sl-track --example gt_model_probe`. `--write DIR` saves each peer's
trajectory as a TUM file in DIR (e.g. for `sldepth eval-traj --estimate-offset`). Needs open3d
(0.19 tested) and numpy; tests never run it.
"""
import argparse, glob, os, sys, time
import numpy as np
import open3d as o3d
import open3d.core as o3c


def quat_to_R(q):
    x, y, z, w = q
    return np.array([[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)],
                     [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)],
                     [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]])


def mat(t, q):
    m = np.eye(4); m[:3, :3] = quat_to_R(q); m[:3, 3] = t; return m


def load(kind, d):
    """(depth paths, timestamps or indices, ground truth {stamp: 4x4}, K, depth scale)"""
    if kind == 'tum':
        rows = [l.split() for l in open(os.path.join(d, 'depth.txt')) if l.strip() and not l.startswith('#')]
        paths = [os.path.join(d, r[1]) for r in rows]; stamps = [float(r[0]) for r in rows]
        gt = {}
        for l in open(os.path.join(d, 'groundtruth.txt')):
            if l.strip() and not l.startswith('#'):
                v = [float(x) for x in l.split()]; gt[v[0]] = mat(v[1:4], v[4:8])
        return paths, stamps, gt, (517.3, 516.5, 318.6, 255.3), 5000.0
    if kind == '7scenes':
        paths = sorted(glob.glob(os.path.join(d, 'frame-*.depth.png')))
        gt = {float(i): np.loadtxt(p.replace('.depth.png', '.pose.txt')) for i, p in enumerate(paths)}
        return paths, [float(i) for i in range(len(paths))], gt, (585.0, 585.0, 320.0, 240.0), 1000.0
    paths = sorted(glob.glob(os.path.join(d, 'depth', '*.png')))
    lines = [l for l in open(os.path.join(d, 'odometry.log')).read().split('\n') if l.strip()]
    gt = {float(i // 5): np.array([[float(x) for x in lines[i + 1 + r].split()] for r in range(4)])
          for i in range(0, len(lines), 5)}
    return paths, [float(i) for i in range(len(paths))], gt, (525.0, 525.0, 319.5, 239.5), 1000.0


def evaluate(est, gt):
    """est, gt: {stamp: 4x4}. ATE RMSE after Horn alignment, RPE per consecutive pair."""
    gts = np.array(sorted(gt)); pairs = []
    for t in sorted(est):
        i = int(np.argmin(abs(gts - t)))
        if abs(gts[i] - t) < 0.02:
            pairs.append((t, gts[i]))
    A = np.array([est[t][:3, 3] for t, _ in pairs]); B = np.array([gt[g][:3, 3] for _, g in pairs])
    ma, mb = A.mean(0), B.mean(0)
    U, _, Vt = np.linalg.svd((A - ma).T @ (B - mb))
    D = np.diag([1, 1, np.sign(np.linalg.det(Vt.T @ U.T))]); R = Vt.T @ D @ U.T
    E = (R @ A.T).T + (mb - R @ ma) - B
    tr, rot = [], []
    for (t1, g1), (t2, g2) in zip(pairs, pairs[1:]):
        e = np.linalg.inv(np.linalg.inv(gt[g1]) @ gt[g2]) @ (np.linalg.inv(est[t1]) @ est[t2])
        tr.append(np.linalg.norm(e[:3, 3]))
        rot.append(np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1))))
    return len(pairs), np.sqrt((E ** 2).sum(1).mean()), np.sqrt(np.mean(np.square(tr))), np.sqrt(np.mean(np.square(rot)))


def grey(depth):
    return o3d.t.geometry.Image(o3c.Tensor(np.full((depth.rows, depth.columns, 3), 128, np.uint8)))


def odometry(paths, K, scale, depth_max):
    dev = o3c.Device('CPU:0'); intr = o3c.Tensor(K)
    crit = [o3d.t.pipelines.odometry.OdometryConvergenceCriteria(i) for i in (6, 3, 1)]
    pose = np.eye(4); poses = [pose.copy()]; prev = None; times = []
    for p in paths:
        d = o3d.t.io.read_image(p).to(dev); cur = o3d.t.geometry.RGBDImage(grey(d), d)
        if prev is not None:
            t0 = time.time()
            r = o3d.t.pipelines.odometry.rgbd_odometry_multi_scale(
                cur, prev, intr, o3c.Tensor(np.eye(4)), scale, depth_max, crit,
                o3d.t.pipelines.odometry.Method.PointToPlane)
            times.append(time.time() - t0)
            pose = pose @ r.transformation.numpy(); poses.append(pose.copy())
        prev = cur
    return poses, np.median(times) * 1e3


def dense_slam(paths, K, scale, depth_max, voxel):
    dev = o3c.Device('CPU:0'); intr = o3c.Tensor(K)
    T = o3c.Tensor(np.eye(4)); poses = []; times = []
    model = o3d.t.pipelines.slam.Model(voxel, 16, 40000, T, dev)
    d0 = o3d.t.io.read_image(paths[0])
    frame = o3d.t.pipelines.slam.Frame(d0.rows, d0.columns, intr, dev)
    ray = o3d.t.pipelines.slam.Frame(d0.rows, d0.columns, intr, dev)
    for i, p in enumerate(paths):
        d = o3d.t.io.read_image(p).to(dev)
        frame.set_data_from_image('depth', d); frame.set_data_from_image('color', grey(d))
        t0 = time.time()
        if i > 0:
            r = model.track_frame_to_model(frame, ray, scale, depth_max, 0.07)
            T = T @ r.transformation
        poses.append(T.cpu().numpy())
        model.update_frame_pose(i, T)
        model.integrate(frame, scale, depth_max, 8.0)
        model.synthesize_model_frame(ray, scale, 0.1, depth_max, 8.0, False)
        times.append(time.time() - t0)
    return poses, np.median(times) * 1e3


def dense_slam_reference_model(paths, gt_poses, K, scale, depth_max, voxel):
    """Open3D's frame-to-model tracking against a model fused with the reference poses (all
    frames), each frame tracked from the last tracked pose: what a tracker that aligns the
    frames to the reference's own map scores against that reference (see gt_model_probe)."""
    dev = o3c.Device('CPU:0'); intr = o3c.Tensor(K)
    model = o3d.t.pipelines.slam.Model(voxel, 16, 40000, o3c.Tensor(np.eye(4)), dev)
    d0 = o3d.t.io.read_image(paths[0])
    frame = o3d.t.pipelines.slam.Frame(d0.rows, d0.columns, intr, dev)
    ray = o3d.t.pipelines.slam.Frame(d0.rows, d0.columns, intr, dev)
    for i, (p, G) in enumerate(zip(paths, gt_poses)):
        d = o3d.t.io.read_image(p).to(dev)
        frame.set_data_from_image('depth', d); frame.set_data_from_image('color', grey(d))
        model.update_frame_pose(i, o3c.Tensor(G))
        model.integrate(frame, scale, depth_max, 8.0)
    T = gt_poses[0].copy(); poses = [T.copy()]
    for i, p in enumerate(paths[1:], 1):
        d = o3d.t.io.read_image(p).to(dev)
        frame.set_data_from_image('depth', d); frame.set_data_from_image('color', grey(d))
        model.update_frame_pose(i, o3c.Tensor(T))
        model.synthesize_model_frame(ray, scale, 0.1, depth_max, 8.0, False)
        r = model.track_frame_to_model(frame, ray, scale, depth_max, 0.07)
        T = T @ r.transformation.numpy(); poses.append(T.copy())
    return poses, float('nan')


def R_to_quat(R):
    """(x, y, z, w) of a rotation matrix (Shepperd's method)."""
    t = np.trace(R)
    if t > 0:
        s = 2 * np.sqrt(t + 1); return [(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, s / 4]
    i = int(np.argmax(np.diag(R))); j, k = (i + 1) % 3, (i + 2) % 3
    s = 2 * np.sqrt(1 + R[i, i] - R[j, j] - R[k, k]); q = [0.0] * 4
    q[i] = s / 4; q[j] = (R[j, i] + R[i, j]) / s; q[k] = (R[k, i] + R[i, k]) / s; q[3] = (R[k, j] - R[j, k]) / s
    return q


def write_tum(path, stamps, poses):
    os.makedirs(os.path.dirname(path) or '.', exist_ok=True)
    with open(path, 'w') as f:
        for t, P in zip(stamps, poses):
            P = np.asarray(P); q = R_to_quat(P[:3, :3])
            f.write(f'{t:.6f} ' + ' '.join(f'{v:.7f}' for v in list(P[:3, 3]) + list(q)) + '\n')


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('kind', choices=['tum', '7scenes', 'icl']); ap.add_argument('dir')
    ap.add_argument('--ours', action='append', default=[]); ap.add_argument('--depth-max', type=float, default=4.0)
    ap.add_argument('--focal-px', type=float, default=None,
                    help="replace the data set's fx = fy (a calibration check, e.g. ICL's sample)")
    ap.add_argument('--reference-model', action='store_true',
                    help='also track against a model fused with the reference poses (7scenes, icl)')
    ap.add_argument('--write', metavar='DIR', default=None,
                    help="save each peer's trajectory in TUM format (camera to world) in DIR")
    a = ap.parse_args()
    paths, stamps, gt, (fx, fy, cx, cy), scale = load(a.kind, a.dir)
    if a.focal_px is not None:
        fx = fy = a.focal_px
    K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
    for o in a.ours:
        est = {}
        for l in open(o):
            if l.strip() and not l.startswith('#'):
                v = [float(x) for x in l.split()]; est[v[0]] = mat(v[1:4], v[4:8])
        n, ate, rt, rr = evaluate(est, gt)
        print(f'{o}: {n} poses, ATE {ate*100:.2f} cm, RPE {rt*1000:.1f} mm {rr:.2f} deg')
    runs = [('open3d odometry PointToPlane', lambda: odometry(paths, K, scale, a.depth_max)),
            ('open3d dense SLAM 8 mm', lambda: dense_slam(paths, K, scale, a.depth_max, 0.008))]
    if a.reference_model and a.kind != 'tum':
        runs.append(('open3d frame to the reference-pose model, 8 mm',
                     lambda: dense_slam_reference_model(paths, [gt[t] for t in stamps], K, scale,
                                                        a.depth_max, 0.008)))
    for name, run in runs:
        poses, ms = run()
        if a.write:
            write_tum(os.path.join(a.write, name.replace(' ', '-') + '.txt'), stamps, poses)
        n, ate, rt, rr = evaluate(dict(zip(stamps, poses)), gt)
        timing = '' if ms != ms else f', {ms:.0f} ms/frame median'
        print(f'{name}: {n} poses, ATE {ate*100:.2f} cm, RPE {rt*1000:.1f} mm {rr:.2f} deg{timing}')


if __name__ == '__main__':
    sys.exit(main())

"""A synthetic odometry from a TUM ground truth: the camera's motion between consecutive
ground-truth samples, corrupted as a drifting odometry would be, integrated in a frame of its own.
usage: synthetic_odometry.py groundtruth.txt out.txt SCALE_ERR NOISE_FRAC ROT_FRAC BIAS_DEG_S SEED NOISE_M NOISE_DEG (the last two per ground-truth sample)"""
import sys
import numpy as np
from scipy.spatial.transform import Rotation as R

gt, out = sys.argv[1], sys.argv[2]
scale_err, noise_frac, rot_frac, bias_deg_s, seed, noise_m, noise_deg = map(float, sys.argv[3:10])
rng = np.random.default_rng(int(seed))
rows = [l.split() for l in open(gt) if l.strip() and not l.startswith('#')]
a = np.array([[float(x) for x in r] for r in rows])
t, p, q = a[:, 0], a[:, 1:4], a[:, 4:8]
rots = R.from_quat(q)
# odometry state, starting at an arbitrary pose of its own frame
cur_t = np.array([1.0, -2.0, 0.3])
cur_r = R.from_rotvec([0.1, 0.2, -0.3]) * rots[0]
bias_axis = np.array([0.0, 0.0, 1.0])
lines = [(t[0], cur_t.copy(), cur_r)]
for i in range(1, len(t)):
    # the camera's motion from sample i-1 to i, in camera i-1's frame
    dr = rots[i - 1].inv() * rots[i]
    dt = rots[i - 1].inv().apply(p[i] - p[i - 1])
    step = np.linalg.norm(dt)
    dt_odo = dt * (1.0 + scale_err) + rng.normal(0, noise_frac * step / np.sqrt(3), 3) + rng.normal(0, noise_m, 3)
    ang = np.linalg.norm(dr.as_rotvec())
    err = rng.normal(0, rot_frac * ang / np.sqrt(3), 3) + rng.normal(0, np.deg2rad(noise_deg), 3) + np.deg2rad(bias_deg_s) * (t[i] - t[i - 1]) * bias_axis
    dr_odo = dr * R.from_rotvec(err)
    cur_t = cur_t + cur_r.apply(dt_odo)
    cur_r = cur_r * dr_odo
    lines.append((t[i], cur_t.copy(), cur_r))
with open(out, 'w') as f:
    f.write('# synthetic odometry: camera in odom, from %s\n' % gt)
    for ti, tt, rr in lines:
        qq = rr.as_quat()
        f.write('%.6f %.6f %.6f %.6f %.7f %.7f %.7f %.7f\n' % (ti, *tt, *qq))

"""Every algorithm on small synthetic frames with known answers."""

import numpy as np
import pytest

import sldepth


def test_filter_keeps_a_flat_wall_and_holes(small_cam, wall):
    z = wall.copy()
    z[10, 10] = 0.0
    for method in ["adaptive", "bilateral", "gaussian", "disparity"]:
        out = sldepth.filter(z, small_cam, method=method)
        assert out.dtype == np.float32 and out.shape == z.shape
        assert out[10, 10] == 0.0
        valid = z > 0
        assert np.allclose(out[valid], 2.0, atol=1e-5), method


def test_filter_reduces_simulated_noise(kinect, three_planes):
    depth, truth, _ = three_planes
    out = sldepth.filter(depth, kinect)
    m = (truth > 0) & (depth > 0) & (out > 0)
    raw = np.sqrt(np.mean((depth[m] - truth[m]) ** 2))
    filtered = np.sqrt(np.mean((out[m] - truth[m]) ** 2))
    assert filtered < 0.7 * raw


def test_filter_can_follow_the_frames_measured_noise(kinect):
    # A sensor with sigma_D 0.14 px through the Kinect camera (0.07 px): with estimate_noise the
    # range kernels are those of the measured sigma_D, i.e. the filter of a camera that says so
    # (noise_stats reports the same measurement), and the error against the truth is lower.
    noisier = sldepth.Camera(640, 480, kinect.fx, kinect.fy, kinect.cx, kinect.cy, sigma_d_px=0.14)
    depth, truth, _ = sldepth.simulate("floor", seed=3, camera=noisier)
    measured = sldepth.filter(depth, kinect, estimate_noise=True)
    sigma = sldepth.noise_stats(depth, kinect)["model_effective_sigma_d_px"]
    assert 0.11 < sigma < 0.17
    told = sldepth.Camera(640, 480, kinect.fx, kinect.fy, kinect.cx, kinect.cy, sigma_d_px=sigma)
    assert np.array_equal(measured, sldepth.filter(depth, told))
    plain = sldepth.filter(depth, kinect)
    m = (truth > 0) & (measured > 0) & (plain > 0)
    rmse = lambda z: np.sqrt(np.mean((z[m] - truth[m]) ** 2))
    assert rmse(measured) < 0.97 * rmse(plain), (rmse(measured), rmse(plain))
    # At the model's own noise nothing changes.
    nominal = sldepth.simulate("floor", seed=3, camera=kinect)[0]
    assert np.array_equal(
        sldepth.filter(nominal, kinect, estimate_noise=True), sldepth.filter(nominal, kinect)
    )


def test_multiscale_is_the_default_of_the_sensor_model_methods(kinect, three_planes):
    depth, truth, _ = three_planes
    m = (truth > 0) & (depth > 0)
    rmse = lambda z: np.sqrt(np.mean((z[m] - truth[m]) ** 2))  # noqa: E731
    default = sldepth.filter(depth, kinect)
    single = sldepth.filter(depth, kinect, multiscale=False)
    assert np.array_equal(default, sldepth.filter(depth, kinect, multiscale=True))
    assert rmse(default) < rmse(single) < rmse(depth)
    gauss = sldepth.filter(depth, kinect, method="gaussian")
    assert np.array_equal(gauss, sldepth.filter(depth, kinect, method="gaussian", multiscale=False))
    assert not np.array_equal(gauss, sldepth.filter(depth, kinect, method="gaussian", multiscale=True))


def test_filter_options_and_errors(small_cam, wall):
    out = sldepth.filter(wall, small_cam, method="adaptive", radius=2, k_per_m=0.05)
    assert np.allclose(out, 2.0)
    with pytest.raises(ValueError, match="unknown method"):
        sldepth.filter(wall, small_cam, method="median")
    with pytest.raises(ValueError, match="adaptive"):
        sldepth.filter(wall, small_cam, method="bilateral", k_per_m=0.05)
    with pytest.raises(ValueError, match="unknown window"):
        sldepth.filter(wall, small_cam, window="round")


def test_disc_window_ignores_the_square_corners(small_cam, wall):
    # A pixel 1 cm deeper at offset (2, 2): inside the 5x5 square, outside the radius-2 disc.
    z = wall.copy()
    z[12, 12] += 0.01
    square = sldepth.filter(z, small_cam, radius=2, window="square", multiscale=False)
    disc = sldepth.filter(z, small_cam, radius=2, window="disc", multiscale=False)
    assert square[10, 10] > 2.0
    assert disc[10, 10] == 2.0


def test_conversions_give_the_same_answer(kinect, three_planes):
    depth = three_planes[0]
    ref = sldepth.filter(depth, kinect)
    assert np.array_equal(sldepth.filter(depth.astype(np.float64), kinect), ref)
    fortran = np.asfortranarray(depth)
    assert not sldepth.input_is_borrowed(fortran)
    assert np.array_equal(sldepth.filter(fortran, kinect), ref)


def test_bad_arrays_raise_valueerror(small_cam, wall):
    with pytest.raises(ValueError, match="2-D"):
        sldepth.filter(wall[None], small_cam)
    with pytest.raises(ValueError, match="camera"):
        sldepth.filter(wall[:, :32].copy(), small_cam)
    with pytest.raises(ValueError, match="NumPy array"):
        sldepth.filter([[1.0, 2.0]], small_cam)
    with pytest.raises(ValueError, match="dtype"):
        sldepth.filter(np.ones((48, 64), dtype=np.int8), small_cam)


def test_planes_of_the_three_plane_scene(kinect, three_planes):
    depth, _, truth_labels = three_planes
    labels, planes = sldepth.extract_planes(depth, kinect)
    assert labels.dtype == np.uint16 and labels.shape == depth.shape
    assert len(planes) >= 3
    for p in planes:
        assert np.linalg.norm(p.normal) == pytest.approx(1.0, abs=1e-9)
        assert p.offset_m > 0 and p.pixels == int(np.sum(labels == p.id))
        a, b, c = p.disparity_affine
        assert np.isfinite([a, b, c]).all()
    # The largest plane covers most of one true surface.
    big = max(planes, key=lambda p: p.pixels)
    surf = np.bincount(truth_labels[labels == big.id]).argmax()
    assert np.mean(truth_labels[labels == big.id] == surf) > 0.95


def test_planes_carry_their_uncertainty(kinect, three_planes):
    depth, _, _ = three_planes
    _, planes = sldepth.extract_planes(depth, kinect)
    for p in planes:
        assert 0 < p.normal_sigma_deg < 10 and 0 < p.offset_sigma_m < 0.05
    # The same surface seen through a smaller window is less certain.
    big = max(planes, key=lambda p: p.pixels)
    labels, _ = sldepth.extract_planes(depth, kinect)
    ys, xs = np.nonzero(labels == big.id)
    cy, cx = int(np.median(ys)), int(np.median(xs))
    crop = np.zeros_like(depth)
    crop[cy - 40 : cy + 40, cx - 50 : cx + 50] = depth[cy - 40 : cy + 40, cx - 50 : cx + 50]
    _, small = sldepth.extract_planes(crop, kinect)
    part = max(small, key=lambda p: p.pixels)
    assert part.normal_sigma_deg > 1.5 * big.normal_sigma_deg
    # Only the planes determined within a bound: every reported one is, and the rest are gone.
    bound = float(np.median([p.normal_sigma_deg for p in planes]))
    labels_sure, sure = sldepth.extract_planes(depth, kinect, max_normal_sigma_deg=bound)
    assert 0 < len(sure) < len(planes)
    assert all(p.normal_sigma_deg <= bound for p in sure)
    assert np.count_nonzero(labels_sure) < np.count_nonzero(labels)
    with pytest.raises(ValueError):
        sldepth.extract_planes(depth, kinect, max_normal_sigma_deg=0.0)


@pytest.mark.parametrize(
    "switch",
    [
        {"split_creases": False},
        {"refine_seams": True},
        {"give_back_taken_in": True},
        {"estimate_noise": False},
    ],
)
def test_the_crease_switches_change_nothing_on_exact_planes(kinect, three_planes, switch):
    # Three planes meeting at right angles near the camera: no plane spans a crease (the split,
    # on by default, changes nothing) and no whole fit is off along one (the seam refinement,
    # off by default, moves no pixel; its effect on bent surfaces is tested in the Rust suite),
    # and no piece sits off a plane (the taken-in test, off by default, gives nothing back).
    # The frame is as noisy as its camera says: measuring its noise (on by default) changes
    # nothing either (a noisier sensor is tested in the Rust suite).
    depth, _, _ = three_planes
    plain, planes_plain = sldepth.extract_planes(depth, kinect)
    switched, planes_switched = sldepth.extract_planes(depth, kinect, **switch)
    assert np.array_equal(plain, switched)
    assert [p.pixels for p in planes_plain] == [p.pixels for p in planes_switched]
    labels, _, _ = sldepth.explain_planes(depth, kinect, **switch)
    assert np.array_equal(labels, switched)


def test_explain_planes_says_why_a_region_is_on_no_plane(kinect, three_planes):
    depth, _, _ = three_planes
    # The same extraction as extract_planes; every region there is taken.
    labels, planes = sldepth.extract_planes(depth, kinect)
    labels2, planes2, regions = sldepth.explain_planes(depth, kinect)
    assert np.array_equal(labels, labels2)
    assert [p.pixels for p in planes] == [p.pixels for p in planes2]
    assert regions == []
    # A LoG test stricter than the simulated noise: no plane, and the LoG is the reason.
    _, planes, regions = sldepth.explain_planes(
        depth, kinect, log_threshold_px=0.02, log_sigma_px=2.0
    )
    assert planes == [] and len(regions) == 1
    r = regions[0]
    assert r.reason == "NotPlanarLog" and "LoG" in r.why
    assert r.log_rejected_fraction > 0.5
    assert r.pixels > 0.99 * depth.size and r.bbox_px == (0, 0, 639, 479)
    # A flat wall with too large a minimum plane: one plane fits it, but no seed was big enough.
    wall = np.full((480, 640), 2.0, dtype=np.float32)
    _, planes, regions = sldepth.explain_planes(
        wall, kinect, min_pixels=400_000, min_region_pixels=1000
    )
    assert planes == [] and [r.reason for r in regions] == ["Unseeded"]
    assert regions[0].pixels == wall.size and regions[0].rms_px < 1e-3
    # With the default min_region_pixels (= min_pixels) the region is too small to report.
    assert sldepth.explain_planes(wall, kinect, min_pixels=400_000)[2] == []
    # Uniform random depth: a measured disparity noise far above threshold_px, no plane,
    # and the reason for every region.
    rng = np.random.default_rng(5)
    noise = rng.uniform(0.5, 4.5, size=(480, 640)).astype(np.float32)
    labels, planes, regions = sldepth.explain_planes(noise, kinect)
    assert planes == [] and not labels.any() and regions
    assert all(r.reason == "NoiseBeyondThreshold" for r in regions)
    assert "threshold_px" in regions[0].why
    with pytest.raises(ValueError, match="log_sigma_px"):
        sldepth.explain_planes(depth, kinect, log_sigma_px=-1.0)
    with pytest.raises(ValueError, match="threshold_px"):
        sldepth.extract_planes(depth, kinect, log_threshold_px=float("nan"))


def test_a_wall_bent_by_the_sensor_is_one_plane(kinect):
    # A wall 2 m away whose disparity the sensor bends into a bowl, 1.5 px higher at the
    # corners (the Kinect's low-frequency distortion): not affine within tau over the frame.
    h, w = 480, 640
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    r2 = ((x - 319.5) ** 2 + (y - 239.5) ** 2) / (319.5**2 + 239.5**2)
    disparity = kinect.fb / 2.0 + 1.5 * r2
    depth = (kinect.fb / disparity).astype(np.float32)
    # Without the join its corners are planes of their own; with it (the default), one plane.
    _, pieces = sldepth.extract_planes(depth, kinect, bend_px_per_px2=0.0)
    assert len(pieces) >= 2
    labels, planes = sldepth.extract_planes(depth, kinect)
    assert len(planes) == 1
    assert planes[0].pixels == sum(p.pixels for p in pieces) == int((labels == 1).sum())
    with pytest.raises(ValueError, match="bend_px_per_px2"):
        sldepth.extract_planes(depth, kinect, bend_px_per_px2=-1.0)


def test_planes_of_a_decimated_frame_are_those_of_the_full_one(kinect, three_planes):
    # A QVGA stream of the VGA sensor: extracted on the sensor's grid, so the same planes.
    depth = three_planes[0]
    half = kinect.resampled(0.5)
    _, full_planes = sldepth.extract_planes(depth, kinect)
    labels, planes = sldepth.extract_planes(depth[::2, ::2].copy(), half)
    assert labels.shape == (240, 320)
    assert len(planes) == len(full_planes) >= 3
    for p, q in zip(sorted(planes, key=lambda p: p.offset_m), sorted(full_planes, key=lambda p: p.offset_m)):
        assert p.pixels == int(np.sum(labels == p.id))
        assert abs(p.pixels * 4 - q.pixels) < 0.1 * q.pixels
        assert np.degrees(np.arccos(min(1.0, float(np.dot(p.normal, q.normal))))) < 1.0
        assert p.offset_m == pytest.approx(q.offset_m, abs=0.01)


def test_motion_of_a_frame_with_itself_is_identity(kinect, three_planes):
    depth = three_planes[0]
    m = sldepth.motion(depth, depth, kinect, icp=True)
    assert m.determined and m.matrix.shape == (4, 4)
    assert np.allclose(m.matrix, np.eye(4), atol=1e-6)
    assert m.rotation_deg == pytest.approx(0.0, abs=1e-6)


def test_motion_undetermined_is_reported_not_guessed(small_cam, wall):
    m = sldepth.motion(wall, wall, small_cam)
    assert not m.determined and m.matrix is None and m.reason
    # One plane proposes no rotation at all: nothing to hand back.
    assert m.candidates == []


def test_an_undecided_motion_hands_back_the_camera_among_its_candidates():
    # TUM fr1/rpy-200 frames 70 and 78 (20 degrees apart): the planes propose rotations the
    # two frames cannot tell apart, so the motion is undetermined, and the candidates (for a
    # caller with more evidence, as the tracker's model) hold the camera's rotation.
    tum = _shared_data() / "tum-fr1-rpy-200"
    names = [l.split()[1] for l in open(tum / "depth.txt") if not l.startswith("#")]
    a, b = (sldepth.read_depth(tum / names[i], depth_scale=5000.0) for i in (70, 78))
    m = sldepth.motion(a, b, sldepth.Camera.preset("tum-fr1"), icp=False)
    assert not m.determined and m.matrix is None and "ambiguous" in m.reason
    assert 2 <= len(m.candidates) <= 3
    for c in m.candidates:
        assert c.shape == (4, 4) and c.dtype == np.float64
        assert np.allclose(c[:3, :3] @ c[:3, :3].T, np.eye(3), atol=1e-9)
    # Camera-to-camera rotation of the motion capture (quaternion x y z w per stamp).
    stamps = [float(l.split()[0]) for l in open(tum / "depth.txt") if not l.startswith("#")]
    gt = np.loadtxt(tum / "groundtruth.txt")

    def rot(t):
        x, y, z, w = gt[np.argmin(np.abs(gt[:, 0] - t)), 4:8]
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )

    truth = rot(stamps[70]).T @ rot(stamps[78])
    errors = [
        np.degrees(np.arccos(np.clip((np.trace(truth.T @ c[:3, :3]) - 1) / 2, -1, 1)))
        for c in m.candidates
    ]
    assert min(errors) < 3.0 and max(errors) > 10.0, errors


def test_tsdf_of_a_wall(small_cam, wall, tmp_path):
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.05, weight="inv-z4")
    assert vol.integrate(wall, small_cam, np.eye(4)) > 0
    mesh = vol.extract_mesh()
    assert mesh.vertices.dtype == np.float32 and mesh.vertices.shape[1] == 3
    assert mesh.triangles.dtype == np.uint32 and mesh.triangles.shape[1] == 3
    assert mesh.normals.shape == mesh.vertices.shape and len(mesh.confidence) == len(mesh)
    assert np.allclose(mesh.vertices[:, 2], 2.0, atol=0.01)
    assert mesh.triangles.max() < len(mesh)
    # Normals point back at the camera (-z).
    assert np.mean(mesh.normals[:, 2]) < -0.9
    s = vol.slice("z", 2.0)
    assert s.dtype == np.float32 and np.nanmax(np.abs(s)) <= 0.05 + 1e-6
    mesh.write_ply(tmp_path / "m.ply")
    vol.write_ply(tmp_path / "v.ply")
    assert (tmp_path / "m.ply").read_bytes()[:3] == b"ply"
    assert (tmp_path / "m.ply").read_bytes() == (tmp_path / "v.ply").read_bytes()


def test_tsdf_pose_moves_the_surface(small_cam, wall):
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.05)
    pose = np.eye(4)
    pose[:3, 3] = [0.0, 0.0, 1.0]
    vol.integrate(wall, small_cam, pose)
    assert np.allclose(vol.extract_mesh().vertices[:, 2], 3.0, atol=0.01)


def test_tsdf_raycast_sees_the_fused_wall(small_cam, wall):
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.05)
    vol.integrate(wall, small_cam, np.eye(4))
    pose = np.eye(4)
    pose[:3, 3] = [0.05, 0.0, 0.3]  # 30 cm closer, 5 cm to the side
    depth, points, normals, weights = vol.raycast(small_cam, pose)
    assert depth.shape == (48, 64) and depth.dtype == np.float32
    assert points.shape == (48, 64, 3) and normals.shape == (48, 64, 3)
    hit = depth > 0
    assert hit[10:38, 10:54].all()
    assert np.allclose(depth[hit], 1.7, atol=0.005)
    assert np.allclose(points[hit][:, 2], 2.0, atol=0.005)
    assert np.all(normals[hit][:, 2] < -0.99)
    assert np.all(weights[hit] > 0) and np.all(weights[~hit] == 0)
    assert np.isnan(points[~hit]).all()
    with pytest.raises(ValueError):
        vol.raycast(small_cam, np.eye(3))


def test_tsdf_bilinear_lookup_keeps_a_grazing_wall_flat():
    # A wall 0.4 m to the side seen at a grazing angle (exact depth, computed here): with the
    # nearest pixel it is fused as steps one pixel wide, whose raycast normals lean away from
    # the wall's; with bilinear inverse depth they match it.
    h, w = 240, 320
    cam = sldepth.Camera(w, h, 290.0, 290.0, 159.5, 119.5, baseline_m=0.075)
    n = np.array([-1.0, 0.15, 0.05])
    n /= np.linalg.norm(n)
    x = (np.arange(w) - 159.5) / 290.0
    y = (np.arange(h) - 119.5) / 290.0
    rays = np.stack(np.broadcast_arrays(x[None, :], y[:, None], np.ones((h, w))), axis=-1)
    # The plane n.p = n.(0.4, 0, 0) along each ray.
    t = (n @ np.array([0.4, 0.0, 0.0])) / (rays @ n)
    depth = np.where((t > 0) & (t < 3.0), t, 0.0).astype(np.float32)
    errors = {}
    for lookup in ("nearest", "bilinear"):
        vol = sldepth.TsdfVolume(voxel_m=0.004, trunc_m=0.02, depth_lookup=lookup)
        vol.integrate(depth, cam, np.eye(4))
        d, _, normals, _ = vol.raycast(cam, np.eye(4))
        hit = d > 0
        hit[:4], hit[-4:], hit[:, :4], hit[:, -4:] = False, False, False, False
        cos = np.clip(normals[hit] @ n, -1.0, 1.0)
        errors[lookup] = np.degrees(np.arccos(cos)).mean()
    assert errors["nearest"] > 5.0 and errors["bilinear"] < 0.5, errors
    with pytest.raises(ValueError, match="depth_lookup"):
        sldepth.TsdfVolume(depth_lookup="cubic")


def test_tsdf_band_follows_the_camera_of_the_first_frame():
    # The sensor-adaptive band is 3 sigma_Z of the first frame's camera (a D435 is 2.3x noisier
    # in depth than a Kinect v1 at the same distance), never below trunc_m.
    d435 = sldepth.Camera.preset("d435")
    depth, truth, _ = sldepth.simulate("floor", seed=1, camera=d435)
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.02)
    vol.integrate(depth, d435, np.eye(4))
    assert vol.band_m(2.0) == pytest.approx(3 * d435.sigma_z(2.0), rel=1e-6)
    assert vol.band_m(0.5) == pytest.approx(0.02)
    kinect = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.02)
    assert kinect.band_m(3.0) == pytest.approx(
        3 * sldepth.Camera.preset("kinect-v1").sigma_z(3.0), rel=1e-6
    )
    fixed = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.02, truncation="fixed")
    fixed.integrate(depth, d435, np.eye(4))
    assert fixed.band_m(2.0) == pytest.approx(0.02) and fixed.noise_scale == 1.0
    assert "truncation=\"sensor\"" in repr(vol) and "truncation=\"fixed\"" in repr(fixed)
    with pytest.raises(ValueError, match="truncation"):
        sldepth.TsdfVolume(truncation="adaptive")
    with pytest.raises(ValueError, match="sigmas"):
        sldepth.TsdfVolume(trunc_sigmas=-1.0)
    with pytest.raises(ValueError, match="z_m"):
        vol.band_m(float("nan"))


def test_tsdf_band_follows_a_noisier_sensors_measured_noise():
    # Frames of a sensor with sigma_D 0.2 px through a camera that says 0.07 px: the first
    # frame's measured variance is (0.2^2 + 1/768) / (0.07^2 + 1/768) = 6.7x the model's, the
    # band is that of the measured sigma_D, and the fused mesh has fewer spurious surfaces.
    kinect = sldepth.Camera.preset("kinect-v1")
    noisier = sldepth.Camera(
        640, 480, kinect.fx, kinect.fy, kinect.cx, kinect.cy, sigma_d_px=0.2
    )
    frames = [sldepth.simulate("floor", seed=s, camera=noisier)[0] for s in range(4)]
    vertices = {}
    for estimate in (True, False):
        vol = sldepth.TsdfVolume(voxel_m=0.01, estimate_noise=estimate)
        for d in frames:
            vol.integrate(d, kinect, np.eye(4))
        vertices[estimate] = len(vol.extract_mesh())
        if estimate:
            assert 5.0 < vol.noise_scale < 8.5
            assert vol.band_m(2.5) == pytest.approx(3 * noisier.sigma_z(2.5), rel=0.1)
        else:
            assert vol.noise_scale == 1.0
            assert vol.band_m(2.5) == pytest.approx(3 * kinect.sigma_z(2.5), rel=1e-6)
    assert vertices[True] < 0.9 * vertices[False], vertices


def test_tsdf_errors(small_cam, wall):
    with pytest.raises(ValueError):
        sldepth.TsdfVolume(voxel_m=-0.01)
    with pytest.raises(ValueError, match="weight"):
        sldepth.TsdfVolume(weight="inv-z3")
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.05)
    bad = np.eye(4)
    bad[0, 0] = np.nan
    with pytest.raises(ValueError):
        vol.integrate(wall, small_cam, bad)
    with pytest.raises(ValueError, match="4, 4"):
        vol.integrate(wall, small_cam, np.eye(3))
    tiny = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.05, memory_budget_bytes=1000)
    with pytest.raises(ValueError, match="budget"):
        tiny.integrate(wall, small_cam, np.eye(4))
    assert tiny.block_count == 0 and tiny.frame_count == 0


def test_analyze_finds_the_square_law(kinect):
    depth, _, _ = sldepth.simulate("floor", seed=1)
    a = sldepth.analyze(depth, kinect)
    assert a.slope == pytest.approx(2.0, abs=0.15)
    assert a.subpixel_steps == 8
    assert a.fb_px_m == pytest.approx(43.5, rel=0.05)


def test_simulate_is_seeded():
    a = sldepth.simulate("wall", seed=5)[0]
    b = sldepth.simulate("wall", seed=5)[0]
    c = sldepth.simulate("wall", seed=6)[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    with pytest.raises(ValueError, match="floor"):
        sldepth.simulate("no-such-scene")


def test_simulate_draws_the_realistic_sensor_by_default(kinect):
    # The default is the realistic Kinect (as for `sldepth simulate`): the disparity error of
    # neighbours is correlated (block matching) and occlusion edges leave invalid bands;
    # noise="white" is the paper's independent error with no bands.
    def neighbour_correlation(depth, truth):
        ok = (depth > 0) & (truth > 0)
        r = np.where(ok, kinect.fb / np.where(ok, depth, 1) - kinect.fb / np.where(ok, truth, 1), 0)
        both = ok[:, 1:] & ok[:, :-1]
        a, b = r[:, 1:][both], r[:, :-1][both]
        return float(np.corrcoef(a, b)[0, 1])

    real, truth, _ = sldepth.simulate("wall", seed=5)
    white, truth_w, _ = sldepth.simulate("wall", seed=5, noise="white")
    assert np.array_equal(truth, truth_w)
    assert neighbour_correlation(real, truth) > 0.5
    assert abs(neighbour_correlation(white, truth)) < 0.2
    boxes_real, boxes_truth, _ = sldepth.simulate("boxes", seed=3)
    boxes_white, _, _ = sldepth.simulate("boxes", seed=3, noise="white")
    seen = boxes_truth > 0
    assert (boxes_real[seen] == 0).sum() > 10 * max(1, (boxes_white[seen] == 0).sum())
    with pytest.raises(ValueError, match="realistic"):
        sldepth.simulate("wall", noise="pink")
    assert sldepth.Camera.preset("tum-fr1").preset_name == "tum-fr1"
    assert sldepth.Camera.preset("tum-fr1").resampled(0.5).preset_name == "tum-fr1"
    assert sldepth.Camera(64, 48, 60.0, 60.0, 32.0, 24.0).preset_name is None


def test_simulate_drops_out_weak_returns():
    # min_return: pixels whose surface returns less than reflectance * cos(theta) / r**2 drop
    # out; a darker surface drops out nearer. Without the bound nothing reads a reflectance: an
    # error, as for `sldepth simulate --reflectance`.
    depth, truth, labels = sldepth.simulate("boxes", seed=3)
    bound, _, _ = sldepth.simulate("boxes", seed=3, min_return=0.04)
    dark, _, _ = sldepth.simulate("boxes", seed=3, min_return=0.04, reflectance={1: 0.1})
    valid = lambda d: int((d > 0).sum())
    assert valid(depth) > valid(bound) > valid(dark)
    floor = labels == 1
    assert valid(dark[floor]) < valid(bound[floor])
    assert np.array_equal(bound[~floor], dark[~floor])
    # An empty dict sets nothing and needs no bound.
    same, _, _ = sldepth.simulate("boxes", seed=3, reflectance={})
    assert np.array_equal(same, depth)
    for kwargs, says in [
        ({"reflectance": {1: 2.0}}, "must be in"),
        ({"reflectance": {-1: 0.5}}, "no surface -1"),
        ({"reflectance": {999: 0.5}}, "no surface 999"),
        ({"min_return": -1.0}, "min_return"),
        ({"min_return": 0.04, "noise": "white"}, "realistic model"),
        ({"reflectance": {1: 0.1}}, "no effect without a positive min_return"),
        ({"reflectance": {1: 0.1}, "min_return": 0.0}, "no effect without a positive min_return"),
        ({"reflectance": {1: 0.1}, "noise": "white"}, 'no effect with noise="white"'),
    ]:
        with pytest.raises(ValueError, match=says):
            sldepth.simulate("boxes", **kwargs)


def test_noise_stats_tell_realistic_from_white_noise(kinect):
    # The statistics of `sldepth noise-stats`: on the realistic simulator the residual of
    # neighbours is correlated and the boxes leave occlusion bands beside them; on white noise
    # neither. sigma_D is the model's 0.07 px (quantised to 1/8 px) either way.
    real, _, truth_labels = sldepth.simulate("boxes", seed=3)
    white, _, _ = sldepth.simulate("boxes", seed=3, noise="white")
    s_real = sldepth.noise_stats(real, kinect)
    s_white = sldepth.noise_stats(white, kinect)
    assert s_real["regions"] > 0 and s_white["regions"] > 0
    acf = {c["lag"]: c for c in s_real["acf"]}
    acf_w = {c["lag"]: c for c in s_white["acf"]}
    assert acf[1]["x"] > 0.5 and abs(acf_w[1]["x"]) < 0.2
    assert 0.05 < s_white["sigma_d_px"] < 0.1 and 0.05 < s_real["sigma_d_px"] < 0.12
    bands = s_real["occlusion"]["left"]["widths"]["count"] + s_real["occlusion"]["right"]["widths"]["count"]
    assert bands > 0
    assert s_white["occlusion"]["left"]["widths"]["count"] == 0
    # The terrace histogram's last bin is open: no upper edge (it was 2**64 - 1).
    assert s_real["terraces"]["bin_upper_px"] == [1, 2, 4, 8, 16, 32, None]
    assert abs(sum(s_real["terraces"]["fractions"]) - 1) < 1e-9
    # Labels given by the caller (the simulator's surfaces) instead of extracted planes.
    s_given = sldepth.noise_stats(real, kinect, truth_labels)
    assert s_given["regions"] > 0 and abs(s_given["sigma_d_px"] - s_real["sigma_d_px"]) < 0.03
    with pytest.raises(ValueError, match="labels"):
        sldepth.noise_stats(real, kinect, truth_labels[:, :10].copy())


def test_noise_stats_measure_a_sensor_against_its_camera_model(kinect):
    # At the camera's own noise the frame is within its model; a sensor twice as noisy
    # (sigma_D 0.14 px behind the 0.07 px Kinect camera) measures about 3.4 times the model's
    # pixel variance, the sigma_D of 0.14 px back within the estimate's spread.
    nominal, _, _ = sldepth.simulate("boxes", seed=3, camera=kinect)
    s = sldepth.noise_stats(nominal, kinect)
    assert s["model_sigma_d_px"] == pytest.approx(kinect.sigma_d_px)
    # The keys of `sldepth noise-stats --json` but its `path`: f·B was missing.
    assert s["fb_px_m"] == pytest.approx(kinect.fx * kinect.baseline_m)
    assert s["model_variance_scale"] == 1.0
    assert s["model_effective_sigma_d_px"] == pytest.approx(kinect.sigma_d_px)
    noisier = sldepth.Camera(
        kinect.width, kinect.height, kinect.fx, kinect.fy, kinect.cx, kinect.cy,
        baseline_m=kinect.baseline_m, subpixel=kinect.subpixel, sigma_d_px=0.14,
    )
    frame, _, _ = sldepth.simulate("boxes", seed=3, camera=noisier)
    s = sldepth.noise_stats(frame, kinect)
    assert 2.5 < s["model_variance_scale"] < 4.5
    assert 0.11 < s["model_effective_sigma_d_px"] < 0.17


def test_trajectories_round_trip_and_evaluate(tmp_path):
    # A known estimate: the ground truth moved rigidly (ATE 0 after Horn's alignment), then one
    # pose displaced by 3 cm (ATE and RPE by hand).
    t = np.arange(20) * 0.05
    gt = np.stack([np.eye(4)] * 20)
    gt[:, 0, 3] = 0.1 * np.arange(20)
    c, s = np.cos(0.3), np.sin(0.3)
    rigid = np.array([[c, -s, 0, 1.0], [s, c, 0, 2.0], [0, 0, 1, 0.5], [0, 0, 0, 1]])
    est = np.einsum("ij,njk->nik", rigid, gt)
    r = sldepth.evaluate_trajectory(t, est, t, gt)
    assert r["poses_matched"] == 20 and r["ate_m"]["rmse"] < 1e-9
    assert r["rpe"]["translation_m"]["max"] < 1e-9 and r["rpe"]["pairs"] == 18
    bumped = est.copy()
    bumped[10, :3, 3] += rigid[:3, :3] @ np.array([0.0, 0.03, 0.0])
    r = sldepth.evaluate_trajectory(t, bumped, t, gt)
    assert r["ate_m"]["max"] == pytest.approx(0.03 * 19 / 20, rel=0.05)  # the alignment absorbs 1/20
    assert r["rpe"]["translation_m"]["max"] == pytest.approx(0.03, rel=1e-6)
    # Per pose: the displaced pose carries the largest error, at its own timestamp.
    pp = r["per_pose"]
    assert pp["translation_m"].dtype == np.float64 and pp["translation_m"].shape == (20,)
    assert np.array_equal(pp["timestamps_s"], t) and np.array_equal(pp["gt_timestamps_s"], t)
    assert int(np.argmax(pp["translation_m"])) == 10
    assert pp["translation_m"].max() == pytest.approx(r["ate_m"]["max"], abs=1e-12)
    assert pp["rotation_deg"].max() < 1e-5
    # Files: written atomically, read back by time.
    path = tmp_path / "est.txt"
    sldepth.write_trajectory(path, t, est)
    t2, est2 = sldepth.read_trajectory(path)
    assert np.allclose(t2, t) and np.allclose(est2, est, atol=1e-6)
    with pytest.raises(ValueError, match="timestamps"):
        sldepth.evaluate_trajectory(t[:5], est, t, gt)
    with pytest.raises(ValueError, match="delta"):
        sldepth.evaluate_trajectory(t, est, t, gt, delta_unit="hours")
    with pytest.raises(OSError):
        sldepth.read_trajectory(tmp_path / "missing.txt")


def test_an_open3d_log_is_read_as_a_trajectory_stamped_by_frame(tmp_path):
    # Entries `i i n` in any order come back by frame number, their poses with them; a pose
    # graph's pairwise entry `i j n` is refused as not a camera pose.
    def entry(i, j, x):
        return f"{i} {j} 3\n1 0 0 {x}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"

    log = tmp_path / "odometry.log"
    log.write_text(entry(2, 2, 0.5) + entry(0, 0, 0.0) + entry(1, 1, 0.25))
    t, poses = sldepth.read_trajectory(log)
    assert t.tolist() == [0.0, 1.0, 2.0]
    assert poses[:, 0, 3].tolist() == [0.0, 0.25, 0.5]
    log.write_text(entry(0, 0, 0.0) + entry(0, 1, 0.1))
    with pytest.raises(OSError, match="relates two frames"):
        sldepth.read_trajectory(log)


def test_a_clock_offset_is_found_and_applied():
    # A camera turning about changing axes; its frames stamped 25 ms after the instants they
    # show, the ground truth sampled every millisecond on the true clock.
    def pose(t):
        a = np.array([0.6 * np.sin(1.3 * t), 1.2 * np.cos(0.9 * t), 0.8 * np.sin(1.7 * t)])
        th = np.linalg.norm(a)
        k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]]) / th
        m = np.eye(4)
        m[:3, :3] = np.eye(3) + np.sin(th) * k + (1 - np.cos(th)) * k @ k
        m[:3, 3] = [0.1 * np.sin(t), 0.05 * t, 0.0]
        return m

    tg = 100.0 + np.arange(6000) * 0.001
    gt = np.stack([pose(t) for t in tg])
    te = 100.2 + np.arange(140) * 0.04
    est = np.stack([pose(t) for t in te])
    found = sldepth.estimate_time_offset(te + 0.025, est, tg, gt)
    assert found["offset_s"] == pytest.approx(-0.025, abs=1e-9)
    assert found["rotation_rmse_deg"] < 1e-4 < 0.5 < found["rotation_rmse_at_zero_deg"]
    assert found["matched"] == 140 and len(found["curve"]) == 201
    r = sldepth.evaluate_trajectory(te + 0.025, est, tg, gt, offset_s=found["offset_s"])
    assert r["offset_s"] == found["offset_s"] and r["ate_m"]["rmse"] < 1e-9
    assert sldepth.evaluate_trajectory(te + 0.025, est, tg, gt)["ate_m"]["rmse"] > 1e-4
    with pytest.raises(ValueError, match="offset"):
        sldepth.evaluate_trajectory(te, est, tg, gt, offset_s=float("nan"))
    with pytest.raises(ValueError, match="step"):
        sldepth.estimate_time_offset(te, est, tg, gt, step_s=0.0)


def test_tracker_follows_a_still_camera_and_fuses(kinect):
    # Boxes on a floor: planes facing three ways, so every motion is pinned down.
    depth = sldepth.simulate("boxes", seed=3)[0]
    tracker = sldepth.Tracker(kinect)
    pose, status = tracker.track(depth)
    assert status == "initialised" and np.allclose(pose, np.eye(4))
    for _ in range(2):
        pose, status = tracker.track(depth)
        assert status in ("tracked", "tracked-against-frame", "recovered"), status
        assert np.abs(pose[:3, 3]).max() < 0.002
        assert np.allclose(pose[:3, :3], np.eye(3), atol=1e-3)
    mesh = tracker.extract_mesh()
    assert len(mesh) > 1000
    with pytest.raises(ValueError):
        tracker.track(depth[:, :100])
    with pytest.raises(ValueError, match="weighting"):
        sldepth.Tracker(kinect, weighting="huber")
    with pytest.raises(ValueError, match="prefilter"):
        sldepth.Tracker(kinect, prefilter="median")
    with pytest.raises(ValueError, match="scale"):
        sldepth.Tracker(kinect, model_scale=0.0)
    # The model rendered at full resolution tracks the still camera as well.
    t = sldepth.Tracker(kinect, model_scale=1.0)
    for _ in range(3):
        pose, status = t.track(depth)
    assert status == "tracked", status
    assert np.abs(pose[:3, 3]).max() < 0.002
    # Without the relocalisation against keyframes, a tracked camera is tracked alike.
    t = sldepth.Tracker(kinect, keyframes=False)
    t.track(depth)
    pose, status = t.track(depth)
    assert status in ("tracked", "tracked-against-frame"), status
    assert np.abs(pose[:3, 3]).max() < 0.002
    for prefilter in ("single", "none"):
        t = sldepth.Tracker(kinect, prefilter=prefilter)
        t.track(depth)
        pose, status = t.track(depth)
        assert status == "tracked" or status == "tracked-against-frame", (prefilter, status)
        assert np.abs(pose[:3, 3]).max() < 0.002


def test_a_tracker_whose_model_is_full_tracks_on_without_fusing(kinect):
    depth = sldepth.simulate("boxes", seed=3)[0]
    roomy = sldepth.Tracker(kinect)
    for _ in range(3):
        roomy.track(depth)
    assert roomy.model_full is None and len(roomy.extract_mesh()) > 1000
    # A budget no block fits in: the first frames are not fused, the camera is still tracked
    # (against the frame before) where it is.
    tight = sldepth.Tracker(kinect, memory_budget_bytes=1)
    for _ in range(3):
        pose, status = tight.track(depth)
    assert status in ("tracked", "tracked-against-frame"), status
    assert np.abs(pose[:3, 3]).max() < 0.002
    assert "memory budget" in tight.model_full
    assert len(tight.extract_mesh()) == 0
    with pytest.raises(TypeError):
        sldepth.Tracker(kinect, memory_budget_bytes=1.5)


def test_a_full_model_goes_on_in_a_fresh_volume_in_the_same_world(kinect):
    # A camera moving sideways (the view shifts 8 px a frame, the new columns without depth)
    # brings a few new blocks into the model with every frame. With the smallest of a few
    # budgets at which the model fills at the third frame or later (found with
    # when_model_full="stop-fusing", under which the model just stops growing and fragment 0
    # goes on), by default the tracker hands fragment 0 over, keeps its mesh and goes on in a
    # continuation, fragment 1: a fresh volume in the same world frame, so its poses go on
    # where fragment 0's ended. Here one frame needs nearly the whole budget (about 29,000
    # blocks), so beside fragment 0's kept mesh the continuation cannot hold its first frame:
    # it says so (model_full) and tracks on against the frame before, as "stop-fusing" does.
    depth = sldepth.simulate("boxes", seed=3)[0]

    def moved(k):
        d = np.zeros_like(depth)
        d[:, 8 * k :] = depth[:, : depth.shape[1] - 8 * k]
        return d

    frames = [moved(k) for k in range(10)]

    def full_at(budget):
        t = sldepth.Tracker(kinect, memory_budget_bytes=budget, when_model_full="stop-fusing")
        for i, d in enumerate(frames):
            assert t.track(d)[1] in ("initialised", "tracked", "tracked-against-frame")
            if t.model_full is not None:
                assert t.fragment == 0 and "memory budget" in t.model_full
                return i
        return None

    budget = next(
        b << 20 for b in range(100, 400, 10) if (full_at(b << 20) or 0) >= 2
    )
    first_full = full_at(budget)
    roomy = sldepth.Tracker(kinect)
    roomy_poses = [roomy.track(d)[0] for d in frames]
    assert roomy.fragment == 0 and roomy.model_full is None
    t = sldepth.Tracker(kinect, memory_budget_bytes=budget)
    for d, expected in zip(frames, roomy_poses):
        pose, status = t.track(d)
        assert status in ("initialised", "tracked", "tracked-against-frame"), status
        # In the first camera's world (a continuation does not restart at the identity):
        # within 2 cm of the roomy tracker's over 20 cm of motion (shifted frames are no exact
        # rigid motion, and a continuation that cannot hold its first frame tracks frame to frame).
        assert np.abs(pose[:3, 3] - expected[:3, 3]).max() < 0.02
    assert t.frame_fragments == [0] * first_full + [1] * (10 - first_full)
    assert t.fragment == 1 and t.joins == []
    assert len(t.extract_mesh(fragment=0)) > 1000
    assert "memory budget" in t.model_full and len(t.extract_mesh(fragment=1)) == 0
    with pytest.raises(ValueError, match="when_model_full"):
        sldepth.Tracker(kinect, when_model_full="evict")


def test_tracker_measures_each_raw_frame_against_the_camera_model(kinect):
    # A sensor twice as noisy as the camera says (sigma_D 0.14 px behind the 0.07 px Kinect):
    # the raw frame's pixel variance is about 3.4 times the model's, measured before the
    # prefilter smooths it, and the still camera is smoothed and tracked with that noise. At the model's
    # noise, or with estimate_noise=False, the scale is 1.
    noisier = sldepth.Camera(
        kinect.width, kinect.height, kinect.fx, kinect.fy, kinect.cx, kinect.cy,
        baseline_m=kinect.baseline_m, subpixel=kinect.subpixel, sigma_d_px=0.14,
    )
    noisy = sldepth.simulate("boxes", seed=3, camera=noisier)[0]
    tracker = sldepth.Tracker(kinect)
    assert tracker.last_noise_scale == 1.0
    for _ in range(3):
        pose, status = tracker.track(noisy)
    assert 2.5 < tracker.last_noise_scale < 4.5
    # The prefilter's range kernel follows the measured noise: sigma_D raised to about 0.14 px.
    assert 0.11 < tracker.last_prefilter_sigma_d_px < 0.17
    assert status in ("tracked", "tracked-against-frame"), status
    assert np.abs(pose[:3, 3]).max() < 0.003
    plain = sldepth.Tracker(kinect, estimate_noise=False)
    assert plain.last_prefilter_sigma_d_px is None
    plain.track(noisy)
    assert plain.last_noise_scale == 1.0
    assert plain.last_prefilter_sigma_d_px == kinect.sigma_d_px
    unfiltered = sldepth.Tracker(kinect, prefilter="none")
    unfiltered.track(noisy)
    assert unfiltered.last_prefilter_sigma_d_px is None
    nominal = sldepth.Tracker(kinect)
    nominal.track(sldepth.simulate("boxes", seed=3)[0])
    assert nominal.last_noise_scale == 1.0


def test_a_tracker_of_one_frame_meshes_that_frame(kinect):
    # With the Kinect preset's rolling-shutter readout the first frame waits for the second
    # frame's motion before it is fused; a mesh taken after one frame still holds it (it was
    # empty), and the same as a global shutter's.
    depth = sldepth.simulate("boxes", seed=3)[0]
    one = sldepth.Tracker(kinect)
    assert one.rolling_shutter_ms > 0
    one.track(depth)
    glob = sldepth.Tracker(kinect, rolling_shutter_ms=0)
    glob.track(depth)
    assert len(one.extract_mesh()) > 1000
    assert len(one.extract_mesh()) == len(glob.extract_mesh())


def test_track_in_map_anchors_at_the_start_and_fuses_nothing(kinect):
    # A map of the boxes fused from one noisy frame at a pose P; other noisy frames of the same
    # view tracked in it from P stay at P (the map pins every direction), and the map is
    # unchanged.
    frames = [sldepth.simulate("boxes", seed=s)[0] for s in (3, 4, 5)]
    start = np.eye(4)
    start[:3, 3] = (0.1, -0.02, 0.05)
    vol = sldepth.TsdfVolume(voxel_m=0.008, trunc_m=0.04)
    vol.integrate(frames[0], kinect, start)
    before = len(vol.extract_mesh())
    out = sldepth.track_in_map(vol, kinect, frames, start)
    assert [s for _, s in out][0] == "initialised"
    for pose, status in out:
        assert status in ("initialised", "tracked"), status
        assert np.abs(pose[:3, 3] - start[:3, 3]).max() < 0.002
        assert np.allclose(pose[:3, :3], np.eye(3), atol=1e-3)
    assert len(vol.extract_mesh()) == before
    # Frames of a sensor three times noisier than the camera says (sigma_D 0.2 px): each raw
    # frame's noise is measured, the frame smoothed and tracked for it; they stay at P too.
    noisier = sldepth.Camera(
        kinect.width, kinect.height, kinect.fx, kinect.fy, kinect.cx, kinect.cy,
        baseline_m=kinect.baseline_m, subpixel=kinect.subpixel, sigma_d_px=0.2,
    )
    noisy = [sldepth.simulate("boxes", seed=s, camera=noisier)[0] for s in (6, 7, 8)]
    for pose, status in sldepth.track_in_map(vol, kinect, noisy, start):
        assert status in ("initialised", "tracked"), status
        assert np.abs(pose[:3, 3] - start[:3, 3]).max() < 0.003
        assert np.allclose(pose[:3, :3], np.eye(3), atol=3e-3)
    assert sldepth.track_in_map(vol, kinect, [], start) == []
    with pytest.raises(ValueError):
        sldepth.track_in_map(vol, kinect, [frames[0][:, :100]], start)
    with pytest.raises(ValueError, match="prefilter"):
        sldepth.track_in_map(vol, kinect, frames, start, prefilter="median")
    with pytest.raises(ValueError, match="pose"):
        sldepth.track_in_map(vol, kinect, frames, np.eye(3))


def test_the_preset_says_whether_the_sensor_has_a_rolling_shutter(kinect):
    # The Kinect-class presets carry their IR camera's readout (an estimate), the global-shutter
    # and rendered ones none; explicit intrinsics none.
    assert kinect.rolling_shutter_ms == pytest.approx(30.0)
    assert sldepth.Camera.preset("tum-fr1").rolling_shutter_ms == pytest.approx(30.0)
    for name in ("d435", "oak-d", "icl-nuim"):
        assert sldepth.Camera.preset(name).rolling_shutter_ms == 0.0
    assert sldepth.Camera(640, 480, 580, 580, 319.5, 239.5).rolling_shutter_ms == 0.0
    assert kinect.resampled(0.5).rolling_shutter_ms == pytest.approx(30.0)
    # A Tracker models the camera's readout against the fused model unless told otherwise;
    # frame to frame (where it made TUM fr1/rpy's trajectory worse) only when told.
    assert sldepth.Tracker(kinect).rolling_shutter_ms == pytest.approx(30.0)
    assert sldepth.Tracker(kinect, rolling_shutter_ms=0).rolling_shutter_ms == 0.0
    assert sldepth.Tracker(kinect, frame_to_model=False).rolling_shutter_ms == 0.0
    assert sldepth.Tracker(kinect, frame_to_model=False, rolling_shutter_ms=20).rolling_shutter_ms == pytest.approx(20.0)
    assert sldepth.Tracker(sldepth.Camera.preset("d435")).rolling_shutter_ms == 0.0


def test_a_rolling_shutter_tracker_keeps_a_still_camera_still(kinect):
    # No motion, no skew: the row-by-row alignment and the rectified fusion leave a still
    # camera where it is; a readout longer than a frame interval is refused.
    depth = sldepth.simulate("boxes", seed=3)[0]
    t = sldepth.Tracker(kinect, rolling_shutter_ms=30.0)
    for _ in range(4):
        pose, status = t.track(depth)
    assert status == "tracked", status
    assert np.abs(pose[:3, 3]).max() < 0.002
    assert np.allclose(pose[:3, :3], np.eye(3), atol=1e-3)
    assert len(t.extract_mesh()) > 1000
    with pytest.raises(ValueError, match="rolling_shutter"):
        sldepth.Tracker(kinect, rolling_shutter_ms=40.0)


def test_a_camera_carried_elsewhere_goes_on_in_a_new_fragment(kinect):
    # Two places: the boxes, then the figure before walls. Frames of the second can be
    # aligned but match nothing near the last good pose: lost in fragment 0 for
    # new_fragment_after_s (two 1/30 s intervals here), then fragment 1 starts.
    boxes = sldepth.simulate("boxes", seed=3)[0]
    walls = sldepth.simulate("figure-walls", seed=4)[0]
    t = sldepth.Tracker(kinect, new_fragment_after_s=2 / 30)
    statuses = [t.track(boxes)[1] for _ in range(2)]
    assert statuses[0] == "initialised" and t.fragment == 0
    statuses += [t.track(walls)[1] for _ in range(3)]
    assert statuses[2] == "lost", statuses
    assert t.fragment == 1 and statuses[3] == "initialised", statuses
    assert statuses[4] in ("tracked", "tracked-against-frame"), statuses
    assert t.frame_fragments == [0, 0, 0, 1, 1]
    # Fragment 0 is suspended (a frame every sixth frame interval is tried against it), not
    # finished: its mesh comes when it is rejoined or pushed out by a newer fragment.
    assert len(t.extract_mesh()) > 1000 and t.joins == []
    with pytest.raises(ValueError, match="fragment 0"):
        t.extract_mesh(fragment=0)
    statuses += [t.track(walls)[1] for _ in range(4)]
    assert t.fragment == 1 and t.joins == [], statuses
    # The camera comes back to the boxes (six intervals after fragment 1 started): fragment 0
    # again, fragment 1 finished (joined only when the frame has a pose in both; here it has
    # none in fragment 1, so it stays in its own frame).
    pose, status = t.track(boxes)
    assert status == "relocalised" and t.fragment == 0, statuses + [status]
    assert np.abs(pose[:3, 3]).max() < 0.002
    assert len(t.extract_mesh(fragment=1)) > 1000 and t.joins == []
    assert t.frame_fragments == [0, 0, 0, 1, 1, 1, 1, 1, 1, 0]
    with pytest.raises(ValueError, match="fragment 2"):
        t.extract_mesh(fragment=2)
    # Never: every frame of the other place is lost in fragment 0.
    t = sldepth.Tracker(kinect, new_fragment_after_s=None)
    for _ in range(2):
        t.track(boxes)
    assert [t.track(walls)[1] for _ in range(3)] == ["lost"] * 3
    assert t.fragment == 0
    with pytest.raises(ValueError, match="new_fragment_after_s"):
        sldepth.Tracker(kinect, new_fragment_after_s=0.0)


def test_a_finished_fragments_mesh_is_kept_within_the_memory_budget(kinect):
    # The places of the test above: fragment 1 finishes when the camera comes back to fragment
    # 0. Its mesh is kept and its bytes come out of the budget; with a budget that holds the
    # two volumes but not the mesh beside them, the mesh is not kept and asking for it says so.
    boxes = sldepth.simulate("boxes", seed=3)[0]
    walls = sldepth.simulate("figure-walls", seed=4)[0]
    frames = [boxes] * 2 + [walls] * 7

    def run(budget):
        t = sldepth.Tracker(kinect, new_fragment_after_s=2 / 30, memory_budget_bytes=budget)
        for d in frames:
            t.track(d)
        before = t.memory_bytes
        assert t.track(boxes)[1] == "relocalised" and t.fragment == 0
        return t, before

    roomy, both_volumes = run(4 << 30)
    assert both_volumes > 0
    mesh = roomy.extract_mesh(fragment=1)
    assert len(mesh) > 1000
    # Fragment 1's volume is gone; its mesh (positions, normals, triangles, confidence) is
    # counted beside fragment 0's volume.
    kept = sum(a.nbytes for a in (mesh.vertices, mesh.normals, mesh.triangles, mesh.confidence))
    assert kept + 1_000_000 < roomy.memory_bytes < 4 << 30
    tight, _ = run(both_volumes)
    with pytest.raises(ValueError, match="fragment 1's mesh was not kept.*memory_budget_bytes"):
        tight.extract_mesh(fragment=1)
    assert len(tight.extract_mesh()) > 1000



def test_track_sequence_moves_joined_fragments_into_the_older_world():
    from sldepth import _poses_in_joined_worlds

    shift = np.eye(4)
    shift[:3, 3] = [1.0, 2.0, 3.0]
    poses = np.stack([np.eye(4)] * 4)
    out = _poses_in_joined_worlds(poses, [0, 1, 1, 2], [(1, 0, shift)])
    assert np.array_equal(out[0], np.eye(4)) and np.array_equal(out[3], np.eye(4))
    assert np.array_equal(out[1], shift) and np.array_equal(out[2], shift)
    assert np.array_equal(poses[1], np.eye(4)), "the input is not modified"


def test_a_resampled_camera_tracks_decimated_frames(kinect):
    # A QVGA stream of the VGA sensor: intrinsics halved, the sensor's noise model kept.
    half = kinect.resampled(0.5)
    assert (half.width, half.height, half.fx) == (320, 240, kinect.fx / 2)
    assert half.sensor_focal_px == kinect.sensor_focal_px == kinect.fx
    assert half.sigma_z(2.0) == kinect.sigma_z(2.0)
    with pytest.raises(ValueError):
        kinect.resampled(0.0)
    depth = sldepth.simulate("boxes", seed=3)[0][::2, ::2]
    t = sldepth.Tracker(half)
    assert t.track(depth)[1] == "initialised"
    pose, status = t.track(depth)
    assert status in ("tracked", "tracked-against-frame"), status
    assert np.abs(pose[:3, 3]).max() < 0.002
    # The pose is known about as well as at full resolution: the frame holds the same scene.
    full = sldepth.Tracker(kinect)
    for _ in range(2):
        full.track(sldepth.simulate("boxes", seed=3)[0])
    ratio = t.last_weakest_sigma_m / full.last_weakest_sigma_m
    assert 0.75 < ratio < 1.33, ratio


def test_tracker_undistorts_with_the_cameras_lens_model():
    # tum-fr1 has a lens model: "auto" resamples each frame, so the fused model differs from
    # the one built from the frames as given; a still camera is tracked either way.
    cam = sldepth.Camera.preset("tum-fr1")
    assert cam.lens is not None
    depth = sldepth.simulate("boxes", seed=3, camera=cam)[0]
    meshes = {}
    for lens in ("auto", "none"):
        t = sldepth.Tracker(cam, lens=lens)
        t.track(depth)
        pose, status = t.track(depth)
        assert status in ("tracked", "tracked-against-frame"), (lens, status)
        assert np.abs(pose[:3, 3]).max() < 0.002
        meshes[lens] = t.extract_mesh()
    assert len(meshes["auto"]) != len(meshes["none"])
    # With "auto" the fused frame is exactly what sldepth.undistort gives.
    t = sldepth.Tracker(cam, lens="none", prefilter="none")
    t.track(sldepth.undistort(depth, cam))
    u = sldepth.Tracker(cam, prefilter="none")
    u.track(depth)
    assert len(t.extract_mesh()) == len(u.extract_mesh())
    with pytest.raises(ValueError, match="lens"):
        sldepth.Tracker(cam, lens="fisheye")


def test_tracker_reports_lost_where_the_scene_does_not_pin_the_motion(kinect):
    # A tilted floor alone leaves the translation along it free: the degenerate-view check
    # (the pose's weakest direction from the sensor model with the floor plane's normal) says
    # "lost" instead of guessing, smoothed or raw (raw, the noise of per-pixel normals used to
    # make the floor look constrained).
    # The floor does not start a sequence either: the tracker waits for a view that pins the pose.
    floor = sldepth.simulate("floor", seed=3)[0]
    for prefilter in ("multiscale", "none"):
        t = sldepth.Tracker(kinect, prefilter=prefilter)
        assert t.track(floor)[1] == "lost", prefilter
        assert t.last_failure.startswith("first frame: degenerate view")
        assert t.track(floor)[1] == "lost", prefilter
        assert "degenerate view" in t.last_failure
        assert t.last_weakest_sigma_m == float("inf")
    # The boxes: constrained every way, the weakest direction known to a few millimetres (the
    # frame alone at the first frame; then the part of it that overlaps the model).
    boxes = sldepth.simulate("boxes", seed=3)[0]
    t = sldepth.Tracker(kinect)
    assert t.track(boxes)[1] == "initialised"
    assert 0 < t.last_weakest_sigma_m < 0.005 and t.last_failure is None
    t.track(floor)  # a floor after a good frame: lost, the boxes' model kept
    assert t.track(boxes)[1] == "relocalised"
    assert 0 < t.last_weakest_sigma_m < 0.005


def test_tracker_takes_a_direction_the_scene_leaves_free_from_the_odometry(kinect):
    # The same floor frame again and again while an odometry says the camera moved 1 cm a
    # frame along its x axis (level, so along the floor): the floor pins its normal, the
    # odometry the rest. Each frame is tracked at the odometry's position along the floor.
    floor = sldepth.simulate("floor", seed=3)[0]
    t = sldepth.Tracker(kinect, odometry_drift=0.05)
    for i in range(4):
        odometry = np.eye(4)
        odometry[0, 3] = 0.01 * i
        pose, status = t.track(floor, odometry=odometry)
        assert status == ("initialised" if i == 0 else "tracked"), (i, t.last_failure)
        np.testing.assert_allclose(pose[:3, 3], [0.01 * i, 0, 0], atol=1e-3)
        np.testing.assert_allclose(pose[:3, :3], np.eye(3), atol=1e-3)
    # A frame the odometry has no pose for (NaN, as RosBag.tf_lookup gives): as without one.
    assert t.track(floor, odometry=np.full((4, 4), np.nan))[1] == "lost"
    assert "degenerate view" in t.last_failure
    with pytest.raises(ValueError, match="odometry"):
        t.track(floor, odometry=np.eye(3))
    with pytest.raises(ValueError, match="odometry_drift"):
        sldepth.Tracker(kinect, odometry_drift=2.0)


def assert_still_within_noise(frames, poses, kinect, timestamps_s=None):
    """The poses of a still camera's frames lie within 3σ of it, σ being the uncertainty the
    tracker reports for each frame (its weakest direction, from the sensor model), and the
    boxes pin each pose to a few millimetres. A step-by-step `Tracker` with the same settings
    gives the same poses and reports the σ."""
    t = sldepth.Tracker(kinect, rolling_shutter_ms=0)
    for i, f in enumerate(frames):
        ts = None if timestamps_s is None else timestamps_s[i]
        pose = t.track(f, timestamp_s=ts)[0]
        assert np.array_equal(pose, poses[i])
        sigma = t.last_weakest_sigma_m
        assert 0 < sigma < 0.005, sigma
        assert np.linalg.norm(poses[i][:3, 3]) < 3 * sigma, (i, poses[i][:3, 3], sigma)


def test_track_sequence_from_arrays_and_files(kinect, tmp_path):
    frames = [sldepth.simulate("boxes", seed=s)[0] for s in (3, 4, 5)]
    # The simulator renders every row from the frame's one pose: a global shutter, whatever
    # the preset's readout.
    poses, statuses, tracker = sldepth.track_sequence(frames, kinect, rolling_shutter_ms=0)
    assert poses.shape == (3, 4, 4) and poses.dtype == np.float64
    assert statuses[0] == "initialised" and np.allclose(poses[0], np.eye(4))
    assert all(s == "tracked" for s in statuses[1:]), statuses
    assert_still_within_noise(frames, poses, kinect)
    assert len(tracker.extract_mesh()) > 1000
    # The same frames as 16-bit millimetre PNGs, read by path with their scale.
    paths = []
    for i, f in enumerate(frames):
        p = tmp_path / f"{i}.png"
        sldepth.write_depth(p, f, depth_scale=1000)
        paths.append(p)
    poses_f, statuses_f, _ = sldepth.track_sequence(
        paths, kinect, depth_scale=1000, rolling_shutter_ms=0
    )
    assert statuses_f == statuses
    assert np.abs(poses_f - poses).max() < 0.002
    with pytest.raises(ValueError, match="weighting"):
        sldepth.track_sequence(frames, kinect, weighting="huber")


def test_tracker_takes_timestamps(kinect):
    frames = [sldepth.simulate("boxes", seed=s)[0] for s in (3, 4, 5)]
    # A still camera with a dropped frame (0.1 s between the last two): tracked as before.
    poses, statuses, _ = sldepth.track_sequence(
        frames, kinect, timestamps_s=[10.0, 10.033, 10.133], rolling_shutter_ms=0
    )
    assert all(s == "tracked" for s in statuses[1:]), statuses
    assert_still_within_noise(frames, poses, kinect, timestamps_s=[10.0, 10.033, 10.133])
    with pytest.raises(ValueError, match="timestamps_s has 2 entries for 3 frames"):
        sldepth.track_sequence(frames, kinect, timestamps_s=[0.0, 1.0])
    # Timestamps must increase; a rejected frame leaves the tracker as it was.
    t = sldepth.Tracker(kinect)
    t.track(frames[0], timestamp_s=5.0)
    with pytest.raises(ValueError, match="not after the previous"):
        t.track(frames[1], timestamp_s=4.0)
    with pytest.raises(ValueError, match="not a finite number of seconds"):
        t.track(frames[1], timestamp_s=float("nan"))
    assert t.track(frames[1], timestamp_s=5.033)[1] == "tracked"


def _shared_data():
    """The shared real-data folder (SLDEPTH_DATA, else ../shared/data beside the checkout), or
    a skip with the reason."""
    import os
    import pathlib

    env = os.environ.get("SLDEPTH_DATA")
    here = pathlib.Path(__file__).resolve().parents[3] / ".." / "shared" / "data"
    path = pathlib.Path(env) if env else here
    if not path.is_dir():
        pytest.skip(f"real data not found ({path}; set SLDEPTH_DATA)")
    return path


def test_a_continuation_that_rejoins_moves_the_fragments_it_continues():
    # TUM fr1/rpy-200 frames 0-29, 90 of its frames upside down (lost, then a new fragment
    # after 0.3 s), frames 29-79 (back: a rejoin). With this budget the new fragment fills and
    # goes on in continuations, and one of them rejoins fragment 0: the first fragment of its
    # chain is joined there too, so every frame's pose and every kept mesh is in fragment 0's
    # world (before, the chain's first fragment stayed in the upside-down camera's world).
    tum = _shared_data() / "tum-fr1-rpy-200"
    names = [l.split()[1] for l in open(tum / "depth.txt") if not l.startswith("#")]
    order = [(False, i) for i in range(30)] + [(True, i) for i in range(90)]
    order += [(False, i) for i in range(29, 80)]
    frames = []
    for upside_down, i in order:
        d = sldepth.read_depth(tum / names[i], depth_scale=5000.0)
        frames.append(np.ascontiguousarray(d[::-1, ::-1]) if upside_down else d)
    cam = sldepth.Camera.preset("tum-fr1")
    poses, statuses, t = sldepth.track_sequence(
        frames,
        cam,
        timestamps_s=[1000.0 + k / 30.0 for k in range(len(frames))],
        keyframes=False,
        new_fragment_after_s=0.3,
        memory_budget_bytes=(800 << 20) // 3,
    )
    into = {f: j for f, j, _ in t.joins}
    continuations = {f for f, j, m in t.joins if j == f - 1 and np.allclose(m, np.eye(4))}

    def world(f):
        while f in into and into[f] < f:
            f = into[f]
        return f

    assert len(poses) == len(frames)
    assert {world(f) for f in set(t.frame_fragments)} == {0}, t.joins
    # The first fragment of a continued chain, joined into fragment 0; its kept mesh lies
    # where fragment 0's does (the camera saw the same desk).
    roots = [f for f in into if f not in continuations and into[f] == 0 and f + 1 in continuations]
    assert roots, t.joins
    c0 = t.extract_mesh(fragment=0).vertices.mean(axis=0)
    for r in roots:
        c = t.extract_mesh(fragment=r).vertices.mean(axis=0)
        assert np.linalg.norm(c - c0) < 0.6, (r, c, c0)


def test_track_sequence_takes_a_real_recordings_folder_as_the_command_line_does():
    # The 30 TUM fr1/rpy frames as TUM ships them (associations.txt): in one call, the
    # folder's frames, timestamps, camera (tum-fr1 by its name, lens model and rolling
    # shutter) and depth scale (5000), exactly as the explicit calls give them; no frame lost.
    tum = _shared_data() / "tum-fr1-rpy"
    poses, statuses, tracker = sldepth.track_sequence(tum)
    assert statuses[0] == "initialised" and statuses.count("tracked") == len(statuses) - 1
    paths, times = sldepth.read_sequence(tum)
    cam = sldepth.sequence_camera(tum)
    assert cam.preset_name == "tum-fr1" and sldepth.sequence_depth_scale(tum) == 5000.0
    explicit, statuses_e, _ = sldepth.track_sequence(
        paths, cam, depth_scale=5000.0, timestamps_s=times
    )
    assert statuses_e == statuses and np.array_equal(explicit, poses)

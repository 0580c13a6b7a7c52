"""Camera model, presets and depth files."""

import warnings

import numpy as np
import pytest

import sldepth


def test_presets_include_the_documented_cameras():
    names = sldepth.Camera.presets()
    for n in ["kinect-v1", "tum-fr1", "7-scenes", "nyu-v2", "icl-nuim", "primesense", "d415", "d435", "d455", "oak-d"]:
        assert n in names
    d435 = sldepth.Camera.preset("d435")
    assert (d435.width, d435.height, d435.subpixel) == (848, 480, 32)
    assert d435.baseline_m == pytest.approx(0.050)


def test_unknown_preset_lists_the_names():
    with pytest.raises(ValueError, match="kinect-v1.*d435"):
        sldepth.Camera.preset("kinect-v9")
    with pytest.raises(sldepth.SlDepthError):
        sldepth.Camera.preset("nope")


def test_sigma_z_follows_the_square_law(kinect):
    # sigma_Z = Z^2 sigma_D / (f B): 0.07 / (580 * 0.075) = 1.609 mm at 1 m.
    assert kinect.sigma_z(1.0) == pytest.approx(0.07 / (580 * 0.075))
    assert kinect.sigma_z(3.0) / kinect.sigma_z(1.5) == pytest.approx(4.0)
    d = kinect.depth_to_disparity(2.0)
    assert d == pytest.approx(580 * 0.075 / 2.0)
    assert kinect.disparity_to_depth(d) == pytest.approx(2.0)
    assert kinect.fb == pytest.approx(43.5)


def test_open3d_style_constructor_and_validation():
    cam = sldepth.Camera(320, 240, 290.0, 290.0, 159.5, 119.5, baseline_m=0.05, subpixel=32)
    assert cam.intrinsic_matrix() == [[290.0, 0.0, 159.5], [0.0, 290.0, 119.5], [0.0, 0.0, 1.0]]
    assert cam == sldepth.Camera(320, 240, 290.0, 290.0, 159.5, 119.5, baseline_m=0.05, subpixel=32)
    with pytest.raises(ValueError):
        sldepth.Camera(320, 240, -1.0, 290.0, 159.5, 119.5)
    with pytest.raises(ValueError):
        sldepth.Camera(320, 240, 290.0, 290.0, 159.5, 119.5, baseline_m=float("nan"))


def test_numbers_are_repeated_compactly():
    # The refused value as it was given (-517.3, 0), not -5.173e2 / 0e0; a repr is no 300-digit
    # decimal, and still evaluates back to the camera.
    with pytest.raises(ValueError, match=r"fx = -517\.3 must be in \[1, 1e7\] pixels"):
        sldepth.Camera(640, 480, -517.3, 500.0, 319.5, 239.5)
    with pytest.raises(ValueError, match=r"baseline -0\.075 m must be"):
        sldepth.Camera(640, 480, 500.0, 500.0, 319.5, 239.5, baseline_m=-0.075)
    with pytest.raises(ValueError, match=r"depth_scale 0 units per metre is outside"):
        sldepth.filter(np.full((48, 64), 2000, dtype=np.uint16), depth_scale=0)
    tiny = sldepth.Camera(640, 480, 517.3, 516.5, 318.6, 255.3, baseline_m=1e-300)
    assert "baseline_m=1e-300," in repr(tiny) and len(repr(tiny)) < 200
    assert eval(repr(tiny), {"Camera": sldepth.Camera}) == tiny


@pytest.mark.parametrize("ext", ["png", "tiff"])
def test_depth_round_trip(tmp_path, ext):
    rng = np.random.default_rng(1)
    z = rng.uniform(0.5, 4.0, size=(48, 64)).astype(np.float32)
    z[5, 7] = 0.0
    path = tmp_path / f"d.{ext}"
    sldepth.write_depth(path, z, depth_scale=5000)
    back = sldepth.read_depth(path, depth_scale=5000)
    assert back.dtype == np.float32 and back.shape == (48, 64)
    assert back[5, 7] == 0.0
    # Stored at 0.2 mm units: round-trip error at most half a unit.
    assert np.max(np.abs(back - z)) <= 0.5 / 5000 + 1e-6


def test_float_tiff_depth_round_trips_exactly_in_metres(tmp_path):
    # A 32-bit float TIFF (as ROS 32FC1 depth and cv2.imwrite of a float array store it): metres
    # by default, bit for bit; "tiff" and "tiff-f32" both read it; invalid pixels come back 0.
    rng = np.random.default_rng(2)
    z = rng.uniform(0.5, 4.0, size=(48, 64)).astype(np.float32)
    z[5, 7] = 0.0
    z[6, 8] = np.nan
    path = tmp_path / "ros.tif"
    sldepth.write_depth(path, z, format="tiff-f32")
    expected = np.nan_to_num(z, nan=0.0)
    for fmt in (None, "tiff", "tiff-f32"):
        back = sldepth.read_depth(path, format=fmt)
        assert back.dtype == np.float32 and np.array_equal(back, expected)
    # Millimetres as floats, read at that scale; read without it, metres as stored.
    mm = tmp_path / "mm.tif"
    sldepth.write_depth(mm, z, depth_scale=1000, format="tiff-f32")
    assert np.allclose(sldepth.read_depth(mm, depth_scale=1000), expected, rtol=1e-6)
    assert np.allclose(sldepth.read_depth(mm), expected * 1000, rtol=1e-6)
    # uint16 depth units, converted at depth_scale, are stored at that scale as floats.
    sldepth.write_depth(mm, np.full((4, 5), 1500, np.uint16), depth_scale=1000, format="tiff-f32")
    assert np.allclose(sldepth.read_depth(mm, depth_scale=1000), 1.5)
    # A 16-bit TIFF is not float depth.
    u16 = tmp_path / "u16.tif"
    sldepth.write_depth(u16, z)
    with pytest.raises(OSError, match="tiff-f32"):
        sldepth.read_depth(u16, format="tiff-f32")


def test_a_tum_folders_frame_is_read_at_tums_scale(tmp_path):
    # A frame in the depth/ folder of a TUM RGB-D folder (depth.txt beside it) is stored at
    # 5000 units per metre: read so without a depth_scale; anywhere else 1000 is assumed.
    z = np.full((48, 64), 1.5, dtype=np.float32)
    seq = tmp_path / "rgbd_dataset_freiburg1_desk"
    (seq / "depth").mkdir(parents=True)
    frame = seq / "depth" / "1.png"
    sldepth.write_depth(frame, z, depth_scale=5000)
    assert np.allclose(sldepth.read_depth(frame), 7.5)
    (seq / "depth.txt").write_text("1.0 depth/1.png\n")
    assert np.allclose(sldepth.read_depth(frame), 1.5)
    assert np.allclose(sldepth.read_depth(frame, depth_scale=1000), 7.5)


def test_a_sun_rgbd_samples_frame_and_camera(tmp_path):
    # A SUN RGB-D sample: its depth/ PNG is SUN's bit-rotated millimetres, read as such without a
    # format; its intrinsics.txt is the camera (sun_camera) for the frame's size.
    sample = tmp_path / "NYU0001"
    (sample / "depth").mkdir(parents=True)
    frame = sample / "depth" / "NYU0001.png"
    # 1500 mm rotated left by 3 bits, as SUN stores it, written as the integers they are.
    rotated = ((1500 << 3) | (1500 >> 13)) & 0xFFFF
    sldepth.write_depth(frame, np.full((48, 64), rotated, dtype=np.uint16), depth_scale=1000)
    assert not np.allclose(sldepth.read_depth(frame), 1.5)  # not yet a sample: a plain PNG
    (sample / "image").mkdir()
    (sample / "intrinsics.txt").write_text("60 0 31.5\n0 60 23.5\n0 0 1\n")
    assert np.allclose(sldepth.read_depth(frame), 1.5)
    cam = sldepth.sun_camera(sample, 64, 48)
    assert (cam.fx, cam.cx, cam.width, cam.height) == (60.0, 31.5, 64, 48)
    with pytest.raises(OSError, match="principal point"):
        sldepth.sun_camera(sample, 16, 12)


def test_uint16_input_needs_a_scale(small_cam):
    mm = np.full((48, 64), 2000, dtype=np.uint16)
    with pytest.raises(ValueError, match="depth_scale"):
        sldepth.filter(mm, small_cam)
    out = sldepth.filter(mm, small_cam, depth_scale=1000)
    assert np.allclose(out, 2.0)


def test_file_errors_are_oserrors(tmp_path):
    with pytest.raises(OSError):
        sldepth.read_depth(tmp_path / "missing.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(sldepth.SlDepthIOError, match="bad.png"):
        sldepth.read_depth(bad)
    with pytest.raises(ValueError, match="extension"):
        sldepth.write_depth(tmp_path / "x.unknown", np.ones((4, 4), np.float32))


def test_max_memory_refuses_an_image_from_its_header(tmp_path):
    # 640x480 needs 307,200 pixels; a 16 MiB budget allows 16 MiB / 256 = 65,536.
    path = tmp_path / "d.png"
    sldepth.write_depth(path, np.full((480, 640), 1.5, np.float32))
    assert sldepth.read_depth(path, max_memory_bytes=1 << 30).shape == (480, 640)
    with pytest.raises(OSError, match="too large"):
        sldepth.read_depth(path, max_memory_bytes=16 << 20)


def test_undistort_resamples_through_the_preset_lens():
    tum = sldepth.Camera.preset("tum-fr1")
    assert tum.lens == pytest.approx((0.2624, -0.9531, -0.0054, 0.0026, 1.1633))
    assert sldepth.Camera.preset("kinect-v1").lens is None
    # A depth ramp along x: the centre stays, a corner pixel comes from where the lens images
    # it (farther out for this lens at the corner), and values are never blended.
    z = np.tile(np.linspace(1.0, 2.0, 640, dtype=np.float32), (480, 1))
    out = sldepth.undistort(z, tum)
    assert out.shape == (480, 640) and out.dtype == np.float32
    assert out[255, 319] == pytest.approx(z[255, 319], abs=2e-3)
    assert set(np.unique(out[out > 0])) <= set(np.unique(z))
    assert not np.array_equal(out, z)
    # No lens: an unchanged copy; a wrong size raises ValueError.
    k = sldepth.Camera.preset("kinect-v1")
    same = sldepth.undistort(z, k)
    assert np.array_equal(same, z) and same is not z
    with pytest.raises(ValueError):
        sldepth.undistort(z[:100], tum)


def test_camera_from_file_reads_open3d_json_and_ros_calibrations(tmp_path):
    # A ROS camera calibration with TUM fr1's published numbers: the preset's intrinsics and
    # lens, so undistort() resamples alike.
    cal = tmp_path / "fr1.yaml"
    cal.write_text(
        "image_width: 640\nimage_height: 480\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [517.3, 0., 318.6, 0., 516.5,\n    255.3, 0., 0., 1.]\n"
        "distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n"
        "  data: [0.2624, -0.9531, -0.0054, 0.0026, 1.1633]\n"
    )
    cam = sldepth.Camera.from_file(cal)
    tum = sldepth.Camera.preset("tum-fr1")
    assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (640, 480, 517.3, 516.5, 318.6, 255.3)
    assert cam.lens == tum.lens and cam.preset_name is None
    z = np.tile(np.linspace(1.0, 2.0, 640, dtype=np.float32), (480, 1))
    assert np.array_equal(sldepth.undistort(z, cam), sldepth.undistort(z, tum))
    # A ROS 2 echo (block lists), no distortion.
    echo = tmp_path / "info.yml"
    echo.write_text(
        "header:\n  frame_id: depth\nheight: 480\nwidth: 848\ndistortion_model: plumb_bob\n"
        "d:\n- 0.0\n- 0.0\n- 0.0\n- 0.0\n- 0.0\nk:\n"
        + "".join(f"- {v}\n" for v in (426.0, 0.0, 423.5, 0.0, 426.0, 239.5, 0.0, 0.0, 1.0))
    )
    d435 = sldepth.Camera.from_file(echo)
    assert (d435.width, d435.fx, d435.cx) == (848, 426.0, 423.5) and d435.lens is None
    # An Open3D JSON with its sensor keys.
    js = tmp_path / "camera_intrinsic.json"
    js.write_text(
        '{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 31.5, 23.5, 1], '
        '"baseline_m": 0.05, "subpixel": 32}'
    )
    small = sldepth.Camera.from_file(js)
    assert (small.width, small.fx, small.baseline_m, small.subpixel) == (64, 60.0, 0.05, 32)
    # Not one camera: OSError naming the file; an unknown kind: ValueError.
    bad = tmp_path / "binned.yaml"
    bad.write_text(echo.read_text() + "binning_x: 2\n")
    with pytest.raises(OSError, match="binned.yaml"):
        sldepth.Camera.from_file(bad)
    with pytest.raises(ValueError, match="json"):
        sldepth.Camera.from_file(tmp_path / "camera.txt")


def _write_frames(folder, names, scale, seeds=(3, 4, 5)):
    folder.mkdir(parents=True, exist_ok=True)
    for name, seed in zip(names, seeds):
        sldepth.write_depth(folder / name, sldepth.simulate("boxes", seed=seed)[0], depth_scale=scale)


def test_read_sequence_reads_a_tum_folder_for_track_sequence(kinect, tmp_path):
    seq = tmp_path / "tum"
    _write_frames(seq / "depth", ["10.000000.png", "10.033000.png", "10.133000.png"], 5000)
    (seq / "depth.txt").write_text(
        "# depth maps\n# timestamp filename\n"
        "10.000000 depth/10.000000.png\n10.033000 depth/10.033000.png\n10.133000 depth/10.133000.png\n"
    )
    paths, times = sldepth.read_sequence(seq)
    assert [p.rsplit("/", 1)[-1] for p in paths] == ["10.000000.png", "10.033000.png", "10.133000.png"]
    assert times.dtype == np.float64 and np.allclose(times, [10.0, 10.033, 10.133])
    assert sldepth.read_sequence(seq, layout="tum")[0] == paths
    # End to end, as `sldepth track --tum`: a still camera with a dropped frame.
    poses, statuses, _ = sldepth.track_sequence(
        paths, kinect, depth_scale=5000, timestamps_s=times, rolling_shutter_ms=0
    )
    assert statuses[0] == "initialised" and all(s == "tracked" for s in statuses[1:]), statuses
    assert np.abs(poses[:, :3, 3]).max() < 0.01
    # The folder itself, in one call: its frames, timestamps and depth scale, as above.
    poses_dir, statuses_dir, _ = sldepth.track_sequence(seq, kinect, rolling_shutter_ms=0)
    assert statuses_dir == statuses and np.array_equal(poses_dir, poses)
    # Without a camera, the folder's (tum-fr1 by its name, with its lens and rolling shutter).
    poses_own, statuses_own, tracker = sldepth.track_sequence(seq, layout="tum")
    assert statuses_own[0] == "initialised" and tracker.rolling_shutter_ms == 30
    with pytest.raises(TypeError, match="needs a camera"):
        sldepth.track_sequence(paths)
    with pytest.raises(TypeError, match="layout is for a recording's folder"):
        sldepth.track_sequence(paths, kinect, layout="tum")
    with pytest.raises(TypeError, match="not a single str"):
        sldepth.track_sequence(paths[0], kinect)
    # associations.txt wins over depth.txt when both are there (its depth columns).
    (seq / "associations.txt").write_text(
        "10.0 rgb/a.png 10.000000 depth/10.000000.png\n10.1 rgb/b.png 10.133000 depth/10.133000.png\n"
    )
    paths2, times2 = sldepth.read_sequence(seq)
    assert len(paths2) == 2 and np.allclose(times2, [10.0, 10.133])
    # Timestamps out of order are an error naming the file, never a reordered trajectory.
    (seq / "associations.txt").unlink()
    (seq / "depth.txt").write_text("10.1 depth/10.033000.png\n10.0 depth/10.000000.png\n")
    with pytest.raises(OSError, match="depth.txt"):
        sldepth.read_sequence(seq)


def test_read_sequence_reads_7scenes_and_open3d_folders_in_natural_order(tmp_path):
    seven = tmp_path / "seven"
    _write_frames(seven, ["frame-2.depth.png", "frame-10.depth.png", "frame-9.depth.png"], 1000)
    (seven / "frame-2.pose.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    paths, times = sldepth.read_sequence(seven)
    assert times is None
    assert [p.rsplit("/", 1)[-1] for p in paths] == [
        "frame-2.depth.png", "frame-9.depth.png", "frame-10.depth.png"
    ]
    o3d = tmp_path / "o3d"
    _write_frames(o3d / "depth", ["1.png", "10.png", "2.png"], 1000)
    paths, times = sldepth.read_sequence(o3d)
    assert times is None
    assert [p.rsplit("/", 1)[-1] for p in paths] == ["1.png", "2.png", "10.png"]
    assert sldepth.read_sequence(o3d, layout="open3d")[0] == paths


def test_read_sequence_times_an_open3d_folder_named_by_its_timestamps(tmp_path):
    # Times written with as few decimals as they need (str(stamp.to_sec())): by the numbers in
    # the names 100.1 came before 100.0333; now in time order, with the times as timestamps.
    o3d = tmp_path / "o3d"
    _write_frames(o3d / "depth", ["100.1.png", "100.0333.png", "100.0667.png"], 1000)
    paths, times = sldepth.read_sequence(o3d)
    assert [p.rsplit("/", 1)[-1] for p in paths] == [
        "100.0333.png", "100.0667.png", "100.1.png"
    ]
    np.testing.assert_array_equal(times, [100.0333, 100.0667, 100.1])
    ns = tmp_path / "ns"
    _write_frames(ns / "depth", ["1305031229664358000.png", "1305031229628790000.png"], 1000)
    paths, times = sldepth.read_sequence(ns)
    assert paths[0].endswith("1305031229628790000.png")
    np.testing.assert_allclose(times, [1305031229.62879, 1305031229.664358], rtol=0, atol=1e-6)
    _write_frames(o3d / "depth", ["100.10.png"], 1000)
    with pytest.raises(OSError, match="name the same time"):
        sldepth.read_sequence(o3d)


def test_read_sequence_errors(tmp_path):
    with pytest.raises(OSError, match="not a folder"):
        sldepth.read_sequence(tmp_path / "missing")
    with pytest.raises(OSError, match="cannot tell the sequence's layout"):
        sldepth.read_sequence(tmp_path)
    with pytest.raises(ValueError, match='unknown sequence layout "bag": "tum", "7scenes" or "open3d"'):
        sldepth.read_sequence(tmp_path, layout="bag")
    with pytest.raises(OSError):
        sldepth.read_sequence(tmp_path, layout="tum")


def test_read_posed_sequence_gives_each_layouts_poses_for_fusion(kinect, tmp_path):
    # A TUM folder: each frame takes the ground-truth pose nearest in time, within max_dt_s.
    seq = tmp_path / "tum"
    _write_frames(seq / "depth", ["10.000000.png", "10.033000.png", "10.066000.png"], 5000)
    (seq / "depth.txt").write_text(
        "10.000000 depth/10.000000.png\n10.033000 depth/10.033000.png\n10.066000 depth/10.066000.png\n"
    )
    (seq / "groundtruth.txt").write_text(
        "# timestamp tx ty tz qx qy qz qw\n10.005 0 0 0 0 0 0 1\n10.038 0.5 0 0 0 0 0 1\n"
    )
    # The third frame has no pose within 0.02 s: left out, and said, as `sldepth fuse` notes it.
    with pytest.warns(UserWarning, match=r"1 depth frames have no groundtruth.txt pose within 0.02 s"):
        paths, times, poses = sldepth.read_posed_sequence(seq)
    assert len(paths) == 2 and np.allclose(times, [10.0, 10.033])
    assert poses.shape == (2, 4, 4) and poses.dtype == np.float64
    assert np.allclose(poses[1][:3, 3], [0.5, 0, 0]) and np.allclose(poses[0], np.eye(4))
    with pytest.warns(UserWarning, match="3 depth frames"):
        assert len(sldepth.read_posed_sequence(seq, max_dt_s=0.001)[0]) == 0
    with pytest.raises(ValueError, match="max_dt_s"):
        sldepth.read_posed_sequence(seq, max_dt_s=0.0)
    # The frames fuse as `sldepth fuse DIR` would.
    vol = sldepth.TsdfVolume(voxel_m=0.02)
    for p, T in zip(paths, poses):
        vol.integrate(sldepth.read_depth(p, depth_scale=5000), kinect, T)
    assert len(vol.extract_mesh()) > 1000
    # An Open3D-style folder: its one .log beside depth/; a second one is ambiguous.
    o3d = tmp_path / "o3d"
    _write_frames(o3d / "depth", ["0.png", "1.png"], 1000)
    (o3d / "odometry.log").write_text(
        "".join(f"{i} {i} {i + 1}\n1 0 0 0\n0 1 0 {0.1 * i}\n0 0 1 0\n0 0 0 1\n" for i in range(2))
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every image has its pose: nothing to say
        paths, times, poses = sldepth.read_posed_sequence(o3d)
    assert times is None and len(paths) == 2 and np.isclose(poses[1][1, 3], 0.1)
    _write_frames(o3d / "depth", ["2.png"], 1000)
    with pytest.warns(UserWarning, match=r"1 depth frames have no entry in the \.log"):
        assert len(sldepth.read_posed_sequence(o3d)[0]) == 2
    # A 7-Scenes folder is read by its pose files; a depth frame without one is said.
    seven = tmp_path / "seven"
    _write_frames(seven, ["frame-000000.depth.png", "frame-000001.depth.png"], 1000)
    (seven / "frame-000000.pose.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    with pytest.warns(UserWarning, match=r"1 depth frames have no pose file"):
        paths, times, poses = sldepth.read_posed_sequence(seven)
    assert times is None and [p[-22:] for p in paths] == ["frame-000000.depth.png"]
    # With no pose file at all: no frame, and still no timestamps (7-Scenes has none).
    (seven / "frame-000000.pose.txt").unlink()
    with pytest.warns(UserWarning, match=r"2 depth frames have no pose file"):
        paths, times, poses = sldepth.read_posed_sequence(seven)
    assert paths == [] and times is None and poses.shape == (0, 4, 4)
    (o3d / "other.log").write_text("")
    with pytest.raises(OSError, match=r"needs one \.log trajectory .*odometry\.log, other\.log"):
        sldepth.read_posed_sequence(o3d)


def test_read_posed_sequence_along_a_trajectory_file(tmp_path):
    # A TUM folder without ground truth, along an estimate: by time; a lost frame (a comment
    # line, as `sldepth track` writes it) has no pose, and is said.
    seq = tmp_path / "tum"
    _write_frames(seq / "depth", ["10.000000.png", "10.033000.png", "10.066000.png"], 5000)
    (seq / "depth.txt").write_text(
        "10.000000 depth/10.000000.png\n10.033000 depth/10.033000.png\n10.066000 depth/10.066000.png\n"
    )
    est = tmp_path / "est.txt"
    est.write_text(
        "# sldepth track\n10.000000 0 0 0 0 0 0 1\n# 10.033000 lost: test\n10.070 0.3 0 0 0 0 0 1\n"
    )
    with pytest.warns(UserWarning, match=r"1 depth frames have no pose in the trajectory"):
        paths, times, poses = sldepth.read_posed_sequence(seq, trajectory=est)
    assert np.allclose(times, [10.0, 10.066]) and np.allclose(poses[1][:3, 3], [0.3, 0, 0])
    # An Open3D .log by frame number; a 7-Scenes folder (no timestamps) likewise.
    log = tmp_path / "est.log"
    log.write_text("".join(f"{i} {i} 3\n1 0 0 {i}\n0 1 0 0\n0 0 1 0\n0 0 0 1\n" for i in (0, 2)))
    seven = tmp_path / "seven"
    _write_frames(seven, [f"frame-00000{i}.depth.png" for i in range(3)], 1000)
    with pytest.warns(UserWarning, match="1 depth frames"):
        paths, times, poses = sldepth.read_posed_sequence(seven, trajectory=log)
    assert times is None and [p[-22:] for p in paths] == ["frame-000000.depth.png", "frame-000002.depth.png"]
    assert np.isclose(poses[1][0, 3], 2.0)
    # Another recording's trajectory: no frame has a pose, an OSError that says how they match.
    (tmp_path / "far.txt").write_text("900 0 0 0 0 0 0 1\n")
    with pytest.raises(OSError, match="gives none of the 3 depth frames"):
        sldepth.read_posed_sequence(seq, trajectory=tmp_path / "far.txt")


def test_a_scannet_export_reads_as_a_posed_sequence_with_its_camera(tmp_path):
    # depth/<n>.png, pose/<n>.txt (a -inf matrix: no pose), intrinsic/intrinsic_depth.txt (4x4).
    scan = tmp_path / "scene0000_00"
    _write_frames(scan / "depth", ["0.png", "1.png", "2.png"], 1000)
    (scan / "pose").mkdir()
    (scan / "pose" / "0.txt").write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    (scan / "pose" / "1.txt").write_text("-inf -inf -inf -inf\n" * 4)
    (scan / "pose" / "2.txt").write_text("1 0 0 0.2\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    (scan / "intrinsic").mkdir()
    (scan / "intrinsic" / "intrinsic_depth.txt").write_text(
        "577.590698 0 318.905426 0\n0 578.729797 242.683609 0\n0 0 1 0\n0 0 0 1\n"
    )
    with pytest.warns(UserWarning, match=r"1 depth frames have no pose \(no pose/ file, or ScanNet"):
        paths, times, poses = sldepth.read_posed_sequence(scan)
    assert times is None and [p[-5:] for p in paths] == ["0.png", "2.png"]
    assert np.isclose(poses[1][0, 3], 0.2)
    cam = sldepth.sequence_camera(scan)
    assert np.isclose(cam.fx, 577.590698) and np.isclose(cam.cy, 242.683609)
    assert (cam.width, cam.height) == (640, 480)
    assert sldepth.sequence_depth_scale(scan) == 1000.0


def test_an_icl_nuim_tum_folder_reads_its_y_up_ground_truth_into_sldepths_frame(tmp_path):
    # ICL-NUIM's TUM-format archive: associations depth first with frame numbers, the
    # data set's livingRoomN.gt.freiburg beside it (frame 0 has no pose), depth / 5000.
    icl = tmp_path / "living_room_traj0_frei_png"
    _write_frames(icl / "depth", ["0.png", "1.png", "2.png"], 5000)
    (icl / "associations.txt").write_text(
        "0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n2 depth/2.png 2 rgb/2.png\n"
    )
    h = np.sqrt(0.5)
    (icl / "livingRoom0.gt.freiburg").write_text(
        f"1 0.5 0.25 -2 0 0 0 1\n2 0.5 0.3 -2 {h} 0 0 {h}\n"
    )
    assert sldepth.icl_nuim_tum_folder(icl) and sldepth.tum_stamps_are_frame_numbers(icl)
    assert not sldepth.icl_nuim_tum_folder(tmp_path)
    cam = sldepth.sequence_camera(icl)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (481.2, 480.0, 319.5, 239.5)
    assert sldepth.sequence_depth_scale(icl) == 5000.0
    with pytest.warns(UserWarning, match="1 depth frames"):
        paths, times, poses = sldepth.read_posed_sequence(icl)
    assert [p[-5:] for p in paths] == ["1.png", "2.png"] and list(times) == [1.0, 2.0]
    # y negated; a turn about x turns the other way: F @ P @ F.
    f = np.diag([1.0, -1.0, 1.0, 1.0])
    raw = sldepth.read_trajectory(icl / "livingRoom0.gt.freiburg")[1]
    assert np.allclose(poses, f @ raw @ f)
    assert np.isclose(poses[0][1, 3], -0.25) and np.isclose(poses[1][1, 2], 1.0)


def test_an_eth3d_folder_takes_its_calibration(tmp_path):
    # ETH3D SLAM: depth.txt, depth/ at 5000 units per metre, calibration.txt "fx fy cx cy".
    eth = tmp_path / "sofa_1"
    _write_frames(eth / "depth", ["1.5.png"], 5000, seeds=(3,))
    (eth / "depth.txt").write_text("1.5 depth/1.5.png\n")
    assert sldepth.sequence_camera(eth).preset_name == "tum-fr1"
    (eth / "calibration.txt").write_text("560.5 561.5 320.2 240.1\n")
    cam = sldepth.sequence_camera(eth)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == (560.5, 561.5, 320.2, 240.1)
    assert cam.preset_name is None and cam.rolling_shutter_ms == 0 and cam.lens is None
    assert sldepth.sequence_depth_scale(eth) == 5000.0


def test_a_sequence_list_over_the_limits_is_refused_with_a_python_hint(tmp_path):
    # More lines than the default budget's text limit: refused while it streams in, and the
    # message does not send a Python user to a command-line option.
    seq = tmp_path / "tum"
    seq.mkdir()
    (seq / "depth.txt").write_text("\n" * ((1 << 20) + 1))
    with pytest.raises(OSError, match="default 4 GiB memory budget") as e:
        sldepth.read_sequence(seq)
    assert "raise it with --max-memory" not in str(e.value)


def test_sequence_depth_scale_is_the_layouts_as_the_command_line_reads_it(tmp_path):
    tum = tmp_path / "tum"
    _write_frames(tum / "depth", ["1.000000.png"], 5000, seeds=(3,))
    (tum / "depth.txt").write_text("1.000000 depth/1.000000.png\n")
    assert sldepth.sequence_depth_scale(tum) == 5000.0
    # Read at that scale, the frame is the one written; as millimetres, five times too deep.
    z = sldepth.simulate("boxes", seed=3)[0]
    read = sldepth.read_depth(tum / "depth" / "1.000000.png", depth_scale=sldepth.sequence_depth_scale(tum))
    assert np.allclose(read, z, atol=2e-4)
    seven = tmp_path / "seven"
    _write_frames(seven, ["frame-000000.depth.png"], 1000, seeds=(3,))
    assert sldepth.sequence_depth_scale(seven) == 1000.0
    assert sldepth.sequence_depth_scale(seven, layout="open3d") == 1000.0
    with pytest.raises(OSError, match="cannot tell the sequence's layout"):
        sldepth.sequence_depth_scale(tmp_path)
    with pytest.raises(ValueError, match="unknown sequence layout"):
        sldepth.sequence_depth_scale(seven, layout="bag")


def test_sequence_camera_is_the_folders_as_the_command_line_picks_it(tmp_path):
    fr2 = tmp_path / "rgbd_dataset_freiburg2_xyz"
    _write_frames(fr2 / "depth", ["1.000000.png"], 5000, seeds=(3,))
    (fr2 / "depth.txt").write_text("1.000000 depth/1.000000.png\n")
    cam = sldepth.sequence_camera(fr2)
    assert cam.preset_name == "tum-fr2" and cam.lens is not None and cam.rolling_shutter_ms > 0
    seven = tmp_path / "seven"
    _write_frames(seven, ["frame-000000.depth.png"], 1000, seeds=(3,))
    assert sldepth.sequence_camera(seven).preset_name == "7-scenes"
    (seven / "camera-intrinsics.txt").write_text("500 0 320\n0 500 240\n0 0 1\n")
    # The file's intrinsics with the data set's sensor: the 7-Scenes Kinect's rolling shutter,
    # which `sldepth track --7scenes` models too.
    cam = sldepth.sequence_camera(seven)
    assert cam.preset_name == "7-scenes" and cam.fx == 500.0
    assert cam.rolling_shutter_ms == sldepth.Camera.preset("7-scenes").rolling_shutter_ms > 0
    # 3DMatch's layout: the scene's camera file above its seq-XX folders.
    seq = tmp_path / "scene" / "seq-01"
    _write_frames(seq, ["frame-000000.depth.png"], 1000, seeds=(3,))
    (seq.parent / "camera-intrinsics.txt").write_text("550 0 320\n0 550 240\n0 0 1\n")
    cam = sldepth.sequence_camera(seq)
    assert cam.preset_name == "7-scenes" and cam.fx == 550.0 and cam.width == 640
    # One of its frames: the same camera, as `sldepth` takes it for the frame alone.
    cam = sldepth.frame_camera(seq / "frame-000000.depth.png")
    assert cam.preset_name == "7-scenes" and cam.fx == 550.0
    # A frame in no sequence folder: none.
    assert sldepth.frame_camera(tmp_path / "loose.png") is None
    o3d = tmp_path / "o3d"
    _write_frames(o3d / "depth", ["0.png"], 1000, seeds=(3,))
    # Without a camera file, Open3D's PrimeSenseDefault, as Open3D takes such a folder.
    assert sldepth.sequence_camera(o3d).preset_name == "ros-default"
    # An Open3D folder's own camera.json: any camera, no preset.
    (o3d / "camera.json").write_text(
        '{"width": 64, "height": 48, "intrinsic_matrix": [60, 0, 0, 0, 60, 0, 32, 24, 1]}'
    )
    cam = sldepth.sequence_camera(o3d)
    assert cam.preset_name is None and cam.width == 64 and cam.rolling_shutter_ms == 0
    assert sldepth.frame_camera(o3d / "depth" / "0.png").width == 64
    (o3d / "camera.json").unlink()
    (o3d / "camera.json").mkdir()
    with pytest.raises(OSError, match="not a regular file"):
        sldepth.sequence_camera(o3d)

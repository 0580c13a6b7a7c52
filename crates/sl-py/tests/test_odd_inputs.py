"""Unusual and hostile inputs: each case below misbehaved before (an abort, a silently wrong
result or a misleading message; docs/bench/README.md, session 47)."""

import math
import re

import numpy as np
import pytest

import sldepth


def test_cameras_beyond_any_frame_budget_or_sensor_are_refused():
    # A 20000x20000 camera made the tracker's constructor abort on allocation.
    with pytest.raises(sldepth.SlDepthError, match="over the limit of"):
        sldepth.Camera(20000, 20000, 525, 525, 1e4, 1e4)
    with pytest.raises(sldepth.SlDepthError, match="over the limit of"):
        sldepth.Camera.preset("kinect-v1").resampled(10)
    with pytest.raises(sldepth.SlDepthError, match=r"must be in \[1, 1e7\]"):
        sldepth.Camera(640, 480, 1e-300, 525, 320, 240)
    with pytest.raises(sldepth.SlDepthError, match="baseline"):
        sldepth.Camera(640, 480, 525, 525, 320, 240, baseline_m=1e30)
    with pytest.raises(sldepth.SlDepthError, match="disparity noise"):
        sldepth.Camera(640, 480, 525, 525, 320, 240, sigma_d_px=1e30)
    # Preset names are looked up loosely and reported canonically.
    cam = sldepth.Camera.preset("  KINECT-v1 ")
    assert cam.preset_name == "kinect-v1"
    assert cam == sldepth.Camera.preset("kinect-v1")
    assert 'preset="kinect-v1"' in repr(cam)
    # No measurement has a depth of 0 or less: its noise is not a number.
    assert all(math.isnan(cam.sigma_z(z)) for z in (-2.0, 0.0, math.inf))
    assert cam.sigma_z(2.0) > 0


@pytest.mark.parametrize("value", [-1, -(2**70), 2**64, 2**200])
def test_integers_out_of_range_are_valueerrors_naming_the_range(small_cam, wall, value):
    # pyo3 raised OverflowError (not a ValueError) for a negative or huge count or size.
    calls = [
        lambda: sldepth.Camera(value, 48, 58.0, 58.0, 31.5, 23.5),
        lambda: sldepth.Camera(64, 48, 58.0, 58.0, 31.5, 23.5, subpixel=value),
        lambda: sldepth.filter(wall, small_cam, radius=value),
        lambda: sldepth.simulate("three-planes", seed=value),
        lambda: sldepth.noise_stats(wall, small_cam, min_plane_pixels=value),
        lambda: sldepth.extract_planes(wall, small_cam, min_pixels=value),
        lambda: sldepth.explain_planes(wall, small_cam, min_region_pixels=value),
        lambda: sldepth.TsdfVolume(memory_budget_bytes=value),
        lambda: sldepth.TsdfVolume().slice("z", 1.0, pixels_per_voxel=value),
        lambda: sldepth.read_depth("does-not-matter.png", max_memory_bytes=value),
        lambda: sldepth.Tracker(small_cam).extract_mesh(fragment=value),
        lambda: sldepth.set_num_threads(value),
    ]
    for call in calls:
        with pytest.raises(sldepth.SlDepthError, match=r"expected an integer in 0\.\.="):
            call()
    # The check is the conversion's alone: in range, NumPy integers pass, floats stay TypeErrors.
    assert sldepth.filter(wall, small_cam, radius=np.uint8(2)).shape == wall.shape
    with pytest.raises(TypeError):
        sldepth.filter(wall, small_cam, radius=2.0)


def test_bools_are_no_numbers_for_the_weak_return_bound():
    # bool is a subclass of int: True was taken as min_return 1.0 and as label 1.
    for flag in (True, False, np.True_):
        with pytest.raises(TypeError, match="min_return must be a number, not a bool"):
            sldepth.simulate("boxes", min_return=flag)
        with pytest.raises(TypeError, match="reflectance: label .* is a bool"):
            sldepth.simulate("boxes", min_return=0.04, reflectance={flag: 0.5})
        with pytest.raises(TypeError, match="reflectance: the reflectance of label 1 is a bool"):
            sldepth.simulate("boxes", min_return=0.04, reflectance={1: flag})
    # A label beyond any integer type names no surface (it was an OverflowError).
    with pytest.raises(sldepth.SlDepthError, match="no surface 1180591620717411303424"):
        sldepth.simulate("boxes", min_return=0.04, reflectance={2**70: 0.5})
    # Integers and NumPy floats stay numbers.
    depth, _, _ = sldepth.simulate("boxes", min_return=np.float64(0.04), reflectance={1: 0})
    assert (depth > 0).sum() > 0


def test_arrays_numpy_hands_over_in_any_layout_read_alike(small_cam, wall):
    expected = sldepth.filter(wall, small_cam)
    buf = np.zeros(wall.size * 4 + 1, np.uint8)
    misaligned = buf[1:].view(np.float32).reshape(wall.shape)
    misaligned[:] = wall
    big_endian = wall.astype(">f4")
    for a in (misaligned, big_endian):
        np.testing.assert_array_equal(sldepth.filter(a, small_cam), expected)
        assert not sldepth.input_is_borrowed(a)
    # A masked array's masked entries are invalid depth.
    masked = np.ma.masked_array(wall, mask=np.zeros(wall.shape, bool))
    masked.mask[10:20, 10:20] = True
    out = sldepth.filter(masked, small_cam)
    assert np.all(out[10:20, 10:20] == 0)
    assert np.all(out[30:, 30:] > 0)
    # Complex numbers are no pose; an absurd integer scale is no scale.
    pose = np.eye(4) + 0j
    pose[0, 3] = 5j
    with pytest.raises(sldepth.SlDepthError, match="real numbers"):
        sldepth.TsdfVolume().integrate(wall, small_cam, pose)
    with pytest.raises(sldepth.SlDepthError, match="outside 1 to 1e6"):
        sldepth.filter((wall * 1000).astype(np.uint16), small_cam, depth_scale=1e300)


def test_sensor_weights_follow_one_sensor_and_a_noise_free_one_fuses(small_cam, wall):
    noise_free = sldepth.Camera(64, 48, 58.0, 58.0, 31.5, 23.5, sigma_d_px=0.0)
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.04, weight="sensor")
    vol.integrate(wall, noise_free, np.eye(4))
    assert len(vol.extract_mesh().vertices) > 0
    other = sldepth.Camera(64, 48, 58.0, 58.0, 31.5, 23.5, baseline_m=0.5)
    with pytest.raises(sldepth.SlDepthError, match="noise model of the camera of its first"):
        vol.integrate(wall, other, np.eye(4))
    with pytest.raises(sldepth.SlDepthError, match="addresses only"):
        sldepth.TsdfVolume(voxel_m=1e-9, trunc_m=1e-8)


def test_files_and_sequences_odd_but_legal(tmp_path, small_cam, wall):
    # A uint16 array is written as it is, at its own scale.
    u16 = (wall * 1000).astype(np.uint16)
    sldepth.write_depth(tmp_path / "u.png", u16, depth_scale=1000)
    back = sldepth.read_depth(tmp_path / "u.png", depth_scale=1000)
    np.testing.assert_array_equal(np.round(back * 1000).astype(np.uint16), u16)
    # Every uint16 value, 65535 (7-Scenes' "no depth") included; 0 and 65535 read back invalid.
    edge = np.array([[0, 1, 65534, 65535]], np.uint16)
    for name in ("edge.png", "edge.tiff"):
        sldepth.write_depth(tmp_path / name, edge, depth_scale=1000)
        back = sldepth.read_depth(tmp_path / name, depth_scale=1000)
        np.testing.assert_allclose(back, [[0.0, 0.001, 65.534, 0.0]], rtol=1e-6)
    # In metres the encoding holds at most 65534 units.
    with pytest.raises(sldepth.SlDepthIOError, match="max depth 65.534 m"):
        sldepth.write_depth(tmp_path / "far.png", np.full((1, 1), 65.535, np.float32))
    # What read_trajectory refuses is not written.
    with pytest.raises(sldepth.SlDepthIOError, match="finite"):
        sldepth.write_trajectory(tmp_path / "t.txt", [math.nan], np.eye(4)[None])
    assert not (tmp_path / "t.txt").exists()
    # A single path or frame is not a sequence.
    for frames in (str(tmp_path / "u.png"), wall):
        with pytest.raises(TypeError, match="sequence of depth arrays or paths"):
            sldepth.track_sequence(frames, small_cam)
    tracker = sldepth.Tracker(small_cam)
    with pytest.raises(sldepth.SlDepthError, match="not a finite number"):
        tracker.track(wall, timestamp_s=math.nan)
    with pytest.raises(sldepth.SlDepthError, match="too small for a pyramid"):
        sldepth.Tracker(sldepth.Camera(3, 3, 5, 5, 1, 1))
    # The budget's message names the keyword, not the command line's option.
    sldepth.write_depth(tmp_path / "big.png", np.zeros((2048, 2048), np.float32))
    with pytest.raises(sldepth.SlDepthIOError, match="max_memory_bytes="):
        sldepth.read_depth(tmp_path / "big.png", max_memory_bytes=16 << 20)


def test_one_volume_and_one_tracker_serve_several_threads(small_cam, wall):
    # pyo3 refused a second call on the object while one ran ("Already borrowed").
    import threading

    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.04)
    tracker = sldepth.Tracker(small_cam, voxel_m=0.01)
    errors = []

    def work(i):
        try:
            vol.integrate(wall, small_cam, np.eye(4))
            vol.extract_mesh()
            tracker.track(wall)
            _ = tracker.fragment, tracker.last_failure
        except Exception as e:  # noqa: BLE001 - every failure is the test's finding
            errors.append(repr(e))

    threads = [threading.Thread(target=work, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert vol.frame_count == 8
    assert len(tracker.frame_fragments) == 8


# The third audit: arguments named in their own words, compact numbers, and frames of a
# decimated camera read as the command line reads them.


def _line_trajectory(n=10):
    stamps = [100.0 + 0.1 * i for i in range(n)]
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = np.arange(n, dtype=float)
    return stamps, poses


def test_rpe_pairs_a_pose_only_with_a_later_one():
    t, p = _line_trajectory()
    # A delta so long that i + delta rounds paired every pose with the first; one shorter
    # than the spacing paired each pose with itself (an RPE of 0).
    for unit in ("frames", "seconds"):
        with pytest.raises(ValueError, match=f"only 0 pose pairs 1e20 {unit} apart"):
            sldepth.evaluate_trajectory(t, p, t, p, delta=1e20, delta_unit=unit)
    with pytest.raises(ValueError, match="delta = 0.001 seconds is shorter than the spacing"):
        sldepth.evaluate_trajectory(t, p, t, p, delta=0.001, delta_unit="seconds")
    assert sldepth.evaluate_trajectory(t, p, t, p)["rpe"]["pairs"] == 8


def test_filter_sigma_s_beyond_the_largest_window_names_sigma_s_and_radius(small_cam, wall):
    with pytest.raises(ValueError, match=r"sigma_s = 20: .* = 40 px, exceeds the maximum 32 px; pass radius"):
        sldepth.filter(wall, small_cam, sigma_s=20)
    assert sldepth.filter(wall, small_cam, sigma_s=20, radius=3, multiscale=False).shape == wall.shape


def test_tsdf_slice_prints_a_far_plane_compactly(small_cam, wall):
    vol = sldepth.TsdfVolume(voxel_m=0.01, trunc_m=0.04)
    vol.integrate(wall, small_cam, np.eye(4))
    with pytest.raises(ValueError, match="plane z = 1e300 m .*span z from") as e:
        vol.slice("z", 1e300)
    assert "0000000000" not in str(e.value)


def test_array_errors_name_the_argument(small_cam, wall):
    with pytest.raises(ValueError, match=r"labels must be uint16 .* got dtype int32"):
        sldepth.noise_stats(wall, small_cam, labels=np.ones((48, 64), dtype=np.int32))
    with pytest.raises(ValueError, match=r"labels must be 2-D \(H, W\), got an array of shape \[48, 64, 1\]"):
        sldepth.noise_stats(wall, small_cam, labels=np.ones((48, 64, 1), dtype=np.uint16))
    with pytest.raises(ValueError, match="depth_b must be float32, float64"):
        sldepth.motion(wall, wall.astype(np.int8), small_cam)
    with pytest.raises(ValueError, match="depth_b must be 2-D"):
        sldepth.motion(wall, wall[None], small_cam)
    with pytest.raises(ValueError, match="depth_b is 32x48 .* but depth_a is 64x48"):
        sldepth.motion(wall, wall[:, :32].copy(), small_cam)


@pytest.mark.parametrize("flag", [True, False, np.bool_(True)])
def test_bools_are_no_numbers_for_any_float_argument(small_cam, wall, flag):
    t, p = _line_trajectory()
    calls = {
        "sigma_s": lambda: sldepth.filter(wall, small_cam, sigma_s=flag),
        "k_per_m": lambda: sldepth.filter(wall, small_cam, k_per_m=flag),
        "threshold_px": lambda: sldepth.extract_planes(wall, small_cam, threshold_px=flag),
        "voxel_m": lambda: sldepth.TsdfVolume(voxel_m=flag),
        "min_weight": lambda: sldepth.TsdfVolume().extract_mesh(min_weight=flag),
        "delta": lambda: sldepth.evaluate_trajectory(t, p, t, p, delta=flag),
        "fx": lambda: sldepth.Camera(64, 48, flag, 58.0, 31.5, 23.5),
        "factor": lambda: small_cam.resampled(flag),
        "depth_scale": lambda: sldepth.analyze(wall, small_cam, depth_scale=flag),
    }
    for name, call in calls.items():
        with pytest.raises(TypeError, match=f"{name} must be a number, not a bool"):
            call()


@pytest.mark.parametrize("flag", [True, False, np.bool_(True)])
def test_bools_are_no_numbers_for_any_integer_argument(small_cam, wall, flag):
    # bool is a subclass of int: True was taken as a seed of 1 or a radius of 1.
    calls = [
        lambda: sldepth.Camera(flag, 48, 58.0, 58.0, 31.5, 23.5),
        lambda: sldepth.filter(wall, small_cam, radius=flag),
        lambda: sldepth.simulate("three-planes", seed=flag),
        lambda: sldepth.noise_stats(wall, small_cam, min_plane_pixels=flag),
        lambda: sldepth.extract_planes(wall, small_cam, min_pixels=flag),
        lambda: sldepth.TsdfVolume(memory_budget_bytes=flag),
        lambda: sldepth.Tracker(small_cam).extract_mesh(fragment=flag),
        lambda: sldepth.set_num_threads(flag),
    ]
    for call in calls:
        with pytest.raises(TypeError, match="expected an integer, not a bool"):
            call()


def test_a_nan_min_return_is_not_finite_whatever_the_noise_model():
    for noise in ("realistic", "white"):
        with pytest.raises(ValueError, match="min_return = NaN must be a finite number >= 0"):
            sldepth.simulate("floor", noise=noise, min_return=float("nan"))
    with pytest.raises(ValueError, match="min_return = -1e300 must be"):
        sldepth.simulate("floor", min_return=-1e300)


def test_decimated_frames_are_read_as_the_sensor_decimated(kinect, three_planes):
    # A 320x240 frame of the 640x480 camera, as `sldepth` and `analyze` accept it.
    full = three_planes[0]
    half = full[::2, ::2].copy()
    assert sldepth.filter(half, kinect).shape == (240, 320)
    np.testing.assert_array_equal(
        sldepth.filter(half, kinect), sldepth.filter(half, kinect.resampled(0.5))
    )
    m = sldepth.motion(half, half, kinect)
    assert m.planes_a >= 3
    assert not m.determined or m.rotation_deg < 0.1
    vol = sldepth.TsdfVolume()
    assert vol.integrate(half, kinect, np.eye(4)) > 0
    other = sldepth.TsdfVolume()
    other.integrate(half, kinect.resampled(0.5), np.eye(4))
    assert vol.block_count == other.block_count
    assert sldepth.analyze(half, kinect).subpixel_steps == 8
    # Any other size still names the argument and both sizes, in analyze too (it took any
    # size, where `sldepth analyze` refuses a camera of another size).
    with pytest.raises(ValueError, match="depth is 300x240 .* camera is 640x480"):
        sldepth.filter(half[:, :300].copy(), kinect)
    with pytest.raises(ValueError, match="depth is 300x240 .* camera is 640x480"):
        sldepth.analyze(half[:, :300].copy(), kinect)


def test_read_depth_refuses_a_budget_below_the_floor(tmp_path):
    with pytest.raises(ValueError, match="max_memory_bytes = 1 is below the minimum"):
        sldepth.read_depth(tmp_path / "x.png", max_memory_bytes=1)
    with pytest.raises(OSError, match="is a directory, not a depth file"):
        sldepth.read_depth(tmp_path)


def test_every_float_argument_out_of_range_is_printed_compactly(small_cam, wall):
    # A huge value in an error is printed as 1e300, not as its 301 digits: every float
    # argument of the functions below, at ±1e300, either works or says why in a short line.
    t = np.arange(5, dtype=float)
    poses = np.tile(np.eye(4), (5, 1, 1))
    poses[:, 0, 3] = t * 0.01
    calls = {
        "extract_planes": (lambda **k: sldepth.extract_planes(wall, small_cam, **k),
                           ["threshold_px", "log_threshold_px", "log_sigma_px",
                            "bend_px_per_px2", "max_normal_sigma_deg"]),
        "explain_planes": (lambda **k: sldepth.explain_planes(wall, small_cam, **k),
                           ["threshold_px", "log_sigma_px", "max_normal_sigma_deg"]),
        "filter": (lambda **k: sldepth.filter(wall, small_cam, **k), ["sigma_s", "k_per_m", "sigma_d_m", "sigma_disp_px"]),
        "resampled": (lambda **k: small_cam.resampled(**k), ["factor"]),
        "TsdfVolume": (lambda **k: sldepth.TsdfVolume(**k),
                       ["voxel_m", "trunc_m", "max_depth_m", "min_depth_m", "trunc_sigmas"]),
        "Tracker": (lambda **k: sldepth.Tracker(small_cam, **k),
                    ["voxel_m", "model_scale", "rolling_shutter_ms"]),
        "evaluate_trajectory": (lambda **k: sldepth.evaluate_trajectory(t, poses, t, poses, **k),
                                ["delta", "max_gap_s", "offset_s"]),
    }
    long_numbers = 0
    for name, (call, params) in calls.items():
        for param in params:
            for value in (1e300, -1e300):
                try:
                    call(**{param: value})
                except (ValueError, TypeError) as e:
                    assert "unexpected keyword" not in str(e), (name, param)
                    if re.search(r"\d{20}", str(e)):
                        long_numbers += 1
                        print(name, param, value, str(e)[:120])
    assert long_numbers == 0

"""Camera model, presets and depth files."""

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

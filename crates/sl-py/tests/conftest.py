"""Shared fixtures: small synthetic frames with known answers (no files outside tmp_path)."""

import numpy as np
import pytest

import sldepth


@pytest.fixture(scope="session")
def kinect():
    return sldepth.Camera.preset("kinect-v1")


@pytest.fixture(scope="session")
def small_cam():
    # 64x48 pixels, f = 58 px (a Kinect scaled down 10x), B = 7.5 cm, 1/8 px.
    return sldepth.Camera(64, 48, 58.0, 58.0, 31.5, 23.5, baseline_m=0.075, subpixel=8)


@pytest.fixture(scope="session")
def wall():
    """A fronto-parallel wall at 2 m seen by the 64x48 camera."""
    return np.full((48, 64), 2.0, dtype=np.float32)


@pytest.fixture(scope="session")
def three_planes():
    return sldepth.simulate("three-planes", seed=3)

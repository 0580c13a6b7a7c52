"""sldepth: noise-aware processing of structured-light and active-stereo depth maps.

Depth is a float32 NumPy array of shape (H, W) in metres, 0 = invalid. A structured-light
camera measures disparity D and reports depth Z = f*B/D, so its depth noise grows as
sigma_Z = Z**2 * sigma_D / (f*B); every function here uses that model:

    import sldepth
    cam = sldepth.Camera.preset("kinect-v1")
    z = sldepth.read_depth("depth.png", depth_scale=1000)
    zf = sldepth.filter(z, cam, method="adaptive")
    labels, planes = sldepth.extract_planes(z, cam)

Every computation releases the GIL and runs on sldepth's thread pool
(``sldepth.set_num_threads``). Errors are ``sldepth.SlDepthError`` (a ``ValueError``) or
``sldepth.SlDepthIOError`` (an ``OSError``).
"""

from ._sldepth import (
    Analysis,
    Camera,
    Mesh,
    Motion,
    Plane,
    SlDepthError,
    SlDepthIOError,
    Tracker,
    TsdfVolume,
    __version__,
    analyze,
    extract_planes,
    filter,
    get_num_threads,
    input_is_borrowed,
    motion,
    read_depth,
    set_num_threads,
    simulate,
    write_depth,
)

__all__ = [
    "Analysis",
    "Camera",
    "Mesh",
    "Motion",
    "Plane",
    "SlDepthError",
    "SlDepthIOError",
    "Tracker",
    "TsdfVolume",
    "__version__",
    "analyze",
    "extract_planes",
    "filter",
    "get_num_threads",
    "input_is_borrowed",
    "motion",
    "read_depth",
    "set_num_threads",
    "simulate",
    "write_depth",
]

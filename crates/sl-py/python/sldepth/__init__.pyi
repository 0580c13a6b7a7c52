"""Type stubs of sldepth: shapes and units are in the docstrings."""

from os import PathLike
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, PathLike]
#: Depth: (H, W) float32/float64 metres, or uint16 with ``depth_scale`` units per metre.
_Depth = npt.NDArray[Union[np.float32, np.float64, np.uint16]]
_Pose = Union[npt.NDArray[np.floating], Sequence[Sequence[float]]]
#: Every float argument refuses a bool (TypeError naming it): True is not 1.0 here.
#: A frame whose size is the camera's divided by a whole n up to 8 (320x240 for a 640x480
#: camera) is read as the camera's sensor decimated, camera.resampled(1/n), as `sldepth` does.

class SlDepthError(ValueError): ...
class SlDepthIOError(OSError): ...

class Camera:
    """Pinhole intrinsics (pixels) plus the disparity noise model."""
    def __init__(
        self,
        width: int,
        height: int,
        fx: float,
        fy: float,
        cx: float,
        cy: float,
        *,
        baseline_m: float = 0.075,
        subpixel: int = 8,
        sigma_d_px: float = 0.07,
    ) -> None:
        """Ranges (ValueError outside them): width x height at most 16,777,216 pixels (the
        default memory budget's frame), fx and fy in [1, 1e7] px, baseline_m in (0, 10],
        subpixel in 1..256, sigma_d_px in [0, 10] (0: a noise-free camera)."""
    @staticmethod
    def preset(name: str) -> Camera:
        """A named camera: "kinect-v1", "tum-fr1", "d435", ... (see presets())."""
    @staticmethod
    def from_file(path: _Path) -> Camera:
        """The camera of an Open3D PinholeCameraIntrinsic .json, or of a ROS camera calibration
        .yaml (camera_calibration's file, or a CameraInfo saved from rostopic echo / ros2 topic
        echo: its K, the Kinect sensor model, its non-zero plumb_bob distortion as lens, which
        undistort() undoes). OSError names a file that is not one camera."""
    @staticmethod
    def presets() -> List[str]: ...
    @property
    def preset_name(self) -> Optional[str]:
        """The preset this camera was made from (kept by resampled), or whose sensor a sequence
        folder's camera file was recorded with (sequence_camera); None for explicit intrinsics."""
    @property
    def lens(self) -> Optional[Tuple[float, float, float, float, float]]:
        """Lens distortion (k1, k2, p1, p2, k3) of the preset's images (or of a ROS camera file's,
        Camera.from_file), or None (pinhole)."""
    @property
    def rolling_shutter_ms(self) -> float:
        """The preset's rolling-shutter readout, milliseconds (30 for the Kinect-class presets,
        an estimate; 0 for global shutters, icl-nuim and explicit intrinsics)."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...
    @property
    def baseline_m(self) -> float: ...
    @property
    def subpixel(self) -> int: ...
    @property
    def sigma_d_px(self) -> float: ...
    @property
    def fb(self) -> float:
        """f*B in pixel-metres."""
    def sigma_z(self, z_m: float) -> float:
        """Depth noise (metres) at depth z_m: z**2 * sigma_D / (f*B); NaN unless z_m > 0."""
    def depth_to_disparity(self, z_m: float) -> float: ...
    def disparity_to_depth(self, d_px: float) -> float: ...
    @property
    def sensor_focal_px(self) -> float:
        """Focal length of the sensor's own images (fx unless resampled)."""
    def resampled(self, factor: float) -> Camera:
        """The same sensor through images resampled by factor (0.5: 320x240 frames of a
        640x480 sensor): intrinsics scaled, noise model and lens kept."""
    def intrinsic_matrix(self) -> List[List[float]]: ...

def read_depth(
    path: _Path,
    depth_scale: Optional[float] = None,
    format: Optional[str] = None,
    *,
    max_memory_bytes: Optional[int] = None,
) -> npt.NDArray[np.float32]:
    """(H, W) float32 metres, 0 = invalid. format: "png", "tiff", "tiff-f32", "nyu-raw",
    "sun". depth_scale (units per metre) None: 5000 for a frame of a TUM RGB-D folder (its
    depth/ beside depth.txt or associations.txt), else 1000; a float TIFF (ROS 32FC1,
    cv2.imwrite of a float array: "tiff" reads both kinds) in metres. A PNG in a SUN RGB-D sample's depth/ or
    depth_bfx/ folder (beside intrinsics.txt and image/) is read as format "sun" by default.
    max_memory_bytes bounds the read (default 4 GiB, at least 16 MiB: less raises ValueError);
    too large an image raises OSError
    from its header, before decoding."""

def write_depth(
    path: _Path,
    depth: _Depth,
    depth_scale: Optional[float] = None,
    format: Optional[str] = None,
) -> None:
    """16-bit PNG/TIFF at depth_scale units per metre (None: 1000), written atomically (depth
    above 65534 units is refused: 65535 marks missing depth, as in 7-Scenes); a uint16 array
    is taken at depth_scale units per metre and written as it is, every value included (0 and
    65535 read back as invalid). format="tiff-f32": a 32-bit float TIFF of metres times
    depth_scale (None: metres), invalid pixels stored as 0."""

class Analysis:
    valid_pixels: int
    unique_depths: int
    slope: float
    slope_robust: float
    quantum_per_m: float
    fb_px_m: Optional[float]
    subpixel_steps: Optional[int]

def analyze(
    depth: _Depth, camera: Optional[Camera] = None, *, depth_scale: Optional[float] = None
) -> Analysis:
    """Depth-resolution analysis (slope of ln dZ vs ln Z, quantum, implied f*B, sub-pixel
    steps). depth has the camera's size (default kinect-v1) or that size divided by a whole
    number, as sldepth analyze reads it."""
def simulate(
    scene: str,
    seed: int = 0,
    camera: Optional[Camera] = None,
    *,
    noise: str = "realistic",
    min_return: float = 0.0,
    reflectance: Optional[Dict[int, float]] = None,
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.uint16]]:
    """(depth, truth, labels) of a named scene: float32 metres with noise, exact float32 metres,
    uint16 surface labels. noise="realistic" (default, as `sldepth simulate`): correlated
    block-matching error, occlusion bands, drop-outs fitted to real Kinect frames; "white": the
    paper's independent Gaussian disparity noise (Algorithm 1's model). min_return (realistic
    model, 0 = off): pixels whose surface returns less than reflectance * cos(theta) / r**2
    (r in metres, relative to a white surface facing the camera at 1 m) drop out; reflectance
    maps labels to their infrared reflectance in [0, 1] (others reflect 1), which only that
    drop-out reads: without a positive min_return (or with noise="white") it raises
    ValueError. min_return must be a finite number >= 0 (NaN raises ValueError)."""

def noise_stats(
    depth: _Depth,
    camera: Optional[Camera] = None,
    labels: Optional[npt.NDArray[np.uint16]] = None,
    *,
    min_plane_pixels: int = 2000,
    depth_scale: Optional[float] = None,
) -> Dict[str, Any]:
    """The real-noise statistics of a depth map with planar regions, with the keys of
    `sldepth noise-stats --json`: sigma_d_px, bands (sigma_D per depth band), acf (residual
    autocorrelation at lags 1-16 px, x and y), terraces (bin_upper_px 1, 2, 4, 8, 16, 32, None:
    the last bin is open), occlusion (left/right invalid bands,
    the predicted projector shadow, and by_shadow: the edges and those with a band per bin of
    predicted shadow, upper_px 2, 5, 10, None), invalid_fraction; None where not measured. labels (uint16
    (H, W), 0 = none; another dtype or shape raises ValueError naming labels) default to the planes extract_planes finds (>= min_plane_pixels). Against the
    camera's own model: model_sigma_d_px, model_variance_scale (the frame's pixel variance over
    the model's, 1 when within it, as extract_planes measures it) and model_effective_sigma_d_px
    (the sigma_D that variance means)."""

def undistort(
    depth: _Depth, camera: Camera, *, depth_scale: Optional[float] = None
) -> npt.NDArray[np.float32]:
    """(H, W) float32 metres resampled into the pinhole image through camera.lens (nearest
    neighbour, values unchanged, 0 where the ray leaves the image); an unchanged copy when the
    camera has no lens model. TUM fr1/fr2 depth is registered to the distorted colour image."""

def filter(
    depth: _Depth,
    camera: Optional[Camera] = None,
    method: str = "adaptive",
    *,
    radius: Optional[int] = None,
    sigma_s: Optional[float] = None,
    k_per_m: Optional[float] = None,
    sigma_d_m: Optional[float] = None,
    sigma_disp_px: Optional[float] = None,
    window: str = "square",
    depth_scale: Optional[float] = None,
    multiscale: Optional[bool] = None,
    estimate_noise: bool = False,
) -> npt.NDArray[np.float32]:
    """A new (H, W) float32 depth map; method: adaptive, bilateral, gaussian, disparity;
    window: "square" (2r+1 square) or "disc" (dx² + dy² ≤ r², as OpenCV's bilateralFilter);
    multiscale: coarse disparity passes after the filter (None: yes for adaptive and
    disparity, as ``sldepth filter``; False: the paper's single pass); estimate_noise: range
    kernels for the frame's measured sigma_D when it is significantly above the camera's
    (as ``sldepth filter`` by default; 0.2-0.4 ms more per 640x480 frame). radius at most 32;
    sigma_s alone sets radius ceil(2*sigma_s), so a sigma_s above 16 needs a radius. A frame
    of the camera decimated by a whole n up to 8 is accepted (see _Depth)."""

class Mesh:
    @property
    def vertices(self) -> npt.NDArray[np.float32]:
        """(N, 3) metres."""
    @property
    def triangles(self) -> npt.NDArray[np.uint32]:
        """(M, 3) vertex indices."""
    @property
    def normals(self) -> npt.NDArray[np.float32]:
        """(N, 3) unit normals."""
    @property
    def confidence(self) -> npt.NDArray[np.float32]:
        """(N,) accumulated fusion weight."""
    def write_ply(self, path: _Path, ascii: bool = False) -> None: ...
    def __len__(self) -> int: ...

class TsdfVolume:
    def __init__(
        self,
        voxel_m: float = 0.004,
        trunc_m: float = 0.02,
        weight: str = "inv-z4",
        *,
        max_depth_m: float = 4.0,
        min_depth_m: float = 0.1,
        memory_budget_bytes: int = 4 << 30,
        depth_lookup: str = "nearest",
        truncation: str = "sensor",
        trunc_sigmas: float = 3.0,
        estimate_noise: bool = True,
    ) -> None:
        """weight: "inv-z4" (default), "inv-z2", "uniform" or "sensor" (inverse sigma_Z**2 of the
        camera of the first integrate; a later camera with another noise model raises
        ValueError). depth_lookup: "nearest" (default) or "bilinear" (no staircase on grazing
        surfaces). truncation: "sensor" (default: the band at depth Z is
        max(trunc_m, trunc_sigmas * sigma_Z(Z)) metres, up to 0.12 m, with sigma_Z of the first
        integrated frame's camera) or "fixed" (trunc_m everywhere, as Open3D's sdf_trunc).
        estimate_noise: measure the first frame's disparity noise against its camera's model and
        widen the band for a sensor significantly noisier than its model (see noise_scale)."""
    @property
    def noise_scale(self) -> float:
        """The first frame's disparity-error variance over its camera's model as measured for
        the band (1.0 before it, without estimate_noise, or within the model)."""
    def band_m(self, z_m: float) -> float:
        """The truncation band (metres) of an observation at depth z_m metres."""
    def integrate(
        self,
        depth: _Depth,
        camera: Camera,
        pose: _Pose,
        *,
        depth_scale: Optional[float] = None,
    ) -> int:
        """pose: (4, 4) camera-to-world. Returns blocks allocated. A frame of the camera
        decimated by a whole n up to 8 is fused as camera.resampled(1/n)."""
    def extract_mesh(self, min_weight: float = 0.0) -> Mesh: ...
    def write_ply(self, path: _Path, min_weight: float = 0.0, ascii: bool = False) -> None: ...
    def slice(
        self, axis: str, coord_m: float, pixels_per_voxel: int = 2
    ) -> npt.NDArray[np.float32]:
        """Signed distance (metres, NaN unobserved) on the plane axis = coord_m."""
    def raycast(
        self, camera: Camera, pose: _Pose, *, min_depth_m: float = 0.1, max_depth_m: float = 4.0
    ) -> Tuple[
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
        npt.NDArray[np.float32],
    ]:
        """(depth (H, W) metres 0 = no hit, world points (H, W, 3), unit normals (H, W, 3),
        fused weights (H, W)) of the first zero crossing seen from pose (4x4 camera-to-world)."""
    @property
    def block_count(self) -> int: ...
    @property
    def frame_count(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...

class Plane:
    id: int
    normal: Tuple[float, float, float]
    offset_m: float
    disparity_affine: Tuple[float, float, float]
    pixels: int
    rms_px: float
    rms_m: float
    centroid_m: Tuple[float, float, float]
    normal_sigma_deg: float
    """Standard uncertainty of the normal from the noise model (RMS angle to the true
    normal), degrees; inf when undetermined (including 61.2 degrees or more, the RMS angle
    of a normal guessed on the hemisphere facing the camera)."""
    offset_sigma_m: float
    """Standard uncertainty of the position along the normal at centroid_m, metres."""

def extract_planes(
    depth: _Depth,
    camera: Optional[Camera] = None,
    *,
    threshold_px: Optional[float] = None,
    min_pixels: Optional[int] = None,
    log_threshold_px: Optional[float] = None,
    log_sigma_px: Optional[float] = None,
    bend_px_per_px2: Optional[float] = None,
    max_normal_sigma_deg: Optional[float] = None,
    split_creases: Optional[bool] = None,
    refine_seams: Optional[bool] = None,
    give_back_taken_in: Optional[bool] = None,
    estimate_noise: Optional[bool] = None,
    depth_scale: Optional[float] = None,
) -> Tuple[npt.NDArray[np.uint16], List[Plane]]:
    """(labels, planes): uint16 (H, W) labels (0 = none, i = planes[i-1]). A camera resampled
    from its sensor by a whole factor (Camera.resampled(0.5)) is extracted on the sensor's
    grid; min_pixels (default 1000) counts the sensor's pixels. threshold_px (0.5): the
    residual threshold tau; log_threshold_px (0.1) and log_sigma_px (2): the LoG planarity
    test's threshold and scale; all in disparity pixels. bend_px_per_px2 (7.7e-5, px/px² at
    f = 585 px): the largest curvature of a surface's disparity the sensor's distortion makes;
    adjacent planes whose slopes agree at their border and whose fits differ by no more than
    this bend allows take one label (0 = never). max_normal_sigma_deg (default: none): report
    only the planes whose normal the noise model determines within that many degrees
    (Plane.normal_sigma_deg); the others' pixels stay unlabelled. split_creases (True): split
    a plane whose residual is curved beyond the distortion and the noise and fitted better by
    two affine pieces meeting along a line than by any smooth surface (one "plane" across a
    crease between two surfaces) along that line. refine_seams (False): re-decide the pixels
    along a crease with the two planes' local fits where a plane's whole fit is off there (a
    surface bent by the sensor's distortion, whose small neighbour would take a strip of it;
    0.1-0.3 ms per 640x480 real frame). give_back_taken_in (False): leave unlabelled the
    pieces of a neighbouring surface a plane took in (8x8-pixel blocks off a quadratic fit of
    the plane by more than the noise model allows, in connected pieces of at least 256 pixels)
    and refit the plane without them (0.4-0.7 ms per 640x480 real frame). estimate_noise
    (True): measure the frame's own noise on
    its 16x16- and 32x32-pixel patches and, where it exceeds the camera's model significantly, run every
    noise test with it (the camera's sigma_d_px is a floor, never lowered); a sensor noisier
    than its camera says otherwise comes out in pieces and spurious planes."""

class UnlabelledRegion:
    pixels: int
    bbox_px: Tuple[int, int, int, int]
    reason: str
    """"NotPlanarLog", "ResidualNotWhite", "SeveralSurfaces", "Unseeded", "Uncertain" (a
    plane left out by max_normal_sigma_deg), "GivenBack" (a piece a plane took in and gave
    back, give_back_taken_in) or "NoiseBeyondThreshold" (the frame's measured disparity noise
    exceeds threshold_px: no plane was extracted; a sensor that noisy needs a larger
    threshold_px)."""
    why: str
    log_rejected_fraction: float
    residual_rejected_fraction: float
    rms_px: Optional[float]

def explain_planes(
    depth: _Depth,
    camera: Optional[Camera] = None,
    *,
    threshold_px: Optional[float] = None,
    min_pixels: Optional[int] = None,
    log_threshold_px: Optional[float] = None,
    log_sigma_px: Optional[float] = None,
    bend_px_per_px2: Optional[float] = None,
    max_normal_sigma_deg: Optional[float] = None,
    split_creases: Optional[bool] = None,
    refine_seams: Optional[bool] = None,
    give_back_taken_in: Optional[bool] = None,
    estimate_noise: Optional[bool] = None,
    min_region_pixels: Optional[int] = None,
    depth_scale: Optional[float] = None,
) -> Tuple[npt.NDArray[np.uint16], List[Plane], List[UnlabelledRegion]]:
    """extract_planes plus, for every region of valid depth of at least min_region_pixels
    (default: min_pixels) that no plane took, largest first, the test that turned it down
    (as `sldepth planes --explain`)."""

class Motion:
    determined: bool
    matrix: Optional[npt.NDArray[np.float64]]
    rotation_deg: Optional[float]
    translation_determined: bool
    confidence: str
    reason: Optional[str]
    inlier_fraction: Optional[float]
    icp_accepted: Optional[bool]
    planes_a: int
    planes_b: int
    matched_planes: int
    candidates: list[npt.NDArray[np.float64]]

def motion(
    depth_a: _Depth,
    depth_b: _Depth,
    camera: Optional[Camera] = None,
    *,
    icp: bool = True,
    verify: bool = True,
    depth_scale: Optional[float] = None,
) -> Motion:
    """X_a = T X_b between two frames of one camera; determined=False when undetermined.
    depth_a and depth_b have one size: the camera's, or the camera's divided by a whole n up to
    8 (its sensor decimated)."""

def track_in_map(
    volume: TsdfVolume,
    camera: Camera,
    frames: Sequence[_Depth],
    start_pose: _Pose,
    depth_scale: Optional[float] = None,
    *,
    weighting: str = "inv-var",
    prefilter: str = "multiscale",
    model_scale: Optional[float] = None,
) -> List[Tuple[npt.NDArray[np.float64], str]]:
    """Tracks frames in a fused map that does not change (nothing is fused); the first frame is
    anchored at start_pose. One (pose (4, 4) camera-to-world, status) per frame."""

def set_num_threads(n: Optional[int] = None) -> None:
    """Threads per computation (None or 0: one per core). Each Python thread computes as the
    first worker of a pool of its own, sized at its first call, so calls from several threads run
    side by side; a call with another count than that goes through a shared pool. Calls on one
    TsdfVolume or Tracker from several threads take turns (a volume's reads run side by side)."""
def get_num_threads() -> int:
    """The number of threads each computation uses now."""
def input_is_borrowed(depth: _Depth, depth_scale: Optional[float] = None) -> bool:
    """Whether the array would be read in place (C-contiguous float32)."""


class RosBag:
    """A robot recording, as `sldepth track REC` reads it: a ROS 1 bag (format 2.0; chunks none,
    bz2 or lz4), a ROS 2 bag in MCAP (.mcap; chunks none, zstd or lz4) or SQLite (.db3), a
    ROS 2 bag's folder, or a folder of one ROS 1 recording split in pieces (NAME_0.bag, ...); RealSense recordings (librealsense's .bag, or .db3 since 2.56) are
    these. Opening reads its index; a file that is not a bag, or a bag without an index
    (`rosbag reindex`), raises OSError."""
    def __init__(self, path: _Path) -> None: ...
    @staticmethod
    def is_recording(path: _Path) -> bool:
        """Whether path names a recording RosBag opens: a .bag, .mcap or .db3 file, a ROS 2 bag's
        folder (metadata.yaml beside its files), or a folder of one ROS 1 recording split by
        `rosbag record --split` (NAME_0.bag, NAME_1.bag, ...)."""
    @property
    def path(self) -> str: ...
    @property
    def container(self) -> str:
        """"ROS 1 bag", "MCAP (ROS 2 bag)" or "SQLite (ROS 2 bag)"."""
    @property
    def files(self) -> int:
        """How many files hold the recording (a ROS 2 bag split into several: all of them)."""
    @property
    def topics(self) -> List[Tuple[str, str, int]]:
        """(topic, message type, messages) of every topic, by name."""
    def depth_topic(self, topic: Optional[str] = None) -> str:
        """topic when given, else the one image topic holding depth (16UC1 millimetres, 32FC1
        metres, or mono16 on a topic named for depth); several raise OSError naming them."""
    def camera(self, topic: Optional[str] = None) -> Camera:
        """The camera of the sensor_msgs/CameraInfo beside the depth topic (or of the camera
        info topic named): its intrinsics, plumb_bob lens as lens, and the noise model of a
        RealSense recording's device (d415/d435/d455 preset, recorded stereo baseline); else
        of the baseline a ROS driver states beside the topic (P[3] = -f*B of realsense2_camera's
        infra2/camera_info: the D400 model; of openni_camera's projector/camera_info: the
        Kinect's); else the Kinect's."""
    def realsense(self, topic: Optional[str] = None) -> Optional[Dict[str, Any]]:
        """What a RealSense recording says of the sensor behind the depth topic: device (name),
        depth_units_m, stereo_baseline_m (each None when not recorded); None when the recording
        is not librealsense's."""
    def depth_frames(
        self, topic: Optional[str] = None, depth_scale: Optional[float] = None
    ) -> "BagFrames":
        """(stamp_s, depth) of every frame of the depth topic in recorded order; depth float32
        (H, W) metres, 16-bit images divided by depth_scale (None: 1000, or a RealSense
        recording's depth units), float ones by it (None: 1); a RealSense recording's frames
        stamped with their sensor timestamps."""
    def image_frame(self, topic: Optional[str] = None) -> str:
        """The frame the depth topic's images name in their headers (the camera driver's
        optical frame: z forward, x right, y down), the frame tf_lookup poses; "" when none."""
    def tf_namespaces(self) -> List[str]:
        """Namespaces holding a tree of transforms, sorted: "" for /tf and /tf_static,
        "/robot1" for /robot1/tf."""
    def transforms(self, namespace: str = "") -> List[Dict[str, Any]]:
        """The frames of the recording's transforms (/tf, /tf_static; namespace "/robot1":
        /robot1/tf, /robot1/tf_static), by name: dicts of frame, parent, static,
        republished_constant, samples, first_s, last_s; empty without transforms. Read once,
        kept."""
    def tf_lookup(
        self,
        target_frame: str,
        frame: str,
        stamps_s: Sequence[float],
        *,
        max_gap_s: float = 0.02,
        namespace: str = "",
    ) -> npt.NDArray[np.float64]:
        """(N, 4, 4) poses of frame in target_frame at each stamp (for the camera's optical
        frame in a world frame: camera-to-world, as `sldepth fuse REC --tf` takes them); each
        transform interpolated between samples no more than twice its median interval apart,
        static ones at any time; all-NaN where a transform has no sample within max_gap_s
        (beyond its samples or in a gap of them), at a stamp that is NaN, or where the pose is
        not finite. stamps_s is one 1-D sequence or array of seconds; max_gap_s is 0 to 3600
        s. Unknown or unjoined frames, or other stamps or gaps, raise ValueError."""

class BagFrames:
    """The depth frames of a bag's topic: an iterator of (stamp_s, depth) with len()."""
    def __len__(self) -> int: ...
    def __iter__(self) -> "BagFrames": ...
    def __next__(self) -> Tuple[float, npt.NDArray[np.float32]]: ...

class Tracker:
    """Noise-weighted camera tracking against the model being fused (sldepth track)."""

    def __init__(
        self,
        camera: Camera,
        *,
        weighting: str = "inv-var",
        frame_to_model: bool = True,
        voxel_m: float = 0.004,
        model_scale: Optional[float] = None,
        prefilter: str = "multiscale",
        lens: str = "auto",
        new_fragment_after_s: Optional[float] = 1.0,
        rolling_shutter_ms: Optional[float] = None,
        estimate_noise: bool = True,
        keyframes: bool = True,
        memory_budget_bytes: int = 4 << 30,
        when_model_full: str = "continue",
        odometry_drift: float = 0.05,
        odometry_min_sigma_m: float = 0.005,
        odometry_min_sigma_deg: float = 0.5,
    ) -> None:
        """odometry_drift, odometry_min_sigma_m, odometry_min_sigma_deg: the uncertainty of an
        odometry given to track() (as sldepth track --odometry-drift, ...): per axis, the floor
        per frame interval (growing as the square root of the intervals across dropped or lost
        frames) plus the drift times the distance (and the angle) it measured.
        rolling_shutter_ms: the sensor's rolling-shutter readout, milliseconds (first row to
        last; as sldepth track --rolling-shutter-ms); None (default): camera.rolling_shutter_ms
        (30 for the Kinect-class presets, 0 for explicit intrinsics) when tracking against the
        model, 0 frame to frame; 0 a global shutter; at most the frame interval (33.3 ms at
        30 Hz).
        new_fragment_after_s: seconds of frames that could be aligned but were lost after
        which a new fragment (own volume and world frame) starts; None or inf: never.
        model_scale: fraction of the camera's resolution the model is rendered at for
        tracking, in (0, 1] (as sldepth track --model-scale; default: one pixel per 4 of the
        sensor's, 0.25 for a 640x480 Kinect); prefilter: "multiscale"
        (default, as sldepth track), "single" or "none"; lens: "auto" (default) undistorts
        every frame with camera.lens when the camera has one (tum-fr1/tum-fr2), "none" keeps
        the frames as given; estimate_noise: measure each raw frame's noise against the
        camera's model and track a noisier frame with its own noise (default; as sldepth track,
        --model-noise-only turns it off); keyframes: when every other attempt on a frame
        fails, align it against earlier frames kept at spread poses (default; as sldepth
        track, --no-keyframes turns it off); memory_budget_bytes: what the model's blocks may
        hold, all fragments together with the meshes kept of finished fragments (default
        4 GiB); when_model_full: "continue" (default: a frame the model cannot hold hands the
        full fragment over and starts a continuation, a new fragment with a fresh volume in the
        same world frame, listed in joins with the identity; meshes overlap where the camera
        came back) or "stop-fusing" (the model is full from then on, model_full; later frames
        tracked against the frame before and not fused); a fresh volume that cannot hold its
        first frame takes the next frame that fits; a finished fragment's mesh that does not
        fit in what is left is not kept."""
    @property
    def memory_bytes(self) -> int:
        """Bytes held against memory_budget_bytes: the current and suspended fragments'
        volumes and the meshes kept of finished fragments."""
    @property
    def model_full(self) -> Optional[str]:
        """Why the current fragment's model is full (its memory budget reached, no continuation took over), or None."""
    @property
    def rolling_shutter_ms(self) -> float:
        """The rolling-shutter readout the tracker models, milliseconds (0: global shutter)."""
    def track(
        self,
        depth: _Depth,
        depth_scale: Optional[float] = None,
        *,
        timestamp_s: Optional[float] = None,
        odometry: Optional[npt.ArrayLike] = None,
    ) -> Tuple[npt.NDArray[np.float64], str]:
        """(pose (4, 4) camera-to-world, status: initialised/tracked/tracked-against-frame/recovered/relocalised/lost).
        timestamp_s: the frame's time, seconds, increasing (frames dropped by the recording are
        predicted across); None: one 1/30 s interval after the previous frame.
        odometry: the camera's pose in an odometry's frame at this frame ((4, 4), camera to
        odometry; e.g. a row of RosBag.tf_lookup("odom", camera_frame, stamps)): its motion
        since the last tracked frame predicts this one and is the prior of its alignment; a
        direction the depth leaves free (a corridor's axis, a single wall) takes the odometry's
        value instead of the frame being lost. None or NaN: none for this frame."""
    @property
    def last_failure(self) -> Optional[str]:
        """Why the last frame was lost (e.g. "degenerate view: ..."), or None."""
    @property
    def last_noise_scale(self) -> float:
        """The last raw frame's disparity-error variance over the camera's model (1: within
        it); the frame was tracked with that noise."""
    @property
    def last_prefilter_sigma_d_px(self) -> Optional[float]:
        """The sigma_D, disparity pixels, the last frame was smoothed for before tracking: the
        camera's, or a noisier raw frame's measured one; None with prefilter="none" or before any frame."""
    @property
    def last_weakest_sigma_m(self) -> float:
        """The last frame's pose sigma along its least-constrained direction, metres (inf: a single plane)."""
    @property
    def fragment(self) -> int:
        """The current fragment's index (0 until tracking stays lost for new_fragment_after_s)."""
    @property
    def frame_fragments(self) -> List[int]:
        """The fragment of every frame given to track(), in order."""
    @property
    def joins(self) -> List[Tuple[int, int, npt.NDArray[np.float64]]]:
        """(fragment, into, (4, 4) transform from fragment's world to into's) for each finished fragment that rejoined the one before, or continues a full one (the identity); when a continuation rejoins, the first fragment of its chain is joined there too (one world frame)."""
    def extract_mesh(self, fragment: Optional[int] = None) -> Mesh:
        """The fused mesh of fragment `fragment` (None: the current one; a rejoined fragment's is in the world of the one it rejoined)."""

def read_sequence(
    path: _Path, layout: Optional[str] = None
) -> Tuple[List[str], Optional[npt.NDArray[np.float64]]]:
    """The depth frames of a sequence folder, in order, as `sldepth track` reads them:
    (paths, timestamps_s), timestamps a float64 array (N,) of seconds or None where the folder
    has none. layout: "tum" (associations.txt when present, else depth.txt; timestamps must
    increase), "7scenes" (frame-XXXXXX.depth.png), "open3d" (depth/*.png: by the times their
    names state when every name is one, e.g. 1305031102.160407.png or 19-digit nanoseconds,
    which are then the timestamps, else by name); None infers it from the folder. Feed both to track_sequence(paths, camera, depth_scale=...,
    timestamps_s=...). A missing folder, one whose layout cannot be inferred, or a malformed
    list raises OSError; an unknown layout name ValueError."""

def read_posed_sequence(
    path: _Path,
    layout: Optional[str] = None,
    *,
    max_dt_s: float = 0.02,
    trajectory: Optional[_Path] = None,
) -> Tuple[List[str], Optional[npt.NDArray[np.float64]], npt.NDArray[np.float64]]:
    """The frames of a sequence folder with their poses, as `sldepth fuse DIR` reads them:
    (paths, timestamps_s, poses), poses a float64 array (N, 4, 4) camera-to-world. A TUM
    folder's frames get the groundtruth.txt pose nearest in time (within max_dt_s seconds;
    frames without one are left out), a 7-Scenes folder's its frame-*.pose.txt, an Open3D-style
    folder's its one .log beside depth/ (none or several: OSError) or, without a .log, the
    pose/<n>.txt of each depth/<n>.png as ScanNet exports a scan (a -inf matrix: no pose).
    An ICL-NUIM TUM-format folder (icl_nuim_tum_folder) reads its *.gt.freiburg when it has no
    groundtruth.txt, its y-up poses turned into sldepth's frame. Depth frames left out for want
    of a pose are counted in a UserWarning. layout as read_sequence. With trajectory (a file:
    sldepth track's output or another system's estimate, camera to world) its poses instead
    of the folder's own, as `sldepth fuse DIR --trajectory FILE`: a TUM-format file by time
    (nearest within max_dt_s; frames without timestamps by their index), an Open3D .log by
    frame number."""

def sequence_camera(path: _Path, layout: Optional[str] = None) -> Camera:
    """The camera a sequence folder implies, as `sldepth track DIR` / `sldepth fuse DIR` use it
    when none is given: its camera file (7-Scenes camera-intrinsics.txt, the folder's own or its
    scene's above it as 3DMatch keeps it; an Open3D folder's camera.json; a ScanNet export's
    intrinsic/intrinsic_depth.txt; text files at the size of the folder's depth images)
    when it has one, else the layout's preset: a TUM folder "tum-fr1", "tum-fr2"
    or "tum-fr3" by its name (with that Kinect's lens model and rolling shutter; an ICL-NUIM
    TUM-format folder "icl-nuim-tum"), 7-Scenes "7-scenes", Open3D "ros-default" (Open3D's
    PrimeSenseDefault; camera files also camera_intrinsic.json, intrinsic.json,
    camera_primesense.json as Open3D's tools name them; a TUM-layout folder's calibration.txt,
    ETH3D's "fx fy cx cy", names no preset). A 7-Scenes camera file gives the intrinsics and "7-scenes"
    the sensor (preset_name, its 30 ms rolling_shutter_ms), as on the command line; an Open3D
    camera.json names no preset. layout as read_sequence."""

def frame_camera(path: _Path) -> Optional[Camera]:
    """The camera of the sequence folder a depth image lies in, as `sldepth` takes it for a
    frame read without --camera: an image in a TUM folder's depth/, a 7-Scenes-layout frame
    (frame-XXXXXX.depth.png: its folder's or its scene's camera-intrinsics.txt, else
    "7-scenes"), an image in the depth/ folder of an Open3D-style folder with a camera file
    (camera_intrinsic.json as Open3D's RealSense recorder writes it, and the names
    sequence_camera reads): that folder's sequence_camera. None for an image anywhere else
    (Camera.preset("kinect-v1") is the command line's default; a SUN RGB-D sample's frames take
    sun_camera). A camera file that cannot be read raises OSError."""

def sun_camera(path: _Path, width: int, height: int) -> Camera:
    """The camera of a SUN RGB-D sample folder (depth/, image/, intrinsics.txt) for its
    width x height depth images: intrinsics.txt's matrix with the Kinect v1 sensor model at that
    focal length, as `sldepth` takes it for the sample's frames (which read_depth reads in SUN's
    format by itself). A principal point outside the image raises OSError."""

def sequence_depth_scale(path: _Path, layout: Optional[str] = None) -> float:
    """Depth units per metre of a sequence folder's 16-bit images, as `sldepth track DIR` /
    `sldepth fuse DIR` read them: 5000 for a TUM folder, 1000 (millimetres) for 7-Scenes and
    Open3D-style folders. Pass it as depth_scale to track_sequence or read_depth (a TUM frame
    read as millimetres is five times too deep). layout as read_sequence."""

def tum_stamps_are_frame_numbers(path: _Path) -> bool:
    """Whether a TUM-layout folder stamps its frames with their numbers (associations.txt lists
    the depth image first with a whole-number stamp, as ICL-NUIM's archives do);
    track_sequence takes such stamps as frames 1/30 s apart."""

def icl_nuim_tum_folder(path: _Path) -> bool:
    """Whether a TUM-layout folder is one of ICL-NUIM's own TUM-format archives (its frames
    numbered, tum_stamps_are_frame_numbers, and a *.gt.freiburg in it or the archive's name,
    ..._frei_png). Its camera is `icl-nuim-tum`, and it renders with y up:
    read_posed_sequence gives its ground truth in sldepth's frame (y down); F @ pose @ F with
    F = diag(1, -1, 1, 1) turns a pose either way."""

def read_trajectory(
    path: _Path,
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """(timestamps_s (N,), poses (N, 4, 4) camera-to-world) of a TUM trajectory file, or of an
    Open3D .log (entries `i i n`, each pose stamped with its frame number i), by time."""

def write_trajectory(
    path: _Path, timestamps_s: Sequence[float], poses: npt.NDArray[np.floating]
) -> None:
    """Writes timestamps (N,) and (N, 4, 4) camera-to-world poses as a TUM file (atomically)."""

def evaluate_trajectory(
    timestamps_s: Sequence[float],
    poses: npt.NDArray[np.floating],
    gt_timestamps_s: Sequence[float],
    gt_poses: npt.NDArray[np.floating],
    *,
    max_gap_s: float = 0.02,
    delta: float = 1.0,
    delta_unit: str = "frames",
    offset_s: float = 0.0,
) -> Dict[str, Any]:
    """ATE (after Horn's rigid alignment) and RPE (over delta frames or seconds) with the TUM
    benchmark's definitions, as `sldepth eval-traj --json`: {"ate_m": {rmse, mean, median,
    std, min, max}, "rpe": {"translation_m": {...}, "rotation_deg": {...}, pairs, ...}, ...}.
    offset_s (seconds) is added to the estimate's timestamps before matching them. "per_pose":
    {"timestamps_s", "gt_timestamps_s", "translation_m", "rotation_deg"}, float64 arrays (M,)
    of each matched pose's error after the alignment, in the estimate's time order (its own
    timestamps, before offset_s; the orientation's error after the world rotation that fits
    the orientations best). An RPE pair
    is a pose and a strictly later one: a delta that pairs no pose with a later one (longer than
    the trajectory, or shorter than its pose spacing) raises ValueError."""

def estimate_time_offset(
    timestamps_s: Sequence[float],
    poses: npt.NDArray[np.floating],
    gt_timestamps_s: Sequence[float],
    gt_poses: npt.NDArray[np.floating],
    *,
    max_gap_s: float = 0.02,
    max_s: float = 0.1,
    step_s: float = 0.001,
) -> Dict[str, Any]:
    """The clock offset (seconds, to add to the estimate's timestamps) under which the
    estimate's orientations, turned by the best rotation of the world, agree best with the
    ground truth's, tried every step_s within +-max_s: {"offset_s", "rotation_rmse_deg",
    "rotation_rmse_at_zero_deg", "matched", "curve": [(offset_s, rmse_deg), ...]}. As
    `sldepth eval-traj --estimate-offset`."""

def track_sequence(
    frames: Union[Iterable[Union[_Depth, _Path]], _Path],
    camera: Optional[Camera] = None,
    *,
    depth_scale: Optional[float] = None,
    timestamps_s: Optional[Iterable[float]] = None,
    layout: Optional[str] = None,
    topic: Optional[str] = None,
    odometry: Optional[Union[str, npt.ArrayLike]] = None,
    weighting: str = "inv-var",
    frame_to_model: bool = True,
    voxel_m: float = 0.004,
    model_scale: Optional[float] = None,
    prefilter: str = "multiscale",
    lens: str = "auto",
    new_fragment_after_s: Optional[float] = 1.0,
    rolling_shutter_ms: Optional[float] = None,
    estimate_noise: bool = True,
    keyframes: bool = True,
    memory_budget_bytes: int = 4 << 30,
    when_model_full: str = "continue",
) -> Tuple[npt.NDArray[np.float64], List[str], Tracker]:
    """Tracks and fuses depth frames (arrays, or paths read with depth_scale) in order, with
    their timestamps (seconds) when given: (poses (N, 4, 4) camera-to-world, statuses, the
    Tracker with the fused model). frames may be a recording's folder (layout as
    read_sequence), read as `sldepth track DIR` reads it: its frames, timestamps and, unless
    given, camera (sequence_camera) and depth scale (sequence_depth_scale); frame-number stamps
    (tum_stamps_are_frame_numbers) are frames 1/30 s apart, an ICL-NUIM folder's poses in
    sldepth's frame. Or a robot recording's path (a ROS 1 .bag, a ROS 2 .mcap, .db3 or its
    folder, a RealSense recording): its depth topic (topic, else
    RosBag.depth_topic), frame by frame with the header stamps, and unless given the camera of
    its camera_info (RosBag.camera).
    camera is needed for arrays and lists of paths. odometry: N (4, 4) camera-to-odometry poses,
    one per frame (NaN: none), or for a recording the name of the odometry's frame in its
    transforms ("odom", as sldepth track REC --odometry-tf odom); see Tracker.track."""

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
(``sldepth.set_num_threads``), so functions called from several Python threads run side by
side; calls on one ``TsdfVolume`` or ``Tracker`` from several threads take turns (a volume's
meshes, raycasts and slices run side by side). Errors are ``sldepth.SlDepthError`` (a
``ValueError``) or ``sldepth.SlDepthIOError`` (an ``OSError``).
"""

import os as _os

from ._sldepth import (
    Analysis,
    BagFrames,
    Camera,
    Mesh,
    Motion,
    Plane,
    RosBag,
    SlDepthError,
    SlDepthIOError,
    Tracker,
    TsdfVolume,
    __version__,
    UnlabelledRegion,
    analyze,
    explain_planes,
    extract_planes,
    filter,
    get_num_threads,
    input_is_borrowed,
    motion,
    noise_stats,
    evaluate_trajectory,
    estimate_time_offset,
    read_depth,
    read_posed_sequence,
    read_sequence,
    sequence_camera,
    frame_camera,
    sequence_depth_scale,
    icl_nuim_tum_folder,
    tum_stamps_are_frame_numbers,
    sun_camera,
    read_trajectory,
    set_num_threads,
    simulate,
    track_in_map,
    undistort,
    write_depth,
    write_trajectory,
)

__all__ = [
    "Analysis",
    "BagFrames",
    "Camera",
    "Mesh",
    "Motion",
    "Plane",
    "RosBag",
    "SlDepthError",
    "SlDepthIOError",
    "Tracker",
    "TsdfVolume",
    "__version__",
    "UnlabelledRegion",
    "analyze",
    "explain_planes",
    "extract_planes",
    "filter",
    "get_num_threads",
    "input_is_borrowed",
    "motion",
    "noise_stats",
    "evaluate_trajectory",
    "estimate_time_offset",
    "read_trajectory",
    "write_trajectory",
    "read_depth",
    "read_posed_sequence",
    "read_sequence",
    "sequence_camera",
    "frame_camera",
    "sequence_depth_scale",
    "icl_nuim_tum_folder",
    "tum_stamps_are_frame_numbers",
    "sun_camera",
    "set_num_threads",
    "simulate",
    "track_in_map",
    "track_sequence",
    "undistort",
    "write_depth",
]


def track_sequence(
    frames,
    camera=None,
    *,
    depth_scale=None,
    timestamps_s=None,
    layout=None,
    topic=None,
    odometry=None,
    **tracker_options,
):
    """Tracks a depth sequence from its first frame on and fuses it (``sldepth track`` in one call).

    ``frames``: depth arrays (float32 metres, or uint16 with ``depth_scale`` units per metre) or
    paths of depth files (read with ``read_depth(path, depth_scale=depth_scale)``), in order;
    or a recording's folder (TUM, 7-Scenes or Open3D-style, ``layout`` as ``read_sequence``),
    read as ``sldepth track DIR`` reads it: its frames and timestamps (``read_sequence``), and
    unless given its camera (``sequence_camera``) and depth scale (``sequence_depth_scale``);
    a folder that stamps its frames with their numbers (``tum_stamps_are_frame_numbers``, as
    ICL-NUIM's TUM-format archives do) has them taken as frames 1/30 s apart, and the poses of
    an ICL-NUIM folder (``icl_nuim_tum_folder``) come in sldepth's frame (y down, not the data
    set's); or a robot recording's path (a ROS 1 ``.bag``, a ROS 2 bag's ``.mcap``, ``.db3`` or
    folder, a RealSense recording, as ``sldepth track REC``): the depth topic
    ``topic`` (None: the one image topic holding depth, ``RosBag.depth_topic``), read frame by
    frame with its header stamps, and unless given the camera of its ``camera_info``
    (``RosBag.camera``).
    ``camera`` is needed for arrays and lists of paths.
    ``timestamps_s``: the frames' times in seconds (one per frame, increasing), so frames the
    recording dropped are predicted across (``Tracker.track(..., timestamp_s=)``); ``None``
    takes the frames as consecutive. ``tracker_options`` are those of ``Tracker``
    (``weighting``, ``frame_to_model``, ``voxel_m``, ``model_scale``, ``prefilter``, ``lens``,
    ``new_fragment_after_s``, ``rolling_shutter_ms``, ``estimate_noise``, ``keyframes``,
    ``memory_budget_bytes`` and ``when_model_full``: by default a model that reaches the budget
    is handed over as a fragment and the sequence goes on in a fresh volume in the same world
    frame; with ``when_model_full="stop-fusing"`` it stops growing and the camera is tracked
    frame to frame from there, ``tracker.model_full``). A single path or array is not a
    sequence: it raises ``TypeError`` (pass a list, e.g. of ``sorted(glob.glob(...))``).
    ``odometry``: the camera's pose in an odometry's frame at each frame
    (``Tracker.track(..., odometry=)``): an array-like of N (4, 4) camera-to-odometry matrices
    (NaN where there is none), or for a robot recording the name of the odometry's frame in its
    transforms (``"odom"``: each frame's camera, ``RosBag.image_frame``, looked up in it at the
    frame's stamp with ``RosBag.tf_lookup``, as ``sldepth track REC --odometry-tf odom``).

    Returns ``(poses, statuses, tracker)``: ``poses`` a float64 array (N, 4, 4) of
    camera-to-world matrices (the first frame is the identity; a lost frame gets the last good
    pose), ``statuses`` the N status strings of ``Tracker.track``, and the ``Tracker`` itself,
    whose ``extract_mesh()`` is the fused model. When tracking stays lost the sequence goes on
    in a new fragment with its own world frame: ``tracker.frame_fragments`` gives each frame's
    fragment, ``tracker.extract_mesh(fragment=k)`` each fragment's mesh. The poses of a fragment
    that rejoined an older one (``tracker.joins``) are returned in that one's world, as
    ``sldepth track`` writes them; those of a fragment that never rejoined one are in its own.
    """
    import numpy as np

    if topic is not None and not _is_bag(frames):
        raise TypeError("topic is for a ROS bag's path; frames is not one")
    if _is_bag(frames):
        if layout is not None or timestamps_s is not None:
            raise TypeError("a ROS bag has its own layout and timestamps")
        bag = RosBag(_os.fsdecode(frames))
        camera = bag.camera(topic) if camera is None else camera
        tracker = Tracker(camera, **tracker_options)
        frames_iter = bag.depth_frames(topic, depth_scale)
        by_name = isinstance(odometry, str)
        if by_name:
            camera_frame = bag.image_frame(topic)
            if not camera_frame:
                raise ValueError(
                    "the depth images name no frame in their headers: give odometry as poses"
                )
            bag.tf_lookup(odometry, camera_frame, [])  # an unknown frame raises here
        else:
            odometry = _odometry_poses(odometry, len(frames_iter))
        poses = []
        statuses = []
        for i, (t, depth) in enumerate(frames_iter):
            if by_name:
                odo = bag.tf_lookup(odometry, camera_frame, [t])[0]
            else:
                odo = None if odometry is None else odometry[i]
            pose, status = tracker.track(depth, timestamp_s=t, odometry=odo)
            poses.append(pose)
            statuses.append(status)
        stacked = np.stack(poses) if poses else np.zeros((0, 4, 4))
        stacked = _poses_in_joined_worlds(stacked, tracker.frame_fragments, tracker.joins)
        return stacked, statuses, tracker
    if isinstance(frames, (str, bytes, _os.PathLike)) and _os.path.isdir(frames):
        folder = _os.fsdecode(frames)
        frames, times = read_sequence(folder, layout)
        camera = sequence_camera(folder, layout) if camera is None else camera
        if depth_scale is None:
            depth_scale = sequence_depth_scale(folder, layout)
        if timestamps_s is None:
            timestamps_s = times
            # Frames stamped with their numbers (ICL-NUIM's): one 30 Hz interval each.
            if times is not None and tum_stamps_are_frame_numbers(folder):
                timestamps_s = [float(t) / 30.0 for t in times]
    elif isinstance(frames, (str, bytes, _os.PathLike)) or (
        isinstance(frames, np.ndarray) and frames.ndim < 3
    ):
        raise TypeError(
            "frames must be a sequence of depth arrays or paths (a list, e.g. "
            "sorted(glob.glob('depth/*.png'))) or a recording's folder, not a single "
            f"{type(frames).__name__}"
        )
    elif layout is not None:
        raise TypeError("layout is for a recording's folder; frames is a sequence")
    if camera is None:
        raise TypeError("track_sequence needs a camera for depth arrays or a list of paths")
    tracker = Tracker(camera, **tracker_options)
    frames = list(frames)
    if isinstance(odometry, str):
        raise TypeError(
            "odometry as a frame name is for a robot recording's transforms; give poses"
        )
    odometry = _odometry_poses(odometry, len(frames))
    if timestamps_s is None:
        times = [None] * len(frames)
    else:
        times = [float(t) for t in timestamps_s]
        if len(times) != len(frames):
            raise ValueError(
                f"timestamps_s has {len(times)} entries for {len(frames)} frames"
            )
    poses = []
    statuses = []
    for i, (frame, t) in enumerate(zip(frames, times)):
        odo = None if odometry is None else odometry[i]
        if isinstance(frame, (str, bytes, _os.PathLike)):
            pose, status = tracker.track(
                read_depth(_os.fsdecode(frame), depth_scale=depth_scale),
                timestamp_s=t,
                odometry=odo,
            )
        else:
            pose, status = tracker.track(frame, depth_scale, timestamp_s=t, odometry=odo)
        poses.append(pose)
        statuses.append(status)
    stacked = np.stack(poses) if poses else np.zeros((0, 4, 4))
    stacked = _poses_in_joined_worlds(stacked, tracker.frame_fragments, tracker.joins)
    return stacked, statuses, tracker


def _odometry_poses(odometry, n):
    """``odometry`` as a float64 (n, 4, 4) array, or None; another shape raises ``ValueError``."""
    import numpy as np

    if odometry is None:
        return None
    poses = np.asarray(odometry, dtype=np.float64)
    if poses.shape != (n, 4, 4):
        raise ValueError(
            f"odometry must be {n} (4, 4) camera-to-odometry poses, one per frame, got shape "
            f"{poses.shape}"
        )
    return poses


def _is_bag(frames):
    """Whether ``frames`` is a robot recording's path (``RosBag.is_recording``: a ROS 1 bag, a
    ROS 2 bag's file or folder, or a folder of one split ROS 1 recording)."""
    if not isinstance(frames, (str, bytes, _os.PathLike)):
        return False
    path = _os.fsdecode(frames)
    return (_os.path.isdir(path) or _os.path.isfile(path)) and RosBag.is_recording(path)


def _poses_in_joined_worlds(poses, frame_fragments, joins):
    """Moves the poses of frames in a fragment that rejoined an older one into that one's world.

    ``poses`` (N, 4, 4), ``frame_fragments`` the fragment of each frame, ``joins`` the
    ``Tracker.joins`` list of ``(fragment, into, transform)``. Returns a new array.
    """
    import numpy as np

    out = np.array(poses, dtype=np.float64, copy=True)
    into = {f: (j, np.asarray(t, dtype=np.float64)) for f, j, t in joins}
    for i, f in enumerate(frame_fragments):
        # On through the fragment that one joined (a continuation is joined to the fragment
        # it continues by the identity); joins always go to an older fragment.
        while f in into and into[f][0] < f:
            out[i] = into[f][1] @ out[i]
            f = into[f][0]
    return out

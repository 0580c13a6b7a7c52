"""sldepth.RosBag and track_sequence on a bag: bags written here by the format's
specification (uncompressed and bz2 chunks, with the standard library), and by the
independent ``rosbags`` library (lz4) when it is installed."""

import bz2
import struct

import numpy as np
import pytest

import sldepth


def _record(fields, data=b""):
    h = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields)
    return struct.pack("<I", len(h)) + h + struct.pack("<I", len(data)) + data


def _string(s):
    return struct.pack("<I", len(s)) + s.encode()


def _header(stamp):
    secs, nsecs = stamp
    return struct.pack("<III", 0, secs, nsecs) + _string("depth_frame")


def _image(stamp, depth, encoding):
    h, w = depth.shape[:2]
    data = depth.tobytes()
    return (_header(stamp) + struct.pack("<II", h, w) + _string(encoding) + b"\0"
            + struct.pack("<I", len(data) // h) + struct.pack("<I", len(data)) + data)


def _camera_info(w, h, f, d):
    k = [f, 0, w / 2 - 0.5, 0, f, h / 2 - 0.5, 0, 0, 1]
    r = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    p = [f, 0, w / 2 - 0.5, 0, 0, f, h / 2 - 0.5, 0, 0, 0, 1, 0]
    return (_header((1, 0)) + struct.pack("<II", h, w) + _string("plumb_bob")
            + struct.pack("<I", len(d)) + struct.pack(f"<{len(d) + 30}d", *d, *k, *r, *p)
            + struct.pack("<IIIIIIB", 0, 0, 0, 0, 0, 0, 0))


def _write_bag(path, conns, msgs, compression):
    """conns: [(id, topic, type)]; msgs: [(conn, (secs, nsecs), data)], one chunk."""
    def conn_record(c):
        cid, topic, typ = c
        data = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v.encode()
                        for k, v in [("topic", topic), ("type", typ), ("md5sum", "*"),
                                     ("message_definition", "")])
        return _record([("op", b"\x07"), ("conn", struct.pack("<I", cid)),
                        ("topic", topic.encode())], data)

    def time(t):
        return struct.pack("<II", *t)

    def bag_header(index_pos):
        fields = [("op", b"\x03"), ("index_pos", struct.pack("<Q", index_pos)),
                  ("conn_count", struct.pack("<I", len(conns))),
                  ("chunk_count", struct.pack("<I", 1))]
        bare = _record(fields)
        return _record(fields, b" " * (4096 - len(bare)))

    out = bytearray(b"#ROSBAG V2.0\n") + bag_header(0)
    inner = bytearray(b"".join(conn_record(c) for c in conns))
    index = {}
    for cid, t, data in msgs:
        index.setdefault(cid, []).append(time(t) + struct.pack("<I", len(inner)))
        inner += _record([("op", b"\x02"), ("conn", struct.pack("<I", cid)), ("time", time(t))], data)
    chunk_pos = len(out)
    body = bytes(inner) if compression == "none" else bz2.compress(bytes(inner))
    out += _record([("op", b"\x05"), ("compression", compression.encode()),
                    ("size", struct.pack("<I", len(inner)))], body)
    counts = b""
    for cid, entries in index.items():
        out += _record([("op", b"\x04"), ("ver", struct.pack("<I", 1)),
                        ("conn", struct.pack("<I", cid)),
                        ("count", struct.pack("<I", len(entries)))], b"".join(entries))
        counts += struct.pack("<II", cid, len(entries))
    index_pos = len(out)
    out += b"".join(conn_record(c) for c in conns)
    out += _record([("op", b"\x06"), ("ver", struct.pack("<I", 1)),
                    ("chunk_pos", struct.pack("<Q", chunk_pos)),
                    ("start_time", time(msgs[0][1])), ("end_time", time(msgs[-1][1])),
                    ("count", struct.pack("<I", len(index)))], counts)
    out[13:13 + 4096] = bag_header(index_pos)
    path.write_bytes(bytes(out))


_CONNS = [(0, "/camera/depth/image_raw", "sensor_msgs/Image"),
          (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo")]


def _frames(n):
    """n simulated boxes frames (a still camera, fresh noise each) in millimetres."""
    return [np.round(sldepth.simulate("boxes", seed=s)[0] * 1000).astype(np.uint16) for s in range(n)]


@pytest.mark.parametrize("compression", ["none", "bz2"])
def test_a_bag_gives_its_depth_frames_stamps_and_camera(tmp_path, compression):
    mm = _frames(3)
    msgs = []
    for i, d in enumerate(mm):
        t = (100 + i, 5_000_000)
        msgs.append((0, (100 + i, 30_000_000), _image(t, d, "16UC1")))
        msgs.append((1, (100 + i, 30_000_000), _camera_info(640, 480, 580.0, [0.0] * 5)))
    path = tmp_path / "rec.bag"
    _write_bag(path, _CONNS, msgs, compression)
    bag = sldepth.RosBag(path)
    assert bag.topics == [("/camera/depth/camera_info", "sensor_msgs/CameraInfo", 3),
                          ("/camera/depth/image_raw", "sensor_msgs/Image", 3)]
    assert bag.depth_topic() == "/camera/depth/image_raw"
    cam = bag.camera()
    assert (cam.width, cam.height, cam.fx, cam.lens) == (640, 480, 580.0, None)
    frames = bag.depth_frames()
    assert len(frames) == 3
    got = list(frames)
    # The header's stamp, not the time the recorder received it.
    assert [t for t, _ in got] == pytest.approx([100.005, 101.005, 102.005], abs=1e-9)
    for (_, z), d in zip(got, mm):
        assert z.dtype == np.float32 and z.shape == (480, 640)
        np.testing.assert_array_equal(z, (d.astype(np.float64) / 1000).astype(np.float32))
    # The same frames as arrays: track_sequence on the bag gives the same poses.
    poses, statuses, _ = sldepth.track_sequence(path, rolling_shutter_ms=0)
    arrays, statuses_a, _ = sldepth.track_sequence(
        [z for _, z in got], cam, timestamps_s=[t for t, _ in got], rolling_shutter_ms=0
    )
    assert statuses == statuses_a and statuses[0] == "initialised"
    np.testing.assert_array_equal(poses, arrays)
    assert np.abs(poses[:, :3, 3]).max() < 0.01


def test_a_compressed_depth_topic_reads_as_the_raw_one(tmp_path):
    """image_transport's compressedDepth (16UC1 PNG after a 12-byte configuration header)."""
    mm = _frames(1)[0]
    png = tmp_path / "f.png"
    sldepth.write_depth(png, mm, depth_scale=1000)
    data = struct.pack("<iff", 0, 0.0, 0.0) + png.read_bytes()
    msg = _header((3, 0)) + _string("16UC1; compressedDepth png") + struct.pack("<I", len(data)) + data
    conns = [(0, "/camera/depth/image_raw/compressedDepth", "sensor_msgs/CompressedImage"),
             (1, "/camera/depth/camera_info", "sensor_msgs/CameraInfo")]
    path = tmp_path / "c.bag"
    _write_bag(path, conns, [(0, (3, 0), msg), (1, (3, 0), _camera_info(640, 480, 570.0, [0.0] * 5))],
               "bz2")
    bag = sldepth.RosBag(path)
    assert bag.depth_topic() == "/camera/depth/image_raw/compressedDepth"
    assert bag.camera().fx == 570.0
    (t, z), = list(bag.depth_frames())
    assert t == 3.0
    np.testing.assert_array_equal(z, (mm.astype(np.float64) / 1000).astype(np.float32))


def test_bag_errors(tmp_path):
    bad = tmp_path / "not.bag"
    bad.write_bytes(b"hello")
    with pytest.raises(OSError, match="not a ROS 1 bag"):
        sldepth.RosBag(bad)
    path = tmp_path / "rgb.bag"
    rgb = np.zeros((2, 2, 3), np.uint8)
    _write_bag(path, _CONNS[:1], [(0, (1, 0), _image((1, 0), rgb, "rgb8"))], "none")
    bag = sldepth.RosBag(path)
    with pytest.raises(OSError, match="no depth image topic"):
        bag.depth_topic()
    with pytest.raises(OSError, match='no topic "/x"'):
        bag.depth_frames("/x")
    with pytest.raises(OSError, match="no sensor_msgs/CameraInfo topic beside"):
        bag.camera("/camera/depth/image_raw")
    with pytest.raises(TypeError, match="topic is for a ROS bag"):
        sldepth.track_sequence([np.zeros((4, 4), np.float32)], topic="/x")


def _rosbags_ros1():
    """The `rosbags` ROS 1 writer and the Noetic types of a depth image (skips without it)."""
    rosbag1 = pytest.importorskip("rosbags.rosbag1")
    typesys = pytest.importorskip("rosbags.typesys")
    ts = typesys.get_typestore(typesys.Stores.ROS1_NOETIC)
    types = [ts.types[n] for n in ("sensor_msgs/msg/Image", "std_msgs/msg/Header",
                                   "builtin_interfaces/msg/Time")]
    return (rosbag1, ts, *types)


def test_a_bag_written_by_rosbags_reads_the_same(tmp_path):
    """The independent `rosbags` writer (lz4 chunks, 32FC1 metres as TUM's bags)."""
    rosbag1, ts, Image, Header, Time = _rosbags_ros1()
    metres = [(d.astype(np.float64) / 1000).astype(np.float32) for d in _frames(2)]
    metres[1][0, :3] = np.nan
    path = tmp_path / "rosbags.bag"
    w = rosbag1.Writer(path)
    w.set_compression(rosbag1.Writer.CompressionFormat.LZ4)
    with w:
        c = w.add_connection("/camera/depth/image", Image.__msgtype__, typestore=ts)
        for i, z in enumerate(metres):
            h = Header(seq=i, stamp=Time(sec=50 + i, nanosec=250_000_000), frame_id="d")
            msg = Image(header=h, height=480, width=640, encoding="32FC1", is_bigendian=0,
                        step=640 * 4, data=np.frombuffer(z.tobytes(), np.uint8))
            w.write(c, (60 + i) * 10**9, ts.serialize_ros1(msg, Image.__msgtype__))
    got = list(sldepth.RosBag(path).depth_frames())
    assert [t for t, _ in got] == pytest.approx([50.25, 51.25], abs=1e-9)
    expected = [np.nan_to_num(z, nan=0.0) for z in metres]
    for (_, z), e in zip(got, expected):
        np.testing.assert_array_equal(z, e)


def test_a_ros1_recording_split_in_pieces_reads_as_one(tmp_path):
    """`rosbag record --split`'s pieces (NAME_0.bag, NAME_1.bag, ...) written by `rosbags`: the
    folder is one recording, track_sequence takes it; a bag of another name beside breaks it."""
    rosbag1, ts, Image, Header, Time = _rosbags_ros1()
    mm = _frames(3)
    rec = tmp_path / "rec"
    rec.mkdir()
    for i, d in enumerate(mm):
        with rosbag1.Writer(rec / f"session_2024-05-01-10-00-00_{i}.bag") as w:
            c = w.add_connection("/camera/depth/image_raw", Image.__msgtype__, typestore=ts)
            msg = Image(header=Header(seq=i, stamp=Time(sec=30 + i, nanosec=0), frame_id="d"),
                        height=480, width=640, encoding="16UC1", is_bigendian=0, step=640 * 2,
                        data=np.frombuffer(d.astype("<u2").tobytes(), np.uint8))
            w.write(c, (30 + i) * 10**9, ts.serialize_ros1(msg, Image.__msgtype__))
    assert sldepth.RosBag.is_recording(rec)
    bag = sldepth.RosBag(rec)
    assert (bag.container, bag.files) == ("ROS 1 bag", 3)
    assert [t for t, _ in bag.depth_frames()] == [30.0, 31.0, 32.0]
    poses, statuses, _ = sldepth.track_sequence(rec, camera=sldepth.Camera.preset("kinect-v1"))
    assert poses.shape == (3, 4, 4)
    (rec / "other_0.bag").write_bytes((rec / "session_2024-05-01-10-00-00_0.bag").read_bytes())
    assert not sldepth.RosBag.is_recording(rec)


def _rosbags_ros2():
    """The `rosbags` ROS 2 writer and the Humble types of a depth image (skips without it)."""
    rosbag2 = pytest.importorskip("rosbags.rosbag2")
    typesys = pytest.importorskip("rosbags.typesys")
    ts = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    return (rosbag2, ts, ts.types["sensor_msgs/msg/Image"], ts.types["std_msgs/msg/Header"],
            ts.types["builtin_interfaces/msg/Time"])


def test_a_ros2_mcap_bag_written_by_rosbags_reads_the_same(tmp_path):
    """ROS 2 (MCAP, CDR) by the independent `rosbags` writer: the bag's folder, 16UC1."""
    rosbag2, ts, Image, Header, Time = _rosbags_ros2()
    mm = _frames(2)
    folder = tmp_path / "rec"
    with rosbag2.Writer(folder, version=8, storage_plugin=rosbag2.StoragePlugin.MCAP) as w:
        c = w.add_connection("/camera/depth/image_rect_raw", Image.__msgtype__, typestore=ts)
        for i, d in enumerate(mm):
            h = Header(stamp=Time(sec=70 + i, nanosec=125_000_000), frame_id="d")
            msg = Image(header=h, height=480, width=640, encoding="16UC1", is_bigendian=0,
                        step=640 * 2, data=np.frombuffer(d.tobytes(), np.uint8))
            w.write(c, (80 + i) * 10**9, ts.serialize_cdr(msg, Image.__msgtype__))
    bag = sldepth.RosBag(folder)
    assert bag.topics == [("/camera/depth/image_rect_raw", "sensor_msgs/Image", 2)]
    got = list(bag.depth_frames())
    assert [t for t, _ in got] == pytest.approx([70.125, 71.125], abs=1e-9)
    for (_, z), d in zip(got, mm):
        np.testing.assert_array_equal(z, (d.astype(np.float64) / 1000).astype(np.float32))


def _cdr_image(stamp, depth, encoding):
    """A ROS 2 sensor_msgs/msg/Image in CDR (little-endian, aligned after the 4-byte header)."""
    out = bytearray(b"\x00\x01\x00\x00")

    def align(n):
        while (len(out) - 4) % n:
            out.append(0)

    def u32(v):
        align(4)
        out.extend(struct.pack("<I", v))

    def string(s):
        b = s.encode() + b"\0"
        u32(len(b))
        out.extend(b)

    u32(stamp[0])
    u32(stamp[1])
    string("depth_optical_frame")
    u32(depth.shape[0])
    u32(depth.shape[1])
    string(encoding)
    out.append(0)
    u32(depth.shape[1] * depth.itemsize)
    u32(depth.nbytes)
    out.extend(depth.tobytes())
    return bytes(out)


_SQLITE_TOPICS = ("CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT "
                  "NULL,serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL)")
_SQLITE_MESSAGES = ("CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
                    "timestamp INTEGER NOT NULL, data BLOB NOT NULL)")


@pytest.mark.parametrize("page_size,journal", [(512, "delete"), (4096, "wal"), (65536, "memory")])
def test_a_ros2_sqlite_bag_written_by_sqlite_itself_reads_the_same(tmp_path, page_size, journal):
    """A .db3 as rosbag2_storage_sqlite3 lays it out, written by SQLite itself (Python's
    sqlite3): pages from 512 B to 64 KiB, rows deleted after they were written (free space
    inside the pages), rows inserted out of time order, a checkpointed WAL file."""
    import sqlite3

    mm = _frames(3)
    path = tmp_path / "rec_0.db3"
    db = sqlite3.connect(path)
    db.execute(f"PRAGMA page_size={page_size}")
    db.execute(f"PRAGMA journal_mode={journal}")
    db.execute(_SQLITE_TOPICS)
    db.execute(_SQLITE_MESSAGES)
    db.execute("CREATE INDEX timestamp_idx ON messages (timestamp ASC)")
    db.execute("INSERT INTO topics VALUES (1, '/camera/depth/image_rect_raw', "
               "'sensor_msgs/msg/Image', 'cdr', '')")
    db.execute("INSERT INTO topics VALUES (2, '/chatter', 'std_msgs/msg/String', 'cdr', '')")
    order = [2, 0, 1]
    for i in order:
        t = (90 + i) * 10**9
        db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?, ?)",
                   (t, _cdr_image((90 + i, 500_000_000), mm[i], "16UC1")))
        for k in range(5):
            db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (2, ?, ?)",
                       (t + k, b"\x00\x01\x00\x00" + struct.pack("<I", 3) + b"hi\0"))
    db.execute("DELETE FROM messages WHERE topic_id = 2 AND timestamp % 2 = 1")
    db.commit()
    db.close()
    assert not (tmp_path / "rec_0.db3-wal").exists() or (tmp_path / "rec_0.db3-wal").stat().st_size == 0
    (tmp_path / "metadata.yaml").write_text("rosbag2_bagfile_information:\n")
    for where in (path, tmp_path):
        bag = sldepth.RosBag(where)
        assert (bag.container, bag.files) == ("SQLite (ROS 2 bag)", 1)
        assert bag.topics == [("/camera/depth/image_rect_raw", "sensor_msgs/Image", 3),
                              ("/chatter", "std_msgs/String", 9)]
        assert bag.realsense() is None
        got = list(bag.depth_frames())
        assert [t for t, _ in got] == pytest.approx([90.5, 91.5, 92.5], abs=1e-9)
        for (_, z), d in zip(got, mm):
            np.testing.assert_array_equal(z, (d.astype(np.float64) / 1000).astype(np.float32))


def test_a_ros2_sqlite_bag_written_by_rosbags_reads_the_same(tmp_path):
    """ROS 2 in SQLite by the independent `rosbags` writer: the bag's folder, 32FC1 metres."""
    rosbag2, ts, Image, Header, Time = _rosbags_ros2()
    metres = [(d.astype(np.float64) / 1000).astype(np.float32) for d in _frames(2)]
    folder = tmp_path / "rec"
    with rosbag2.Writer(folder, version=8, storage_plugin=rosbag2.StoragePlugin.SQLITE3) as w:
        c = w.add_connection("/camera/depth/image", Image.__msgtype__, typestore=ts)
        for i, z in enumerate(metres):
            h = Header(stamp=Time(sec=40 + i, nanosec=75_000_000), frame_id="d")
            msg = Image(header=h, height=480, width=640, encoding="32FC1", is_bigendian=0,
                        step=640 * 4, data=np.frombuffer(z.tobytes(), np.uint8))
            w.write(c, (41 + i) * 10**9, ts.serialize_cdr(msg, Image.__msgtype__))
    bag = sldepth.RosBag(folder)
    assert bag.topics == [("/camera/depth/image", "sensor_msgs/Image", 2)]
    got = list(bag.depth_frames())
    assert [t for t, _ in got] == pytest.approx([40.075, 41.075], abs=1e-9)
    for (_, z), e in zip(got, metres):
        np.testing.assert_array_equal(z, e)


def test_a_realsense_recording_by_librealsense_reads_its_units_and_timestamps(tmp_path):
    """librealsense's own recorder (a software device; .db3 since 2.56, .bag before): the
    depth units (0.25 mm), the device's preset and recorded baseline, and each frame's sensor
    timestamp. Runs where pyrealsense2 (and its libusb) is installed."""
    rs = pytest.importorskip("pyrealsense2")
    mm = _frames(2)
    units = [np.round(d.astype(np.float64) * 4).astype(np.uint16) for d in mm]
    dev = rs.software_device()
    dev.register_info(rs.camera_info.name, "Intel RealSense D455")
    sensor = dev.add_sensor("Stereo Module")
    intr = rs.intrinsics()
    intr.width, intr.height, intr.ppx, intr.ppy, intr.fx, intr.fy = 640, 480, 319.5, 239.5, 580.0, 580.0
    intr.model = rs.distortion.brown_conrady
    intr.coeffs = [0.0] * 5
    vs = rs.video_stream()
    vs.type, vs.index, vs.uid, vs.width, vs.height, vs.fps, vs.bpp = rs.stream.depth, 0, 0, 640, 480, 30, 2
    vs.fmt, vs.intrinsics = rs.format.z16, intr
    profile = sensor.add_video_stream(vs)
    sensor.add_read_only_option(rs.option.depth_units, 0.00025)
    path = tmp_path / "rs.db3"
    try:
        recorder = rs.recorder(str(path), dev)
    except RuntimeError:
        path = tmp_path / "rs.bag"
        recorder = rs.recorder(str(path), dev)
    queue = rs.frame_queue(4)
    sensor.open(profile)
    sensor.start(queue)
    for i, u in enumerate(units):
        f = rs.software_video_frame()
        f.pixels = np.ascontiguousarray(u).tobytes()
        f.bpp, f.stride, f.timestamp = 2, 2 * 640, 1_700_000_000_000.0 + 33.0 * i
        f.domain, f.frame_number = rs.timestamp_domain.system_time, i
        f.profile = profile.as_video_stream_profile()
        sensor.on_video_frame(f)
        queue.wait_for_frame()
    sensor.stop()
    sensor.close()
    del recorder
    bag = sldepth.RosBag(path)
    assert bag.realsense() == {"device": "Intel RealSense D455", "depth_units_m": 0.00025,
                               "stereo_baseline_m": None}
    cam = bag.camera()
    assert (cam.fx, cam.baseline_m) == (pytest.approx(580.0), 0.095)
    got = list(bag.depth_frames())
    assert [t for t, _ in got] == pytest.approx([1_700_000_000.0, 1_700_000_000.033], abs=1e-5)
    for (_, z), u in zip(got, units):
        np.testing.assert_array_equal(z, (u.astype(np.float64) / 4000).astype(np.float32))


def test_a_ros2_bag_split_into_files_reads_as_one_recording(tmp_path):
    """A ROS 2 bag's folder of several .db3 files (ros2 bag record --max-bag-size), written by
    SQLite itself: one recording, its frames in time order across the files."""
    import sqlite3

    mm = _frames(3)
    for k, n in enumerate([0, 1, 10]):
        db = sqlite3.connect(tmp_path / f"rec_{n}.db3")
        db.execute(_SQLITE_TOPICS)
        db.execute(_SQLITE_MESSAGES)
        db.execute("INSERT INTO topics VALUES (1, '/depth', 'sensor_msgs/msg/Image', 'cdr', '')")
        db.execute("INSERT INTO messages (topic_id, timestamp, data) VALUES (1, ?, ?)",
                   ((20 + k) * 10**9, _cdr_image((20 + k, 0), mm[k], "16UC1")))
        db.commit()
        db.close()
    (tmp_path / "metadata.yaml").write_text("rosbag2_bagfile_information:\n")
    bag = sldepth.RosBag(tmp_path)
    assert (bag.container, bag.files) == ("SQLite (ROS 2 bag)", 3)
    assert bag.topics == [("/depth", "sensor_msgs/Image", 3)]
    got = list(bag.depth_frames())
    assert [t for t, _ in got] == [20.0, 21.0, 22.0]
    for (_, z), d in zip(got, mm):
        np.testing.assert_array_equal(z, (d.astype(np.float64) / 1000).astype(np.float32))


def test_transforms_written_by_rosbags_pose_the_camera(tmp_path):
    """/tf (a base moving 1 m/s along x, sampled at 10 Hz) and /tf_static (the base -> the
    camera's optical frame) written by the independent `rosbags` writer: the frames listed,
    the images' frame, and the camera's pose at the depth stamps as `fuse --tf` takes it."""
    rosbag1, ts, Image, Header, Time = _rosbags_ros1()
    typesys = pytest.importorskip("rosbags.typesys")
    ts.register(typesys.get_types_from_msg("geometry_msgs/TransformStamped[] transforms",
                                           "tf2_msgs/msg/TFMessage"))
    TF = ts.types["tf2_msgs/msg/TFMessage"]
    TS, Tr = ts.types["geometry_msgs/msg/TransformStamped"], ts.types["geometry_msgs/msg/Transform"]
    V3, Q = ts.types["geometry_msgs/msg/Vector3"], ts.types["geometry_msgs/msg/Quaternion"]

    def tfs(sec, nsec, parent, child, t, q):
        return TS(header=Header(seq=0, stamp=Time(sec=sec, nanosec=nsec), frame_id=parent),
                  child_frame_id=child,
                  transform=Tr(translation=V3(x=t[0], y=t[1], z=t[2]),
                               rotation=Q(x=q[0], y=q[1], z=q[2], w=q[3])))

    # The optical frame in the base: z forward (the base's x), x right (-y), y down (-z):
    # the rotation of 120 degrees about (1, -1, 1), quaternion (0.5, -0.5, 0.5, -0.5).
    optical = [0.5, -0.5, 0.5, -0.5]
    z = (_frames(1)[0].astype(np.float64) / 1000).astype(np.float32)
    path = tmp_path / "tf.bag"
    with rosbag1.Writer(path) as w:
        c_tf = w.add_connection("/tf", TF.__msgtype__, typestore=ts)
        c_st = w.add_connection("/tf_static", TF.__msgtype__, typestore=ts)
        c_d = w.add_connection("/camera/depth/image", Image.__msgtype__, typestore=ts)
        st = TF(transforms=[tfs(0, 0, "base", "camera_depth_optical_frame", [0, 0, 0.5], optical)])
        w.write(c_st, 10 * 10**9, ts.serialize_ros1(st, TF.__msgtype__))
        for i in range(21):
            sec, nsec = 10 + i // 10, (i % 10) * 100_000_000
            m = TF(transforms=[tfs(sec, nsec, "/odom", "base", [i * 0.1, 0, 0], [0, 0, 0, 1])])
            w.write(c_tf, sec * 10**9 + nsec, ts.serialize_ros1(m, TF.__msgtype__))
        for i in range(2):
            h = Header(seq=i, stamp=Time(sec=10 + i, nanosec=550_000_000),
                       frame_id="camera_depth_optical_frame")
            msg = Image(header=h, height=480, width=640, encoding="32FC1", is_bigendian=0,
                        step=640 * 4, data=np.frombuffer(z.tobytes(), np.uint8))
            w.write(c_d, (10 + i) * 10**9 + 560_000_000, ts.serialize_ros1(msg, Image.__msgtype__))
    bag = sldepth.RosBag(path)
    frames = bag.transforms()
    assert [(f["frame"], f["parent"], f["static"], f["samples"]) for f in frames] == [
        ("base", "odom", False, 21), ("camera_depth_optical_frame", "base", True, 1)]
    assert not frames[0]["republished_constant"]
    assert frames[0]["first_s"] == 10.0 and frames[0]["last_s"] == 12.0
    cam = bag.image_frame()
    assert cam == "camera_depth_optical_frame"
    stamps = [t for t, _ in bag.depth_frames()]
    poses = bag.tf_lookup("odom", cam, stamps + [12.5])
    assert poses.shape == (3, 4, 4) and poses.dtype == np.float64
    for t, p in zip(stamps, poses):
        # Interpolated between the 10 Hz samples: the base at x = t - 10, the camera 0.5 m up,
        # looking along x with the image's y down.
        np.testing.assert_allclose(p[:3, 3], [t - 10, 0, 0.5], atol=1e-9)
        np.testing.assert_allclose(p[:3, 2], [1, 0, 0], atol=1e-12)
        np.testing.assert_allclose(p[:3, 1], [0, 0, -1], atol=1e-12)
    # Half a second after the last sample: no pose (NaN), unless the gap allows it.
    assert np.isnan(poses[2]).all()
    assert not np.isnan(bag.tf_lookup("odom", cam, [12.5], max_gap_s=0.6)).any()
    # A NumPy array of stamps is taken as a list; a stamp that is no number has no pose.
    np.testing.assert_array_equal(bag.tf_lookup("odom", cam, np.array(stamps)), poses[:2])
    assert np.isnan(bag.tf_lookup("odom", cam, [float("nan")])).all()
    # ... even a frame's in itself; and no stamps give no poses.
    assert np.isnan(bag.tf_lookup(cam, cam, [float("nan")])).all()
    np.testing.assert_array_equal(bag.tf_lookup(cam, cam, [11.0])[0], np.eye(4))
    assert bag.tf_lookup("odom", cam, []).shape == (0, 4, 4)
    # Stamps are one 1-D sequence of numbers: anything else says so.
    for bad in ([stamps], 11.0, ["11.0"], np.array(stamps).reshape(2, 1)):
        with pytest.raises(ValueError, match="stamps_s must be a 1-D sequence"):
            bag.tf_lookup("odom", cam, bad)
    with pytest.raises(ValueError, match='no transform names the frame "map"'):
        bag.tf_lookup("map", cam, stamps)
    with pytest.raises(ValueError, match="max_gap_s"):
        bag.tf_lookup("odom", cam, stamps, max_gap_s=float("nan"))
    # At most an hour, as `sldepth fuse --max-gap-s` (a larger number is a unit mistake).
    for gap in (-1.0, 3600.5, 1e308, float("inf")):
        with pytest.raises(ValueError, match="max_gap_s must be from 0 to 3600"):
            bag.tf_lookup("odom", cam, stamps, max_gap_s=gap)
    # The same transforms as an odometry for track_sequence: each frame's camera looked up in
    # "odom" at its stamp; an unknown frame, poses of another shape, and a frame name for
    # arrays are refused.
    kinect = sldepth.Camera.preset("kinect-v1")
    poses, statuses, _ = sldepth.track_sequence(path, kinect, odometry="odom", prefilter="none")
    assert poses.shape == (2, 4, 4) and statuses[0] == "initialised"
    with pytest.raises(ValueError, match='no transform names the frame "map"'):
        sldepth.track_sequence(path, kinect, odometry="map")
    with pytest.raises(ValueError, match=r"odometry must be 2 \(4, 4\)"):
        sldepth.track_sequence(path, kinect, odometry=np.zeros((3, 4, 4)))
    with pytest.raises(TypeError, match="frame name is for a robot recording"):
        sldepth.track_sequence([z, z], kinect, odometry="odom")
    # One tree, the root's; another namespace holds none (a multi-robot recording's
    # /robot1/tf would be read with namespace="/robot1").
    assert bag.tf_namespaces() == [""]
    assert bag.transforms(namespace="/robot1") == []
    with pytest.raises(ValueError, match="no transform names the frame"):
        bag.tf_lookup("odom", cam, stamps, namespace="/robot1")

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


def test_a_bag_written_by_rosbags_reads_the_same(tmp_path):
    """The independent `rosbags` writer (lz4 chunks, 32FC1 metres as TUM's bags)."""
    rosbag1 = pytest.importorskip("rosbags.rosbag1")
    typesys = pytest.importorskip("rosbags.typesys")
    ts = typesys.get_typestore(typesys.Stores.ROS1_NOETIC)
    Image = ts.types["sensor_msgs/msg/Image"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
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


def test_a_ros2_mcap_bag_written_by_rosbags_reads_the_same(tmp_path):
    """ROS 2 (MCAP, CDR) by the independent `rosbags` writer: the bag's folder, 16UC1."""
    rosbag2 = pytest.importorskip("rosbags.rosbag2")
    typesys = pytest.importorskip("rosbags.typesys")
    ts = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    Image = ts.types["sensor_msgs/msg/Image"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
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

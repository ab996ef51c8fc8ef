"""ROS 2 bags from Python and the CLI: bags written by rosbags (PyPI, an official writer) from
real scans, read back by `read_bag` and `kitti2pgm unpack` exactly as the PCD files they came
from; padded and big-endian records; wrong topics named; memory flat as the bag grows."""

import importlib.util
import json
import os
import pathlib
import subprocess

import kitti2pgm as k2
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
LIDARS = REPO / "fixtures" / "lidars"
VLP16 = LIDARS / "velodyne" / "vlp16_1673400472138016708.pcd"
XT32M = LIDARS / "hesai" / "PandarXT32M_1660893203292679064.pcd"
BAG = REPO / "fixtures" / "own_lidar_bag"
BIN = os.environ.get("KITTI2PGM_BIN", "kitti2pgm")


def make_bag():
    """fixtures/make_bag.py, the fixture bag's own writer."""
    pytest.importorskip("rosbags")
    spec = importlib.util.spec_from_file_location("make_bag", REPO / "fixtures" / "make_bag.py")
    assert spec and spec.loader
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


PC2 = "sensor_msgs/msg/PointCloud2"


def test_read_bag_gives_the_pcd_reader_s_clouds_with_stamps():
    frames = k2.read_bag(BAG, "/velodyne_points")
    assert len(frames) == 2
    expected = k2.read_cloud(VLP16)
    got = list(frames)
    assert [f["index"] for f in got] == [0, 1]
    assert [f["stamp"] for f in got] == [1673400472138016708, 1673400472238016708]
    for f in got:  # the second message is big-endian
        assert f["frame_id"] == "velodyne"
        np.testing.assert_array_equal(f["points"], expected["points"])
        np.testing.assert_array_equal(f["ring"], expected["ring"])
    topics = {t["topic"]: (t["type"], t["messages"]) for t in k2.bag_topics(BAG)}
    assert topics == {"/velodyne_points": (PC2, 2), "/pandar_points": (PC2, 1),
                      "/rosout_text": ("std_msgs/msg/String", 1)}


def test_padded_and_big_endian_records_read_as_the_pcd(tmp_path):
    mb = make_bag()
    ts = typestore()
    pts = mb.read_pcd(XT32M)
    msgs = [("/points", PC2, mb.pointcloud2(ts, pts, 10**18 + i, "hesai", big_endian=big, point_step=step),
             i, not big)
            for i, (big, step) in enumerate([(False, None), (True, None), (False, 48), (True, 64)])]
    mb.write_bag(tmp_path / "bag", msgs, ts)
    expected = k2.read_cloud(XT32M)
    frames = list(k2.read_bag(tmp_path / "bag", topic="/points"))
    assert len(frames) == 4
    for f in frames:
        np.testing.assert_array_equal(f["points"], expected["points"], err_msg=str(f["index"]))
        assert f["ring"] is None and expected["ring"] is None
    # The CLI's PCD of a padded big-endian message is the driver's own PCD again.
    out = tmp_path / "root"
    r = subprocess.run([BIN, "unpack", str(tmp_path / "bag"), "--topic", "/points", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    for i in range(4):
        assert (out / "sequences/00/velodyne" / f"{i:06d}.pcd").read_bytes() == XT32M.read_bytes()
    # project() on a bag frame: rows are the XT32M's 32 beams from its beam table.
    m = k2.project(frames[3]["points"], preset="full", cols=1024, sensor="pandarxt32m")
    assert m["map"].shape == (32, 1024, 6) and m["stats"]["off_model"] == 0
    e = k2.project(expected["points"], preset="full", cols=1024, sensor="pandarxt32m")
    np.testing.assert_array_equal(m["map"], e["map"])


def test_a_wrong_topic_lists_the_point_cloud_topics():
    with pytest.raises(ValueError, match=r"no topic /x; .*/pandar_points \(1 message\), /velodyne_points"):
        k2.read_bag(BAG, "/x")
    with pytest.raises(ValueError, match="no topic given"):
        k2.read_bag(BAG)
    with pytest.raises(ValueError, match="is std_msgs/msg/String, not sensor_msgs/msg/PointCloud2"):
        k2.read_bag(BAG, "/rosout_text")
    with pytest.raises(OSError):
        k2.read_bag(BAG / "nothing.mcap", "/x")


def test_a_bad_message_raises_at_its_frame(tmp_path):
    mb = make_bag()
    ts = typestore()
    pts = mb.read_pcd(VLP16)
    PointField = ts.types["sensor_msgs/msg/PointField"]
    # z declared at byte 40 of a 32-byte record.
    bad = [PointField(name="x", offset=0, datatype=7, count=1), PointField(name="y", offset=4, datatype=7, count=1),
           PointField(name="z", offset=40, datatype=7, count=1)]
    mb.write_bag(tmp_path / "bag", [("/p", PC2, mb.pointcloud2(ts, pts, 1, "v"), 1, True),
                                    ("/p", PC2, mb.pointcloud2(ts, pts, 2, "v", fields=bad), 2, True)], ts)
    it = iter(k2.read_bag(tmp_path / "bag", "/p"))
    assert next(it)["index"] == 0
    with pytest.raises(ValueError, match=r"message 1 of /p.*field z ends at byte 44, beyond the 32-byte"):
        next(it)


# Peak memory of one command, measured by a small fresh Python process: a child started by
# this (large) test process would inherit its peak at the exec (Linux keeps the high-water mark
# of the memory it replaced).
MEASURE = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
           "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); "
           "sys.stderr.write(r.stderr); print(r.stdout)")


def peak_rss_mib(args):
    """Runs the CLI and returns its peak resident memory (MiB) and its JSON output."""
    r = subprocess.run(["python3", "-c", MEASURE, *args], capture_output=True, text=True)
    head, _, out = r.stdout.partition("\n")
    code, kib = head.split()
    assert code == "0", r.stderr
    return int(kib) / 1024, json.loads(out)


def test_unpack_memory_stays_flat_as_the_bag_grows(tmp_path):
    mb = make_bag()
    ts = typestore()
    pts = mb.read_pcd(VLP16)
    peaks = []
    for n in (8, 96):
        bag = tmp_path / f"bag{n}"
        mb.write_bag(bag, [("/v", PC2, mb.pointcloud2(ts, pts, i, "v"), i, True) for i in range(n)], ts)
        peak, j = peak_rss_mib([BIN, "unpack", str(bag), "--topic", "/v", "--out", str(tmp_path / f"o{n}"),
                                "--json", "--threads", "2"])
        assert j["frames_written"] == n
        peaks.append(peak)
    size = sum(f.stat().st_size for f in (tmp_path / "bag96").iterdir()) / 2**20
    # A bag of 96 scans (about 44 MiB) costs no more than a few scans more than one of 8.
    assert size > 40
    assert peaks[1] < peaks[0] + 12, (peaks, size)


def convert_bag(*args):
    r = subprocess.run(["rosbags-convert", *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_a_ros1_bag_through_rosbags_convert_and_mcap_chunk_compression(tmp_path):
    """docs/sources.md's path for ROS 1 bags: rosbags-convert into an MCAP bag (zstd chunks
    here), then read as any ROS 2 bag."""
    mb = make_bag()
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    pts = mb.read_pcd(VLP16)
    msg = mb.pointcloud2(ts, pts, 1673400472138016708, "velodyne")
    with Writer(tmp_path / "run.bag") as w:
        c = w.add_connection("/velodyne_points", PC2, typestore=ts)
        for i in range(3):
            w.write(c, 1673400472138016708 + i, ts.serialize_ros1(msg, PC2))
    convert_bag("--src", tmp_path / "run.bag", "--dst", tmp_path / "ros2", "--dst-storage", "mcap",
                "--compress", "zstd", "--compress-mode", "storage")
    frames = list(k2.read_bag(tmp_path / "ros2", "/velodyne_points"))
    assert len(frames) == 3
    expected = k2.read_cloud(VLP16)
    for f in frames:
        np.testing.assert_array_equal(f["points"], expected["points"])
        np.testing.assert_array_equal(f["ring"], expected["ring"])
    # rosbag2's own FILE compression (a .mcap.zstd) is named, with how to undo it.
    convert_bag("--src", tmp_path / "run.bag", "--dst", tmp_path / "filez", "--dst-storage", "mcap",
                "--compress", "zstd", "--compress-mode", "file")
    with pytest.raises(ValueError, match=r"compressed by rosbag2 \(file mode, zstd\).*decompress"):
        k2.read_bag(tmp_path / "filez", "/velodyne_points")


def test_dataset_on_an_unpacked_bag_gives_convert_s_maps(tmp_path):
    """A training loader on a user's own recording: unpack the bag, then Dataset(sensor=...)
    loads each frame with its beam rows and projects it to the map convert writes."""
    root, out = tmp_path / "root", tmp_path / "out"
    r = subprocess.run([BIN, "unpack", str(BAG), "--topic", "/velodyne_points", "--out", str(root)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([BIN, "convert", str(root), "--out", str(out), "--sensor", "vlp16", "--all-frames",
                        "--cols", "1024"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    ds = k2.Dataset(root, sensor="vlp16", all_frames=True)
    assert ds.frames == ["00_000000", "00_000001"]
    expected = k2.read_cloud(VLP16)
    for i, frame in enumerate(ds):
        np.testing.assert_array_equal(frame["ring"], 15 - expected["ring"])  # row 0 is the highest beam
        m = ds.project(i, cols=1024)
        assert m["map"].shape == (16, 1024, 6)
        np.testing.assert_array_equal(m["map"], np.load(out / "lidar_2d" / f"{frame['id']}.npy"))
    # The calibration file gives the same rows; a bad sensor name is a ValueError naming the presets.
    cal = k2.Dataset(root, sensor=str(LIDARS / "velodyne" / "VLP16.yaml"), all_frames=True)
    np.testing.assert_array_equal(cal[0]["ring"], ds[0]["ring"])
    with pytest.raises(ValueError, match="neither a built-in sensor"):
        k2.Dataset(root, sensor="vlp17", all_frames=True)


def test_dataset_sensor_pose_brings_a_vehicle_frame_cloud_back(tmp_path):
    """The VLP-16 scan raised 1.8 m (a base_link cloud, x, y, z only): off the beam model until
    its pose is given, then every point on a beam."""
    mb = make_bag()
    pts = mb.read_pcd(VLP16)
    xyz = np.zeros(len(pts), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    xyz["x"], xyz["y"], xyz["z"] = pts["x"], pts["y"], pts["z"] + np.float32(1.8)
    seq = tmp_path / "sequences" / "00" / "velodyne"
    seq.mkdir(parents=True)
    head = (f"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {len(xyz)}\nHEIGHT 1\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(xyz)}\nDATA binary\n")
    (seq / "000000.pcd").write_bytes(head.encode() + xyz.tobytes())
    raised = k2.Dataset(tmp_path, sensor="vlp16", all_frames=True)
    assert raised.project(0, cols=1024)["stats"]["off_model"] > len(xyz) // 2
    back = k2.Dataset(tmp_path, sensor="vlp16", all_frames=True, sensor_pose="0,0,1.8")
    m = back.project(0, cols=1024)
    assert m["stats"]["off_model"] == 0
    np.testing.assert_array_equal(back[0]["ring"], 15 - k2.read_cloud(VLP16)["ring"])
    # project(sensor_pose=) on the points themselves: the same map.
    xyzi = np.stack([xyz["x"], xyz["y"], xyz["z"], np.zeros(len(xyz), "f4")], axis=-1)
    p = k2.project(xyzi, preset="full", cols=1024, sensor="vlp16", sensor_pose="0,0,1.8")
    assert p["stats"]["off_model"] == 0
    np.testing.assert_array_equal(p["map"], m["map"])
    with pytest.raises(ValueError, match="sensor_pose needs the sensor"):
        k2.project(xyzi, sensor_pose="0,0,1.8")
    with pytest.raises(ValueError, match="sensor_pose needs the sensor"):
        k2.Dataset(tmp_path, all_frames=True, sensor_pose="0,0,1.8")
    with pytest.raises(ValueError, match="expected x,y,z or x,y,z,roll,pitch,yaw"):
        k2.Dataset(tmp_path, sensor="vlp16", all_frames=True, sensor_pose="0,1.8")


def tf_message(ts, transforms):
    """A tf2_msgs/msg/TFMessage of (parent, child, (x, y, z), (qx, qy, qz, qw))."""
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    return T["tf2_msgs/msg/TFMessage"](transforms=[
        T["geometry_msgs/msg/TransformStamped"](
            header=Header(stamp=Time(sec=0, nanosec=0), frame_id=parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=t[0], y=t[1], z=t[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])))
        for parent, child, t, q in transforms])


def test_unpack_finds_the_sensor_pose_in_the_bag_s_static_transforms(tmp_path):
    """A bag whose clouds are in base_link (the VLP-16 scan raised 1.8 m) and whose /tf_static
    places velodyne there through a mount: unpack --sensor-frame prints the --sensor-pose that
    brings every point back on a beam; a frame /tf_static does not know is named."""
    mb, ts = make_bag(), typestore()
    pts = mb.read_pcd(VLP16)
    lifted = pts.copy()
    lifted["z"] = pts["z"] + np.float32(1.8)
    tf = "tf2_msgs/msg/TFMessage"
    q = (0.0, 0.0, 0.0, 1.0)
    mb.write_bag(tmp_path / "bag", [
        ("/tf_static", tf, tf_message(ts, [("base_link", "lidar_mount", (0.0, 0.0, 1.0), q)]), 1, True),
        ("/tf_static", tf, tf_message(ts, [("lidar_mount", "velodyne", (0.0, 0.0, 0.8), q)]), 2, False),
        ("/points", PC2, mb.pointcloud2(ts, lifted[["x", "y", "z", "intensity"]], 10, "base_link"), 10, True),
    ], ts)
    r = subprocess.run([BIN, "unpack", str(tmp_path / "bag"), "--list"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "velodyne in lidar_mount: 0.0000,0.0000,0.8000,0.0000,0.0000,0.0000" in r.stdout
    out = tmp_path / "root"
    r = subprocess.run([BIN, "unpack", str(tmp_path / "bag"), "--topic", "/points", "--out", str(out),
                        "--sensor-frame", "velodyne"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "--sensor-pose 0.0000,0.0000,1.8000,0.0000,0.0000,0.0000" in r.stdout
    found = json.loads((out / "sequences" / "00" / "unpack.json").read_text())["sensor_pose"]
    assert (found["sensor_frame"], found["points_frame"]) == ("velodyne", "base_link")
    conv = tmp_path / "conv"
    r = subprocess.run([BIN, "convert", str(out), "--out", str(conv), "--sensor", "vlp16", "--all-frames",
                        "--sensor-pose", "0.0000,0.0000,1.8000,0.0000,0.0000,0.0000", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["off_model"] == 0
    # A frame the transforms do not reach: exit 1 naming what they know; the frames are kept.
    r = subprocess.run([BIN, "unpack", str(tmp_path / "bag"), "--topic", "/points", "--out", str(out),
                        "--overwrite", "--sensor-frame", "os_sensor"], capture_output=True, text=True)
    assert r.returncode == 1
    assert "os_sensor" in r.stderr and "base_link, lidar_mount, velodyne" in r.stderr
    assert (out / "sequences" / "00" / "velodyne" / "000000.pcd").is_file()
    assert (out / "sequences" / "00" / "times.txt").is_file()


def write_typed_bag(path, messages, ts, compression=None):
    """A rosbag2 MCAP bag whose one topic /points carries messages of several types (one
    connection a type, as MCAP's channels): [(msgtype, msg, log_time_ns)]."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    if compression:
        w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with w:
        conns = {}
        for msgtype, msg, t in messages:
            if msgtype not in conns:
                conns[msgtype] = w.add_connection("/points", msgtype, typestore=ts)
            w.write(conns[msgtype], t, ts.serialize_cdr(msg, msgtype))


def test_a_flipped_byte_in_an_uncompressed_chunk_fails_its_frame_alone(tmp_path):
    """Issue 47, defect 2: uncompressed chunks (rosbag2's default) have their CRC checked in
    read_bag and unpack, and a damaged chunk's frames fail alone. The bag is written by the
    `mcap` package (CRCs on, as rosbag2's own writer writes them), the messages serialised by
    rosbags; Python's mcap reader with CRC validation names the same damage. (rosbags' own
    writer stores CRC 0, "none": no reader can check its chunks.)"""
    from mcap.reader import make_reader
    from mcap.stream_reader import CRCValidationError
    from mcap.writer import CompressionType, Writer

    mb = make_bag()
    ts = typestore()
    pts = mb.read_pcd(VLP16)
    data = ts.serialize_cdr(mb.pointcloud2(ts, pts, 10**18, "v"), PC2)
    path = tmp_path / "plain.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=1 << 16, compression=CompressionType.NONE)
        w.start("ros2", "test")
        ch = w.register_channel("/v", "cdr", w.register_schema(PC2, "ros2msg", b""))
        for i in range(5):
            w.add_message(ch, 10**18 + i, bytes(data), 10**18 + i)
        w.finish()
    raw = bytearray(path.read_bytes())
    raw[len(raw) // 2] ^= 0x01
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(raw))
    with open(bad, "rb") as f, pytest.raises(CRCValidationError, match="Chunk"):
        for _ in make_reader(f, validate_crcs=True).iter_messages():
            pass
    frames = k2.read_bag(bad, "/v")
    got, failed = [], []
    while True:  # a failed chunk raises once; the iteration goes on after it
        try:
            got.append(next(frames))
        except ValueError as e:
            failed.append(str(e))
        except StopIteration:
            break
    assert len(failed) == 1 and "CRC" in failed[0] and "bad.mcap" in failed[0], failed
    lost = [i for i in range(5) if i not in [f["index"] for f in got]]
    assert len(lost) == 1, lost
    assert failed[0].endswith(f"frames lost: {lost[0]} (iterating again goes on after it)"), failed
    expected = k2.read_cloud(VLP16)
    for f in got:
        np.testing.assert_array_equal(f["points"], expected["points"])
    r = subprocess.run([BIN, "unpack", str(bad), "--topic", "/v", "--out", str(tmp_path / "root"), "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 3, r.stderr
    j = json.loads(r.stdout)
    assert j["frames_written"] == 4 and [f["frame"] for f in j["failures"]] == lost, j
    for i in range(5):
        scan = tmp_path / "root/sequences/00/velodyne" / f"{i:06d}.pcd"
        assert scan.exists() == (i != lost[0])
        assert not scan.exists() or scan.read_bytes() == VLP16.read_bytes()


@pytest.mark.parametrize("compression", [None, "zstd"])
def test_messages_of_another_type_on_the_topic_are_passed_over(tmp_path, compression):
    """Issue 47, defect 4: four PointCloud2 messages and one std_msgs/String on /points: the
    clouds are read, the string counted as passed over, the same in read_bag and unpack."""
    mb = make_bag()
    ts = typestore()
    pts = mb.read_pcd(VLP16)
    String = ts.types["std_msgs/msg/String"]
    msgs = [(PC2, mb.pointcloud2(ts, pts, i, "v"), i) for i in range(4)]
    msgs.insert(2, ("std_msgs/msg/String", String(data="hello"), 10))
    write_typed_bag(tmp_path / "bag", msgs, ts, compression)
    topics = sorted((t["topic"], t["type"], t["messages"]) for t in k2.bag_topics(tmp_path / "bag"))
    assert topics == [("/points", PC2, 4), ("/points", "std_msgs/msg/String", 1)]
    frames = k2.read_bag(tmp_path / "bag", "/points")
    assert frames.skipped_other_types == 1
    assert [f["index"] for f in frames] == [0, 1, 2, 3]
    r = subprocess.run([BIN, "unpack", str(tmp_path / "bag"), "--topic", "/points", "--out", str(tmp_path / "root"),
                        "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    j = json.loads(r.stdout)
    assert (j["frames_written"], j["skipped_other_types"]) == (4, 1)


def test_an_unfinished_unpack_is_refused_by_dataset(tmp_path):
    """Issue 47, defect 8: a sequence whose unpack.json says complete: false (a killed unpack)
    is refused by Dataset as by convert."""
    root = tmp_path / "root"
    r = subprocess.run([BIN, "unpack", str(BAG), "--topic", "/velodyne_points", "--out", str(root)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    marker = root / "sequences/00/unpack.json"
    j = json.loads(marker.read_text())
    assert j["complete"] is True
    j["complete"] = False
    marker.write_text(json.dumps(j))
    with pytest.raises(ValueError, match=r"unfinished unpack.*--overwrite"):
        k2.Dataset(root, sensor="vlp16", all_frames=True)

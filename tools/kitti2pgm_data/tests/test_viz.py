"""(Issue 29) The --viz topics are Foxglove's official schemas: every message of a viz shard
decodes with the official protobuf classes (foxglove-schemas-protobuf from PyPI), with no byte
left over, and the schema stored in the file describes the official message."""

import pathlib
import subprocess

import pytest
from mcap.reader import make_reader

pytest.importorskip("foxglove_schemas_protobuf")
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage  # noqa: E402
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud  # noqa: E402
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate  # noqa: E402
from google.protobuf.descriptor_pb2 import FileDescriptorSet  # noqa: E402

OFFICIAL = {"foxglove.PointCloud": PointCloud, "foxglove.SceneUpdate": SceneUpdate,
            "foxglove.CompressedImage": CompressedImage}


def decode_all(path):
    """Every viz message of an MCAP file decoded with the official class: {schema: [messages]}."""
    seen = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if not channel.topic.startswith("/kitti2pgm/viz/"):
                continue
            assert schema.encoding == "protobuf" and channel.message_encoding == "protobuf"
            cls = OFFICIAL[schema.name]
            # The stored schema describes the official message.
            fds = FileDescriptorSet.FromString(schema.data)
            names = {f"{fd.package}.{m.name}" for fd in fds.file for m in fd.message_type}
            assert schema.name in names
            msg = cls.FromString(message.data)
            assert msg.ByteSize() == len(message.data), "every field is the official message's"
            seen.setdefault(schema.name, []).append(msg)
    return seen


RAW = pathlib.Path(__file__).resolve().parents[3] / "fixtures" / "raw"


def test_every_viz_message_decodes_with_the_official_schema(kitti2pgm_path, tmp_path):
    out = tmp_path / "viz"
    subprocess.run([kitti2pgm_path, "--no-progress", "convert", str(RAW), "--out", str(out), "--format", "mcap",
                    "--viz", "--rgb"], check=True, capture_output=True)
    seen = {}
    for shard in sorted((out / "shards").glob("*.mcap")):
        for k, v in decode_all(shard).items():
            seen.setdefault(k, []).extend(v)
    assert {k: len(v) for k, v in seen.items()} == {k: 3 for k in OFFICIAL}
    for cloud in seen["foxglove.PointCloud"]:
        assert cloud.point_stride == 21 and cloud.frame_id == "velodyne"
        assert [f.name for f in cloud.fields] == ["x", "y", "z", "intensity", "class", "red", "green", "blue", "alpha"]
        assert len(cloud.data) % 21 == 0 and len(cloud.data) // 21 > 100_000
    assert any(len(s.entities[0].cubes) > 0 for s in seen["foxglove.SceneUpdate"])
    assert all(i.format == "png" and i.data[:4] == b"\x89PNG" for i in seen["foxglove.CompressedImage"])

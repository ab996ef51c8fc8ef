"""Other sensors from Python: `read_cloud` reads PCD and nuScenes files as pypcd4 and numpy do,
`project(sensor=...)` gives the bytes `convert --sensor` writes, and rows are the beams."""

import pathlib
import subprocess

import kitti2pgm as k2
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
LIDARS = REPO / "fixtures" / "lidars"
VLP16 = LIDARS / "velodyne" / "vlp16_1673400472138016708.pcd"
P40 = LIDARS / "hesai" / "Pandar40P_1673400149711850138.pcd"
NUSCENES = next((LIDARS / "nuscenes").glob("*.pcd.bin"))
OWN = REPO / "fixtures" / "own_lidar"


def test_read_cloud_matches_numpy_on_the_vlp16_pcd():
    c = k2.read_cloud(VLP16)
    raw = VLP16.read_bytes()
    start = raw.index(b"DATA binary\n") + len(b"DATA binary\n")
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "u1"), ("return_type", "u1"),
                   ("channel", "<u2"), ("azimuth", "<f4"), ("elevation", "<f4"), ("distance", "<f4"),
                   ("time_stamp", "<u4")])
    a = np.frombuffer(raw[start:], dt)
    assert c["file_points"] == len(a) == 14831
    np.testing.assert_array_equal(c["points"][:, 0], a["x"])
    np.testing.assert_array_equal(c["points"][:, 3], a["intensity"].astype(np.float32))
    np.testing.assert_array_equal(c["ring"], a["channel"])


def test_read_cloud_reads_zero_wide_fields_and_trailing_bytes_of_exports(tmp_path):
    """Issue 47, defect 5: a PCD with a COUNT 0 padding field (zero bytes, as three.js's
    PCDLoader reads it) and bytes after its points, as labelling tools export them, reads as the
    numpy reference does; the trailing bytes are counted."""
    raw = VLP16.read_bytes()
    start = raw.index(b"DATA binary\n") + len(b"DATA binary\n")
    head = (raw[:start].decode()
            .replace("time_stamp\n", "time_stamp _\n")
            .replace("SIZE 4 4 4 1 1 2 4 4 4 4\n", "SIZE 4 4 4 1 1 2 4 4 4 4 4\n")
            .replace("TYPE F F F U U U F F F U\n", "TYPE F F F U U U F F F U F\n")
            .replace("COUNT 1 1 1 1 1 1 1 1 1 1\n", "COUNT 1 1 1 1 1 1 1 1 1 1 0\n"))
    assert "COUNT 1 1 1 1 1 1 1 1 1 1 0" in head
    path = tmp_path / "export.pcd"
    path.write_bytes(head.encode() + raw[start:] + bytes(7))
    c = k2.read_cloud(path)
    assert c["trailing_bytes"] == 7
    ref = k2.read_cloud(VLP16)
    assert ref["trailing_bytes"] == 0
    np.testing.assert_array_equal(c["points"], ref["points"])
    np.testing.assert_array_equal(c["ring"], ref["ring"])


def test_read_cloud_reads_what_pypcd4_writes_in_every_encoding(tmp_path):
    pypcd4 = pytest.importorskip("pypcd4")
    src = k2.read_cloud(P40)["points"][:, :3]
    ring = (np.arange(len(src)) % 40).astype(np.uint16)
    for enc in ("ascii", "binary", "binary_compressed"):
        pc = pypcd4.PointCloud.from_points([src[:, 0], src[:, 1], src[:, 2], ring], ("x", "y", "z", "ring"),
                                           (np.float32, np.float32, np.float32, np.uint16))
        path = tmp_path / f"{enc}.pcd"
        pc.save(path, encoding=getattr(pypcd4.Encoding, enc.upper()))
        c = k2.read_cloud(path)
        if enc == "ascii":  # pypcd4 writes about 8 significant digits
            np.testing.assert_allclose(c["points"][:, :3], src, rtol=1e-6, atol=1e-9, err_msg=enc)
        else:
            np.testing.assert_array_equal(c["points"][:, :3], src, err_msg=enc)
        np.testing.assert_array_equal(c["ring"], ring, err_msg=enc)


def test_nuscenes_keyframe_and_declared_fields(tmp_path):
    c = k2.read_cloud(NUSCENES)
    a = np.fromfile(NUSCENES, "<f4").reshape(-1, 5)
    np.testing.assert_array_equal(c["ring"], a[:, 4].astype(np.uint16))
    # The same bytes named .bin with its layout declared.
    p = tmp_path / "scan.bin"
    p.write_bytes(NUSCENES.read_bytes())
    d = k2.read_cloud(p, fields="x,y,z,intensity,ring:f32")
    np.testing.assert_array_equal(d["points"], c["points"])
    with pytest.raises(ValueError, match="unknown type"):
        k2.read_cloud(p, fields="x,y,z:f33")
    with pytest.raises(ValueError, match="not a multiple of 24"):
        k2.read_cloud(p, fields="x,y,z,intensity,ring,extra:f32")


def test_project_with_a_sensor_is_convert_with_that_sensor(tmp_path, kitti2pgm_path):
    subprocess.run([kitti2pgm_path, "--no-progress", "convert", str(OWN), "--out", str(tmp_path), "--sensor",
                    "vlp16", "--all-frames", "--cols", "1024"], check=True, capture_output=True)
    written = np.load(tmp_path / "lidar_2d" / "00_000000.npy")
    c = k2.read_cloud(VLP16)
    # Rows from the channel field (bottom-up) as convert takes it.
    rows = (15 - c["ring"]).astype(np.uint8)
    m = k2.project(c["points"], preset="full", cols=1024, rings=rows, beams=16)
    np.testing.assert_array_equal(m["map"], written)
    # The beam table alone gives the same rows.
    t = k2.project(c["points"], preset="full", cols=1024, rows=16, sensor="vlp16")
    np.testing.assert_array_equal(t["map"], written)
    assert t["stats"]["off_model"] == 0
    assert k2.SENSORS["vlp16"] == 16 and k2.SENSORS["ot128"] == 128
    with pytest.raises(ValueError, match="neither a built-in sensor"):
        k2.project(c["points"], sensor="vlp17")
    with pytest.raises(ValueError, match="not below 16"):
        k2.project(c["points"], rings=np.full(len(rows), 16, np.uint8), beams=16)


def test_dataset_reads_flat_bin_scans_of_a_declared_layout(tmp_path):
    """Dataset(fields=) as `convert --fields`: the VLP-16 scan as 16-byte records loads with its
    rings and projects to the PCD's map; without the sensor it is a ValueError."""
    c = k2.read_cloud(VLP16)
    rec = np.zeros(len(c["points"]), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("i", "u1"),
                                            ("pad", "u1"), ("ring", "<u2")])
    rec["x"], rec["y"], rec["z"] = c["points"][:, 0], c["points"][:, 1], c["points"][:, 2]
    rec["i"], rec["ring"] = c["points"][:, 3].astype("u1"), c["ring"]
    seq = tmp_path / "sequences" / "00" / "velodyne"
    seq.mkdir(parents=True)
    (seq / "000000.bin").write_bytes(rec.tobytes())
    fields = "x,y,z:f32,intensity:u8,_:u8,ring:u16"
    ds = k2.Dataset(tmp_path, sensor="vlp16", fields=fields, all_frames=True)
    np.testing.assert_array_equal(ds[0]["ring"], 15 - c["ring"])
    pcd = k2.Dataset(OWN, sensor="vlp16", all_frames=True)
    np.testing.assert_array_equal(ds.project(0, cols=1024)["map"], pcd.project(0, cols=1024)["map"])
    with pytest.raises(ValueError, match="fields needs the sensor"):
        k2.Dataset(tmp_path, fields=fields, all_frames=True)
    with pytest.raises(ValueError, match="unknown type"):
        k2.Dataset(tmp_path, sensor="vlp16", fields="x,y,z:f16", all_frames=True)


def _rx_ry_rz(a):
    x, y, z = a
    rx = np.array([[1, 0, 0], [0, np.cos(x), -np.sin(x)], [0, np.sin(x), np.cos(x)]])
    ry = np.array([[np.cos(y), 0, np.sin(y)], [0, 1, 0], [-np.sin(y), 0, np.cos(y)]])
    rz = np.array([[np.cos(z), -np.sin(z), 0], [np.sin(z), np.cos(z), 0], [0, 0, 1]])
    return rx @ ry @ rz


def test_read_boxes_gives_sustechpoints_boxes_that_label_points_as_numpy_does(tmp_path):
    """Issue 46: a SUSTechPOINTS label file (psr: centre, full extents, Euler x, y, z applied
    Rx Ry Rz) read by read_boxes; its boxes label the real VLP-16 scan's points as a numpy
    reference of the convention does, point for point (off the faces)."""
    import json

    scene = tmp_path / "scene"
    (scene / "label").mkdir(parents=True)
    (scene / "lidar").mkdir()
    boxes = [([-0.6, 0.0, 0.1], [2.0, 1.6, 1.2], [0.2, -0.1, 0.6]),
             ([-7.0, 0.0, 0.5], [4.0, 6.0, 3.0], [0.0, 0.0, 0.3])]
    objs = [{"obj_type": "Car", "obj_id": str(i), "psr": {k: dict(zip("xyz", v)) for k, v in
            zip(("position", "scale", "rotation"), b)}} for i, b in enumerate(boxes)]
    (scene / "label" / "000000.json").write_text(json.dumps(objs))
    got = k2.read_boxes(str(scene), "sustechpoints")
    assert got["format"] == "sustechpoints" and got["tracks"] == ["0", "1"]
    frame = got["frames"]["000000"]
    assert frame["file"].endswith("000000.json")
    pts = k2.read_cloud(str(REPO / "fixtures/own_lidar/sequences/00/velodyne/000000.pcd"))["points"][:, :3]
    want = np.zeros(len(pts), np.uint16)
    edge = np.zeros(len(pts), bool)
    for i, (c, s, r) in enumerate(boxes):
        b = frame["boxes"][i]
        rot = _rx_ry_rz(r)
        assert b["class_name"] == "Car" and b["track"] == i
        assert np.allclose(b["centre"], c, atol=1e-5) and np.allclose(b["size"], s, atol=1e-5)
        assert np.allclose(b["rotation"], rot, atol=1e-6)
        q = (pts.astype(np.float64) - c) @ rot
        margin = (np.asarray(s) / 2 - np.abs(q)).min(axis=1)
        edge |= np.abs(margin) < 1e-3
        want[(margin >= 0) & (want == 0)] = i + 1
        b["class"] = 1
        b["instance"] = i + 1
    _, inst = k2.label_points(pts, frame["boxes"])
    assert (want > 0).sum() > 100
    assert np.array_equal(inst[~edge], want[~edge])
    # Boxes drawn in a vehicle frame where the sensor sits 1 m forward, turned 90 degrees.
    moved = k2.read_boxes(str(scene), "sustechpoints", sensor_pose="1,0,0,0,0,90")["frames"]["000000"]["boxes"]
    c = np.asarray(boxes[0][0]) - [1.0, 0.0, 0.0]
    assert np.allclose(moved[0]["centre"], [c[1], -c[0], c[2]], atol=1e-5)
    with pytest.raises(ValueError, match="looks like sustechpoints"):
        k2.read_boxes(str(scene), "supervisely")
    with pytest.raises(ValueError, match="format must be a known name"):
        k2.read_boxes(str(scene), "labelme")


def test_label_points_with_a_class_map_equals_kitti2pgm_label(tmp_path, kitti2pgm_path):
    """Issue 46: the boxes of fixtures/own_boxes (a SUSTechPOINTS scene around the real VLP-16
    scan) labelled from Python with the class map give the .label file `kitti2pgm label` writes,
    class and instance, point for point; unknown types are refused unless unknown_class says."""
    import shutil

    root = tmp_path / "root"
    shutil.copytree(OWN, root)
    boxes = REPO / "fixtures" / "own_boxes"
    subprocess.run([kitti2pgm_path, "--no-progress", "label", str(root), "--boxes", str(boxes)], check=True)
    written = np.fromfile(root / "sequences/00/labels/000000.label", "<u4")
    pts = k2.read_cloud(str(root / "sequences/00/velodyne/000000.pcd"))["points"][:, :3]
    frame = k2.read_boxes(str(boxes), "sustechpoints")["frames"]["000000"]
    cls, inst = k2.label_points(pts, frame["boxes"], class_map="sustechpoints")
    assert len(written) == len(pts) and (cls > 0).sum() > 100
    assert np.array_equal(written & 0xFFFF, cls) and np.array_equal(written >> 16, inst)
    frame["boxes"][0]["class_name"] = "Rider"
    with pytest.raises(ValueError, match="Rider"):
        k2.label_points(pts, frame["boxes"], class_map="sustechpoints")
    cls2, _ = k2.label_points(pts, frame["boxes"], class_map="sustechpoints", unknown_class="background")
    assert (cls2 == 1).sum() < (cls == 1).sum()
    grown, _ = k2.label_points(pts, frame["boxes"], class_map="sustechpoints", unknown_class="car", margin=0.3)
    assert (grown > 0).sum() > (cls > 0).sum()


def test_dataset_reads_a_box_labelled_root_with_its_recorded_class_map(tmp_path, kitti2pgm_path):
    """Issue 46: Dataset on a root labelled by `kitti2pgm label` takes the class map recorded
    beside the labels, as convert does, and its map's label channel holds the boxes' classes."""
    import shutil

    root = tmp_path / "root"
    shutil.copytree(OWN, root)
    subprocess.run([kitti2pgm_path, "--no-progress", "label", str(root), "--boxes",
                    str(REPO / "fixtures" / "own_boxes")], check=True)
    ds = k2.Dataset(str(root), sensor="vlp16", all_frames=True)
    assert ds.class_map["name"] == "sustechpoints"
    m = ds.project(0, cols=1024)["map"]
    labels = m[..., 5][m[..., 4] > 0]
    names = [c["name"] for c in ds.class_map["classes"]]
    assert {names[int(c)] for c in np.unique(labels)} >= {"background", "car", "truck", "pedestrian"}
    # Named explicitly, another map is taken (and SemanticKITTI's does not list ids 2-5).
    with pytest.raises(ValueError, match="learning_map"):
        k2.Dataset(str(root), sensor="vlp16", all_frames=True, class_map="semantic-kitti").project(0, cols=1024)

"""The native module against the converter: `project` gives the bytes `convert` writes, rings are
the converter's, augmentation keeps rings and shifts columns exactly, bad arrays are refused."""

import pathlib
import subprocess
import threading

import kitti2pgm as k2
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
RAW = REPO / "fixtures" / "raw"
SEMANTICKITTI = REPO / "fixtures" / "semantickitti"
OBJECT = REPO / "fixtures" / "kitti_object"
FULL = dict(cols=2048, fov_deg=360.0)


@pytest.fixture()
def converted(kitti2pgm_path):
    """Runs `kitti2pgm convert ROOT --out TMP --format npy EXTRA`; returns TMP/lidar_2d."""
    def run(tmp, root, *extra):
        subprocess.run([kitti2pgm_path, "--no-progress", "convert", str(root), "--out", str(tmp), "--format", "npy",
                        *extra], check=True, capture_output=True)
        return tmp / "lidar_2d"
    return run


def args_of(frame, rgb):
    kw = dict(labels=frame["label"], instance=frame["instance"])
    if rgb:
        kw.update(rgb=frame["rgb"], rgb_valid=frame["rgb_valid"])
    return kw


@pytest.mark.parametrize("rgb,full", [(False, False), (True, False), (False, True), (True, True)])
def test_project_is_the_converters_bytes_on_raw(converted, tmp_path, rgb, full):
    extra = (["--rgb"] if rgb else []) + (["--cols", "2048", "--fov-deg", "360"] if full else [])
    out = converted(tmp_path, RAW, *extra)
    ds = k2.Dataset(RAW, rgb_camera=2 if rgb else None)
    assert len(ds) == 3 and ds.layout == "raw"
    shape = FULL if full else {}
    for fid in ds.frames:
        f = ds.load(fid)
        m = k2.project(f["points"], **args_of(f, rgb), **shape)
        want = np.load(out / f"{fid}.npy")
        assert m["map"].dtype == np.float32 and m["map"].shape == want.shape
        assert m["map"].tobytes() == want.tobytes(), fid
        assert m["channels"] == ["x", "y", "z", "intensity", "range", "label"] + (["r", "g", "b"] if rgb else [])
        assert np.array_equal(m["mask"], want[..., 4] > 0)
        assert np.array_equal(ds.project(fid, **shape)["map"], want)
        # From the file itself, through the reader.
        scan = k2.read_scan(pathlib.Path(str(RAW)) / "2011_09_26" / f"2011_09_26_drive_{fid[11:15]}_sync"
                            / "velodyne_points" / "data" / f"{fid[16:]}.bin")
        assert np.array_equal(scan, f["points"])


def test_project_is_the_converters_bytes_on_semantickitti_and_object(converted, tmp_path):
    out = converted(tmp_path / "sk", SEMANTICKITTI, *["--cols", "2048", "--fov-deg", "360"])
    ds = k2.Dataset(SEMANTICKITTI)
    assert ds.layout == "semantickitti" and len(ds.class_map["classes"]) == 20
    f = ds.load(0)
    m = k2.project(f["points"], labels=f["label"], instance=f["instance"], **FULL)
    assert m["map"].tobytes() == np.load(out / f"{ds.frames[0]}.npy").tobytes()
    # The labels are the learning-mapped raw labels of the kept points.
    raw = k2.read_point_labels(SEMANTICKITTI / "sequences" / "00" / "labels" / "000000.label")
    lut = np.zeros(1 << 16, np.uint8)
    for k, v in ds.class_map["learning_map"].items():
        lut[int(k)] = v
    assert np.array_equal(f["label"], lut[raw[f["file_index"]] & 0xFFFF])
    # (Issue 29) Dataset.project defaults to convert's preset for the source (full here), and
    # project(preset=...) is convert --preset's map; the numbers are the library's one table.
    default = converted(tmp_path / "skd", SEMANTICKITTI)
    assert ds.project(0)["map"].tobytes() == np.load(default / f"{ds.frames[0]}.npy").tobytes()
    rangenet = converted(tmp_path / "skr", SEMANTICKITTI, "--preset", "rangenet")
    got = k2.project(f["points"], labels=f["label"], instance=f["instance"], preset="rangenet")
    assert got["map"].tobytes() == np.load(rangenet / f"{ds.frames[0]}.npy").tobytes()
    assert k2.PRESETS["full"] == {"rows": 64, "cols": 2048, "fov_deg": 360.0, "fov_up_deg": 2.0,
                                  "fov_down_deg": -24.9, "row_mode": "rings"}
    assert k2.project(f["points"])["map"].shape == (64, 512, 6)  # squeezeseg without a source

    out = converted(tmp_path / "obj", OBJECT, "--rgb")
    ds = k2.Dataset(OBJECT, rgb_camera=2)
    for fid in ds.frames:
        f = ds.load(fid)
        m = k2.project(f["points"], **args_of(f, True))
        assert m["map"].tobytes() == np.load(out / f"{fid}.npy").tobytes()


def test_rings_are_the_converters():
    ds = k2.Dataset(RAW)
    for fid in ds.frames:
        f = ds.load(fid)
        r = k2.rings(f["points"])
        assert r is not None and r.dtype == np.uint8 and np.array_equal(r, f["ring"])
        assert r[0] == 0 and r[-1] == k2.LASERS - 1
        m = k2.project(f["points"])
        # Every point in view sits in the row of its ring, and the kept point of a cell is one
        # of them.
        seen = m["row"] >= 0
        assert np.array_equal(m["row"][seen], r[seen].astype(np.int32))
        idx = m["point_index"]
        rows = np.nonzero(idx >= 0)[0]
        assert np.array_equal(r[idx[idx >= 0]], rows.astype(np.uint8))
        assert np.array_equal(m["map"][..., :3][idx >= 0], f["points"][idx[idx >= 0], :3])
        # Given rings give the same map.
        assert np.array_equal(k2.project(f["points"], rings=r)["map"], m["map"])


def test_row_and_col_name_every_points_cell():
    # row and col are split from the cell index by a floating-point multiplication: every kept
    # point's (row, col) is its cell, every point's cell holds a point at least as near, and a
    # point outside the map has (-1, -1); on map widths that are not powers of two too.
    f = k2.Dataset(RAW).load(0)
    rng = np.linalg.norm(f["points"][:, :3], axis=1)
    for rows, cols in ((64, 512), (64, 2048), (7, 1000), (33, 4095), (3, 65535)):
        m = k2.project(f["points"], rows=rows, cols=cols, fov_deg=360.0, row_mode="elevation")
        row, col, idx = m["row"], m["col"], m["point_index"]
        assert row.dtype == col.dtype == np.int32
        out = row < 0
        assert np.array_equal(out, col < 0) and np.all(row[out] == -1) and np.all(col[out] == -1)
        assert np.all((row[~out] < rows) & (col[~out] < cols))
        kept_rows, kept_cols = np.nonzero(idx >= 0)
        kept = idx[idx >= 0]
        assert np.array_equal(row[kept], kept_rows) and np.array_equal(col[kept], kept_cols)
        assert np.all(idx[row[~out], col[~out]] >= 0)
        assert np.all(rng[idx[row[~out], col[~out]]] <= rng[~out])


def test_identity_augmentation_and_one_column_rotation():
    ds = k2.Dataset(RAW)
    f = ds.load(0)
    kw = dict(labels=f["label"], rings=f["ring"])
    for shape in ({}, FULL):
        base = k2.project(f["points"], **kw, **shape)
        same = k2.project(f["points"], **kw, **shape, rotate_deg=0.0, scale=1.0, seed=1234)
        assert same["map"].tobytes() == base["map"].tobytes()
    base = k2.project(f["points"], **kw, **FULL)
    rot = k2.project(f["points"], **kw, **FULL, rotate_deg=360.0 / 2048)
    # z, intensity, range, label move one column to the right-to-left; x, y turn.
    assert np.array_equal(np.roll(base["map"], -1, axis=1)[..., 2:], rot["map"][..., 2:])
    assert np.array_equal(np.roll(base["mask"], -1, axis=1), rot["mask"])
    assert np.array_equal(base["row"], rot["row"]), "a rotation never changes a point's row"
    seen = base["col"] >= 0
    assert np.array_equal((base["col"][seen] - 1) % 2048, rot["col"][seen])
    # A real augmentation: seeded, rows kept, points dropped.
    aug = dict(rotate_deg=37.0, scale=1.05, flip=True, jitter=0.02, drop=0.2, seed=7)
    a = k2.project(f["points"], **kw, **FULL, **aug)
    b = k2.project(f["points"], **kw, **FULL, **aug)
    assert a["map"].tobytes() == b["map"].tobytes()
    kept = a["row"] >= 0
    assert 0.75 < kept.mean() < 0.85
    assert np.array_equal(a["row"][kept], f["ring"][kept].astype(np.int32))


def test_label_points_is_the_converters_labelling():
    ds = k2.Dataset(RAW)
    for fid in ds.frames:
        f = ds.load(fid)
        assert f["boxes"], "fixture frames have cars"
        cls, inst = k2.label_points(f["points"], f["boxes"], background=0)
        assert np.array_equal(cls, f["label"]) and np.array_equal(inst, f["instance"])
    # A box given by yaw: an axis-aligned 2 m cube around (10, 0, 0).
    pts = np.array([[10, 0, 0, 0], [10, 0.9, 0.9, 0], [10, 1.1, 0, 0]], np.float32)
    cls, inst = k2.label_points(pts, [{"centre": [10, 0, 0], "size": [2, 2, 2], "yaw": 0.0, "class": 1}])
    assert cls.tolist() == [1, 1, 0] and inst.tolist() == [1, 1, 0]
    with pytest.raises(ValueError, match="box 0: no 'size'"):
        k2.label_points(pts, [{"centre": [0, 0, 0], "class": 1}])


def test_readers():
    c = k2.read_calibration(RAW / "2011_09_26")
    assert c["velo_to_image"][2].shape == (3, 4) and c["velo_to_cam"].shape == (4, 4)
    assert np.allclose(c["velo_to_image"][2], c["P_rect"][2] @ c["R_rect_00"] @ c["velo_to_cam"])
    t = k2.read_tracklets(RAW / "2011_09_26" / "2011_09_26_drive_0001_sync" / "tracklet_labels.xml")
    assert len(t) > 5 and {"object_type", "h", "w", "l", "first_frame", "poses"} <= set(t[0])
    fc = k2.read_frame_calibration(OBJECT / "training" / "calib" / "000000.txt")
    assert fc["velo_to_image"][2].shape == (3, 4)
    objs = k2.read_object_labels(OBJECT / "training" / "label_2" / "000000.txt")
    assert objs and {"type", "hwl", "location", "rotation_y"} <= set(objs[0])
    assert [c["name"] for c in k2.class_map()["classes"]] == ["background", "car", "pedestrian", "cyclist"]
    pts, index = k2.read_scan(SEMANTICKITTI / "sequences" / "00" / "velodyne" / "000000.bin", with_file_index=True)
    assert pts.shape[1] == 4 and index.shape == (pts.shape[0],)
    with pytest.raises(OSError, match="nothing.bin"):
        k2.read_scan(REPO / "nothing.bin")
    with pytest.raises(KeyError):
        k2.Dataset(RAW).load("2011_09_26_0001_9999999999")
    with pytest.raises(ValueError, match="dataset must be a known name"):
        k2.Dataset(RAW, dataset="lidar")
    with pytest.raises(ValueError, match="dataset must be a known name"):
        k2.Dataset(RAW, source="lidar")
    with pytest.raises(ValueError, match="one option"):
        k2.Dataset(RAW, dataset="raw", source="raw")
    assert k2.Dataset(RAW, source="raw").frames == k2.Dataset(RAW, dataset="raw").frames


def test_bad_arrays_raise_clear_value_errors():
    f = k2.Dataset(RAW).load(0)
    pts = f["points"]
    n = len(pts)
    cases = [
        (pts[:, :3], {}, r"points must be a float32 array of shape \(N, 4\).*shape \(%d, 3\)" % n),
        (pts.astype(np.complex64), {}, "points must be a float32 array.*got a complex64 array"),
        (pts.tolist(), {}, "points must be a float32 array.*list"),
        (pts, {"labels": f["label"][:-1]}, r"labels must be a uint8 array of shape \(%d,\)" % n),
        (pts, {"labels": f["label"].astype(np.float32)}, "labels must be a uint8 array"),
        (pts, {"labels": np.full(n, 300, np.int64)}, r"labels holds 300, which does not fit uint8"),
        (pts, {"labels": np.full(n, -1, np.int16)}, r"labels holds -1, which does not fit uint8"),
        (pts, {"rings": np.full(n, 64, np.uint8)}, "ring 64 of point 0 is not below 64"),
        (pts, {"rgb": np.zeros((n, 4), np.float32)}, r"rgb must be a float32 array of shape \(%d, 3\)" % n),
        # (Issue 26) colours are what convert --rgb samples: [0, 1].
        (pts, {"rgb": np.full((n, 3), 1e30, np.float32)},
         r"rgb: value 1e30 \(point 0, channel r\) is outside \[0, 1\]"),
        (pts, {"rgb": np.full((n, 3), -7, np.float32)}, r"rgb: value -7 \(point 0, channel r\)"),
        (pts, {"cols": 0}, "map size 64x0 is out of range"),
        (pts, {"fov_deg": 400.0}, "FOV 400"),
        (pts, {"drop": 1.0}, r"drop 1 must be in \[0, 1\)"),
        (pts, {"row_mode": "bins"}, "row_mode must be"),
    ]
    for p, kw, msg in cases:
        with pytest.raises(ValueError, match=msg):
            k2.project(p, **kw)
    bad = pts.copy()
    bad[5, 1] = np.nan
    with pytest.raises(ValueError, match="point 5 is not finite"):
        k2.project(bad)
    bad = pts.copy()
    bad[9, 3] = np.inf
    with pytest.raises(ValueError, match="intensity of point 9 is inf, outside"):
        k2.project(bad)
    # A non-contiguous view is read correctly (one copy), not refused.
    wide = np.zeros((n, 8), np.float32)
    wide[:, :4] = pts
    assert np.array_equal(k2.project(wide[:, :4])["map"], k2.project(pts)["map"])


def test_fortran_ordered_and_transposed_arrays_read_in_their_logical_order():
    """(Issue 18) Fortran-ordered points, (4, N).T and strided colours give exactly what the
    C-ordered arrays give, in project, label_points and rings."""
    ds = k2.Dataset(RAW, rgb_camera=2)
    f = ds.load(0)
    pts = f["points"]
    want = k2.project(pts, **args_of(f, True))
    want_cls, want_inst = k2.label_points(pts, f["boxes"], background=0)
    want_rings = k2.rings(pts)
    assert want_rings is not None
    for p in (np.asfortranarray(pts), np.ascontiguousarray(pts.T).T):
        assert not p.flags.c_contiguous
        got = k2.project(p, labels=np.asfortranarray(f["label"]), instance=f["instance"],
                         rgb=np.asfortranarray(f["rgb"]), rgb_valid=f["rgb_valid"])
        assert got["map"].tobytes() == want["map"].tobytes()
        assert np.array_equal(got["row"], want["row"]) and np.array_equal(got["col"], want["col"])
        cls, inst = k2.label_points(p, f["boxes"], background=0)
        assert np.array_equal(cls, want_cls) and np.array_equal(inst, want_inst)
        assert np.array_equal(k2.rings(p), want_rings)


def test_maps_stay_finite_and_bad_options_are_refused():
    """(Issue 18) The converter's range rules apply to project(): points beyond 500 m, intensity
    outside 0..1 and absurd augmentation options are refused, never written as inf."""
    f = k2.Dataset(RAW).load(0)
    pts = f["points"]
    far = pts.copy()
    far[3, 0] = 1e20
    with pytest.raises(ValueError, match="point 3 is not finite or beyond 500 m"):
        k2.project(far)
    bright = pts.copy()
    bright[4, 3] = 1e30
    with pytest.raises(ValueError, match="intensity of point 4 is 1e30, outside"):
        k2.project(bright)
    for kw, msg in [({"scale": 1e38}, "scale 1e38 must be in"), ({"jitter": 1e30}, "jitter 1e30 must be in"),
                    ({"scale": float("nan")}, "scale NaN must be in"), ({"fov_up_deg": float("inf")}, "fov-up inf"),
                    ({"fov_down_deg": -1e300}, "fov-down -1e300"), ({"rotate_deg": float("inf")}, "not finite")]:
        with pytest.raises(ValueError, match=msg):
            k2.project(pts, **kw)
    m = k2.project(pts, scale=1.1, jitter=0.05, seed=1)["map"]
    assert np.isfinite(m).all()


def test_wild_boxes_are_refused_not_hung():
    """(Issue 18) A NaN, inf or 1e200 rotation (nalgebra's nearest-rotation search never
    converged on them, with the GIL released) and NaN yaws or sizes beyond float32 are refused."""
    pts = np.array([[10, 0, 0, 0]], np.float32)
    box = {"centre": [10, 0, 0], "size": [2, 2, 2], "class": 1}
    for rot, msg in [([[np.nan] * 3] * 3, "holds a non-finite"),
                     ([[np.inf, 0, 0], [0, 1, 0], [0, 0, 1]], "holds a non-finite"),
                     ([[1e200] * 3] * 3, "is not a rotation"), ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "is a reflection")]:
        with pytest.raises(ValueError, match="box 0: rotation " + msg):
            k2.label_points(pts, [dict(box, rotation=rot)])
    with pytest.raises(ValueError, match="yaw must be finite"):
        k2.label_points(pts, [dict(box, yaw=float("nan"))])
    with pytest.raises(ValueError, match="not finite in single precision"):
        k2.label_points(pts, [dict(box, size=[1e39, 1, 1], yaw=0.0)])
    # (Issue 26) The bounds of every box source: positive, at most MAX_BOX_EXTENT_M.
    with pytest.raises(ValueError, match="l=1e38 m is implausible"):
        k2.label_points(pts, [dict(box, size=[1e38, 1, 1], yaw=0.0)])
    with pytest.raises(ValueError, match="must be positive, found w=0"):
        k2.label_points(pts, [dict(box, size=[1, 0, 1], yaw=0.0)])
    cls, _ = k2.label_points(pts, [dict(box, rotation=np.eye(3).tolist())])
    assert cls.tolist() == [1]


def test_a_class_map_that_cannot_label_the_source_is_refused():
    with pytest.raises(ValueError, match="has no rule for the annotations"):
        k2.Dataset(RAW, class_map="semantic-kitti")


def test_one_dtype_rule_and_one_vocabulary():
    """(Issue 20) Numeric arrays convert by one rule (float64 points, int64 labels that fit);
    Dataset indexes, iterates and projects to the same dict as project(); class maps go by the
    names outputs record; paths may be str or Path."""
    ds = k2.Dataset(str(RAW))
    assert len(ds) == 3 and [f["id"] for f in ds] == ds.frames
    f = ds[0]
    assert ds[ds.frames[0]]["id"] == f["id"] and ds[-1]["id"] == ds.frames[-1]
    with pytest.raises(IndexError):
        ds[3]
    want = k2.project(f["points"], labels=f["label"], instance=f["instance"])
    got = k2.project(f["points"].astype(np.float64), labels=f["label"].astype(np.int64),
                     instance=f["instance"].astype(np.int32))
    assert got["map"].tobytes() == want["map"].tobytes()
    d = ds.project(0)
    assert set(d) == set(want) and d["map"].tobytes() == want["map"].tobytes()
    # (Issue 29) One name for the colour arrays: rgb / rgb_valid, the shards' and Dataset.load's.
    c = k2.Dataset(RAW, rgb_camera=2)[0]
    assert "colours" not in c and c["rgb"].shape == (len(c["points"]), 3)
    a = k2.project(c["points"], rgb=c["rgb"], rgb_valid=c["rgb_valid"])
    assert a["channels"][-3:] == ["r", "g", "b"]
    with pytest.raises(TypeError, match="colours"):
        k2.project(c["points"], colours=c["rgb"])
    assert k2.class_map("kitti-paper-4")["name"] == "kitti-paper-4"
    assert k2.class_map("semantic-kitti")["name"] == "semantic-kitti"
    assert k2.Dataset(RAW, class_map="kitti-paper-4").class_map["name"] == "kitti-paper-4"
    import inspect
    sig = str(inspect.signature(k2.project))
    # (Issue 29) The map keywords default to the preset's values: no number is written twice.
    assert "preset=None" in sig and "fov_down_deg=None" in sig and "Ellipsis" not in sig, sig
    assert "preset=None" in str(inspect.signature(k2.Dataset.project))


def test_a_dataset_without_frames_says_why(tmp_path):
    root = tmp_path / "2011_09_26" / "2011_09_26_drive_0001_sync" / "velodyne_points" / "data"
    root.mkdir(parents=True)
    with pytest.raises(ValueError, match="no frame to load"):
        k2.Dataset(tmp_path)


def test_threads_get_the_same_maps():
    f = k2.Dataset(RAW).load(0)
    want = k2.project(f["points"], **FULL)["map"]
    got = [None] * 4

    def work(i):
        got[i] = k2.project(f["points"], **FULL)["map"]

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(np.array_equal(g, want) for g in got)


@pytest.mark.parametrize("threads", [2, 3, 8])
def test_threads_inside_one_call_give_the_same_arrays(threads):
    f = k2.Dataset(RAW).load(0)
    for opts in [FULL, {}, dict(FULL, rotate_deg=30.0, jitter=0.01, drop=0.1, seed=4)]:
        one = k2.project(f["points"], labels=f["label"], **opts)
        many = k2.project(f["points"], labels=f["label"], threads=threads, **opts)
        for key, v in one.items():
            if isinstance(v, np.ndarray):
                assert many[key].dtype == v.dtype and np.array_equal(many[key], v), (key, opts)
        assert many["stats"] == one["stats"]
    with pytest.raises(ValueError, match="threads must be at least 1"):
        k2.project(f["points"], threads=0)


def test_point_shards_project_to_the_converters_maps(tmp_path, kitti2pgm_path):
    from kitti2pgm_data import ShardDataset, ShardReader, iter_frames

    subprocess.run([kitti2pgm_path, "--no-progress", "convert", str(RAW), "--out", str(tmp_path), "--format",
                    "npy,points", "--rgb", "--val-drives", "52"], check=True, capture_output=True)
    shards = sorted((tmp_path / "points").glob("*.mcap"))
    assert [p.name for p in shards] == ["train-00000.mcap", "val-00000.mcap"]
    with ShardReader(shards[0]) as r:
        assert r.kind == "points" and len(r) == 2
    ds = ShardDataset(shards)
    assert len(ds) == 3
    for i in range(len(ds)):
        f = ds[i]
        assert f["points"].dtype == np.float32 and f["points"].shape == (f["count"], 4)
        m = k2.project(f["points"], rings=f["ring"], labels=f["label"], instance=f["instance"],
                       rgb=f["rgb"], rgb_valid=f["rgb_valid"].astype(bool))
        want = np.load(tmp_path / "lidar_2d" / f"{f['id']}.npy")
        assert m["map"].tobytes() == want.tobytes(), f["id"]
    assert [f["id"] for f in iter_frames(shards)] == [ds[i]["id"] for i in range(3)]


def test_fuzzed_array_inputs_raise_value_errors_or_give_finite_maps():
    """A seeded mutation run over the module's array inputs (dtype, shape, memory order, wild
    values): every call either raises ValueError naming an argument or returns a finite map.
    KITTI2PGM_FUZZ_ROUNDS runs it longer."""
    import os

    rng = np.random.default_rng(2026)
    f = k2.Dataset(RAW).load(0)
    base = f["points"][:5000]
    n = len(base)
    wild = [np.nan, np.inf, -np.inf, 1e30, -1e30, 1e20, 600.0, -1.0, 2.0, 0.0]
    for _ in range(int(os.environ.get("KITTI2PGM_FUZZ_ROUNDS", "60"))):
        p = base.copy()
        for _ in range(int(rng.integers(0, 4))):
            p[rng.integers(0, n), rng.integers(0, 4)] = wild[rng.integers(0, len(wild))]
        choice = rng.integers(0, 6)
        if choice == 0:
            p = np.asfortranarray(p)
        elif choice == 1:
            with np.errstate(all="ignore"):
                p = p.astype([np.float64, np.float16, np.int32][rng.integers(0, 3)])
        elif choice == 2:
            p = p[:, : int(rng.integers(1, 5))]
        elif choice == 3:
            p = p[:: int(rng.integers(1, 4))]
        elif choice == 4:
            p = np.ascontiguousarray(p.T).T
        kw = {}
        if rng.random() < 0.5:
            kw["labels"] = rng.integers(0, 4, len(p)).astype([np.uint8, np.int64][rng.integers(0, 2)])
        if rng.random() < 0.3:
            kw["rings"] = rng.integers(0, 70, len(p)).astype(np.uint8)
        if rng.random() < 0.3:
            kw["scale"] = float([1.05, 0.0, -1.0, 1e38, np.nan][rng.integers(0, 5)])
        if rng.random() < 0.3:
            kw["jitter"] = float([0.01, -0.1, 1e30, np.inf][rng.integers(0, 4)])
        try:
            m = k2.project(p, **kw)
        except ValueError as e:
            assert str(e), "a ValueError says what is wrong"
            continue
        assert np.isfinite(m["map"]).all()
        assert m["map"].shape[:2] == (64, 512)
        try:
            cls, _ = k2.label_points(p, f["boxes"], background=0)
        except ValueError:
            continue
        assert len(cls) == len(p)


def test_type_stubs_ship_with_the_module():
    """kitti2pgm.pyi and py.typed are installed beside the module, and the stub names every
    public function and the Dataset's methods."""
    import os

    here = os.path.dirname(k2.__file__)
    assert os.path.exists(os.path.join(here, "py.typed"))
    stub = open(os.path.join(here, "__init__.pyi")).read()
    for name in ["def project(", "def rings(", "def label_points(", "def read_scan(", "def class_map(",
                 "class Dataset", "def __getitem__", "def __iter__", "rgb_valid"]:
        assert name in stub, name
    public = [n for n in dir(k2) if not n.startswith("_") and callable(getattr(k2, n))]
    for n in public:
        assert f"def {n}(" in stub or f"class {n}" in stub or n == "DatasetIter", n


def test_knn_unprojection_refuses_a_range_channel_that_is_not_ranges():
    """(Issue 26) A NaN or negative cell_range would vote with garbage weights."""
    f = k2.Dataset(RAW).load(0)
    m = k2.project(f["points"], labels=f["label"])
    pred = m["label"]
    rng = m["map"][..., 4].copy()
    labels = k2.unproject(pred, m["row"], m["col"], f["points"], rng, method="knn", class_map="kitti-paper-4")
    assert len(labels) == len(f["points"])
    for bad, what in ((np.nan, "NaN"), (-1.0, "-1")):
        r = rng.copy()
        r[3, 7] = bad
        with pytest.raises(ValueError, match=r"cell_range: value %s at cell \(3, 7\) is not a range" % what):
            k2.unproject(pred, m["row"], m["col"], f["points"], r, method="knn", class_map="kitti-paper-4")


def test_point_predictions_are_written_where_and_as_unproject_writes_them(tmp_path):
    """(Issue 29) The prediction layout and raw-id mapping have one owner, the library: the
    module writes what `kitti2pgm unproject` writes."""
    assert k2.point_prediction_path(tmp_path, "00_000007") == (
        tmp_path / "sequences" / "00" / "predictions" / "000007.label")
    assert k2.point_prediction_path(tmp_path, "2011_09_26_0001_0000000010") == (
        tmp_path / "labels" / "2011_09_26_drive_0001_sync" / "0000000010.label")
    sk = k2.class_map("semantic-kitti")
    car = [c["name"] for c in sk["classes"]].index("car")
    path, missing = k2.write_point_predictions(tmp_path, "00_000007", np.array([car, -1, 0]),
                                               class_map="semantic-kitti")
    assert missing == 1
    raw = np.fromfile(path, "<u4")
    assert raw.tolist() == [sk["learning_map_inv"][car], 0, sk["learning_map_inv"][0]]
    path, _ = k2.write_point_predictions(tmp_path, "000042", np.array([1, -1]), class_map="kitti-paper-4")
    assert np.fromfile(path, "<u4").tolist() == [1, 0xFFFF]
    with pytest.raises(ValueError, match="point 0 has class 9"):
        k2.write_point_predictions(tmp_path, "000042", np.array([9]), class_map="kitti-paper-4")
    with pytest.raises(ValueError, match="not a frame id"):
        k2.write_point_predictions(tmp_path, "frame7", np.array([1]), class_map="kitti-paper-4")


def test_every_reading_function_gives_the_same_points_of_one_file(tmp_path):
    """Issue 49: a KITTI .bin with two reflectances outside 0-1 gave 114,278 points through
    read_cloud and 114,276 through read_scan and the converter; KITTI's drop rule is now the one
    rule of its source, whichever function reads it."""
    drive = pathlib.Path(__file__).resolve().parents[3] / "fixtures/raw/2011_09_26/2011_09_26_drive_0001_sync"
    src = drive / "velodyne_points/data/0000000000.bin"
    raw = np.fromfile(src, dtype="<f4").reshape(-1, 4).copy()
    raw[100, 3], raw[2000, 3] = 1.5, -0.5
    path = tmp_path / "0000000000.bin"
    raw.tofile(path)
    keep = np.ones(len(raw), bool)
    keep[[100, 2000]] = False
    cloud = k2.read_cloud(str(path))
    pts, index = k2.read_scan(str(path), with_file_index=True)
    assert cloud["file_points"] == len(raw) and cloud["dropped"] == 2
    assert np.array_equal(cloud["points"], raw[keep]) and np.array_equal(pts, raw[keep])
    assert np.array_equal(cloud["file_index"], np.flatnonzero(keep)) and np.array_equal(index, cloud["file_index"])

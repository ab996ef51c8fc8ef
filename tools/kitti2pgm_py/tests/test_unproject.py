"""Map predictions back to points: `kitti2pgm.unproject` against an independent numpy version of
RangeNet++'s kNN post-processing (lidar-bonnetal postproc/KNN.py, read and re-derived: unfold a
window around each point's cell, zero padding, empty cells at infinite range, the centre at the
point's own range, |range difference| x (1 - normalised Gaussian), the k smallest, cutoff votes
for nobody, argmax over the classes but 0 and "nobody"), point for point on the real
SemanticKITTI scan; and the cell method against the converter's own per-point labels."""

import pathlib

import kitti2pgm as k2
import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]
SEMANTICKITTI = REPO / "fixtures" / "semantickitti"


def knn_reference(proj_range, unproj_range, proj_argmax, px, py, k, search, sigma, cutoff, nclasses):
    """RangeNet++'s kNN in numpy. proj_range: (H, W), -1 for empty cells; unproj_range: (N,);
    proj_argmax: (H, W) class ids; px, py: (N,) columns and rows. Ties among equal distances go
    to the earlier window cell (a stable sort; torch.topk leaves them unspecified)."""
    pad = (search - 1) // 2
    rng = np.pad(proj_range.astype(np.float32), pad, constant_values=0)
    arg = np.pad(proj_argmax.astype(np.int64), pad, constant_values=0)
    dy, dx = np.divmod(np.arange(search * search), search)
    win_r = rng[py[:, None] + dy[None, :], px[:, None] + dx[None, :]]
    win_a = arg[py[:, None] + dy[None, :], px[:, None] + dx[None, :]]
    win_r[win_r < 0] = np.inf
    centre = (search * search - 1) // 2
    win_r[:, centre] = unproj_range
    # The Gaussian kernel over the window, normalised to 1 (double, rounded to single).
    mean, var = (search - 1) / 2.0, sigma ** 2
    g = (1.0 / (2 * np.pi * var)) * np.exp(-((dx - mean) ** 2 + (dy - mean) ** 2) / (2 * var))
    inv = np.float32(1) - (g / g.sum()).astype(np.float32)
    d = np.abs(win_r - unproj_range[:, None].astype(np.float32)) * inv[None, :]
    order = np.argsort(d, axis=1, kind="stable")[:, :k]
    chosen_d = np.take_along_axis(d, order, axis=1)
    votes = np.take_along_axis(win_a, order, axis=1)
    if cutoff > 0:
        votes[chosen_d > cutoff] = nclasses
    counts = np.zeros((len(px), nclasses + 1), np.int64)
    np.add.at(counts, (np.arange(len(px))[:, None], votes), 1)
    return counts[:, 1:-1].argmax(axis=1) + 1


@pytest.fixture(scope="module")
def scan():
    ds = k2.Dataset(SEMANTICKITTI)
    return ds[0]


def noisy(label_map, share, seed):
    rng = np.random.default_rng(seed)
    pred = label_map.copy()
    flip = rng.random(pred.shape) < share
    pred[flip] = rng.integers(0, 20, flip.sum())
    return pred


@pytest.mark.parametrize("shape", [dict(cols=2048, fov_deg=360.0),
                                   dict(cols=2048, fov_deg=360.0, row_mode="elevation", fov_up_deg=3.0,
                                        fov_down_deg=-25.0),
                                   dict(cols=512, fov_deg=90.0)])
@pytest.mark.parametrize("params", [dict(k=5, window=5, sigma=1.0, cutoff=1.0),
                                    dict(k=3, window=3, sigma=0.7, cutoff=0.5),
                                    dict(k=7, window=7, sigma=2.0, cutoff=0.0),
                                    dict(k=4, window=5, sigma=1.5, cutoff=2.0)])  # the general path
def test_knn_equals_the_reference_point_for_point(scan, shape, params):
    pts = scan["points"]
    m = k2.project(pts, labels=scan["label"], **shape)
    pred = noisy(m["label"], 0.3, seed=len(shape) + params["k"])
    cell_range = m["map"][..., 4]
    got = k2.unproject(pred, m["row"], m["col"], pts, cell_range, method="knn", **params)
    inside = m["row"] >= 0
    assert (got[~inside] == -1).all() and (got[inside] >= 1).all()
    proj_range = np.where(m["mask"], cell_range, -1.0).astype(np.float32)
    rng = np.sqrt(pts[:, 0] * pts[:, 0] + pts[:, 1] * pts[:, 1] + pts[:, 2] * pts[:, 2])
    want = knn_reference(proj_range, rng[inside], pred, m["col"][inside], m["row"][inside],
                         params["k"], params["window"], params["sigma"], params["cutoff"], 20)
    diff = np.flatnonzero(got[inside] != want)
    assert diff.size == 0, f"{diff.size} of {inside.sum()} points differ, first {diff[:5]}"


def test_knn_repairs_noise_and_cell_gives_each_point_its_cells_class(scan):
    pts = scan["points"]
    m = k2.project(pts, labels=scan["label"], cols=2048, fov_deg=360)
    truth = m["label"]
    # The ground-truth map unprojected by cell: the converter's label of every point that won
    # its cell.
    cell = k2.unproject(truth, m["row"], m["col"], pts, method="cell")
    inside = m["row"] >= 0
    won = np.zeros(len(pts), bool)
    idx = m["point_index"][m["mask"]]
    won[idx] = True
    assert np.array_equal(cell[won], scan["label"][won])
    assert (cell[~inside] == -1).all()
    # kNN of a noisy map agrees with the points' labels more often than the cell method does.
    pred = noisy(truth, 0.2, seed=3)
    by_cell = k2.unproject(pred, m["row"], m["col"], pts, method="cell")
    by_knn = k2.unproject(pred, m["row"], m["col"], pts, m["map"][..., 4], method="knn")
    scored = inside & (scan["label"] != 0)

    def acc(p):
        return (p[scored] == scan["label"][scored]).mean()

    assert acc(by_knn) > acc(by_cell) + 0.05, (acc(by_knn), acc(by_cell))
    # Wrapping the seam changes only points near the left and right edges.
    wrapped = k2.unproject(pred, m["row"], m["col"], pts, m["map"][..., 4], method="knn", wrap_columns=True)
    changed = np.flatnonzero(wrapped != by_knn)
    assert ((m["col"][changed] < 3) | (m["col"][changed] > 2044)).all()


def test_bad_inputs_are_named(scan):
    pts = scan["points"]
    m = k2.project(pts, cols=2048, fov_deg=360)
    pred = m["label"]
    with pytest.raises(ValueError, match="needs cell_range"):
        k2.unproject(pred, m["row"], m["col"], pts, method="knn")
    # (Issue 29) The default method is the CLI's: knn, which needs the range channel.
    with pytest.raises(ValueError, match="method 'knn' needs cell_range"):
        k2.unproject(pred, m["row"], m["col"], pts)
    with pytest.raises(ValueError, match="window 4 must be odd"):
        k2.unproject(pred, m["row"], m["col"], pts, m["map"][..., 4], method="knn", window=4)
    with pytest.raises(ValueError, match="cell_range is 64x512, pred is 64x2048"):
        k2.unproject(pred, m["row"], m["col"], pts, np.zeros((64, 512), np.float32), method="knn")
    bad = pred.copy()
    bad[0, 0] = 20
    with pytest.raises(ValueError, match=r"cell \(0, 0\) is predicted as class 20"):
        k2.unproject(bad, m["row"], m["col"], pts, method="cell")
    with pytest.raises(ValueError, match="outside the 64x512 prediction"):
        k2.unproject(pred[:, :512], m["row"], m["col"], pts, method="cell")
    with pytest.raises(ValueError, match="row must be a int32 array of shape"):
        k2.unproject(pred, m["row"][:-1], m["col"], pts)
    with pytest.raises(ValueError, match="method must be"):
        k2.unproject(pred, m["row"], m["col"], pts, method="nearest")


def test_cells_emptied_under_their_points_and_an_empty_map(scan):
    """A range channel that is not the map's own (every seventh cell emptied under its points)
    still puts each point's own cell at distance 0, as the reference does (the lane kernels put
    it at NaN once); a map without columns holds no point, the seam wrapped or not."""
    pts = scan["points"]
    m = k2.project(pts, labels=scan["label"], cols=2048, fov_deg=360)
    pred = noisy(m["label"], 0.3, seed=7)
    cell_range = np.ascontiguousarray(m["map"][..., 4])
    cell_range.reshape(-1)[::7] = 0.0
    got = k2.unproject(pred, m["row"], m["col"], pts, cell_range, method="knn")
    inside = m["row"] >= 0
    proj_range = np.where(cell_range > 0, cell_range, -1.0).astype(np.float32)
    rng = np.sqrt(pts[:, 0] * pts[:, 0] + pts[:, 1] * pts[:, 1] + pts[:, 2] * pts[:, 2])
    want = knn_reference(proj_range, rng[inside], pred, m["col"][inside], m["row"][inside], 5, 5, 1.0, 1.0, 20)
    assert np.array_equal(got[inside], want)
    none = np.full(3, -1, np.int32)
    for wrap in (False, True):
        got = k2.unproject(np.zeros((4, 0), np.uint8), none, none, pts[:3], np.zeros((4, 0), np.float32),
                           method="knn", wrap_columns=wrap)
        assert (got == -1).all()

"""quarry's point-cloud bindings against scikit-learn (MeanShift), numpy (closed-form rigid fit,
the peers' per-beam chi-square test) and bench-data's ground truth (ICP transforms, laser
labels)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from sklearn.cluster import MeanShift as SkMeanShift

import quarry


def partition(labels):
    """A clustering as a set of frozensets of point indices (noise left out)."""
    out = {}
    for i, l in enumerate(labels):
        if l >= 0:
            out.setdefault(int(l), set()).add(i)
    return {frozenset(v) for v in out.values()}


def test_mean_shift_matches_sklearn(bench_data):
    d = np.genfromtxt(bench_data / "meanshift_points.csv", delimiter=",", names=True)
    pts = np.column_stack([d["x"], d["y"]])
    for seeding, sk_bins in (("bins", True), ("all", False)):
        labels, modes, sizes = quarry.mean_shift(pts, bandwidth=0.3, seeding=seeding)
        sk = SkMeanShift(bandwidth=0.3, bin_seeding=sk_bins).fit(pts)
        assert len(modes) == len(sk.cluster_centers_) == len(set(d["person"].astype(int)))
        assert partition(labels) == partition(sk.labels_)
        # the same modes, in some order
        dist = np.linalg.norm(modes[:, None] - sk.cluster_centers_[None], axis=2)
        assert dist.min(axis=1).max() < 0.01
        assert sizes.sum() == (labels >= 0).sum()
    # and the people of the ground truth
    assert partition(labels) == partition(d["person"].astype(int))


@settings(max_examples=40, deadline=None)
@given(st.integers(3, 40), st.floats(-3.0, 3.0), st.floats(-5, 5), st.floats(-5, 5), st.integers(0, 2**32 - 1))
def test_rigid_transform_matches_kabsch(n, theta, tx, ty, seed):
    rng = np.random.default_rng(seed)
    src = rng.normal(size=(n, 2))
    R = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    dst = src @ R.T + [tx, ty] + rng.normal(0, 0.01, (n, 2))
    x, y, th = quarry.rigid_transform_2d(src, dst)
    # Kabsch / Umeyama without scale, numpy SVD
    ms, md = src.mean(0), dst.mean(0)
    U, _, Vt = np.linalg.svd((src - ms).T @ (dst - md))
    D = np.diag([1, np.sign(np.linalg.det(Vt.T @ U.T))])
    Rk = Vt.T @ D @ U.T
    tk = md - Rk @ ms
    assert math.atan2(Rk[1, 0], Rk[0, 0]) == pytest.approx(th, abs=1e-9) or abs(abs(th) - math.pi) < 1e-9
    np.testing.assert_allclose([x, y], tk, atol=1e-9)


def test_icp_recovers_bench_transforms(bench_data):
    model = np.genfromtxt(bench_data / "icp_model.csv", delimiter=",", skip_header=1)
    obs = np.genfromtxt(bench_data / "icp_observed.csv", delimiter=",", skip_header=1)
    tr = np.genfromtxt(bench_data / "icp_transforms.csv", delimiter=",", names=True)
    ok = 0
    for t in tr:
        data = obs[obs[:, 0] == t["trial"], 1:]
        init = (t["init_tx"], t["init_ty"], math.radians(t["init_theta_deg"]))
        r = quarry.icp_2d(model, np.ascontiguousarray(data), init=init, preset="contour")
        x, y, th = r["pose"]
        rot_err = abs((th - math.radians(t["theta_deg"]) + math.pi) % (2 * math.pi) - math.pi)
        ok += rot_err < math.radians(2) and math.hypot(x - t["tx"], y - t["ty"]) < 0.02
        assert r["rms"] < 0.05 and r["inliers"] > 0
    print(f"ICP contour preset: {ok}/{len(tr)} trials within 2 deg / 2 cm (Open3D point-to-point: 11/20)")
    assert ok >= 11  # at least Open3D's success on the same trials (docs/PERFORMANCE.md)


def test_icp_exact_on_noiseless_contour():
    a = np.radians(np.arange(0, 360, 10))
    model = np.column_stack([0.25 * np.cos(a), 0.15 * np.sin(a)])
    th, tx, ty = 0.3, 1.0, -2.0
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    data = model @ R.T + [tx, ty]
    r = quarry.icp_2d(model, data, init=(0.97, -1.97, 0.25), preset="contour", rms_stop=0.0,
                      delta_stop=1e-12, max_iter=500)
    np.testing.assert_allclose(r["pose"], (tx, ty, th), atol=1e-6)


def laser(bench_data):
    sensors = np.genfromtxt(bench_data / "laser_sensors.csv", delimiter=",", names=True)
    bg = np.genfromtxt(bench_data / "laser_background.csv", delimiter=",", skip_header=1)
    cur = np.genfromtxt(bench_data / "laser_scan.csv", delimiter=",", names=True)
    return sensors, bg, cur


def test_variance_chi2_matches_the_numpy_peer(bench_data):
    """peers/bench_chi2.py's numpy test, computed here, and quarry's on the same window."""
    _, bg, cur = laser(bench_data)
    W = np.stack([bg[bg[:, 0] == k, 2:].reshape(-1) for k in range(20)])
    r = cur["range"].copy()
    mu = W.mean(0)
    s2 = np.maximum(W.var(0, ddof=1), 0.005**2)
    ref = ((r - mu) ** 2 / s2 > 10.83) & (r - mu < 0)
    t = quarry.VarianceChi2Test(W, min_sigma=0.005, threshold=10.83)
    np.testing.assert_array_equal(t.test(r), ref)
    truth = cur["label"] >= 0
    assert np.sum(ref & truth) == truth.sum()  # recall 1 (the peer's figure)
    t.push(r)  # the window moves: the people are no longer that far from it
    assert t.test(r).sum() < ref.sum()


def test_chi_square_background_finds_the_people(bench_data):
    """The paper's model (window 20, no long-term background) fed the 20 empty-room scans then
    the scan with 5 people, per sensor: precision and recall of the dynamic beams."""
    sensors, bg, cur = laser(bench_data)
    tp = fp = fn = 0
    for s in sensors:
        k = int(s["sensor"])
        model = quarry.ChiSquareBackground(int(s["nbeams"]), math.radians(-135.0), math.radians(0.25),
                                           window=20, long_term=False)
        rows = bg[bg[:, 1] == k]
        for i, row in enumerate(rows[np.argsort(rows[:, 0])]):
            model.classify(np.ascontiguousarray(row[2:]), t=0.025 * i)
        sel = cur[cur["sensor"] == k]
        labels = model.classify(np.ascontiguousarray(sel["range"]), t=0.025 * 20)
        truth = sel["label"] >= 0
        dyn = labels == 1
        tp += int(np.sum(dyn & truth))
        fp += int(np.sum(dyn & ~truth))
        fn += int(np.sum(~dyn & truth))
    print(f"chi-square background: precision {tp / (tp + fp):.4f}, recall {tp / (tp + fn):.4f}")
    assert tp / (tp + fn) > 0.95 and tp / (tp + fp) > 0.95


def test_cloud_errors_name_the_argument():
    with pytest.raises(ValueError, match="points"):
        quarry.mean_shift(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="points"):
        quarry.mean_shift(np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match="bandwidth"):
        quarry.mean_shift(np.zeros((5, 2)), bandwidth=-1.0)
    with pytest.raises(ValueError, match="kernel"):
        quarry.mean_shift(np.zeros((5, 2)), kernel="box")
    assert len(quarry.mean_shift(np.zeros((0, 2)))[1]) == 0
    with pytest.raises(ValueError, match="data"):
        quarry.icp_2d(np.zeros((5, 2)), np.zeros((0, 2)))
    with pytest.raises(ValueError, match="preset"):
        quarry.icp_2d(np.zeros((5, 2)), np.zeros((5, 2)), preset="fast")
    with pytest.raises(ValueError, match="dst"):
        quarry.rigid_transform_2d(np.zeros((5, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="ranges"):
        quarry.ChiSquareBackground(10, 0.0, 0.1).classify(np.zeros(9), 0.0)
    with pytest.raises(ValueError, match="t"):
        quarry.ChiSquareBackground(10, 0.0, 0.1).classify(np.zeros(10), math.nan)
    with pytest.raises(ValueError, match="n_beams"):
        quarry.ChiSquareBackground(0, 0.0, 0.1)
    # sizes that would exhaust memory (and abort the interpreter) are refused up front
    with pytest.raises(ValueError, match="n_beams"):
        quarry.ChiSquareBackground(2**31 - 1, 0.0, 1e-9)
    with pytest.raises(ValueError, match="window"):
        quarry.ChiSquareBackground(10, 0.0, 0.1, window=2**40)
    with pytest.raises(ValueError, match="window"):
        quarry.VarianceChi2Test(np.zeros((1, 5)))

"""Times quarry's Python bindings and the libraries Python users have, side by side in one run,
on the ../shared/bench-data inputs (the same workloads as ../shared/peers/bench_*.py).

Usage (the quarry-py test venv has every peer; see docs/PERFORMANCE.md for the full command):
  cargo build --release -p quarry-py && mkdir -p /tmp/qrel && cp target/release/libquarry_py.so /tmp/qrel/quarry.so
  PYTHONPATH=/tmp/qrel target/tmp/pyenv-py/bin/python benches/python/bench_bindings.py

Everything runs on one thread: OMP/BLAS threads and OpenCV set to 1, and RAYON_NUM_THREADS=1 for
quarry's parallel kernels (SIFT, blur). Each figure is the best of 5 repeats (timeit). Prints a
markdown table: workload, peer figure, quarry figure, ratio peer / quarry.
"""
import datetime
import json
import math
import os
import pathlib
import timeit

for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RAYON_NUM_THREADS"):
    os.environ.setdefault(v, "1")

import numpy as np  # noqa: E402

import quarry  # noqa: E402

DATA = pathlib.Path(os.environ.get("QUARRY_BENCH_DATA", pathlib.Path(__file__).resolve().parents[2].parent / "shared" / "bench-data"))
PERM = [0, 2, 1, 3]  # bench-data [x, vx, y, vy] -> quarry [x, y, vx, vy]
ROWS = []


def best(fn, number, repeat=5):
    return min(timeit.repeat(fn, number=number, repeat=repeat)) / number


def fmt(t):
    if t >= 1e-3:
        return f"{t * 1e3:.2f} ms"
    if t >= 1e-6:
        return f"{t * 1e6:.2f} µs"
    return f"{t * 1e9:.0f} ns"


def row(workload, peer_name, t_peer, t_q, note=""):
    ratio = f"{t_peer / t_q:.1f}x" if t_peer and t_peer / t_q < 100 else (f"{t_peer / t_q:.0f}x" if t_peer else "")
    peer = f"{peer_name}: {fmt(t_peer)}" if t_peer else peer_name
    ROWS.append((workload, peer, fmt(t_q) + (f" {note}" if note else ""), ratio))


def cv_fq(dt, q):
    F = np.kron(np.eye(2), np.array([[1.0, dt], [0.0, 1.0]]))
    Q = np.kron(np.eye(2), q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]))
    return F, Q


# ------------------------------------------------------------------ binding overhead
kf1 = quarry.KalmanFilter(np.zeros(1), np.eye(1), np.eye(1), np.eye(1), np.eye(1), np.eye(1))
row("binding overhead: `KalmanFilter.predict()` on a 1-state filter (method call, no arrays)", "Python no-op call", best(lambda: None, 200000), best(kf1.predict, 200000))
one = np.ones(1)
row("binding overhead: `quarry.effective_sample_size(np.ones(1))` (one array checked: dtype, shape, layout, NaN)", "numpy `1 / (w @ w)`", best(lambda: 1.0 / (one @ one), 200000), best(lambda: quarry.effective_sample_size(one), 200000))

# ------------------------------------------------------------------ Kalman filter vs filterpy
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter as FpKF  # noqa: E402

P = json.loads((DATA / "params.json").read_text())
pk = P["kf"]
d = np.genfromtxt(DATA / "kf_track.csv", delimiter=",", names=True)
zs = np.ascontiguousarray(np.column_stack([d["zx"], d["zy"]]))
F, Q = cv_fq(pk["dt"], pk["q"])
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
R = pk["sigma_meas_m"] ** 2 * np.eye(2)
x0 = np.array(pk["x0"], float)
Fq, Qq, Hq = F[np.ix_(PERM, PERM)], Q[np.ix_(PERM, PERM)], np.eye(2, 4)


def fp_kf():
    kf = FpKF(dim_x=4, dim_z=2)
    kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
    kf.x, kf.P = x0.reshape(4, 1).copy(), np.eye(4)
    return kf


kf_fp = fp_kf()
kf_q = quarry.KalmanFilter(x0[PERM], np.eye(4), Fq, Qq, Hq, R)
z0 = zs[0]


def fp_step():
    kf_fp.predict()
    kf_fp.update(z0)


row("KF step per call (`KalmanFilter.step`, 4-state CV, 2-D z; kf_track.csv model)", "filterpy predict + update", best(fp_step, 5000), best(lambda: kf_q.step(z0), 50000))


def fp_seq(zz):
    k = fp_kf()
    for z in zz:
        k.predict()
        k.update(z)


def q_seq(zz):
    quarry.KalmanFilter(x0[PERM], np.eye(4), Fq, Qq, Hq, R).filter_sequence(zz)


row(f"KF whole sequence (`filter_sequence`, T = {len(zs)}, kf_track.csv; P reaches its fixed point at step 155)", "filterpy loop", best(lambda: fp_seq(zs), 3), best(lambda: q_seq(zs), 200))
head = zs[:150]
row("KF whole sequence, first 150 steps only (full recursion every step)", "filterpy loop", best(lambda: fp_seq(head), 10), best(lambda: q_seq(head), 1000))

pe = P["ekf"]
de = np.genfromtxt(DATA / "ekf_rb.csv", delimiter=",", names=True)
Fe, Qe = cv_fq(pe["dt"], pe["q"])
Re = np.diag([pe["sigma_range_m"] ** 2, pe["sigma_bearing_rad"] ** 2])
ze = np.column_stack([de["range"], de["bearing"]])


def HJ(x):
    px, py = x[0, 0], x[2, 0]
    r2 = px * px + py * py
    r = math.sqrt(r2)
    return np.array([[px / r, 0.0, py / r, 0.0], [-py / r2, 0.0, px / r2, 0.0]])


def Hx(x):
    return np.array([[math.hypot(x[0, 0], x[2, 0])], [math.atan2(x[2, 0], x[0, 0])]])


def resid(a, b):
    y = a - b
    y[1] = (y[1] + math.pi) % (2 * math.pi) - math.pi
    return y


def fp_ekf():
    e = ExtendedKalmanFilter(dim_x=4, dim_z=2)
    e.F, e.Q, e.R = Fe, Qe, Re
    e.x, e.P = np.array(pe["x0"], float).reshape(4, 1), np.diag([4.0, 1.0, 4.0, 1.0])
    for z in ze[:200]:
        e.predict()
        e.update(z.reshape(2, 1), HJ, Hx, residual=resid)


def q_ekf():
    x, Pm = np.array(pe["x0"], float)[PERM], np.diag([4.0, 4.0, 1.0, 1.0])
    for z in ze[:200]:
        x, Pm = quarry.ekf_predict(x, Pm, pe["dt"], motion="cv2", q=pe["q"])
        x, Pm, _, _ = quarry.ekf_update(x, Pm, z, measurement="range_bearing", R=Re)


row("EKF range-bearing step from Python (`ekf_predict` + `ekf_update` on (x, P) arrays; ekf_rb.csv)", "filterpy ExtendedKalmanFilter", best(fp_ekf, 3) / 200, best(q_ekf, 10) / 200)

# ------------------------------------------------------------------ particle filter vs numpy
Lq = np.linalg.cholesky(Q)


def numpy_pf(N, steps=300, seed=0):
    rng = np.random.default_rng(seed)
    X = x0 + rng.standard_normal((N, 4))
    for k in range(steps):
        X = X @ F.T + rng.standard_normal((N, 4)) @ Lq.T
        dx, dy = X[:, 0] - zs[k, 0], X[:, 2] - zs[k, 1]
        lw = -0.5 * (dx * dx + dy * dy) / pk["sigma_meas_m"] ** 2
        w = np.exp(lw - lw.max())
        w /= w.sum()
        c = np.cumsum(w)
        c[-1] = 1.0
        X = X[np.searchsorted(c, (rng.random() + np.arange(N)) / N)]


for N in (500, 5000):
    parts = x0[PERM] + np.random.default_rng(1).standard_normal((N, 4))
    row(f"bootstrap PF step, N = {N} (`particle_filter_cv2`, CV + position likelihood + systematic resampling every step)", "numpy vectorised (peers/bench_pf.py)",
        best(lambda: numpy_pf(N), 3) / 300, best(lambda: quarry.particle_filter_cv2(parts, zs[:300], pk["dt"], pk["q"], R, seed=0), 3) / 300)

# ------------------------------------------------------------------ JPDA vs Stone Soup
from stonesoup.dataassociator import probability as ssprob  # noqa: E402
from stonesoup.hypothesiser.probability import PDAHypothesiser  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity  # noqa: E402
from stonesoup.predictor.kalman import KalmanPredictor  # noqa: E402
from stonesoup.types.detection import Detection  # noqa: E402
from stonesoup.types.state import GaussianState  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402
from stonesoup.updater.kalman import KalmanUpdater  # noqa: E402

pj = P["jpda"]
tm = CombinedLinearGaussianTransitionModel([ConstantVelocity(pj["q"]), ConstantVelocity(pj["q"])])
mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=pj["sigma_meas_m"] ** 2 * np.eye(2))
predictor, kupdater = KalmanPredictor(tm), KalmanUpdater(mm)
Rj = pj["sigma_meas_m"] ** 2 * np.eye(2)
for n, cls in ((3, "JPDA"), (10, "JPDAwithEHM")):
    tr = np.genfromtxt(DATA / f"jpda_n{n}_truth.csv", delimiter=",", names=True)
    me = np.genfromtxt(DATA / f"jpda_n{n}_meas.csv", delimiter=",", names=True)
    t0 = datetime.datetime(2024, 1, 1)
    P0 = np.diag([0.25, 0.05, 0.25, 0.05])
    first = tr[tr["scan"] == 0]
    tracks = {Track([GaussianState(np.array([[r["x"]], [r["vx"]], [r["y"]], [r["vy"]]]), P0, timestamp=t0)]) for r in first}
    ts = t0 + datetime.timedelta(seconds=pj["dt"])
    sel = me[me["scan"] == 1]
    dets = {Detection(np.array([[r["x"]], [r["y"]]]), timestamp=ts, measurement_model=mm) for r in sel}
    hyp = PDAHypothesiser(predictor=predictor, updater=kupdater, clutter_spatial_density=pj["clutter_density"],
                          prob_detect=pj["prob_detect"], prob_gate=0.99)
    assoc = getattr(ssprob, cls)(hypothesiser=hyp)
    t_ss = best(lambda: assoc.associate(tracks, dets, ts), 1, repeat=3)
    X = [np.array([r["x"], r["y"], r["vx"], r["vy"]]) for r in first]
    P0q = np.diag([0.25, 0.25, 0.05, 0.05])
    z = np.array([[r["x"], r["y"]] for r in sel])

    def q_scan():
        zhat, S = np.empty((n, 2)), np.empty((n, 2, 2))
        for i, x in enumerate(X):
            xp, Pp = quarry.ekf_predict(x, P0q, pj["dt"], motion="cv2", q=pj["q"])
            zhat[i], S[i] = xp[:2], Pp[:2, :2] + Rj
        _, ll = quarry.chi2_gate(zhat, S, z, 0.99)
        return quarry.jpda(ll, pj["prob_detect"], 0.99, pj["clutter_density"])

    row(f"JPDA scan, n = {n} (jpda_n{n} scan 1: predict every track, gate, exact marginals)", f"Stone Soup {cls}.associate", t_ss, best(q_scan, 200))

# ------------------------------------------------------------------ metrics vs motmetrics / TrackEval
import motmetrics as mmx  # noqa: E402
import trackeval  # noqa: E402

if not hasattr(np, "asfarray"):
    np.asfarray = lambda a, dtype=np.float64: np.asarray(a, dtype=dtype)
gt = np.loadtxt(DATA / "mot_gt.csv", delimiter=",", skiprows=1)
hy = np.loadtxt(DATA / "mot_hyp.csv", delimiter=",", skiprows=1)
frames = sorted(set(gt[:, 0].astype(int)) | set(hy[:, 0].astype(int)))


def mm_run():
    acc = mmx.MOTAccumulator(auto_id=True)
    for f in frames:
        g, h = gt[gt[:, 0] == f], hy[hy[:, 0] == f]
        acc.update(list(g[:, 1].astype(int)), list(h[:, 1].astype(int)), mmx.distances.iou_matrix(g[:, 2:6], h[:, 2:6], max_iou=0.5))
    mmx.metrics.create().compute(acc, metrics=["mota", "motp", "idf1", "num_switches"], name="s")


def iou(A, B):
    ax1, ay1 = A[:, 0:1] + A[:, 2:3], A[:, 1:2] + A[:, 3:4]
    iw = np.clip(np.minimum(ax1, B[:, 0] + B[:, 2]) - np.maximum(A[:, 0:1], B[:, 0]), 0, None)
    ih = np.clip(np.minimum(ay1, B[:, 1] + B[:, 3]) - np.maximum(A[:, 1:2], B[:, 1]), 0, None)
    inter = iw * ih
    return inter / (A[:, 2:3] * A[:, 3:4] + B[:, 2] * B[:, 3] - inter)


def te_run():
    gid = {v: i for i, v in enumerate(sorted(set(gt[:, 1].astype(int))))}
    tid = {v: i for i, v in enumerate(sorted(set(hy[:, 1].astype(int))))}
    data = dict(num_timesteps=len(frames), num_gt_ids=len(gid), num_tracker_ids=len(tid), num_gt_dets=len(gt),
                num_tracker_dets=len(hy), gt_ids=[], tracker_ids=[], similarity_scores=[])
    for f in frames:
        g, h = gt[gt[:, 0] == f], hy[hy[:, 0] == f]
        data["gt_ids"].append(np.array([gid[i] for i in g[:, 1].astype(int)]))
        data["tracker_ids"].append(np.array([tid[i] for i in h[:, 1].astype(int)]))
        data["similarity_scores"].append(iou(g[:, 2:6], h[:, 2:6]))
    cfg = {"THRESHOLD": 0.5, "PRINT_CONFIG": False}
    trackeval.metrics.CLEAR(cfg).eval_sequence(data)
    trackeval.metrics.Identity(cfg).eval_sequence(data)
    trackeval.metrics.HOTA().eval_sequence(data)


t_q = best(lambda: quarry.mot_metrics(gt, hy), 200)
row("MOT metrics, bench pair (60 frames; `mot_metrics`: CLEAR + IDF1 + HOTA)", "py-motmetrics (CLEAR + IDF1)", best(mm_run, 1, repeat=3), t_q)
row("MOT metrics, bench pair (same call)", "TrackEval (CLEAR + Identity + HOTA)", best(te_run, 1, repeat=3), t_q)

# ------------------------------------------------------------------ vision vs OpenCV / scikit-image
import cv2  # noqa: E402
from scipy import ndimage  # noqa: E402
from skimage.morphology import local_minima  # noqa: E402
from skimage.segmentation import watershed as sk_watershed  # noqa: E402

cv2.setNumThreads(1)
g8 = cv2.imread(str(DATA / "photo_gray.png"), cv2.IMREAD_GRAYSCALE)
g32 = g8.astype(np.float32)
row("Gaussian blur f32 σ = 8, photo_gray 800×450 (`gaussian_blur`)", "cv2.GaussianBlur", best(lambda: cv2.GaussianBlur(g32, (0, 0), 8.0, borderType=cv2.BORDER_REFLECT_101), 20), best(lambda: quarry.gaussian_blur(g32, 8.0), 20))
bl = cv2.GaussianBlur(g32, (0, 0), 8.0, borderType=cv2.BORDER_REFLECT_101)
row("regional minima 4-conn of the blur, labelled (`regional_minima`)", "skimage local_minima + ndimage.label", best(lambda: ndimage.label(local_minima(bl, connectivity=1)), 10), best(lambda: quarry.regional_minima(bl, 4), 20))
markers = ndimage.label(local_minima(bl, connectivity=1))[0].astype(np.int32)
row("watershed 4-conn of the blur from its 160 minima (`watershed(relief, markers)`)", "skimage watershed", best(lambda: sk_watershed(bl, markers), 5), best(lambda: quarry.watershed(bl, markers), 20))
sift_q, sift_c = quarry.Sift(), cv2.SIFT_create()
row("SIFT detect + compute, photo_gray, 1 thread (`Sift.detect_and_compute`)", "cv2.SIFT detectAndCompute", best(lambda: sift_c.detectAndCompute(g8, None), 3), best(lambda: sift_q.detect_and_compute(g8), 3))
g2 = cv2.imread(str(DATA / "sift_rot30_s0.8.png"), cv2.IMREAD_GRAYSCALE)
_, d1 = sift_q.detect_and_compute(g8)
_, d2 = sift_q.detect_and_compute(g2)
f1, f2 = d1.astype(np.float32), d2.astype(np.float32)  # OpenCV's SIFT descriptors are float32
bf = cv2.BFMatcher(cv2.NORM_L2)
row(f"SIFT matching {len(d1)}×{len(d2)} descriptors, ratio 0.8 (`match_sift`)", "cv2.BFMatcher knnMatch k=2 (float32 descriptors) + ratio test",
    best(lambda: [m[0] for m in bf.knnMatch(f1, f2, k=2) if m[0].distance < 0.8 * m[1].distance], 3), best(lambda: quarry.match_sift(d1, d2), 3))

# ------------------------------------------------------------------ point clouds
from sklearn.cluster import MeanShift as SkMeanShift  # noqa: E402

dm = np.genfromtxt(DATA / "meanshift_points.csv", delimiter=",", names=True)
pts = np.ascontiguousarray(np.column_stack([dm["x"], dm["y"]]))
row(f"MeanShift h = 0.3, {len(pts)} points, bin seeds (`mean_shift`)", "sklearn MeanShift(bin_seeding=True)", best(lambda: SkMeanShift(bandwidth=0.3, bin_seeding=True).fit(pts), 3), best(lambda: quarry.mean_shift(pts), 200))
bg = np.genfromtxt(DATA / "laser_background.csv", delimiter=",", skip_header=1)
W = np.stack([bg[bg[:, 0] == k, 2:].reshape(-1) for k in range(20)])
cur = np.genfromtxt(DATA / "laser_scan.csv", delimiter=",", names=True)["range"].copy()
vt = quarry.VarianceChi2Test(W)


def np_chi2():
    mu = W.mean(0)
    s2 = np.maximum(W.var(0, ddof=1), 0.005**2)
    dd = cur - mu
    return (dd * dd / s2 > 10.83) & (dd < 0)


row("χ² per-beam test, 3 × 1081 beams, window 20 (`VarianceChi2Test.test`)", "numpy recompute (peers/bench_chi2.py)", best(np_chi2, 200), best(lambda: vt.test(cur), 2000))

print("| workload | peer (library: time) | quarry from Python | ratio |")
print("|---|---|---|---|")
for r in ROWS:
    print("| " + " | ".join(r) + " |")

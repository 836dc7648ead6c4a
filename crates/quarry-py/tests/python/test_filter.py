"""quarry's filter bindings against filterpy on bench-data (KF and range-bearing EKF to 1e-9),
on random linear models of every size class, and the particle filter / resamplers against their
definitions and the Kalman filter."""
import json
import math

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter as FpKF
from hypothesis import given, settings, strategies as st

import quarry

# filterpy / bench-data order [x, vx, y, vy] <-> quarry's [x, y, vx, vy]
PERM = [0, 2, 1, 3]


def cv_fq(dt, q):
    F = np.kron(np.eye(2), np.array([[1.0, dt], [0.0, 1.0]]))
    Q = np.kron(np.eye(2), q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]]))
    return F, Q


def test_kf_track_functional_matches_filterpy(bench_data):
    """ekf_predict(motion="cv2", q) + ekf_update(measurement="position2") on kf_track.csv."""
    p = json.loads((bench_data / "params.json").read_text())["kf"]
    d = np.genfromtxt(bench_data / "kf_track.csv", delimiter=",", names=True)
    F, Q = cv_fq(p["dt"], p["q"])
    R = p["sigma_meas_m"] ** 2 * np.eye(2)
    kf = FpKF(dim_x=4, dim_z=2)
    kf.F, kf.Q, kf.R = F, Q, R
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    kf.x, kf.P = np.array(p["x0"], float).reshape(4, 1), np.eye(4)
    x, P = np.array(p["x0"], float)[PERM], np.eye(4)
    worst = 0.0
    for zx, zy in zip(d["zx"], d["zy"]):
        z = np.array([zx, zy])
        kf.predict()
        kf.update(z)
        x, P = quarry.ekf_predict(x, P, p["dt"], motion="cv2", q=p["q"])
        x, P, nis, ll = quarry.ekf_update(x, P, z, measurement="position2", R=R)
        worst = max(worst, np.abs(x - kf.x.ravel()[PERM]).max(), np.abs(P - kf.P[np.ix_(PERM, PERM)]).max())
    print(f"kf_track, {len(d)} steps: max |quarry - filterpy| {worst:.1e}")
    assert worst < 1e-9


def test_ekf_range_bearing_matches_filterpy(bench_data):
    """ekf_update(measurement="range_bearing") on ekf_rb.csv, filterpy's ExtendedKalmanFilter
    as peers/bench_ekf.py drives it."""
    p = json.loads((bench_data / "params.json").read_text())["ekf"]
    d = np.genfromtxt(bench_data / "ekf_rb.csv", delimiter=",", names=True)
    dt, q, sr, sb = p["dt"], p["q"], p["sigma_range_m"], p["sigma_bearing_rad"]
    F, Q = cv_fq(dt, q)
    R = np.diag([sr**2, sb**2])

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

    ekf = ExtendedKalmanFilter(dim_x=4, dim_z=2)
    ekf.F, ekf.Q, ekf.R = F, Q, R
    P0 = np.diag([4.0, 1.0, 4.0, 1.0])
    ekf.x, ekf.P = np.array(p["x0"], float).reshape(4, 1), P0.copy()
    x, P = np.array(p["x0"], float)[PERM], P0[np.ix_(PERM, PERM)]
    worst = 0.0
    for r, b in zip(d["range"], d["bearing"]):
        z = np.array([r, b])
        ekf.predict()
        ekf.update(z.reshape(2, 1), HJ, Hx, residual=resid)
        x, P = quarry.ekf_predict(x, P, dt, motion="cv2", q=q)
        x, P, _, _ = quarry.ekf_update(x, P, z, measurement="range_bearing", R=R, sensor=(0.0, 0.0, 0.0))
        worst = max(worst, np.abs(x - ekf.x.ravel()[PERM]).max(), np.abs(P - ekf.P[np.ix_(PERM, PERM)]).max())
    print(f"ekf_rb, {len(d)} steps: max |quarry - filterpy| {worst:.1e}")
    assert worst < 1e-9


def random_model(rng, n, m):
    F = np.eye(n) + 0.1 * rng.normal(size=(n, n))
    A = rng.normal(size=(n, n))
    Q = 0.05 * (A @ A.T) + 0.01 * np.eye(n)
    H = rng.normal(size=(m, n))
    B = rng.normal(size=(m, m))
    R = 0.3 * (B @ B.T) + 0.1 * np.eye(m)
    return F, Q, H, R


# sizes on the fixed-size path (n <= 6, m <= 4) and on the dynamic fallback
@pytest.mark.parametrize("n,m", [(1, 1), (2, 1), (3, 2), (4, 2), (5, 3), (6, 4), (6, 5), (8, 3), (9, 9)])
def test_kalman_filter_class_matches_filterpy_every_size(n, m):
    rng = np.random.default_rng(n * 10 + m)
    F, Q, H, R = random_model(rng, n, m)
    x0, P0 = rng.normal(size=n), np.eye(n)
    ours = quarry.KalmanFilter(x0, P0, F, Q, H, R)
    fp = FpKF(dim_x=n, dim_z=m)
    fp.F, fp.Q, fp.H, fp.R = F, Q, H, R
    fp.x, fp.P = x0.reshape(n, 1).copy(), P0.copy()
    zs = rng.normal(size=(60, m)).cumsum(axis=0) * 0.1
    means = ours.filter_sequence(zs[:30])
    ref = []
    for z in zs[:30]:
        fp.predict()
        fp.update(z)
        ref.append(fp.x.ravel().copy())
    np.testing.assert_allclose(means, np.array(ref), rtol=0, atol=1e-9)
    for z in zs[30:]:
        ours.step(z)
        fp.predict()
        fp.update(z)
        np.testing.assert_allclose(ours.x, fp.x.ravel(), rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours.P, fp.P, rtol=0, atol=1e-9)
    # the functional linear path agrees too where it has a fixed size
    if n <= 6 and m <= 4:
        x, P = quarry.ekf_predict(ours.x, ours.P, 0.0, motion="linear", F=F, Q=Q)
        x, P, _, _ = quarry.ekf_update(x, P, zs[0], measurement="linear", H=H, R=R)
        fp.predict()
        fp.update(zs[0])
        np.testing.assert_allclose(x, fp.x.ravel(), rtol=0, atol=1e-9)


def test_update_log_likelihood_and_nis():
    from scipy.stats import multivariate_normal
    x, P = np.array([1.0, 2.0, 0.5, -0.5]), np.diag([1.0, 2.0, 0.3, 0.3])
    R = np.array([[0.5, 0.1], [0.1, 0.4]])
    z = np.array([1.7, 1.1])
    S = P[:2, :2] + R
    _, _, nis, ll = quarry.ekf_update(x, P, z, measurement="position2", R=R)
    e = z - x[:2]
    assert nis == pytest.approx(e @ np.linalg.solve(S, e), rel=1e-12)
    assert ll == pytest.approx(multivariate_normal.logpdf(z, x[:2], S), rel=1e-12)


# ---------------------------------------------------------------- particles
@settings(max_examples=50, deadline=None)
@given(st.integers(1, 200), st.integers(0, 2**32 - 1), st.sampled_from(["systematic", "stratified", "residual", "multinomial"]))
def test_resamplers_keep_their_guarantees(n, seed, scheme):
    rng = np.random.default_rng(seed)
    w = rng.random(n) ** 3
    w /= w.sum()
    a = quarry.resample(w, seed, scheme)
    assert a.shape == (n,) and a.dtype == np.int64 and a.min() >= 0 and a.max() < n
    assert np.all(w[a] > 0)
    np.testing.assert_array_equal(a, quarry.resample(w, seed, scheme))  # reproducible
    counts = np.bincount(a, minlength=n)
    if scheme == "systematic":
        assert np.all(np.abs(counts - n * w) < 1 + 1e-9)  # floor or ceil of N w_i
    if scheme == "residual":
        assert np.all(counts >= np.floor(n * w + 1e-9) - 0)
    if scheme == "stratified":
        assert np.all(np.abs(counts - n * w) < 2 + 1e-9)


def test_multinomial_is_unbiased():
    w = np.array([0.1, 0.2, 0.3, 0.4])
    counts = sum(np.bincount(quarry.resample(w, s, "multinomial"), minlength=4) for s in range(400))
    freq = counts / counts.sum()
    np.testing.assert_allclose(freq, w, atol=0.02)  # 1600 draws: sd ~0.012 per cell


def test_weights_helpers():
    lw = np.array([-1000.0, -1001.0, -np.inf])
    w, ls = quarry.normalise_log_weights(lw)
    np.testing.assert_allclose(w, [1 / (1 + math.e**-1), math.e**-1 / (1 + math.e**-1), 0.0])
    assert ls == pytest.approx(-1000 + math.log(1 + math.e**-1))
    assert quarry.effective_sample_size(np.full(10, 0.1)) == pytest.approx(10.0)


def test_particle_filter_converges_to_the_kalman_filter(bench_data):
    """Linear-Gaussian model: the bootstrap PF's mean approaches the KF's posterior mean."""
    p = json.loads((bench_data / "params.json").read_text())["kf"]
    d = np.genfromtxt(bench_data / "kf_track.csv", delimiter=",", names=True)[:100]
    zs = np.column_stack([d["zx"], d["zy"]])
    dt, q, sig = p["dt"], p["q"], p["sigma_meas_m"]
    R = sig**2 * np.eye(2)
    x0 = np.array(p["x0"], float)[PERM]
    rng = np.random.default_rng(0)
    particles = x0 + rng.standard_normal((20000, 4))  # the prior N(x0, I)
    pf = quarry.particle_filter_cv2(particles, zs, dt, q, R, seed=7)
    F, Q = cv_fq(dt, q)
    kf = quarry.KalmanFilter(x0, np.eye(4), F[np.ix_(PERM, PERM)], Q[np.ix_(PERM, PERM)],
                             np.eye(2, 4), R)
    km = kf.filter_sequence(zs)
    err = np.abs(pf - km)[:, :2]
    print(f"PF (N = 20000) vs KF position: mean |diff| {err.mean():.4f} m, max {err.max():.4f} m")
    assert err.mean() < 0.02 and err.max() < 0.1
    # reproducible from the seed, different for another seed
    again = quarry.particle_filter_cv2(particles[:500], zs[:10], dt, q, R, seed=3)
    np.testing.assert_array_equal(again, quarry.particle_filter_cv2(particles[:500], zs[:10], dt, q, R, seed=3))
    assert not np.array_equal(again, quarry.particle_filter_cv2(particles[:500], zs[:10], dt, q, R, seed=4))
    # resampling only below an ESS threshold still tracks
    lazy = quarry.particle_filter_cv2(particles[:5000], zs, dt, q, R, seed=1, scheme="residual", ess_threshold=0.5)
    assert np.abs(lazy - km)[:, :2].mean() < 0.05


def test_filter_errors_name_the_argument():
    F, Q = cv_fq(0.1, 0.5)
    with pytest.raises(ValueError, match="P"):
        quarry.ekf_predict(np.zeros(4), -np.eye(4), 0.1, q=0.5)
    with pytest.raises(ValueError, match="x"):
        quarry.ekf_predict(np.zeros(3), np.eye(3), 0.1, q=0.5)
    with pytest.raises(ValueError, match="q"):
        quarry.ekf_predict(np.zeros(4), np.eye(4), 0.1)
    with pytest.raises(ValueError, match="time step|dt"):
        quarry.ekf_predict(np.zeros(4), np.eye(4), -0.1, q=0.5)
    with pytest.raises(ValueError, match="motion"):
        quarry.ekf_predict(np.zeros(4), np.eye(4), 0.1, motion="warp", q=0.5)
    with pytest.raises(ValueError, match="z"):
        quarry.ekf_update(np.zeros(4), np.eye(4), np.zeros(3), R=np.eye(2))
    with pytest.raises(ValueError, match="z"):
        quarry.ekf_update(np.zeros(4), np.eye(4), np.array([np.nan, 0.0]), R=np.eye(2))
    with pytest.raises(ValueError, match="R"):
        quarry.ekf_update(np.zeros(4), np.eye(4), np.zeros(2), R=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="R"):
        quarry.ekf_update(np.zeros(4), np.eye(4), np.zeros(2))
    with pytest.raises(ValueError, match="x"):
        quarry.ekf_update(np.zeros(3), np.eye(3), np.zeros(2), measurement="range_bearing", R=np.eye(2))
    with pytest.raises(TypeError, match="P"):
        quarry.ekf_update(np.zeros(4), np.eye(4, dtype=np.float32), np.zeros(2), R=np.eye(2))
    with pytest.raises(ValueError, match="weights"):
        quarry.resample(np.array([0.5, -0.1]), 0)
    with pytest.raises(ValueError, match="weights"):
        quarry.resample(np.zeros(3), 0)
    with pytest.raises(ValueError, match="scheme"):
        quarry.resample(np.ones(3), 0, "best")
    with pytest.raises(ValueError, match="particles"):
        quarry.particle_filter_cv2(np.zeros((5, 3)), np.zeros((2, 2)), 0.1, 0.5, np.eye(2), 0)
    with pytest.raises(ValueError, match="ess_threshold"):
        quarry.particle_filter_cv2(np.zeros((5, 4)), np.zeros((2, 2)), 0.1, 0.5, np.eye(2), 0, ess_threshold=2.0)
    kf = quarry.KalmanFilter(np.zeros(4), np.eye(4), F, Q, np.eye(2, 4), np.eye(2))
    with pytest.raises(ValueError, match="zs"):
        kf.filter_sequence(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="zs"):
        kf.filter_sequence(np.zeros((5, 4))[:, ::2])


@pytest.mark.parametrize("n,m,seed", [(0, 0, 0), (4, 2, 0), (2, 1, 1), (6, 3, 2), (3, 2, 3)])
def test_filter_sequence_is_bit_identical_to_steps(n, m, seed):
    """filter_sequence switches to a mean-only recursion once P reaches its floating-point fixed
    point; the output must be the same bits as calling step() (always the full update).
    n = 0: the 4-state CV model of the benchmark, whose P reaches the fixed point."""
    rng = np.random.default_rng(seed)
    if n == 0:
        n, m = 4, 2
        F, Q = (a[np.ix_(PERM, PERM)] for a in cv_fq(0.1, 0.5))
        H, R = np.eye(2, 4), 0.25 * np.eye(2)
    else:
        F, Q, H, R = random_model(rng, n, m)
        F = 0.97 * F / max(1.0, np.abs(np.linalg.eigvals(F)).max())  # a stable model
    zs = rng.normal(size=(1500, m))
    a = quarry.KalmanFilter(np.zeros(n), np.eye(n), F, Q, H, R)
    b = quarry.KalmanFilter(np.zeros(n), np.eye(n), F, Q, H, R)
    seq = a.filter_sequence(zs)
    steps = []
    for z in zs:
        b.step(z)
        steps.append(b.x)
    assert np.array_equal(seq, np.array(steps))
    assert np.array_equal(a.P, b.P) and np.array_equal(a.x, b.x)
    if np.array_equal(F, cv_fq(0.1, 0.5)[0][np.ix_(PERM, PERM)]):
        P = b.P  # P did reach its fixed point, so the fast path ran
        b.step(zs[0])
        assert np.array_equal(P, b.P)

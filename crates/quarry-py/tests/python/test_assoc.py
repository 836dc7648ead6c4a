"""quarry's association bindings against Stone Soup's JPDA on the bench-data scenarios, and
against brute force / scipy on random problems."""
import datetime
import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2, multivariate_normal

import quarry

PROB_GATE = 0.99


# ---------------------------------------------------------------- Stone Soup, bench-data
def stonesoup_run(bench_data, n, scans, assoc_name):
    """Replays peers/bench_jpda.py's "known n" workload with Stone Soup and, scan by scan,
    computes quarry's gate + JPDA from the same predicted measurements. Returns the largest
    |beta_quarry - beta_stonesoup| and the number of compared entries."""
    from stonesoup.dataassociator import probability as ssprob
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.kalman import KalmanUpdater
    from stonesoup.updater.probability import PDAUpdater

    pj = json.loads((bench_data / "params.json").read_text())["jpda"]
    dt, q, sigma, pd, density = pj["dt"], pj["q"], pj["sigma_meas_m"], pj["prob_detect"], pj["clutter_density"]
    tm = CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)])
    mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=sigma**2 * np.eye(2))
    predictor, kupdater, pda_updater = KalmanPredictor(tm), KalmanUpdater(mm), PDAUpdater(mm)
    hyp = PDAHypothesiser(predictor=predictor, updater=kupdater, clutter_spatial_density=density,
                          prob_detect=pd, prob_gate=PROB_GATE)
    assoc = getattr(ssprob, assoc_name)(hypothesiser=hyp)

    truth = np.genfromtxt(bench_data / f"jpda_n{n}_truth.csv", delimiter=",", names=True)
    meas = np.genfromtxt(bench_data / f"jpda_n{n}_meas.csv", delimiter=",", names=True)
    t0 = datetime.datetime(2024, 1, 1)
    p0 = np.diag([0.25, 0.05, 0.25, 0.05])
    tracks = []
    for r in truth[truth["scan"] == 0]:
        tracks.append(Track([GaussianState(np.array([[r["x"]], [r["vx"]], [r["y"]], [r["vy"]]]), p0, timestamp=t0)]))
    worst, compared, gated = 0.0, 0, 0
    for k in range(scans):
        ts = t0 + datetime.timedelta(seconds=k * dt)
        sel = meas[meas["scan"] == k]
        dets = [Detection(np.array([[r["x"]], [r["y"]]]), timestamp=ts, measurement_model=mm) for r in sel]
        hyps = assoc.associate(set(tracks), set(dets), ts)
        # quarry from the same predicted measurements
        zhat, S = [], []
        for tr in tracks:
            mp = kupdater.predict_measurement(predictor.predict(tr, timestamp=ts))
            zhat.append(np.asarray(mp.state_vector, float).ravel())
            S.append(np.asarray(mp.covar, float))
        z = np.array([[r["x"], r["y"]] for r in sel], float).reshape(-1, 2)
        _, loglik = quarry.chi2_gate(np.array(zhat), np.array(S), z, PROB_GATE)
        beta, _ = quarry.jpda(loglik, pd, PROB_GATE, density, method="exact")
        for i, tr in enumerate(tracks):
            seen = np.zeros(len(dets) + 1, bool)
            for h in hyps[tr]:
                col = 0 if not h else 1 + dets.index(h.measurement)
                worst = max(worst, abs(beta[i, col] - float(h.probability)))
                seen[col] = True
                compared += 1
            gated += int(seen[1:].sum())
            # detections Stone Soup gated out have beta = 0 in quarry
            assert np.all(beta[i, ~seen] == 0.0)
            np.testing.assert_allclose(beta[i].sum(), 1.0, atol=1e-12)
        for tr in tracks:
            tr.append(pda_updater.update(hyps[tr]))
    return worst, compared, gated


@pytest.mark.parametrize("n,scans,assoc", [(3, 100, "JPDA"), (10, 25, "JPDAwithEHM")])
def test_jpda_matches_stonesoup(bench_data, n, scans, assoc):
    worst, compared, gated = stonesoup_run(bench_data, n, scans, assoc)
    print(f"jpda_n{n}: {compared} marginals over {scans} scans, {gated} gated pairs, max |diff| {worst:.2e}")
    assert gated > n * scans // 2  # the comparison covers real associations
    assert worst < 1e-9


# ---------------------------------------------------------------- gate
@pytest.mark.parametrize("d", [1, 2, 3, 4])
def test_chi2_threshold_matches_scipy(d):
    for p in (0.5, 0.9, 0.99, 0.999):
        assert quarry.chi2_threshold(p, d) == pytest.approx(chi2.ppf(p, d), rel=1e-9)


def test_chi2_gate_matches_scipy():
    rng = np.random.default_rng(1)
    n, m, d = 4, 9, 2
    zhat = rng.normal(0, 3, (n, d))
    A = rng.normal(0, 1, (n, d, d))
    S = A @ A.transpose(0, 2, 1) + 0.5 * np.eye(d)
    z = rng.normal(0, 3, (m, d))
    d2, ll = quarry.chi2_gate(zhat, S, z, 0.9)
    gamma = chi2.ppf(0.9, d)
    for i in range(n):
        Si = np.linalg.inv(S[i])
        for j in range(m):
            e = z[j] - zhat[i]
            assert d2[i, j] == pytest.approx(e @ Si @ e, rel=1e-10)
            if e @ Si @ e <= gamma:
                assert ll[i, j] == pytest.approx(multivariate_normal.logpdf(z[j], zhat[i], S[i]), rel=1e-10)
            else:
                assert ll[i, j] == -np.inf
    assert np.isfinite(ll).any() and np.isinf(ll).any()


# ---------------------------------------------------------------- brute force
def brute_jpda(loglik, pd, pg, kappa, existence=None):
    """Enumerates every joint event; returns (beta, existence) as quarry defines them."""
    n, m = loglik.shape
    psi = np.ones(n) if existence is None else np.asarray(existence)
    miss = 1 - pd * pg * psi
    det = pd * psi[:, None] * np.exp(loglik) / kappa
    beta = np.zeros((n, m + 1))
    total = 0.0
    for ev in itertools.product(*[range(-1, m)] * n):
        used = [j for j in ev if j >= 0]
        if len(used) != len(set(used)):
            continue
        w = 1.0
        for i, j in enumerate(ev):
            w *= miss[i] if j < 0 else det[i, j]
        total += w
        for i, j in enumerate(ev):
            beta[i, j + 1] += w
    beta /= total
    if existence is None:
        return beta, None
    r = (1 - pd * pg) * psi / miss
    post = beta[:, 0] * r + beta[:, 1:].sum(axis=1)
    cond = beta.copy()
    cond[:, 0] = beta[:, 0] * r / post
    cond[:, 1:] /= post[:, None]
    return cond, post


def random_loglik(rng, n, m, gated=0.6):
    ll = rng.uniform(-6, 0, (n, m))
    ll[rng.random((n, m)) > gated] = -np.inf
    return ll


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 4), st.integers(0, 4), st.integers(0, 2**32 - 1))
def test_jpda_and_jipda_match_brute_force(n, m, seed):
    rng = np.random.default_rng(seed)
    ll = random_loglik(rng, n, m)
    pd, pg, kappa = 0.9, 0.99, 0.05
    want, _ = brute_jpda(ll, pd, pg, kappa)
    for method in ("auto", "exact"):
        beta, _ = quarry.jpda(ll, pd, pg, kappa, method=method)
        np.testing.assert_allclose(beta, want, atol=1e-10)
    ex = rng.uniform(0.1, 1.0, n)
    want_b, want_e = brute_jpda(ll, pd, pg, kappa, ex)
    beta, post, _ = quarry.jipda(ll, ex, pd, pg, kappa)
    np.testing.assert_allclose(beta, want_b, atol=1e-10)
    np.testing.assert_allclose(post, want_e, atol=1e-10)


def test_pda_is_per_track_normalisation():
    rng = np.random.default_rng(4)
    ll = random_loglik(rng, 3, 5)
    pd, pg, kappa = 0.8, 0.95, 0.01
    beta, _ = quarry.pda(ll, pd, pg, kappa)
    w = np.concatenate([np.full((3, 1), 1 - pd * pg), pd * np.exp(ll) / kappa], axis=1)
    np.testing.assert_allclose(beta, w / w.sum(axis=1, keepdims=True), atol=1e-12)


def test_jpda_kbest_and_lbp_close_to_exact():
    rng = np.random.default_rng(5)
    ll = random_loglik(rng, 4, 4, gated=1.0)
    exact, _ = quarry.jpda(ll, 0.9, 0.99, 0.05, method="exact")
    kb, _ = quarry.jpda(ll, 0.9, 0.99, 0.05, method="kbest", k=1000)
    np.testing.assert_allclose(kb, exact, atol=1e-10)  # 1000 events cover all 209 here
    lbp, _ = quarry.jpda(ll, 0.9, 0.99, 0.05, method="lbp")
    assert np.abs(lbp - exact).max() < 0.35  # documented LBP tolerance on dense clusters


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 5), st.integers(1, 5), st.integers(0, 2**32 - 1))
def test_assign_matches_scipy(n, m, seed):
    rng = np.random.default_rng(seed)
    c = rng.uniform(0, 10, (n, m))
    row_to_col, cost = quarry.assign(c)
    r, cidx = linear_sum_assignment(c)
    assert cost == pytest.approx(c[r, cidx].sum(), abs=1e-9)
    used = row_to_col[row_to_col >= 0]
    assert len(used) == min(n, m) and len(set(used)) == len(used)


def all_assignments(c, miss=None):
    """Every feasible assignment (rows may miss when miss is given) with its cost."""
    n, m = c.shape
    out = []
    opts = range(-1, m) if miss is not None else range(m)
    if miss is None and n > m:
        raise ValueError("only n <= m without miss")
    for ev in itertools.product(*[opts] * n):
        used = [j for j in ev if j >= 0]
        if len(used) != len(set(used)):
            continue
        cost = sum(miss[i] if j < 0 else c[i, j] for i, j in enumerate(ev))
        if np.isfinite(cost):
            out.append(cost)
    return sorted(out)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 3), st.integers(1, 4), st.integers(1, 8), st.integers(0, 2**32 - 1))
def test_murty_k_best_matches_enumeration(n, m, k, seed):
    rng = np.random.default_rng(seed)
    c = rng.uniform(0, 10, (n, m))
    c[rng.random((n, m)) > 0.8] = np.inf
    miss = rng.uniform(5, 15, n)
    rows, costs = quarry.murty_k_best(c, k, miss_cost=miss)
    want = all_assignments(c, miss)[:k]
    np.testing.assert_allclose(costs, want, atol=1e-9)
    assert rows.shape == (len(want), n)
    for r, cost in zip(rows, costs):
        got = sum(miss[i] if j < 0 else c[i, j] for i, j in enumerate(r))
        assert got == pytest.approx(cost, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 4), st.integers(0, 4), st.integers(0, 2**32 - 1))
def test_gnn_is_most_likely_joint_event(n, m, seed):
    rng = np.random.default_rng(seed)
    ll = random_loglik(rng, n, m)
    pd, pg, kappa = 0.9, 0.99, 0.05
    row_to_col, cost = quarry.gnn(ll, pd, pg, kappa)
    c = -(np.log(pd) - np.log(kappa) + ll)
    miss = np.full(n, -np.log(1 - pd * pg))
    assert cost == pytest.approx(all_assignments(c, miss)[0], abs=1e-9)
    # the event it returns has that cost
    got = sum(miss[i] if j < 0 else c[i, j] for i, j in enumerate(row_to_col))
    assert got == pytest.approx(cost, abs=1e-9)


# ---------------------------------------------------------------- bad input
def test_assoc_errors_name_the_argument():
    ll = np.zeros((2, 3))
    with pytest.raises(TypeError, match="loglik"):
        quarry.jpda(ll.astype(np.float32), 0.9, 0.99, 1e-3)
    with pytest.raises(TypeError, match="loglik"):
        quarry.jpda([[0.0]], 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="loglik"):
        quarry.jpda(np.zeros(3), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="loglik"):
        quarry.jpda(np.array([[np.nan, 0.0]]), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="loglik"):
        quarry.jpda(np.array([[np.inf, 0.0]]), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="loglik"):
        quarry.jpda(np.zeros((3, 4))[:, ::2], 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="loglik"):
        quarry.jpda(np.zeros((0, 3)), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="clutter_density"):
        quarry.jpda(ll, 0.9, 0.99, -1.0)
    with pytest.raises(ValueError, match="pd"):
        quarry.jpda(ll, 1.5, 0.99, 1e-3)
    with pytest.raises(ValueError, match="method"):
        quarry.jpda(ll, 0.9, 0.99, 1e-3, method="magic")
    with pytest.raises(ValueError, match="existence"):
        quarry.jipda(ll, np.array([0.5, 1.5]), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="existence"):
        quarry.jipda(ll, np.array([0.5]), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="cost"):
        quarry.assign(np.array([[np.nan]]))
    with pytest.raises(ValueError, match="infeasible"):
        quarry.assign(np.array([[np.inf, np.inf]]))
    with pytest.raises(ValueError, match="S"):
        quarry.chi2_gate(np.zeros((1, 2)), np.zeros((1, 2, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="S"):
        quarry.chi2_gate(np.zeros((1, 2)), np.zeros((2, 2, 2)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="z"):
        quarry.chi2_gate(np.zeros((1, 2)), np.eye(2)[None], np.zeros((1, 3)))
    with pytest.raises(ValueError, match="not supported"):
        quarry.chi2_gate(np.zeros((1, 5)), np.eye(5)[None], np.zeros((1, 5)))

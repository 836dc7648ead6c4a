"""Hypothesis over shapes, dtypes, values (NaN, infinities, huge numbers) and memory layouts for
every binding: each call either returns or raises ValueError / TypeError — never another
exception, never a Rust panic (pyo3's PanicException), never a crash of the interpreter."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import array_shapes, arrays

import quarry

DTYPES = [np.float64, np.float32, np.int64, np.int32, np.uint8, np.bool_]


@st.composite
def any_array(draw, max_dims=3, max_side=6):
    dt = draw(st.sampled_from(DTYPES))
    a = draw(arrays(dt, array_shapes(min_dims=0, max_dims=max_dims, min_side=0, max_side=max_side)))
    if a.ndim >= 1 and a.shape[-1] > 1 and draw(st.booleans()):
        a = a[..., ::2]  # a strided view
    return a


@st.composite
def float_array(draw, shape):
    """A float64 array of a plausible shape, with any values (NaN, inf, huge, tiny)."""
    return draw(arrays(np.float64, shape, elements=st.floats(allow_nan=True, allow_infinity=True)))


def kp(n):
    dt = np.dtype([("pt", "<f4", (2,)), ("size", "<f4"), ("angle", "<f4"), ("response", "<f4"),
                   ("octave", "<i4"), ("class_id", "<i4")])
    return np.zeros(n, dt)


CALLS = {
    "chi2_gate": (3, lambda a, b, c: quarry.chi2_gate(a, b, c)),
    "pda": (1, lambda a: quarry.pda(a, 0.9, 0.99, 1e-3)),
    "jpda": (1, lambda a: quarry.jpda(a, 0.9, 0.99, 1e-3)),
    "jpda_lbp": (1, lambda a: quarry.jpda(a, 0.9, 0.99, 1e-3, method="lbp")),
    "jipda": (2, lambda a, b: quarry.jipda(a, b, 0.9, 0.99, 1e-3)),
    "gnn": (1, lambda a: quarry.gnn(a, 0.9, 0.99, 1e-3)),
    "gnn_card": (1, lambda a: quarry.gnn(a, 0.9, 0.99, 1e-3, cost="max_cardinality")),
    "assign": (2, lambda a, b: quarry.assign(a, b)),
    "murty_k_best": (2, lambda a, b: quarry.murty_k_best(a, 4, b)),
    "mot_metrics": (2, lambda a, b: quarry.mot_metrics(a, b)),
    "mot_metrics_euclid": (2, lambda a, b: quarry.mot_metrics(a, b, similarity="euclidean", threshold=1.0)),
    "ospa": (2, lambda a, b: quarry.ospa(a, b, 2.0)),
    "gospa": (2, lambda a, b: quarry.gospa(a, b, 2.0, 2.0)),
    "gaussian_blur": (1, lambda a: quarry.gaussian_blur(a, 1.5)),
    "regional_minima": (1, lambda a: quarry.regional_minima(a, 8)),
    "watershed": (2, lambda a, b: quarry.watershed(a, b)),
    "sift_detect": (1, lambda a: quarry.Sift().detect(a)),
    "sift_compute": (2, lambda a, b: quarry.Sift().compute(a, b)),
    "match_sift": (2, lambda a, b: quarry.match_sift(a, b)),
    "kalman_filter": (6, lambda *a: quarry.KalmanFilter(*a)),
    "ekf_predict": (2, lambda a, b: quarry.ekf_predict(a, b, 0.1, q=0.5)),
    "ekf_predict_linear": (4, lambda a, b, c, d: quarry.ekf_predict(a, b, 0.1, motion="linear", F=c, Q=d)),
    "ekf_update": (3, lambda a, b, c: quarry.ekf_update(a, b, c, R=np.eye(2))),
    "ekf_update_rb": (4, lambda a, b, c, d: quarry.ekf_update(a, b, c, measurement="range_bearing", R=d)),
    "ekf_update_linear": (5, lambda a, b, c, d, e: quarry.ekf_update(a, b, c, measurement="linear", H=d, R=e)),
    "resample": (1, lambda a: quarry.resample(a, 3, "residual")),
    "normalise_log_weights": (1, lambda a: quarry.normalise_log_weights(a)),
    "effective_sample_size": (1, lambda a: quarry.effective_sample_size(a)),
    "particle_filter_cv2": (3, lambda a, b, c: quarry.particle_filter_cv2(a, b, 0.1, 0.5, c, 0)),
    "mean_shift": (1, lambda a: quarry.mean_shift(a)),
    "rigid_transform_2d": (3, lambda a, b, c: quarry.rigid_transform_2d(a, b, c)),
    "icp_2d": (2, lambda a, b: quarry.icp_2d(a, b)),
    "variance_chi2": (2, lambda a, b: quarry.VarianceChi2Test(a).test(b)),
    "chi2_background": (1, lambda a: quarry.ChiSquareBackground(5, 0.0, 0.1).classify(a, 0.0)),
    "track_video": (1, lambda a: quarry.track_video(a, person_size=(3.0, 5.0))),
    "track_lidar": (2, lambda a, b: quarry.track_lidar(a, b, 0.0, 0.1, config_toml="window_m = 2")),
    "track_rgbd": (2, lambda a, b: quarry.track_rgbd(a, b, (0.0, 0.0, 2.0, 2.0))),
}


def call(name, args):
    try:
        CALLS[name][1](*args)
    except (ValueError, TypeError):
        pass


@pytest.mark.parametrize("name", sorted(CALLS))
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_any_arrays(name, data):
    n = CALLS[name][0]
    call(name, [data.draw(any_array()) for _ in range(n)])


# Plausible shapes with arbitrary float values: reaches the numerical code more often than
# random shapes do.
SHAPED = {
    "chi2_gate": [(3, 2), (3, 2, 2), (4, 2)],
    "jpda": [(3, 4)],
    "jipda": [(3, 4), (3,)],
    "gnn": [(3, 4)],
    "assign": [(3, 4), (3,)],
    "murty_k_best": [(3, 3), (3,)],
    "mot_metrics": [(5, 6), (5, 6)],
    "mot_metrics_euclid": [(5, 4), (5, 4)],
    "ospa": [(4, 2), (3, 2)],
    "gospa": [(4, 2), (3, 2)],
    "gaussian_blur": [(6, 7)],
    "watershed": [(6, 7)],
    "ekf_predict": [(4,), (4, 4)],
    "ekf_update": [(4,), (4, 4), (2,)],
    "ekf_update_rb": [(4,), (4, 4), (2,), (2, 2)],
    "kalman_filter": [(2,), (2, 2), (2, 2), (2, 2), (1, 2), (1, 1)],
    "normalise_log_weights": [(6,)],
    "resample": [(6,)],
    "particle_filter_cv2": [(5, 4), (3, 2), (2, 2)],
    "mean_shift": [(8, 2)],
    "rigid_transform_2d": [(4, 2), (4, 2), (4,)],
    "icp_2d": [(6, 2), (5, 2)],
    "variance_chi2": [(3, 5), (5,)],
    "chi2_background": [(5,)],
    "track_lidar": [(6, 9), (6,)],
}


@pytest.mark.parametrize("name", sorted(SHAPED))
@settings(max_examples=80, deadline=None)
@given(data=st.data())
def test_shaped_float_arrays(name, data):
    call(name, [data.draw(float_array(s)) for s in SHAPED[name]])


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 3), st.floats(allow_nan=True, allow_infinity=True))
def test_sift_compute_keypoint_values(n, v):
    img = (np.arange(32 * 32) % 251).astype(np.uint8).reshape(32, 32)
    k = kp(n)
    with np.errstate(over="ignore"):
        k["pt"] = v
        k["size"] = v
    k["octave"] = int(np.nan_to_num(v, posinf=1e9, neginf=-1e9)) % (2**31) if np.isfinite(v) else 7
    call("sift_compute", [img, k])


def test_kalman_filter_methods_survive_bad_input():
    kf = quarry.KalmanFilter(np.zeros(2), np.eye(2), np.eye(2), np.eye(2), np.eye(1, 2), np.eye(1))
    for z in (np.array([np.inf]), np.zeros((1, 1)), np.zeros(0), np.array([1e308])):
        for f in (kf.step, kf.update):
            try:
                f(z)
            except (ValueError, TypeError):
                pass


def test_derived_matrices_beyond_memory_are_errors():
    """Small arguments whose derived matrix would not fit (an abort, not an exception) are
    refused: the gate output, GNN's and assign's miss-augmented problem, OSPA's distances."""
    big = np.zeros((100_000, 2))
    with pytest.raises(ValueError, match="z"):
        quarry.chi2_gate(big, np.broadcast_to(np.eye(2), (100_000, 2, 2)).copy(), big)
    with pytest.raises(ValueError, match="loglik"):
        quarry.gnn(np.zeros((100_000, 1)), 0.9, 0.99, 1e-3)
    with pytest.raises(ValueError, match="cost"):
        quarry.assign(np.zeros((100_000, 1)), np.zeros(100_000))
    with pytest.raises(ValueError, match="y"):
        quarry.ospa(big, big, 1.0)

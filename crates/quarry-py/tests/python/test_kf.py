"""quarry.KalmanFilter against filterpy's KalmanFilter, to 1e-9."""
import numpy as np
import pytest
from filterpy.kalman import KalmanFilter as FpKF

import quarry


def cv_model(dt=0.1):
    F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    q = 0.5
    Q = q * np.array(
        [
            [dt**3 / 3, 0, dt**2 / 2, 0],
            [0, dt**3 / 3, 0, dt**2 / 2],
            [dt**2 / 2, 0, dt, 0],
            [0, dt**2 / 2, 0, dt],
        ]
    )
    H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
    R = 0.25 * np.eye(2)
    return F, Q, H, R


def peer(F, Q, H, R, x, P):
    kf = FpKF(dim_x=4, dim_z=2)
    kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
    kf.x, kf.P = x.copy().reshape(4, 1), P.copy()
    return kf


def test_step_matches_filterpy():
    rng = np.random.default_rng(7)
    F, Q, H, R = cv_model()
    x0, P0 = np.zeros(4), np.eye(4)
    ours = quarry.KalmanFilter(x0, P0, F, Q, H, R)
    theirs = peer(F, Q, H, R, x0, P0)
    for t in range(200):
        z = np.array([t * 0.1, 0.05 * t]) + rng.normal(0, 0.5, 2)
        ours.step(z)
        theirs.predict()
        theirs.update(z)
        np.testing.assert_allclose(ours.x, theirs.x.ravel(), rtol=0, atol=1e-9)
        np.testing.assert_allclose(ours.P, theirs.P, rtol=0, atol=1e-9)


def test_filter_sequence_matches_filterpy():
    rng = np.random.default_rng(3)
    F, Q, H, R = cv_model()
    zs = rng.normal(0, 1, (100, 2)).cumsum(axis=0)
    ours = quarry.KalmanFilter(np.zeros(4), np.eye(4), F, Q, H, R)
    means = ours.filter_sequence(zs)
    theirs = peer(F, Q, H, R, np.zeros(4), np.eye(4))
    ref = []
    for z in zs:
        theirs.predict()
        theirs.update(z)
        ref.append(theirs.x.ravel().copy())
    np.testing.assert_allclose(means, np.array(ref), rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.P, theirs.P, rtol=0, atol=1e-9)


def test_errors_are_exceptions():
    F, Q, H, R = cv_model()
    with pytest.raises(ValueError, match="F"):
        quarry.KalmanFilter(np.zeros(4), np.eye(4), np.ones((4, 3)), Q, H, R)
    with pytest.raises(TypeError, match="x"):
        quarry.KalmanFilter(np.zeros(4, dtype=np.int32), np.eye(4), F, Q, H, R)
    kf = quarry.KalmanFilter(np.zeros(4), np.eye(4), F, Q, H, R)
    with pytest.raises(ValueError, match="z"):
        kf.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="z"):
        kf.step(np.zeros(3))

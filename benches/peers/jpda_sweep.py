#!/usr/bin/env python3
"""Stone Soup side of quarry's `cluster_sweep` benchmark (benches/assoc.rs): one scan of k
mutually gated targets, k = 2..12, with JPDA / JPDAwithEHM / JPDAwithEHM2 / JPDAwithLBP.

Geometry (identical in benches/assoc.rs `sweep_scene`): track i at (0.2 i, 0), zero velocity,
position covariance 0.75 I, measurement noise 0.25 I (so S = I), dt = 0; detection j < k at
(0.2 j + 0.1 sin(1.7 j + k), 0.1 cos(j)), two clutter points at (0.06 k, 0.3) and
(0.14 k, -0.3); P_D 0.9, P_G 0.99, clutter density 0.01. Every pair is inside the gate
(d² ≤ 5.2 < 9.21). Timing: associate() only (it includes Stone Soup's hypothesis generation,
i.e. the likelihoods); median of repeats, with a per-call budget: a variant is dropped for larger k
once one call exceeds 20 s.

Run with the peers venv:  ~/.cache/quarry-peers-venv/bin/python benches/peers/jpda_sweep.py
Prints one JSON line {k: {variant: seconds}}.
"""
import datetime
import json
import math
import sys
import time

import numpy as np
from stonesoup.dataassociator import probability as ssprob
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track
from stonesoup.updater.kalman import KalmanUpdater

T0 = datetime.datetime(2024, 1, 1)
tm = CombinedLinearGaussianTransitionModel([ConstantVelocity(1e-9), ConstantVelocity(1e-9)])
mm = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=0.25 * np.eye(2))
hyp = PDAHypothesiser(predictor=KalmanPredictor(tm), updater=KalmanUpdater(mm),
                      clutter_spatial_density=0.01, prob_detect=0.9, prob_gate=0.99)


def scene(k):
    P = np.diag([0.75, 1e-6, 0.75, 1e-6])
    tracks = {Track([GaussianState(np.array([[0.2 * i], [0.0], [0.0], [0.0]]), P, timestamp=T0)])
              for i in range(k)}
    pts = [(0.2 * j + 0.1 * math.sin(1.7 * j + k), 0.1 * math.cos(j)) for j in range(k)]
    pts += [(0.06 * k, 0.3), (0.14 * k, -0.3)]
    dets = {Detection(np.array([[x], [y]]), timestamp=T0, measurement_model=mm) for x, y in pts}
    return tracks, dets


variants = [("JPDA", ssprob.JPDA), ("JPDAwithEHM", ssprob.JPDAwithEHM),
            ("JPDAwithEHM2", ssprob.JPDAwithEHM2), ("JPDAwithLBP", ssprob.JPDAwithLBP)]
out = {}
dropped = set()
for k in range(2, 13):
    tracks, dets = scene(k)
    out[k] = {}
    for name, cls in variants:
        if name in dropped:
            continue
        assoc = cls(hypothesiser=hyp)
        samples = []
        total = 0.0
        while len(samples) < 5 and total < 20.0:
            t0 = time.perf_counter()
            assoc.associate(tracks, dets, T0)
            dt = time.perf_counter() - t0
            samples.append(dt)
            total += dt
        out[k][name] = float(np.median(samples))
        out[k][name + "_min"] = float(min(samples))
        if min(samples) > 20.0 / 5:
            dropped.add(name)
        print(k, name, out[k][name], file=sys.stderr, flush=True)
print(json.dumps(out))

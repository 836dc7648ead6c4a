#!/usr/bin/env python3
"""Batch-smoothing peer for `quarry slamot --mrclam --smooth` (issue 16): the same smoothing
problem solved by GTSAM (Georgia Tech Smoothing and Mapping, `pip install gtsam==4.3.0`) on one
robot of a UTIAS MRCLAM dataset, scored with the definitions of `mrclam_peers.py` (identical to
`quarry_repro::slamot::score`).

The factor graph, written here from GTSAM's documented factors, not from quarry's code:
- a node at the start (the true pose from Vicon, as for every filter) and at every distinct
  measurement stamp (an epoch, as in mrclam_peers.py);
- PriorFactorPose2 on the start node, sigma 1 mm / 1 mrad;
- BetweenFactorPose2 between consecutive nodes: the unicycle odometry integrated along exact
  arcs, its covariance propagated from the per-step control noise diag(sigma_v^2, sigma_w^2)
  (the textbook V M V^T of Table 5.3) and moved into GTSAM's tangent space at the end pose;
- BearingRangeFactor2D for each landmark detection (known correspondences through the
  barcodes), with a Huber(1.345) robust noise model on (sigma_b, sigma_r);
- Levenberg-Marquardt (GTSAM defaults, relative tolerance 1e-9, at most 100 iterations).

Noise: by default quarry's `mrclam` preset values (sigma_v 0.046 m/s, sigma_w 0.139 rad/s per
step, sigma_r 0.079 m, sigma_b 0.0109 rad: robot 1's, estimated against its Vicon truth), so that
this peer and quarry's smoother solve the same problem with different code; `--noise course`
uses mrclam_peers.py's course values instead.

Initial values: `--init dead_reckoning` (the odometry alone) or `--init ekf` (the textbook
EKF-SLAM of mrclam_peers.py run forward first: a filter front-end, as quarry starts from its
RBPF).

Usage (peers venv with gtsam added):
  ~/.cache/quarry-peers-venv/bin/pip install gtsam==4.3.0
  ~/.cache/quarry-peers-venv/bin/python benches/peers/mrclam_gtsam.py \\
      --data ../shared/data/mrclam-6 --robot 1 --init ekf
Prints one JSON line (scores, iterations, seconds for the graph build and the optimisation).
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mrclam_peers as mp  # noqa: E402

import gtsam  # noqa: E402

NOISE = {
    "quarry": (0.046, 0.139, 0.079, 0.0109),
    "course": (mp.SIG_V, mp.SIG_W, mp.SIG_R, mp.SIG_B),
}


def arc(v, w, dt):
    """Exact unicycle increment in the start frame."""
    th = w * dt
    if abs(th) < 1e-9:
        return v * dt, v * dt * th / 2.0, th
    return (v / w) * math.sin(th), (v / w) * (1.0 - math.cos(th)), th


class Segment:
    """Integrates odometry steps from the identity, with the covariance of the result."""

    def __init__(self, sv, sw):
        self.x = np.zeros(3)
        self.P = np.zeros((3, 3))
        self.M = np.diag([sv * sv, sw * sw])

    def step(self, dt, v, w):
        x, y, th = self.x
        dx, dy, dth = arc(v, w, dt)
        c, s = math.cos(th), math.sin(th)
        G = np.array([[1, 0, -s * dx - c * dy], [0, 1, c * dx - s * dy], [0, 0, 1]])
        # d(arc)/d(v, w), rotated into the segment frame
        h = 1e-7
        a0 = np.array(arc(v, w, dt))
        Jv = (np.array(arc(v + h, w, dt)) - a0) / h
        Jw = (np.array(arc(v, w + h, dt)) - a0) / h
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        V = R @ np.column_stack([Jv, Jw])
        self.P = G @ self.P @ G.T + V @ self.M @ V.T
        self.x = np.array([x + c * dx - s * dy, y + s * dx + c * dy, th + dth])

    def factor(self, i, j):
        dx, dy, dth = self.x
        # our covariance is of (dx, dy, dth) in the start frame; GTSAM's Pose2 tangent is at the
        # end pose: d (+) xi ~ d + blockdiag(R(dth), 1) xi
        c, s = math.cos(dth), math.sin(dth)
        A_inv = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
        cov = A_inv @ self.P @ A_inv.T + np.diag([1e-8, 1e-8, 1e-10])
        noise = gtsam.noiseModel.Gaussian.Covariance(0.5 * (cov + cov.T))
        return gtsam.BetweenFactorPose2(X(i), X(j), gtsam.Pose2(dx, dy, dth), noise)


def walk(run, move):
    """The recording's events in order: `move(dt, v, w)` with the controls in force since the
    previous event, then each measurement event yielded as (stamp, detections)."""
    t = run["t0"]
    u = (0.0, 0.0)
    for te, kind, payload in run["events"]:
        dt = te - t
        if dt > 0.0:
            move(dt, *u)
            t = te
        if kind == 0:
            u = payload
            continue
        yield te, payload


def X(i):
    return gtsam.symbol("x", i)


def L(j):
    return gtsam.symbol("l", j)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="../shared/data/mrclam-6")
    ap.add_argument("--robot", type=int, default=1)
    ap.add_argument("--init", choices=["dead_reckoning", "ekf"], default="ekf")
    ap.add_argument("--noise", choices=sorted(NOISE), default="quarry")
    args = ap.parse_args()
    sv, sw, sr, sb = NOISE[args.noise]
    run = mp.load(args.data, args.robot)
    gt = run["gt"]
    t_build = time.perf_counter()

    # nodes: the start and every measurement stamp; odometry segments between them
    graph = gtsam.NonlinearFactorGraph()
    init = run["init"]
    graph.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*init),
                                     gtsam.noiseModel.Diagonal.Sigmas([1e-3, 1e-3, 1e-3])))
    meas_noise = gtsam.noiseModel.Robust.Create(
        gtsam.noiseModel.mEstimator.Huber.Create(1.345),
        gtsam.noiseModel.Diagonal.Sigmas([sb, sr]))
    seg = Segment(sv, sw)
    node = 0
    node_t = [run["t0"]]
    first_obs = {}
    epochs_node = []  # (node, stamp) of every epoch inside the Vicon span
    # a lambda: `seg` is replaced at every new node, the moves go to the current one
    for te, payload in walk(run, lambda dt, v, w: seg.step(dt, v, w)):
        if te > node_t[-1]:
            graph.add(seg.factor(node, node + 1))
            node += 1
            node_t.append(te)
            seg = Segment(sv, sw)
        for j, r, b in payload:
            if j is None:
                continue
            graph.add(gtsam.BearingRangeFactor2D(X(node), L(j), gtsam.Rot2.fromAngle(b), r,
                                                 meas_noise))
            first_obs.setdefault(j, (node, r, b))
        if gt[0, 0] <= te <= gt[-1, 0]:
            epochs_node.append((node, te))

    # initial values: a forward method's pose at the start and at every new measurement stamp
    if args.init == "ekf":
        fwd = mp.EkfSlam(init)
        # the EKF with the same noise as the graph
        fwd.M = np.diag([sv * sv, sw * sw])
        fwd.Q = np.diag([sr * sr, sb * sb])
    else:
        fwd = mp.DeadReckoning(init)
    poses = [init.copy()]
    for te, payload in walk(run, fwd.propagate):
        obs = [(j, r, b) for j, r, b in payload if j is not None]
        if obs:
            fwd.update(obs)
        if len(poses) < len(node_t) and te == node_t[len(poses)]:
            poses.append(fwd.pose())
    lm_init = fwd.map()
    values = gtsam.Values()
    for i, p in enumerate(poses):
        values.insert(X(i), gtsam.Pose2(float(p[0]), float(p[1]), float(p[2])))
    for j, (n, r, b) in first_obs.items():
        if j in lm_init:
            m = lm_init[j]
        else:
            x, y, th = poses[n]
            m = np.array([x + r * math.cos(th + b), y + r * math.sin(th + b)])
        values.insert(L(j), gtsam.Point2(float(m[0]), float(m[1])))
    t_build = time.perf_counter() - t_build

    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-9)
    params.setMaxIterations(100)
    t_opt = time.perf_counter()
    opt = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    result = opt.optimize()
    t_opt = time.perf_counter() - t_opt

    epochs = []
    for n, te in epochs_node:
        p = result.atPose2(X(n))
        epochs.append((te - run["t0"], np.array([p.x(), p.y(), p.theta()]), mp.interp_pose(gt, te)))
    lm_map = {j: np.array(result.atPoint2(L(j))) for j in first_obs}
    s = mp.score(epochs, lm_map, run["lm_true"])
    s.update(method=f"gtsam_lm_{args.init}", robot=args.robot, noise=args.noise, nodes=node + 1,
             factors=graph.size(), iterations=opt.iterations(),
             error=[graph.error(values), graph.error(result)],
             seconds_build=round(t_build, 3), seconds_optimize=round(t_opt, 3))
    print(json.dumps(s), flush=True)


if __name__ == "__main__":
    main()

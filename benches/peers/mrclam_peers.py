#!/usr/bin/env python3
"""Textbook peers for `quarry slamot --mrclam` (issue 16): FastSLAM 1.0, EKF-SLAM and dead
reckoning on one robot of a UTIAS MRCLAM dataset, scored with the same definitions as
`quarry_repro::slamot::score` (docs/slamot.md, "Scores").

Written here from the textbook (Thrun, Burgard, Fox, "Probabilistic Robotics": Table 10.1 EKF
SLAM with known correspondences, Table 13.1 FastSLAM 1.0 with known correspondences, Table 4.4
low-variance resampling), in the style of the public course code
(ChengeYang/Probabilistic-Robotics-Algorithms), numpy only:
- the robot starts at its true pose (Vicon, interpolated at the first odometry time inside the
  robot's ground-truth span), no alignment;
- landmarks are known correspondences (barcode -> subject via Barcodes.dat); detections of the
  other robots and unknown barcodes are ignored (the peers do no target tracking);
- each measurement is applied at its own stamp: the unicycle is propagated with the current
  odometry command to the stamp, then updated (the same event order as quarry's reader);
- FastSLAM 1.0 resamples (low variance) after every landmark measurement, as in Table 13.1;
- bearing innovations are wrapped to (-pi, pi];
- noise: sigma_v = 0.1 m/s, sigma_omega = 0.15 rad/s (per odometry step, on the command),
  sigma_r = 0.05 m, sigma_b = 0.02 rad: the values of the public course code's MRCLAM test
  script (chosen there for dataset 1), NOT estimated from this recording's Vicon truth.

Scores (identical definitions in quarry): at every distinct measurement stamp inside the
robot's ground-truth span (an "epoch"), the estimated pose is compared with Vicon linearly
interpolated at that stamp:
- robot_err = mean_k |p_k - p*_k| (m), no alignment; robot_err_max = max_k;
- ate_rmse = sqrt(mean_k |p_k - p*_k|^2), no alignment;
- ate_rmse_aligned = the same after the least-squares rigid SE(2) transform (rotation +
  translation, no scale; Horn/Umeyama closed form) of the estimated positions onto the truth;
- map_err = mean over the landmarks in the final map of |m_j - m*_j|, no alignment.

Noise estimation for quarry's cross-robot protocol (docs/slamot.md): `--estimate-noise --robot K`
prints robot K's measurement residuals and odometry error against its own Vicon truth, to be
used when ANOTHER robot is evaluated.

Usage (peers venv, numpy only):
  ~/.cache/quarry-peers-venv/bin/python benches/peers/mrclam_peers.py \\
      --data ../shared/data/mrclam-6 --robot 1 --particles 100 --seeds 5
Prints one JSON line per (method, seed) and a summary line per method.
"""
import argparse
import json
import math
import sys
import time

import numpy as np

SIG_V, SIG_W = 0.1, 0.15
SIG_R, SIG_B = 0.05, 0.02


def wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def table(path, cols):
    rows = []
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            v = line.split()
            if len(v) != cols:
                raise ValueError(f"{path}: expected {cols} columns: {line!r}")
            rows.append([float(x) for x in v])
    return np.array(rows, dtype=float).reshape(-1, cols)


def interp_pose(gt, t):
    """Linear interpolation of [t, x, y, theta] rows at t (heading through the short way)."""
    i = int(np.searchsorted(gt[:, 0], t, side="right"))
    if i == 0:
        return gt[0, 1:4].copy()
    if i >= len(gt):
        return gt[-1, 1:4].copy()
    a, b = gt[i - 1], gt[i]
    s = (t - a[0]) / (b[0] - a[0]) if b[0] > a[0] else 0.0
    th = wrap(a[3] + s * wrap(b[3] - a[3]))
    return np.array([a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]), th])


def load(data, robot):
    bar = table(f"{data}/Barcodes.dat", 2)
    subject_of = {int(b): int(s) for s, b in bar}
    lms = table(f"{data}/Landmark_Groundtruth.dat", 5)
    lm_true = {int(r[0]) - 6: r[1:3] for r in lms}
    gt = table(f"{data}/Robot{robot}_Groundtruth.dat", 4)
    odo = table(f"{data}/Robot{robot}_Odometry.dat", 3)
    meas = table(f"{data}/Robot{robot}_Measurement.dat", 4)
    odo = odo[np.all(np.isfinite(odo), axis=1)]
    odo = odo[(odo[:, 0] >= gt[0, 0]) & (odo[:, 0] <= gt[-1, 0])]
    t0, t_end = odo[0, 0], odo[-1, 0]
    meas = meas[np.all(np.isfinite(meas), axis=1) & (meas[:, 2] > 0.0)]
    meas = meas[(meas[:, 0] > t0) & (meas[:, 0] <= t_end)]
    # events: ("odo", t, v, w) and ("meas", t, [(lm, r, b), ...]) grouped by stamp
    events = []
    for r in odo:
        events.append((r[0], 0, (r[1], r[2])))
    groups = {}
    for m in meas:
        s = subject_of.get(int(m[1]))
        groups.setdefault(m[0], []).append((s - 6 if s is not None and s >= 6 else None,
                                             m[2], wrap(m[3])))
    for t, g in groups.items():
        events.append((t, 1, g))
    # at equal times an odometry record is applied first (quarry: a measurement at an odometry
    # stamp closes the interval that ends there, the new command starts after it)
    events.sort(key=lambda e: (e[0], -e[1]))
    init = interp_pose(gt, t0)
    return dict(t0=t0, gt=gt, events=events, init=init, lm_true=lm_true)


def unicycle(x, y, th, v, w, dt):
    """Exact arc (straight line when |w| is tiny); arrays or scalars."""
    small = np.abs(w) < 1e-9
    ws = np.where(small, 1.0, w)
    nth = th + w * dt
    dx = np.where(small, v * dt * np.cos(th), (v / ws) * (np.sin(nth) - np.sin(th)))
    dy = np.where(small, v * dt * np.sin(th), (v / ws) * (-np.cos(nth) + np.cos(th)))
    return x + dx, y + dy, wrap(nth)


def low_variance(w, rng):
    n = len(w)
    pos = (rng.random() + np.arange(n)) / n
    c = np.cumsum(w)
    c[-1] = 1.0
    return np.searchsorted(c, pos)


class Runner:
    """Walks the events, calls propagate(dt, v, w) and update(obs), records the epochs."""

    def __init__(self, run):
        self.run = run

    def go(self, method):
        gt = self.run["gt"]
        t = self.run["t0"]
        u = (0.0, 0.0)
        epochs = []
        for te, kind, payload in self.run["events"]:
            dt = te - t
            if dt > 0.0:
                method.propagate(dt, *u)
                t = te
            if kind == 0:
                u = payload
            else:
                obs = [(j, r, b) for j, r, b in payload if j is not None]
                if obs:
                    method.update(obs)
                if gt[0, 0] <= te <= gt[-1, 0]:
                    epochs.append((te - self.run["t0"], method.pose(), interp_pose(gt, te)))
        return epochs


class DeadReckoning:
    def __init__(self, init):
        self.p = init.copy()

    def propagate(self, dt, v, w):
        self.p = np.array(unicycle(self.p[0], self.p[1], self.p[2], v, w, dt), dtype=float)

    def update(self, obs):
        pass

    def pose(self):
        return self.p.copy()

    def map(self):
        return {}


class FastSlam1:
    """Table 13.1, known correspondences, vectorised over particles."""

    def __init__(self, init, n, rng, n_lm=15):
        self.n, self.rng = n, rng
        self.x = np.full(n, init[0])
        self.y = np.full(n, init[1])
        self.th = np.full(n, init[2])
        self.mu = np.zeros((n, n_lm, 2))
        self.sig = np.zeros((n, n_lm, 2, 2))
        self.seen = np.zeros(n_lm, dtype=bool)
        self.w = np.full(n, 1.0 / n)
        self.Q = np.diag([SIG_R**2, SIG_B**2])

    def propagate(self, dt, v, w):
        vn = v + self.rng.normal(0.0, SIG_V, self.n)
        wn = w + self.rng.normal(0.0, SIG_W, self.n)
        self.x, self.y, self.th = unicycle(self.x, self.y, self.th, vn, wn, dt)

    def update(self, obs):
        for j, r, b in obs:
            if not self.seen[j]:
                a = self.th + b
                self.mu[:, j, 0] = self.x + r * np.cos(a)
                self.mu[:, j, 1] = self.y + r * np.sin(a)
                # H^-1 Q H^-T with H the Jacobian w.r.t. the landmark
                dx, dy = self.mu[:, j, 0] - self.x, self.mu[:, j, 1] - self.y
                H = self._jac(dx, dy)
                Hi = np.linalg.inv(H)
                self.sig[:, j] = Hi @ self.Q @ np.transpose(Hi, (0, 2, 1))
                self.seen[j] = True
                continue
            dx, dy = self.mu[:, j, 0] - self.x, self.mu[:, j, 1] - self.y
            q = dx * dx + dy * dy
            zhat = np.stack([np.sqrt(q), wrap(np.arctan2(dy, dx) - self.th)], axis=1)
            H = self._jac(dx, dy)
            S = H @ self.sig[:, j] @ np.transpose(H, (0, 2, 1)) + self.Q
            Si = np.linalg.inv(S)
            K = self.sig[:, j] @ np.transpose(H, (0, 2, 1)) @ Si
            nu = np.stack([r - zhat[:, 0], wrap(b - zhat[:, 1])], axis=1)
            self.mu[:, j] += np.einsum("nij,nj->ni", K, nu)
            self.sig[:, j] = (np.eye(2) - K @ H) @ self.sig[:, j]
            d2 = np.einsum("ni,nij,nj->n", nu, Si, nu)
            lik = np.exp(-0.5 * d2) / (2.0 * np.pi * np.sqrt(np.linalg.det(S)))
            w = self.w * lik
            s = w.sum()
            self.w = w / s if s > 1e-300 and np.isfinite(s) else np.full(self.n, 1.0 / self.n)
            idx = low_variance(self.w, self.rng)
            self.x, self.y, self.th = self.x[idx], self.y[idx], self.th[idx]
            self.mu, self.sig = self.mu[idx], self.sig[idx]
            self.w = np.full(self.n, 1.0 / self.n)

    @staticmethod
    def _jac(dx, dy):
        q = dx * dx + dy * dy
        sq = np.sqrt(q)
        H = np.empty((len(dx), 2, 2))
        H[:, 0, 0], H[:, 0, 1] = dx / sq, dy / sq
        H[:, 1, 0], H[:, 1, 1] = -dy / q, dx / q
        return H

    def pose(self):
        w = self.w
        return np.array([w @ self.x, w @ self.y,
                         math.atan2(w @ np.sin(self.th), w @ np.cos(self.th))])

    def map(self):
        return {int(j): self.w @ self.mu[:, j] for j in np.flatnonzero(self.seen)}


class EkfSlam:
    """Table 10.1, known correspondences; control noise mapped through V."""

    def __init__(self, init, n_lm=15):
        self.m = np.zeros(3 + 2 * n_lm)
        self.m[:3] = init
        self.P = np.zeros((3 + 2 * n_lm, 3 + 2 * n_lm))
        self.P[3:, 3:] = np.eye(2 * n_lm) * 1e10
        self.seen = np.zeros(n_lm, dtype=bool)
        self.M = np.diag([SIG_V**2, SIG_W**2])
        self.Q = np.diag([SIG_R**2, SIG_B**2])

    def propagate(self, dt, v, w):
        x, y, th = self.m[:3]
        nx, ny, nth = unicycle(x, y, th, v, w, dt)
        if abs(w) < 1e-9:
            G = np.array([[1, 0, -v * dt * math.sin(th)], [0, 1, v * dt * math.cos(th)],
                          [0, 0, 1]])
            V = np.array([[dt * math.cos(th), 0], [dt * math.sin(th), 0], [0, 0]])
        else:
            s0, c0, s1, c1 = math.sin(th), math.cos(th), math.sin(th + w * dt), math.cos(th + w * dt)
            G = np.array([[1, 0, (v / w) * (-c0 + c1)], [0, 1, (v / w) * (-s0 + s1)], [0, 0, 1]])
            V = np.array([[(-s0 + s1) / w, v * (s0 - s1) / w**2 + v * c1 * dt / w],
                          [(c0 - c1) / w, -v * (c0 - c1) / w**2 + v * s1 * dt / w],
                          [0, dt]])
        self.m[:3] = [float(nx), float(ny), float(nth)]
        P = self.P
        P[:3, :3] = G @ P[:3, :3] @ G.T + V @ self.M @ V.T
        P[:3, 3:] = G @ P[:3, 3:]
        P[3:, :3] = P[:3, 3:].T

    def update(self, obs):
        for j, r, b in obs:
            k = 3 + 2 * j
            x, y, th = self.m[:3]
            if not self.seen[j]:
                self.m[k] = x + r * math.cos(th + b)
                self.m[k + 1] = y + r * math.sin(th + b)
                self.seen[j] = True
            dx, dy = self.m[k] - x, self.m[k + 1] - y
            q = dx * dx + dy * dy
            sq = math.sqrt(q)
            zhat = np.array([sq, wrap(math.atan2(dy, dx) - th)])
            H = np.zeros((2, len(self.m)))
            H[:, :3] = [[-dx / sq, -dy / sq, 0.0], [dy / q, -dx / q, -1.0]]
            H[:, k:k + 2] = [[dx / sq, dy / sq], [-dy / q, dx / q]]
            S = H @ self.P @ H.T + self.Q
            K = self.P @ H.T @ np.linalg.inv(S)
            nu = np.array([r - zhat[0], wrap(b - zhat[1])])
            self.m += K @ nu
            self.m[2] = wrap(self.m[2])
            self.P = (np.eye(len(self.m)) - K @ H) @ self.P
            self.P = 0.5 * (self.P + self.P.T)

    def pose(self):
        return self.m[:3].copy()

    def map(self):
        return {int(j): self.m[3 + 2 * j:5 + 2 * j].copy() for j in np.flatnonzero(self.seen)}


def align_se2(est, true):
    """Least-squares rotation R and translation t with R est + t ~ true (no scale)."""
    me, mt = est.mean(axis=0), true.mean(axis=0)
    a, b = est - me, true - mt
    c = (a * b).sum()
    s = (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum()
    th = math.atan2(s, c)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    return R, mt - R @ me


def score(epochs, lm_map, lm_true):
    est = np.array([e[1][:2] for e in epochs])
    tru = np.array([e[2][:2] for e in epochs])
    err = np.linalg.norm(est - tru, axis=1)
    R, t = align_se2(est, tru)
    err_al = np.linalg.norm(est @ R.T + t - tru, axis=1)
    map_errs = [float(np.linalg.norm(m - lm_true[j])) for j, m in lm_map.items() if j in lm_true]
    return dict(
        robot_err=float(err.mean()),
        robot_err_max=float(err.max()),
        ate_rmse=float(math.sqrt((err**2).mean())),
        ate_rmse_aligned=float(math.sqrt((err_al**2).mean())),
        map_err=float(np.mean(map_errs)) if map_errs else float("nan"),
        landmarks_mapped=len(map_errs),
        epochs=len(epochs),
    )


def estimate_noise(data, robot, window=1.0):
    """Noise of robot `robot`'s sensors against its Vicon truth (to be used on the OTHER robots:
    estimating on the evaluated robot would fit the evaluation data). Measurement residuals of the
    landmark detections (robust std = 1.4826 MAD, and plain std); odometry: the control is
    integrated over `window`-second windows from the true pose, and the along-track distance and
    heading errors at the window's end converted to the per-step control noise of a model that
    draws (v + sigma_v e1, w + sigma_w e2) at every odometry step: std_T = sigma sqrt(dt T)."""
    run = load(data, robot)
    gt, lm_true = run["gt"], run["lm_true"]
    res_r, res_b = [], []
    odo = []
    for te, kind, payload in run["events"]:
        if kind == 0:
            odo.append((te, payload[0], payload[1]))
            continue
        p = interp_pose(gt, te)
        for j, r, b in payload:
            if j is None or j not in lm_true:
                continue
            dx, dy = lm_true[j][0] - p[0], lm_true[j][1] - p[1]
            res_r.append(r - math.hypot(dx, dy))
            res_b.append(wrap(b - (math.atan2(dy, dx) - p[2])))
    odo = np.array(odo)
    dts = np.diff(odo[:, 0])
    # irregular steps: var over a window = sigma^2 sum dt_i^2 = sigma^2 T mean(dt^2) / mean(dt)
    dt_mean = float(np.mean(dts**2) / np.mean(dts))
    e_d, e_h = [], []
    i = 0
    while i < len(odo) - 1:
        t_start = odo[i, 0]
        p = interp_pose(gt, t_start)
        q = p.copy()
        j = i
        while j < len(odo) - 1 and odo[j + 1, 0] <= t_start + window:
            q = np.array(unicycle(q[0], q[1], q[2], odo[j, 1], odo[j, 2], odo[j + 1, 0] - odo[j, 0]))
            j += 1
        if j == i:
            i += 1
            continue
        tr = interp_pose(gt, odo[j, 0])
        d_true = math.hypot(tr[0] - p[0], tr[1] - p[1])
        d_odo = math.hypot(q[0] - p[0], q[1] - p[1])
        e_d.append(d_odo - d_true)
        e_h.append(wrap(q[2] - tr[2]))
        i = j
    robust = lambda v: float(1.4826 * np.median(np.abs(np.array(v) - np.median(v))))
    sd = np.std(e_d)
    sh = np.std(e_h)
    return dict(
        robot=robot,
        range_std=float(np.std(res_r)), range_robust_std=robust(res_r),
        bearing_std=float(np.std(res_b)), bearing_robust_std=robust(res_b),
        range_bias=float(np.median(res_r)), bearing_bias=float(np.median(res_b)),
        odo_window_s=window, odo_dist_err_std=float(sd), odo_heading_err_std=float(sh),
        odo_dt=dt_mean,
        sigma_v_per_step=float(sd / math.sqrt(dt_mean * window)),
        sigma_w_per_step=float(sh / math.sqrt(dt_mean * window)),
        detections=len(res_r),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="../shared/data/mrclam-6")
    ap.add_argument("--robot", type=int, default=1)
    ap.add_argument("--particles", type=int, default=100)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--methods", default="fastslam1,ekf,dead_reckoning")
    ap.add_argument("--estimate-noise", action="store_true",
                    help="print the sensor noise of --robot against its Vicon truth and exit")
    args = ap.parse_args()
    if args.estimate_noise:
        print(json.dumps(estimate_noise(args.data, args.robot)))
        return
    run = load(args.data, args.robot)
    runner = Runner(run)
    methods = args.methods.split(",")
    summary = {}
    for name in methods:
        seeds = range(args.seeds) if name == "fastslam1" else range(1)
        for seed in seeds:
            rng = np.random.default_rng(seed)
            if name == "fastslam1":
                m = FastSlam1(run["init"], args.particles, rng)
            elif name == "ekf":
                m = EkfSlam(run["init"])
            elif name == "dead_reckoning":
                m = DeadReckoning(run["init"])
            else:
                sys.exit(f"unknown method {name}")
            t_start = time.perf_counter()
            epochs = runner.go(m)
            s = score(epochs, m.map(), run["lm_true"])
            s.update(method=name, robot=args.robot, seed=seed,
                     seconds=round(time.perf_counter() - t_start, 2))
            print(json.dumps(s), flush=True)
            summary.setdefault(name, []).append(s)
    for name, rows in summary.items():
        out = {"summary": name, "robot": args.robot, "runs": len(rows)}
        for key in ("robot_err", "robot_err_max", "ate_rmse", "ate_rmse_aligned", "map_err"):
            v = np.array([r[key] for r in rows])
            out[key] = [round(float(v.mean()), 3), round(float(v.std()), 3),
                        round(float(v.min()), 3), round(float(v.max()), 3)]
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()

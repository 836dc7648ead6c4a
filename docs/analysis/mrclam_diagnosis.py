#!/usr/bin/env python3
"""Why SLAM on UTIAS MRCLAM dataset 6 is hard for a forward filter (issue 16): measurements of the
recording itself against its Vicon truth, and two reference runs of the textbook FastSLAM 1.0
(benches/peers/mrclam_peers.py, unchanged). Every figure of docs/slamot.md "Diagnosis (stop 29)"
comes from this script; nothing here is fitted into quarry's configuration.

Usage (any Python with numpy, e.g. the peers venv):
    python docs/analysis/mrclam_diagnosis.py --data ../shared/data/mrclam-6 [--seeds 2]

Sections (one block of output each):
  1. landmark residuals against Vicon: range bias and spread by range, bearing spread (robust
     std = 1.4826 MAD) and gross outliers;
  2. odometry against Vicon: yaw-rate scale (least squares over 5-s windows), the time offset
     that best aligns the odometry's yaw increments with Vicon's, and the heading drift of pure
     odometry over windows of 5-120 s against what a white-noise model with the noise used by
     quarry's cross-robot protocol (0.139 rad/s per 15-ms step) predicts;
  3. landmark clusters in view: the 15 landmarks form 6 tight clusters (<= 0.35 m across); per
     5-s window, how many clusters the robot saw (one cluster constrains the pose only up to a
     rotation about it);
  4. the map's frame: at each landmark's first sighting, the heading error of pure odometry from
     the true start pose (no estimator anchored at the start pose can place that landmark
     better than range x this error without calibrating the odometry retroactively);
  5. FastSLAM 1.0 (the peer's code, N = 100) with the cross-robot noise, once mapping and once
     localising in the TRUE map: the gap between them is the part of the error the map causes.
"""
import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benches", "peers"))
import mrclam_peers as mp  # noqa: E402

CLUSTER = {6: "A", 7: "A", 8: "A", 9: "B", 10: "B", 11: "C", 12: "C", 13: "C", 14: "D",
           15: "D", 16: "E", 17: "E", 18: "E", 19: "F", 20: "F"}
# quarry's cross-robot protocol (docs/slamot.md row E): robot 1's noise
SIG_V, SIG_W, SIG_R, SIG_B = 0.046, 0.139, 0.079, 0.0109


def mad(v):
    return 1.4826 * float(np.median(np.abs(v - np.median(v))))


def raw(data, robot):
    bar = mp.table(f"{data}/Barcodes.dat", 2)
    b2s = {int(b): int(s) for s, b in bar}
    lms = mp.table(f"{data}/Landmark_Groundtruth.dat", 5)
    lm = {int(r[0]): r[1:3] for r in lms}
    gt = mp.table(f"{data}/Robot{robot}_Groundtruth.dat", 4)
    od = mp.table(f"{data}/Robot{robot}_Odometry.dat", 3)
    ms = mp.table(f"{data}/Robot{robot}_Measurement.dat", 4)
    od = od[np.all(np.isfinite(od), axis=1)]
    ms = ms[np.all(np.isfinite(ms), axis=1)]
    return b2s, lm, gt, od, ms


def residuals(data, robot):
    b2s, lm, gt, _, ms = raw(data, robot)
    th = np.unwrap(gt[:, 3])
    ms = ms[(ms[:, 0] >= gt[0, 0]) & (ms[:, 0] <= gt[-1, 0])]
    subj = np.array([b2s.get(int(b), -1) for b in ms[:, 1]])
    m, s = ms[subj >= 6], subj[subj >= 6]
    x, y = np.interp(m[:, 0], gt[:, 0], gt[:, 1]), np.interp(m[:, 0], gt[:, 0], gt[:, 2])
    h = np.interp(m[:, 0], gt[:, 0], th)
    lx, ly = np.array([lm[k][0] for k in s]), np.array([lm[k][1] for k in s])
    rr = np.hypot(lx - x, ly - y)
    er = m[:, 2] - rr
    eb = mp.wrap(m[:, 3] - mp.wrap(np.arctan2(ly - y, lx - x) - h))
    bins = []
    for lo, hi in [(0, 3), (3, 4.5), (4.5, 99)]:
        k = (rr >= lo) & (rr < hi)
        bins.append(f"[{lo},{hi if hi < 99 else 'inf'}) m: {np.median(er[k]):+.3f}/{mad(er[k]):.3f}")
    print(f"  robot {robot}: {len(m)} detections; range bias/robust std by range "
          + ", ".join(bins) + f"; bearing bias {np.median(eb):+.4f} robust std {mad(eb):.4f} rad,"
          f" |bearing err| > 0.5 rad: {int(np.sum(np.abs(eb) > 0.5))}")


def odometry(data, robot):
    _, _, gt, od, _ = raw(data, robot)
    th = np.unwrap(gt[:, 3])
    ct = od[:, 0]
    wint = np.r_[0.0, np.cumsum(od[:-1, 2] * np.diff(ct))]
    lo, hi = max(ct[0], gt[0, 0]) + 1.0, min(ct[-1], gt[-1, 0]) - 2.0
    best = None
    for off in np.arange(-0.5, 0.501, 0.05):
        t = np.arange(lo, hi - 1.0, 1.0)
        e = np.median(np.abs(np.diff(np.interp(t + off, gt[:, 0], th))
                             - np.diff(np.interp(t, ct, wint))))
        if best is None or e < best[1]:
            best = (off, e)
    off = best[0]
    t = np.arange(lo, hi - 5.0, 5.0)
    dg = np.diff(np.interp(t + off, gt[:, 0], th))
    do = np.diff(np.interp(t, ct, wint))
    scale = float(np.sum(dg * do) / np.sum(do * do))
    drift = []
    for w in [5, 30, 120]:
        t = np.arange(lo, hi - w - 1.0, 2.0)
        e = (np.interp(t + w, ct, wint) - np.interp(t, ct, wint)) - (
            np.interp(t + w + off, gt[:, 0], th) - np.interp(t + off, gt[:, 0], th))
        white = SIG_W * math.sqrt(0.015 * w)
        drift.append(f"{w} s: {math.sqrt(np.mean(e * e)):.3f} (model {white:.3f})")
    print(f"  robot {robot}: odometry leads Vicon by {off:+.2f} s; Vicon/odometry yaw scale "
          f"{scale:.3f}; heading drift rms over " + ", ".join(drift))


def clusters(data, robot):
    b2s, _, _, _, ms = raw(data, robot)
    s = np.array([b2s.get(int(b), -1) for b in ms[:, 1]])
    t = ms[s >= 6, 0]
    c = [CLUSTER[x] for x in s[s >= 6]]
    b = np.floor((t - t[0]) / 5.0).astype(int)
    seen = [set() for _ in range(b.max() + 1)]
    for i, x in zip(b, c):
        seen[i].add(x)
    n = np.array([len(x) for x in seen])
    print(f"  robot {robot}: 5-s windows with 0 / 1 / >= 2 clusters in view: "
          f"{np.mean(n == 0):.2f} / {np.mean(n == 1):.2f} / {np.mean(n >= 2):.2f}")


def first_sightings(data, robot):
    run = mp.load(data, robot)
    gt = run["gt"]
    t, u, p, seen, out = run["t0"], (0.0, 0.0), run["init"].copy(), set(), []
    for te, kind, pl in run["events"]:
        if te > t:
            x, y, h = mp.unicycle(p[0], p[1], p[2], u[0], u[1], te - t)
            p, t = np.array([float(x), float(y), float(h)]), te
        if kind == 0:
            u = pl
            continue
        for j, r, _ in pl:
            if j is not None and j not in seen:
                seen.add(j)
                g = mp.interp_pose(gt, te)
                out.append((te - run["t0"], CLUSTER[j + 6], r, mp.wrap(p[2] - g[2])))
    firsts = {}
    for o in out:
        firsts.setdefault(o[1], o)
    txt = ", ".join(f"{c} at {o[0]:.0f} s, {o[2]:.1f} m: {o[3]:+.3f} rad (~{abs(o[3]) * o[2]:.2f} m)"
                    for c, o in sorted(firsts.items(), key=lambda kv: kv[1][0]))
    print(f"  robot {robot}: odometry heading error at each cluster's first sighting: {txt}")


def fastslam(data, robot, seeds, known_map):
    mp.SIG_V, mp.SIG_W, mp.SIG_R, mp.SIG_B = SIG_V, SIG_W, SIG_R, SIG_B
    run = mp.load(data, robot)
    errs, maps = [], []
    for seed in range(seeds):
        f = mp.FastSlam1(run["init"], 100, np.random.default_rng(seed))
        if known_map:
            for j, m in run["lm_true"].items():
                f.mu[:, j] = m
                f.sig[:, j] = np.eye(2) * 1e-6
                f.seen[j] = True
        sc = mp.score(mp.Runner(run).go(f), f.map(), run["lm_true"])
        errs.append(sc["robot_err"])
        maps.append(sc["map_err"])
    return float(np.mean(errs)), float(np.mean(maps))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="../shared/data/mrclam-6")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--robots", default="1,2,3,4,5")
    a = ap.parse_args()
    if not os.path.isdir(a.data):
        print(f"skipped: {a.data} is absent")
        return
    robots = [int(r) for r in a.robots.split(",")]
    for title, fn in [("1. landmark residuals", residuals), ("2. odometry", odometry),
                      ("3. clusters in view", clusters), ("4. the map's frame", first_sightings)]:
        print(title)
        for r in robots:
            fn(a.data, r)
    print(f"5. FastSLAM 1.0 (peer code, N = 100, cross-robot noise, {a.seeds} seeds): "
          "robot error / map error (m)")
    for r in robots:
        slam = fastslam(a.data, r, a.seeds, False)
        loc = fastslam(a.data, r, a.seeds, True)
        print(f"  robot {r}: mapping {slam[0]:.3f} / {slam[1]:.3f}; in the true map {loc[0]:.3f}")


if __name__ == "__main__":
    main()

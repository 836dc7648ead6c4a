#!/usr/bin/env python3
"""What the `mrclam` preset's target values are measured from (issue 16, association of the
other robots): how often the camera reports a robot that is in its view, and how the robots move.

Usage (any Python with numpy, e.g. the peers venv):
    python docs/analysis/mrclam_target_stats.py --data ../shared/data/mrclam-6

1. Detection probability per observation epoch. An epoch is a time stamp of RobotK_Measurement
   (landmark or robot), as in quarry's MRCLAM runner. A target robot is "in view" when its Vicon
   position lies within the preset's sensor model (6 m, 72 degrees centred on the heading) of the
   observer's Vicon pose; P_D = epochs with a detection of it / epochs in view. Pooled over the
   five observers, per observer, and per 1-m range band.
2. Motion of the robots, from their own odometry (no Vicon): world-frame velocity
   v (cos th, sin th) with th the integrated yaw rate; the stationary standard deviation per
   axis sqrt(E|v|^2 / 2) and the correlation time (first lag where the velocity's
   autocorrelation falls below 1/e). The same from Vicon as a cross-check.
3. Sightings: per observer and target, detections and the number of runs separated by gaps of
   more than 10 s (a track that lives through shorter gaps needs one birth per run).
"""
import argparse

import numpy as np

FOV = 1.2 * np.pi / 3.0  # the preset's sensor_fov (72 degrees)
RANGE = 6.0  # the preset's sensor_range


def load(path):
    return np.loadtxt(path, comments="#")


def corr_time(t, vx, vy, step=0.1):
    tt = np.arange(t[0], t[-1], step)
    x, y = np.interp(tt, t, vx), np.interp(tt, t, vy)
    c0 = np.mean(x * x + y * y)
    for k in range(1, len(tt) // 2):
        if np.mean(x[:-k] * x[k:] + y[:-k] * y[k:]) / c0 < np.exp(-1.0):
            return k * step
    return float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True)
    a = ap.parse_args()
    d = a.data.rstrip("/") + "/"
    barcode_subject = {int(b): int(s) for s, b in load(d + "Barcodes.dat")}
    gt = {r: load(d + f"Robot{r}_Groundtruth.dat") for r in range(1, 6)}

    def at(r, t):
        g = gt[r]
        return np.array([np.interp(t, g[:, 0], g[:, i]) for i in (1, 2, 3)])

    print("1. detection probability per epoch, target in the preset's view (6 m, 72 deg)")
    tot_in = tot_det = 0
    bands = np.zeros((6, 2))
    for k in range(1, 6):
        m = load(d + f"Robot{k}_Measurement.dat")
        n_in = n_det = 0
        for t in np.unique(m[:, 0]):
            p = at(k, t)
            seen = {barcode_subject.get(int(b)) for b in m[m[:, 0] == t, 1]}
            for r in range(1, 6):
                if r == k:
                    continue
                q = at(r, t)
                dx, dy = q[0] - p[0], q[1] - p[1]
                rng = np.hypot(dx, dy)
                brg = (np.arctan2(dy, dx) - p[2] + np.pi) % (2 * np.pi) - np.pi
                if rng <= RANGE and abs(brg) <= 0.5 * FOV:
                    n_in += 1
                    n_det += r in seen
                    bands[min(int(rng), 5)] += (1, r in seen)
        print(f"   observer {k}: {n_det} / {n_in} = {n_det / n_in:.3f}")
        tot_in += n_in
        tot_det += n_det
    print(f"   pooled: {tot_det} / {tot_in} = {tot_det / tot_in:.3f}")
    print("   by range band [m]: " + ", ".join(
        f"{i}-{i + 1}: {b[1] / b[0]:.2f}" for i, b in enumerate(bands) if b[0] > 0))

    print("2. motion of the robots (odometry; Vicon in brackets)")
    sig_all, tau_all = [], []
    for r in range(1, 6):
        o = load(d + f"Robot{r}_Odometry.dat")
        t, v, w = o[:, 0], o[:, 1], o[:, 2]
        th = np.concatenate([[0.0], np.cumsum(w[:-1] * np.diff(t))])
        vx, vy = v * np.cos(th), v * np.sin(th)
        sig = np.sqrt(np.mean(vx ** 2 + vy ** 2) / 2)
        tau = corr_time(t, vx, vy)
        g = gt[r]
        tt = np.arange(g[0, 0], g[-1, 0], 0.1)
        gx = np.convolve(np.gradient(np.interp(tt, g[:, 0], g[:, 1]), tt), np.ones(5) / 5, "same")
        gy = np.convolve(np.gradient(np.interp(tt, g[:, 0], g[:, 2]), tt), np.ones(5) / 5, "same")
        print(f"   robot {r}: sigma_v per axis {sig:.3f} m/s ({np.sqrt(np.mean(gx**2 + gy**2) / 2):.3f}),"
              f" correlation time {tau:.1f} s ({corr_time(tt, gx, gy):.1f})")
        sig_all.append(sig)
        tau_all.append(tau)
    print(f"   mean over the robots: sigma_v {np.mean(sig_all):.3f} m/s, tau {np.mean(tau_all):.1f} s")

    print("3. sightings: detections, runs separated by > 10 s")
    for k in range(1, 6):
        m = load(d + f"Robot{k}_Measurement.dat")
        parts = []
        n_all = runs_all = 0
        for r in range(1, 6):
            if r == k:
                continue
            codes = [b for b, s in barcode_subject.items() if s == r]
            ts = np.unique(m[np.isin(m[:, 1], codes), 0])
            n = int(np.sum(np.isin(m[:, 1], codes)))
            runs = 1 + int(np.sum(np.diff(ts) > 10.0)) if len(ts) else 0
            parts.append(f"robot {r}: {n} in {runs} runs")
            n_all += n
            runs_all += runs
        print(f"   observer {k}: " + "; ".join(parts)
              + f" -> at most {1 - runs_all / n_all:.3f} associated if every run starts a track")


if __name__ == "__main__":
    main()

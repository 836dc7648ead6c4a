#!/usr/bin/env python3
"""Copy of ../shared/peers/bench_icp.py restricted to the Open3D peer (numpy and simpleicp dropped:
simpleicp alone takes minutes). (f) ICP of the 36-point ellipse model and the observed partial noisy arcs (20 trials).

Known truth per trial: observed = R(theta) * model_point + t.  Two initialisations: the identity,
and the tracker-like predicted pose of icp_transforms.csv (truth + up to 5 deg / 3 cm); the
source is pre-transformed by the initial guess and the result composed with it, identically for
every peer.  Two directions are reported:
  arc->model  source = observed arc, target = full model; the estimate of (theta, t) is the
              inverse of the returned transform (every observed point has a true partner);
  model->arc  source = model, target = arc; the returned transform is the estimate directly
              (the unseen half of the model biases plain point-to-point ICP).
Peers: open3d registration_icp point-to-point (z = 0, max correspondence distance 0.5 m, up to
100 iterations, relative fitness/rmse 1e-9), simpleicp (point-to-plane; needs 3D surfaces, so
the 2D points are extruded to z in {-0.1, -0.05, 0, 0.05, 0.1}; needs pandas < 3), and a hand-written numpy 2D point-to-point
ICP (brute-force nearest neighbour + SVD, same stopping rule) as a floor.
Figures: median us per registration (over the 20 trials), trial-0 errors, median errors, and the
success rate (rotation error < 2 deg and translation error < 2 cm).
"""
import contextlib
import io
import math
import warnings

import common
import numpy as np

model = np.stack([common.read_csv("icp_model.csv")[c] for c in ("x", "y")], 1)
obs_all = common.read_csv("icp_observed.csv")
tf = common.read_csv("icp_transforms.csv")
TRIALS = [(int(r["trial"]), math.radians(r["theta_deg"]), np.array([r["tx"], r["ty"]])) for r in tf]
INITS = {int(r["trial"]): (math.radians(r["init_theta_deg"]), np.array([r["init_tx"], r["init_ty"]])) for r in tf}
OBS = {t: np.stack([obs_all["x"][obs_all["trial"] == t], obs_all["y"][obs_all["trial"] == t]], 1)
       for t, _, _ in TRIALS}
rep = common.Report("icp_2d")


def to_theta_t(T):
    """2D pose (theta, t) from a 3x3 or 4x4 homogeneous rigid transform."""
    return math.atan2(T[1, 0], T[0, 0]), np.array([T[0, -1], T[1, -1]])


def inv(T):
    Ti = np.eye(T.shape[0])
    Ti[:-1, :-1] = T[:-1, :-1].T
    Ti[:-1, -1] = -T[:-1, :-1].T @ T[:-1, -1]
    return Ti


def errors(T_model_to_obs, theta, t):
    th, tt = to_theta_t(T_model_to_obs)
    dth = abs((th - theta + math.pi) % (2 * math.pi) - math.pi)
    return math.degrees(dth), float(np.linalg.norm(tt - t))


def numpy_icp(src, dst, max_iter=100, max_dist=0.5, tol=1e-9):
    """2D point-to-point ICP, returns 3x3 T with dst ~ T src."""
    T = np.eye(3)
    cur = src.copy()
    prev = None
    for _ in range(max_iter):
        d2 = np.sum((cur[:, None] - dst[None]) ** 2, axis=2)
        j = np.argmin(d2, axis=1)
        ok = d2[np.arange(len(cur)), j] <= max_dist ** 2
        a, b = cur[ok], dst[j[ok]]
        rmse = math.sqrt(np.mean(d2[np.arange(len(cur)), j][ok]))
        ma, mb = a.mean(0), b.mean(0)
        H = (a - ma).T @ (b - mb)
        U, S, Vt = np.linalg.svd(H)
        R = Vt.T @ U.T
        if np.linalg.det(R) < 0:
            Vt[1] *= -1
            R = Vt.T @ U.T
        tt = mb - R @ ma
        step = np.eye(3)
        step[:2, :2], step[:2, 2] = R, tt
        T = step @ T
        cur = cur @ R.T + tt
        if prev is not None and abs(prev - rmse) <= tol * max(prev, 1e-12):
            break
        prev = rmse
    return T


def pose(theta, t):
    T = np.eye(3)
    c, s_ = math.cos(theta), math.sin(theta)
    T[:2, :2] = [[c, -s_], [s_, c]]
    T[:2, 2] = t
    return T


def as3(T):
    """4x4 (z = 0 plane) or 3x3 -> 3x3 planar transform."""
    if T.shape == (3, 3):
        return T
    return np.array([[T[0, 0], T[0, 1], T[0, 3]], [T[1, 0], T[1, 1], T[1, 3]], [0.0, 0.0, 1.0]])


def evaluate(name, dist, register, repeat=5, inits=("identity", "predicted")):
    """register(src, dst) -> T (dst ~ T src).  Runs both directions, both inits, on all trials."""
    for init in inits:
        for direction in ("arc->model", "model->arc"):
            errs, times = [], []
            for t, theta, tt in TRIALS:
                obs = OBS[t]
                T0 = pose(*INITS[t]) if init == "predicted" else np.eye(3)   # model -> obs guess
                if direction == "arc->model":
                    Tinit, src, dst = inv(T0), obs, model
                else:
                    Tinit, src, dst = T0, model, obs
                src0 = src @ Tinit[:2, :2].T + Tinit[:2, 2]
                fn = lambda: register(src0, dst)
                T = as3(fn()) @ Tinit
                Tm = inv(T) if direction == "arc->model" else T
                errs.append(errors(Tm, theta, tt))
                times.append(common.bench(fn, repeat=repeat, warmup=1 if repeat > 1 else 0))
            errs = np.array(errs)
            ok = (errs[:, 0] < 2.0) & (errs[:, 1] < 0.02)
            tag = "%s [%s, init %s]" % (name, direction, init)
            rep.add(tag, dist, "time per registration", float(np.median(times)) * 1e6, "us",
                    min=float(np.min(times)) * 1e6)
            rep.add(tag, dist, "trial 0 rotation error", errs[0, 0], "deg", translation_m=errs[0, 1])
            rep.add(tag, dist, "median rotation error (20 trials)", float(np.median(errs[:, 0])), "deg")
            rep.add(tag, dist, "median translation error (20 trials)", float(np.median(errs[:, 1])), "m")
            rep.add(tag, dist, "success rate (<2 deg, <2 cm)", float(ok.mean()), "ratio")



try:
    import open3d as o3d
    reg = o3d.pipelines.registration

    def o3d_icp(src, dst):
        ps = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.c_[src, np.zeros(len(src))]))
        pd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.c_[dst, np.zeros(len(dst))]))
        r = reg.registration_icp(ps, pd, 0.5, np.eye(4), reg.TransformationEstimationPointToPoint(),
                                 reg.ICPConvergenceCriteria(relative_fitness=1e-9, relative_rmse=1e-9,
                                                            max_iteration=100))
        return np.asarray(r.transformation)

    evaluate("open3d registration_icp point-to-point", "open3d", o3d_icp, inits=("predicted",))
    rep.info["open3d_threads_note"] = "OMP_NUM_THREADS as set by the caller"
except Exception as e:  # pragma: no cover
    rep.info["open3d"] = "failed: %r" % e

rep.emit()

"""Times quarry's Python bindings and filterpy side by side in one run.

Usage: PYTHONPATH=<dir holding quarry.so, built with --release> python benches/python/bench_bindings.py
"""
import timeit

import numpy as np
from filterpy.kalman import KalmanFilter as FpKF

import quarry

dt = 0.1
F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
Q = 0.01 * np.eye(4)
H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
R = 0.25 * np.eye(2)
T = 1000
zs = np.random.default_rng(0).normal(0, 1, (T, 2)).cumsum(axis=0)


def fp():
    kf = FpKF(dim_x=4, dim_z=2)
    kf.F, kf.Q, kf.H, kf.R = F, Q, H, R
    kf.x, kf.P = np.zeros((4, 1)), np.eye(4)
    return kf


def best(stmt, number):
    return min(timeit.repeat(stmt, number=number, repeat=5)) / number


kf_fp = fp()
z0 = zs[0]


def fp_step():
    kf_fp.predict()
    kf_fp.update(z0)


kf_q = quarry.KalmanFilter(np.zeros(4), np.eye(4), F, Q, H, R)
t_fp = best(fp_step, 2000)
t_q = best(lambda: kf_q.step(z0), 20000)
t_noop = best(lambda: kf_q.predict, 20000)


def fp_seq():
    k = fp()
    for z in zs:
        k.predict()
        k.update(z)


def q_seq():
    quarry.KalmanFilter(np.zeros(4), np.eye(4), F, Q, H, R).filter_sequence(zs)


t_fp_seq = best(fp_seq, 3)
t_q_seq = best(q_seq, 50)
print("| workload | filterpy | quarry | ratio |")
print("|---|---|---|---|")
print(f"| KF step per call (4-state CV, 2-D z) | {t_fp*1e6:.2f} µs | {t_q*1e6:.3f} µs | {t_fp/t_q:.1f}x |")
print(f"| filter_sequence, T = {T} | {t_fp_seq*1e3:.2f} ms | {t_q_seq*1e3:.3f} ms | {t_fp_seq/t_q_seq:.0f}x |")
print(f"| timeit lambda + bound-method lookup floor (no Rust call) | | {t_noop*1e9:.0f} ns | |")

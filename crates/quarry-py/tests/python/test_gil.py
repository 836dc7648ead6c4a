"""Long calls release the GIL: a Python thread keeps running while another thread is inside a
quarry call (with the GIL held it would be frozen until the call returns)."""
import threading
import time

import numpy as np
import pytest

import quarry


def python_progress_during(call):
    """Counts the iterations of a pure-Python loop in the main thread while `call` runs in a
    second thread; returns (iterations, seconds the call took)."""
    started, done = threading.Event(), threading.Event()
    took = []

    def worker():
        started.set()
        t0 = time.perf_counter()
        call()
        took.append(time.perf_counter() - t0)
        done.set()

    th = threading.Thread(target=worker)
    th.start()
    started.wait()
    n = 0
    while not done.is_set():
        n += 1
    th.join()
    return n, took[0]


rng = np.random.default_rng(0)
IMG = (rng.random((600, 800)) * 255).astype(np.uint8)
RELIEF = rng.random((2000, 2000))
GT = np.array([[f, i, 10 * i + f, 5.0, 30.0, 60.0] for f in range(1, 8001) for i in range(8)])
LOGLIK = rng.uniform(-6, 0, (14, 15))


def free_rate(seconds=0.05):
    """Iterations per second of the same loop with nothing else running."""
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        n += 1
    return n / seconds


@pytest.mark.parametrize("name,call", [
    ("Sift.detect_and_compute", lambda: quarry.Sift().detect_and_compute(IMG)),
    ("watershed", lambda: quarry.watershed(RELIEF)),
    ("mot_metrics", lambda: quarry.mot_metrics(GT, GT + [0, 0, 1, 1, 0, 0])),
    ("jpda exact", lambda: quarry.jpda(LOGLIK, 0.9, 0.99, 1e-3, method="exact")),
])
def test_long_calls_release_the_gil(name, call):
    n, took = python_progress_during(call)
    print(f"{name}: {took * 1e3:.0f} ms, {n} Python iterations meanwhile")
    rate = free_rate()
    assert took > 0.05, "the workload is too small to tell"
    # with the GIL held the main thread runs at most one switch interval (5 ms) of the call;
    # released, it runs most of the time (the loop's perf_counter calls make the free rate an
    # underestimate of the counting loop's)
    assert n > 0.3 * rate * took, (n, rate, took)

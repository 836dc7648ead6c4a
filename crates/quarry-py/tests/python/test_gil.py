"""Long calls release the GIL: a Python thread keeps running while another thread is inside a
quarry call (with the GIL held it would stall until the call returns)."""
import threading
import time

import numpy as np
import pytest

import quarry


def python_progress_during(call):
    """Runs `call` in a second thread while the main thread loops on the clock; returns (the
    longest time the main thread went without an iteration while the call ran, the call's
    duration). With the GIL held by the call the main thread would stall for (almost) all of
    it; with the GIL released it only waits for the scheduler."""
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
    last = time.perf_counter()
    longest = 0.0
    while not done.is_set():
        now = time.perf_counter()
        longest = max(longest, now - last)
        last = now
    # a call holding the GIL blocks the loop once, and the loop then sees `done` at once: that
    # last gap counts too
    longest = max(longest, time.perf_counter() - last)
    th.join()
    return longest, took[0]


rng = np.random.default_rng(0)
IMG = (rng.random((600, 800)) * 255).astype(np.uint8)
RELIEF = rng.random((2000, 2000))
GT = np.array([[f, i, 10 * i + f, 5.0, 30.0, 60.0] for f in range(1, 8001) for i in range(8)])
LOGLIK = rng.uniform(-6, 0, (14, 15))


@pytest.mark.parametrize("name,call", [
    ("Sift.detect_and_compute", lambda: quarry.Sift().detect_and_compute(IMG)),
    ("watershed", lambda: quarry.watershed(RELIEF)),
    ("mot_metrics", lambda: quarry.mot_metrics(GT, GT + [0, 0, 1, 1, 0, 0])),
    ("jpda exact", lambda: quarry.jpda(LOGLIK, 0.9, 0.99, 1e-3, method="exact")),
])
def test_long_calls_release_the_gil(name, call):
    longest, took = python_progress_during(call)
    print(f"{name}: {took * 1e3:.0f} ms, longest stall of the other Python thread {longest * 1e3:.1f} ms")
    assert took > 0.08, "the workload is too small to tell"
    assert longest < 0.5 * took

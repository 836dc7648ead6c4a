"""Long calls release the GIL: a Python thread runs while another thread is inside a quarry call.

No duration is asserted. The worker thread records the interval of each quarry call; the main
thread spins, recording when it ran. While a call holds the GIL the main thread cannot execute a
single bytecode, so none of its timestamps can fall inside the call's interval (less a margin of
a few switch intervals at each end, where the interpreter hands the GIL over). With the GIL
released the main thread runs throughout. The assertion is about the order of events, so a
loaded machine can only make the call longer, not the test fail.
"""
import sys
import threading
import time

import numpy as np
import pytest

import quarry

SWITCH = 0.001  # the interpreter's switch interval during the test, seconds
MARGIN = 8 * SWITCH  # edges of a call where a GIL hand-over can legitimately happen
ROUNDS = 3  # calls per workload: the main thread has several windows to show it ran


def main_thread_ran_inside(call):
    """(main-thread iterations inside the calls' intervals less the margins, the intervals, the
    fraction of those intervals' 1-ms bins in which the main thread ran)."""
    done = threading.Event()
    windows = []

    def worker():
        for _ in range(ROUNDS):
            t0 = time.perf_counter()
            call()
            windows.append((t0, time.perf_counter()))
        done.set()

    old = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH)
    try:
        stamps = []
        th = threading.Thread(target=worker)
        th.start()
        while not done.is_set():
            if len(stamps) < 400_000:
                stamps.append(time.perf_counter())
        th.join()
    finally:
        sys.setswitchinterval(old)
    stamps = np.array(stamps)
    inside, bins, covered = 0, 0, 0
    for t0, t1 in windows:
        a, b = t0 + MARGIN, t1 - MARGIN
        hit = stamps[(stamps > a) & (stamps < b)]
        inside += len(hit)
        if b > a:
            n = int(np.ceil((b - a) / SWITCH))
            bins += n
            covered += len(np.unique(np.floor((hit - a) / SWITCH)))
    return inside, windows, covered / bins if bins else 0.0


rng = np.random.default_rng(0)
IMG = (rng.random((600, 800)) * 255).astype(np.uint8)
RELIEF = rng.random((2000, 2000))
GT = np.array([[f, i, 10 * i + f, 5.0, 30.0, 60.0] for f in range(1, 16001) for i in range(8)])
LOGLIK = rng.uniform(-6, 0, (14, 15))


@pytest.mark.parametrize("name,call", [
    ("Sift.detect_and_compute", lambda: quarry.Sift().detect_and_compute(IMG)),
    ("watershed", lambda: quarry.watershed(RELIEF)),
    ("mot_metrics", lambda: quarry.mot_metrics(GT, GT + [0, 0, 1, 1, 0, 0])),
    ("jpda exact", lambda: quarry.jpda(LOGLIK, 0.9, 0.99, 1e-3, method="exact")),
])
def test_long_calls_release_the_gil(name, call):
    inside, windows, _ = main_thread_ran_inside(call)
    span = sum(max(0.0, t1 - t0 - 2 * MARGIN) for t0, t1 in windows)
    print(f"{name}: {len(windows)} calls, {span * 1e3:.0f} ms inside the margins, "
          f"{inside} main-thread iterations there")
    if span <= 0.0:
        pytest.skip(f"{name}: every call was shorter than twice the margin; nothing to observe")
    assert inside > 0, f"{name} held the GIL: the main thread never ran during {span:.3f} s of calls"


def test_the_check_tells_a_call_that_holds_the_gil():
    """The check can fail: builtin sum over a range runs in C without releasing the GIL, and the
    main thread runs in (almost) none of its interval. A stray iteration can still land inside
    when the OS preempts the main thread just as it takes the GIL at a call's end, so this
    reference asks for little coverage, not for none; a releasing call leaves the main thread
    running throughout."""
    inside, windows, coverage = main_thread_ran_inside(lambda: sum(range(6_000_000)))
    span = sum(max(0.0, t1 - t0 - 2 * MARGIN) for t0, t1 in windows)
    print(f"sum(range): {span * 1e3:.0f} ms inside the margins, {inside} iterations, "
          f"coverage {coverage:.3f}")
    if span <= 0.0:
        pytest.skip("the reference call was shorter than twice the margin")
    assert coverage < 0.2, f"the main thread ran in {coverage:.0%} of a GIL-holding call"

#!/usr/bin/env python3
"""CPU-time twin of ../shared/peers/bench_blur.py and bench_watershed.py (same workloads).

Times each peer call with time.thread_time() (CPU time of the calling thread), one thread
(cv2.setNumThreads(1); numpy/scipy/skimage are single-threaded here), so the figures can be set
beside quarry's `segmentation-cpu` criterion group on a machine loaded by other processes.
Prints one JSON line: min and median CPU ms per call for each workload.
Run: ~/.cache/quarry-peers-venv/bin/python benches/peers/seg_cpu.py [path/to/photo_gray.png]
"""
import json
import os
import statistics
import sys
import time

import cv2
import numpy as np
from scipy import ndimage
from skimage.morphology import local_minima
from skimage.segmentation import watershed

here = os.path.dirname(os.path.abspath(__file__))
path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "..", "..", "shared", "bench-data", "photo_gray.png")
cv2.setNumThreads(1)
gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
blurred = cv2.GaussianBlur(gray, (0, 0), 8.0, borderType=cv2.BORDER_REFLECT_101)
markers, nseeds = ndimage.label(local_minima(blurred, connectivity=1))
markers = markers.astype(np.int32)
img8 = cv2.cvtColor(np.clip(np.rint(blurred), 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)


def cpu(fn, repeat, warmup=2):
    for _ in range(warmup):
        fn()
    s = []
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        s.append((time.thread_time() - t0) * 1e3)
    return {"min_ms": min(s), "median_ms": statistics.median(s), "n": repeat}


rows = {
    "cv2.GaussianBlur f32 sigma8 1 thread": cpu(lambda: cv2.GaussianBlur(gray, (0, 0), 8.0, borderType=cv2.BORDER_REFLECT_101), 41),
    "scipy.ndimage.gaussian_filter f32 sigma8": cpu(lambda: ndimage.gaussian_filter(gray, 8.0, mode="mirror", truncate=4.0), 11),
    "skimage local_minima (mask)": cpu(lambda: local_minima(blurred, connectivity=1), 15),
    "local_minima + ndimage.label": cpu(lambda: ndimage.label(local_minima(blurred, connectivity=1)), 15),
    "skimage watershed 4-conn": cpu(lambda: watershed(blurred, markers), 9),
    "cv2.watershed 8UC3 1 thread": cpu(lambda: cv2.watershed(img8, markers.copy()), 21),
}
print(json.dumps({"workload": "segmentation peers, CPU time", "seeds": int(nseeds),
                  "cv2": cv2.__version__, "rows": rows}))

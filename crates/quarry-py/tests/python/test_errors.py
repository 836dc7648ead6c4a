"""Hypothesis: any shape/dtype given to KalmanFilter raises a clean exception or works; never a crash."""
import numpy as np
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays, array_shapes

import quarry

dtypes = st.sampled_from([np.float64, np.float32, np.int64, np.uint8, np.bool_])
any_array = dtypes.flatmap(
    lambda dt: arrays(dt, array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=4))
)


@settings(max_examples=200, deadline=None)
@given(st.lists(any_array, min_size=6, max_size=6), any_array)
def test_never_crashes(args, z):
    try:
        kf = quarry.KalmanFilter(*args)
    except (ValueError, TypeError):
        return
    for call in (kf.step, kf.update, kf.filter_sequence):
        try:
            call(z)
        except (ValueError, TypeError):
            pass

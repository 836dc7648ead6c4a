"""Shared fixtures: where the bench inputs are (../shared/bench-data beside the checkout)."""
import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[4]


def bench_data_dir():
    env = os.environ.get("QUARRY_BENCH_DATA")
    return pathlib.Path(env) if env else ROOT.parent / "shared" / "bench-data"


@pytest.fixture(scope="session")
def bench_data():
    d = bench_data_dir()
    if not (d / "params.json").exists():
        msg = f"bench inputs not found at {d} (set QUARRY_BENCH_DATA)"
        if os.environ.get("QUARRY_REQUIRE_PYTHON"):
            pytest.fail(msg)
        pytest.skip(msg)
    return d


# CI runs a fixed set of examples (reproducible runs); elsewhere hypothesis explores new ones.
from hypothesis import settings  # noqa: E402

settings.register_profile("ci", derandomize=True)
if os.environ.get("QUARRY_REQUIRE_PYTHON"):
    settings.load_profile("ci")

"""Shared test settings: every random choice is seeded."""
import os

# Tests check correctness, not speed: no cache flushing between timed runs (bench/timing.py);
# tests/bench/test_bench.py::test_flush_caches_evicts covers the flush itself.
os.environ.setdefault("HFTRACE_FLUSH_MB", "0")

from hypothesis import HealthCheck, settings

# derandomize: Hypothesis draws the same examples on every run and machine
settings.register_profile(
    "hftrace", derandomize=True, deadline=None, print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
    max_examples=int(os.environ.get("HFTRACE_HYPOTHESIS_EXAMPLES", "200")),
)
settings.load_profile("hftrace")


import pytest  # noqa: E402


@pytest.fixture(autouse=True, scope="session")
def _private_cache(tmp_path_factory):
    """Tests never touch the user's dataset cache: one temporary cache per session
    (inherited by the subprocesses the tests start)."""
    os.environ["HFTRACE_CACHE"] = str(tmp_path_factory.mktemp("hftrace-cache"))
    yield


_START_AFFINITY = set(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None


@pytest.fixture(autouse=True)
def _restore_cpu_affinity():
    """A study or command run in-process pins this process to one CPU (as the command line
    does): every test starts with the CPUs the session started with, so a test that
    measures contention sees every CPU and not the one an earlier test left."""
    if _START_AFFINITY is not None and set(os.sched_getaffinity(0)) != _START_AFFINITY:
        os.sched_setaffinity(0, _START_AFFINITY)
    yield
    if _START_AFFINITY is not None and set(os.sched_getaffinity(0)) != _START_AFFINITY:
        os.sched_setaffinity(0, _START_AFFINITY)

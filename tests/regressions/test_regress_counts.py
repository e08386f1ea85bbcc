"""The instruction-count regression gate (hftrace regress --metric instructions)."""
import json
import os
import shutil

import pytest

from bench.regress import instructions_gate as rc

needs_valgrind = pytest.mark.skipif(
    shutil.which("valgrind") is None or "libasan" in os.environ.get("LD_PRELOAD", ""),
    reason="needs valgrind (and no preloaded sanitizer runtime)")

SOME = {"first_hit/triangles/dda", "first_hit/bilinear/runs", "first_hit/flat/runs_maxmip",
        "first_hit/plane3/dda_maxmip", "visit/-/midpoint", "runs/-/runs_periodic"}


@pytest.fixture(scope="module")
def counted():
    return rc.measure(echo=lambda *_: None, only=SOME)


@needs_valgrind
def test_counts_are_identical_across_runs(counted):
    again = rc.measure(echo=lambda *_: None, only=SOME)
    assert set(counted) == SOME
    assert again == counted  # instructions, branches and every function's count
    for case in counted.values():
        assert case["instructions_per_ray"] > 100 and case["branches_per_ray"] > 10
        assert case["functions"]


@needs_valgrind
def test_a_two_percent_slowdown_is_caught(counted):
    """A baseline 2 % cheaper than the build (the build 2 % slower) fails the 1 % gate and
    names the case, its counts and the functions that grew; an unchanged build passes."""
    assert rc.compare(counted, counted, rc.DEFAULT_TOLERANCE) == []
    victim = "first_hit/triangles/dda"
    cheaper = json.loads(json.dumps(counted))
    cheaper[victim]["instructions_per_ray"] /= 1.02
    cheaper[victim]["functions"] = {fn: int(v / 1.02) for fn, v in cheaper[victim]["functions"].items()}
    failures = rc.compare(cheaper, counted, rc.DEFAULT_TOLERANCE)
    assert [f["case"] for f in failures] == [victim]
    assert "+2.00 %" in failures[0]["reason"]
    assert failures[0]["grew"] and failures[0]["grew"][0][2] > failures[0]["grew"][0][1]
    # 0.5 % stays inside the tolerance
    cheaper[victim]["instructions_per_ray"] = counted[victim]["instructions_per_ray"] / 1.005
    assert rc.compare(cheaper, counted, rc.DEFAULT_TOLERANCE) == []


def test_missing_cases_fail_and_tolerance_is_checked():
    base = {"visit/-/dda": {"instructions_per_ray": 10.0, "branches_per_ray": 2.0}}
    assert rc.compare(base, {}, 0.01)[0]["reason"] == "not measured"
    with pytest.raises(ValueError, match="tolerance"):
        rc.compare(base, base, 1.5)


def test_clear_message_without_valgrind(monkeypatch, tmp_path):
    monkeypatch.setattr(rc, "callgrind_available", lambda: False)
    lines = []
    status = rc.run(str(tmp_path / "b.json"), echo=lines.append)
    assert status == 2
    assert "valgrind" in lines[-1] and "apt-get install valgrind" in lines[-1]


def test_committed_baseline_covers_every_case():
    path = rc.BASELINE
    with open(path) as f:
        base = json.load(f)
    assert base["metric"] == "instructions" and base["tolerance"] == rc.DEFAULT_TOLERANCE
    assert set(base["cases"]) == {rc.key(*c) for c in rc.cases()}

"""The targets study (bench/studies/targets.py): a tiny tier runs every row, a kernel the
registry does not hold gives "not available" while the rest runs, and the table names its
regime, the load and Embree's reach. Ratios are not asserted (timing on a shared machine)."""
import csv
import math
import os

import pytest

import algos
from bench.studies import targets

TINY = dict(random=(("fbm", 64),), camera=(("fbm", 64),), image=(32, 18), rays=300, repeats=2,
            parallel=("fbm", 64), run_lengths=(5,), cache=("fbm", 64), cache_rays=20,
            embree_mesh_max_side=32, judge=False)


@pytest.fixture
def tiny(monkeypatch):
    monkeypatch.setitem(targets.TIERS, "tiny", TINY)
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    yield "tiny"
    if affinity is not None:
        os.sched_setaffinity(0, affinity)  # the study pins the process to one CPU


def _rows(out):
    with open(out / "targets.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_every_row_runs_and_absent_kernels_say_not_available(tmp_path, tiny):
    lines = []
    rows = targets.run(out_dir=str(tmp_path), tier=tiny, counts=False,
                       packet_kernel="no_such_packet", compact_kernel="no_such_compact",
                       echo=lines.append)
    by = {}
    for row in _rows(tmp_path):
        by.setdefault(row["row"], []).append(row)
    assert sorted(by) == ["1", "2", "3", "4", "5"] and len(rows) == 5
    for k in ("1", "2", "4"):
        for row in by[k]:
            ratio = float(row["ratio"])
            assert math.isfinite(ratio) and ratio > 0 and row["status"] == "not judged (tiny tier)"
    assert by["3"][0]["status"] == "not available" and "no_such_packet" in by["3"][0]["note"]
    assert by["5"][0]["status"] == "not available"
    # the best exact kernel is a strict one, agreeing with the exact reference
    assert algos.INTERSECTOR_REGISTRY[by["1"][0]["ours"]].accuracy in ("exact", "float64")
    assert by["1"][0]["agree"].startswith(f"{by['1'][0]['ours']} 1.0000")
    assert by["4"][0]["agree"] == "equal t: True"
    text = (tmp_path / "targets.md").read_text()
    assert "cache regime **warm**" in text and "load averages" in text
    assert "embreex reaches single-ray triangle queries only" in text
    assert lines[0].startswith("targets (tiny tier)") and "os.getloadavg()" in lines[0]
    assert rows[0]["load_before"] and rows[0]["load_after"]


def test_embree_configurations_listed(tmp_path, tiny):
    from algos.peers import embree3 as embree3_peer

    rows = targets.run(out_dir=str(tmp_path), tier=tiny, regime="flushed", counts=False,
                       echo=lambda *_: None)
    note = rows[0]["note"]
    assert "embreex triangles x1" in note
    if embree3_peer.available():
        # every native width on both geometries; the meshes above embree_mesh_max_side (32)
        # were timed in their own pair
        for width in embree3_peer.native_widths():
            assert f"embree3 grid x{width}" in note and f"embree3 triangles x{width}" in note
    assert rows[0]["regime"] == "flushed"


def test_registered_kernels_are_found_by_name(tmp_path, tiny):
    # any registered name fills row 3: here runs_maxmip stands in for the packet kernel of
    # the other branch; without counts row 5 says why it was not measured
    rows = targets.run(out_dir=str(tmp_path), tier=tiny, counts=False,
                       packet_kernel="runs_maxmip", compact_kernel="runs_maxmip",
                       echo=lambda *_: None)
    row3 = [r for r in rows if r["row"] == 3][0]
    assert row3["ours"] == "runs_maxmip" and row3["status"] == "not judged (tiny tier)"
    assert row3["agree"].startswith("bit-identical t: ") and float(row3["ours_ns_per_ray"]) > 0
    row5 = [r for r in rows if r["row"] == 5][0]
    assert row5["status"] == "not available" and "--no-counts" in row5["note"]


def test_misses_row_is_the_ratio_of_last_level_misses_per_ray(monkeypatch):
    # callgrind's part is bench.profile's (tested there); here the row's arithmetic
    from bench import profile as profile_module

    seen = []

    def fake_profile(kernel, **kwargs):
        seen.append((kernel, kwargs["size"], kwargs["r"], kwargs["cache_sim"]))
        return {"ll_misses": {"dda_maxmip": 400, "runs_maxmip": 100}[kernel]}

    monkeypatch.setattr(profile_module, "profile", fake_profile)
    monkeypatch.setattr(profile_module, "callgrind_available", lambda: True)
    row = targets._misses_row(TINY, "runs_maxmip", 7, True, dict(regime="warm"))
    assert seen == [("dda_maxmip", 64, "random", True), ("runs_maxmip", 64, "random", True)]
    assert row["ratio"] == 0.25 and row["status"] == "met"
    assert row["ours_ns_per_ray"] == "5.00 misses" and row["theirs_ns_per_ray"] == "20.00 misses"


def test_bad_tier_and_regime(tmp_path):
    with pytest.raises(ValueError, match="tier: expected one of"):
        targets.run(out_dir=str(tmp_path), tier="huge")
    with pytest.raises(ValueError, match="regime: expected one of"):
        targets.run(out_dir=str(tmp_path), regime="lukewarm")

"""The targets study (bench/studies/targets.py, targets_measure.py, targets_counts.py):
the quick tier runs every row in processes of its own and writes a table with every line of
the targets; an absent kernel or peer says "not available"; the status logic on
synthetic numbers; resuming; the command line's validation. Ratios are not asserted
(timing on a shared machine)."""
import csv
import json
import math
import os

import pytest

import algos
from bench.studies import targets, targets_counts, targets_measure
from bench.timing import STOPS

# The study runs each row in a child interpreter and counts under valgrind: neither runs
# under the sanitizer's preloaded runtime (the kernels it times are in the sanitized
# suite through their own tests)
pytestmark = pytest.mark.skipif("libasan" in os.environ.get("LD_PRELOAD", ""),
                                reason="child interpreters and valgrind under ASan")

TINY = dict(sides=dict(random2048=40, random4096=48, level=40, pitched=40, horizon16=40),
            rays=120, image=(16, 9), repeats=2, processes=2, horizon_repeats=1, count_rays=20,
            count_mesh_max_side=64, mesh_max_side=44, judge=False, counts=False, kernels=None,
            peers=None)


@pytest.fixture
def tiny(monkeypatch):
    monkeypatch.setitem(targets.TIERS, "tiny", TINY)
    return "tiny"


def _csv(out):
    with open(out / "targets.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_quick_tier_writes_every_line_of_the_targets(tmp_path, monkeypatch):
    # the quick tier as the command runs it, but for mesh_max_side: 96^2 meshes are timed
    # in pairs of their own here, 64^2 ones with everything
    quick = dict(targets.TIERS["quick"], mesh_max_side=80)
    monkeypatch.setitem(targets.TIERS, "quick", quick)
    lines = []
    record = targets.run(out_dir=str(tmp_path), tier="quick", echo=lines.append)
    for name in ("targets.csv", "targets.json", "targets.md", "env.json"):
        assert (tmp_path / name).exists(), name
    env = json.loads((tmp_path / "env.json").read_text())
    assert env["load_before"] and env["load_after"] and env["tier"] == "quick"
    # every row of the tier measured, none failed; 8192^2 is the full tier's
    assert set(record["rows"]) == set(quick["sides"])
    assert not any("error" in r for r in record["rows"].values())
    line1 = record["rows"]["random2048"]
    assert len(line1["runs"]) == 2  # two processes
    for regime in ("flushed", "warm"):
        s = line1["summary"][f"{regime}/embreex"]
        assert s["processes"] == 2 and s["spread"][0] <= s["spread"][1] <= s["spread"][2]
        assert s["status"] == "not judged (quick tier)"
        for run in line1["runs"]:
            best = run["regimes"][regime]["best"]
            # the best exact kernel is a strict one that agrees with the exact reference
            assert algos.INTERSECTOR_REGISTRY[best].accuracy in ("exact", "float64")
            assert run["agree"][best] == 1.0
            ns = run["regimes"][regime]["ns"]  # the kernels left after the screening call
            assert ns[best] == min(ns[k] for k in ns if k in algos.INTERSECTOR_REGISTRY
                                   and run["agree"][k] == 1.0)
            assert not set(run["left_out"]) & set(ns)
            # the ratio is confirmed afresh in paired rounds (the selection's repeats only
            # pick the contenders): at least 8 pairs, and why they stopped
            for peer, e in run["regimes"][regime]["peers"].items():
                assert e["pairs"] >= 8 and e["stop"] in STOPS, (peer, e)
                assert e["ns"] > 0 and e["ours_ns"] > 0 and e["low"] <= e["ratio"] <= e["high"]
    # above mesh_max_side each triangle mesh is timed in a pair of its own with the best
    # exact kernel; below it, with everything
    for regime in ("flushed", "warm"):
        apart = record["rows"]["random4096"]["runs"][0]["regimes"][regime]["paired_apart"]
        assert "embreex triangles x1" in apart and not any("grid" in x for x in apart)
        assert record["rows"]["level"]["runs"][0]["regimes"][regime]["paired_apart"] == []
    seconds = record["rows"]["horizon16"]["summary"]["seconds"]
    assert seconds["seconds"] > 0 and seconds["target"] == 20.0
    text = (tmp_path / "targets.md").read_text()
    assert "| rays | today | measured | target | status |" in text
    for line in targets.LINES:
        assert f"| {line.rays} | {line.today} |" in text
    assert "min-median-max over 2 processes" in text
    # the detail gives each ratio's pairs and why they stopped, and the command names
    # the output directory it wrote
    e = line1["runs"][0]["regimes"]["warm"]["peers"]["embreex"]
    other = line1["runs"][1]["regimes"]["warm"]["peers"]["embreex"]
    assert f"| {e['pairs']}, {other['pairs']} ({e['stop']}, {other['stop']}) |" in text
    assert f"Command: `hftrace targets --tier quick --out {tmp_path}`" in text
    assert "8192^2: not measured (quick tier; `--tier full`)" in text
    # the quick tier's cells name the sizes it measured, not the lines' own
    assert "| fBm 64^2, 300 random rays: warm: " in text
    assert "| fBm 96^2, 300 random rays: warm: " in text and "| 4096^2: " not in text
    assert "| fBm 64^2, level camera 32x18, 60 deg: warm: " in text
    assert "| Jacksboro 64 x 60, 16 azimuths, unlimited distance, 1 thread: " in text
    assert "no counts in the quick tier" in (tmp_path / "targets.json").read_text()
    rows = _csv(tmp_path)
    assert {r["row"] for r in rows} == {r.key for r in targets.ROWS}
    ray_rows = [r for r in rows if r["regime"]]
    assert {(r["regime"], r["peer"]) for r in ray_rows if r["row"] == "level"} == {
        (g, p) for g in ("flushed", "warm") for p in ("embreex", "embree3")}
    for r in ray_rows:
        if r["ratio"]:
            assert math.isfinite(float(r["ratio"])) and float(r["ratio"]) > 0
            assert float(r["low"]) <= float(r["ratio"]) <= float(r["high"]) or r["processes"] == "2"
    assert lines[0].startswith("targets (quick tier)") and "os.getloadavg()" in lines[0]


def test_absent_kernel_and_peer_say_not_available(tmp_path, monkeypatch):
    tier = dict(TINY, kernels=("no_such_kernel",), peers=("embreex", "embree9"))
    monkeypatch.setitem(targets.TIERS, "absent", tier)
    record = targets.run(out_dir=str(tmp_path), tier="absent", counts=False, only=["level"],
                         echo=lambda *_: None)
    summary = record["rows"]["level"]["summary"]
    assert set(summary) == {f"{g}/{p}" for g in ("flushed", "warm") for p in ("embreex", "embree9")}
    assert summary["warm/embreex"]["status"].startswith("not available (no strict kernel")
    assert summary["warm/embree9"]["status"] == "not available (no peer named 'embree9')"
    text = (tmp_path / "targets.md").read_text()
    # rows not asked for are listed, not dropped
    assert "| 4000 random, fBm 2048^2 |" in text and "not measured yet" in text


def test_judge_on_synthetic_intervals():
    assert targets.judge(2.1, 2.5, 2.0) == "met"
    assert targets.judge(2.0, 2.5, 2.0) == "met"  # the target reached is met
    assert targets.judge(1.9, 2.5, 2.0) == "inconclusive"
    assert targets.judge(1.2, 1.9, 2.0) == "missed"
    assert targets.judge(2.5, 2.1, 2.0) == "met"  # the ends in either order
    assert targets.judge(math.nan, 2.5, 2.0) == "not measured"
    assert targets.judge(None, 2.5, 2.0) == "not measured"
    # seconds: smaller is better
    assert targets.judge(15.0, 18.0, 20.0, smaller_is_better=True) == "met"
    assert targets.judge(19.0, 21.0, 20.0, smaller_is_better=True) == "inconclusive"
    assert targets.judge(21.0, 25.0, 20.0, smaller_is_better=True) == "missed"


def test_line_status_combines_its_targets():
    assert targets.line_status(["met", "met", "met", "met"]) == "met"
    assert targets.line_status(["met", "inconclusive", "met"]) == "inconclusive"
    assert targets.line_status(["met", "inconclusive", "missed"]) == "missed"
    assert targets.line_status(["not available (x)", "not available (x)"]) == "not available (x)"
    assert targets.line_status(["met", "not available (y)"]) == \
        "met where measured; not available (y) elsewhere"
    assert targets.line_status([]) == "not measured"
    assert targets.spread([3.0, 1.0, math.nan, 2.0]) == (1.0, 2.0, 3.0)
    assert all(math.isnan(v) for v in targets.spread([]))


def _process(ratios_by_regime, low=None, high=None):
    """A synthetic process result of measure_rays: embreex ratios per regime."""
    regimes = {}
    for regime, ratio in ratios_by_regime.items():
        regimes[regime] = dict(best="dda_maxmip", ns={"dda_maxmip": 100.0}, peers={
            "embreex": dict(config="embreex triangles x1", ns=100.0 * ratio, ratio=ratio,
                            low=ratio * 0.9 if low is None else low,
                            high=ratio * 1.1 if high is None else high)})
    return dict(setting="synthetic", rays=4000, agree={"dda_maxmip": 1.0},
                missing={"embree3": "not available (not built)"}, configs={}, regimes=regimes)


def test_several_processes_are_judged_on_their_spread():
    line = targets.LINES[0]  # >= 2x embreex, >= 1.5x the C peer
    cfg = dict(TINY, judge=True)
    runs = [_process({"flushed": r, "warm": r + 0.5}) for r in (1.9, 2.2, 2.4)]
    s = targets._summarise_rays(line, runs, cfg)
    # flushed: 1.9 to 2.4 straddles 2: inconclusive, whatever each process's interval
    assert s["flushed/embreex"]["status"] == "inconclusive"
    assert s["flushed/embreex"]["spread"] == [1.9, 2.2, 2.4]
    assert s["flushed/embreex"]["ratio"] == 2.2
    assert s["warm/embreex"]["status"] == "met"  # 2.4 to 2.9
    assert s["warm/embree3"]["status"] == "not available (not built)"
    # one process: its paired interval decides
    one = targets._summarise_rays(line, [_process({"flushed": 2.2, "warm": 2.2}, 1.8, 2.6)], cfg)
    assert one["warm/embreex"]["status"] == "inconclusive"
    one = targets._summarise_rays(line, [_process({"flushed": 1.5, "warm": 1.5}, 1.4, 1.6)], cfg)
    assert one["warm/embreex"]["status"] == "missed"
    failed = targets._summarise_rays(line, [{"error": "boom"}], cfg)
    assert failed["warm/embreex"]["status"] == "failed"


def test_counted_configuration_is_one_valgrind_runs():
    cfg = dict(TINY, count_mesh_max_side=1024)
    assert targets_counts.countable("embree3 grid x16 coherent", 2048, cfg)[0] == \
        "embree3 grid x8 coherent"
    label, note = targets_counts.countable("embree3 triangles x8", 2048, cfg)
    assert label == "embree3 grid x8" and "grid geometry" in note
    assert targets_counts.countable("embreex triangles x1", 2048, cfg)[0] is None
    assert targets_counts.countable("embreex triangles x1", 512, cfg) == ("embreex triangles x1", "")


def test_embree_configurations_of_both_peers():
    from algos.peers import embree3 as embree3_peer

    configs = targets_measure.peer_configs(coherent=True)
    labels = {label: peer for peer, label, _, _ in configs}
    assert labels.get("embreex triangles x1") == "embreex"
    if embree3_peer.available():  # both geometries at every native width, coherent packets
        for width in embree3_peer.native_widths():
            flag = " coherent" if width > 1 else ""
            for geometry in ("grid", "triangles"):
                assert labels[f"embree3 {geometry} x{width}{flag}"] == "embree3"
    assert [c[0] for c in targets_measure.embree_configs(True)] == list(labels)
    assert targets_measure.peer_configs(False, peers=("embree9",)) == []


def test_counted_rays_keep_whole_image_columns():
    cfg = dict(TINY, rays=4000, image=(640, 360), count_rays=2000)
    assert list(targets_measure.counted_rays("random", cfg)) == list(range(0, 4000, 2))
    keep = targets_measure.counted_rays("level", cfg)
    columns = keep % 640
    assert len(keep) == 6 * 360 and sorted(set(columns)) == [0, 106, 213, 320, 426, 533]
    for c in set(columns):  # every kept column whole: its 360 rows, top to bottom
        assert list(keep[columns == c] // 640) == list(range(360))
    assert len(targets_measure.counted_rays("pitched", dict(cfg, count_rays=10))) == 360
    assert list(targets_measure.counted_rays("pitched", dict(cfg, count_rays=None))) == \
        list(range(640 * 360))
    assert len(targets_measure.counted_rays("random", dict(cfg, count_rays=9000))) == 4000


def test_resume_keeps_the_measured_rows(tmp_path, tiny, monkeypatch):
    targets.run(out_dir=str(tmp_path), tier=tiny, counts=False, only=["horizon16"],
                echo=lambda *_: None)

    def no_child(*args):
        raise AssertionError("a kept row was measured again")

    monkeypatch.setattr(targets, "_run_child", no_child)
    lines = []
    record = targets.run(out_dir=str(tmp_path), tier=tiny, counts=False, resume=True,
                         only=["horizon16"], echo=lines.append)
    assert "horizon16" in record["rows"] and any("kept from" in x for x in lines)
    # the resumed table holds the rows of both runs, and its command names them all (as
    # if the first run had been `--only level`), or none when a run measured every row
    saved = json.loads((tmp_path / "targets.json").read_text())
    for before, after in ((["level"], ["level", "horizon16"]), (None, None)):
        (tmp_path / "targets.json").write_text(json.dumps(dict(saved, only=before)))
        record = targets.run(out_dir=str(tmp_path), tier=tiny, counts=False, resume=True,
                             only=["horizon16"], echo=lines.append)
        assert record["only"] == after
        assert json.loads((tmp_path / "targets.json").read_text())["only"] == after
    monkeypatch.setitem(targets.TIERS, "other", TINY)
    with pytest.raises(ValueError, match="resume: .* holds the tiny tier, not other"):
        targets.run(out_dir=str(tmp_path), tier="other", resume=True, echo=lambda *_: None)


def test_resume_refuses_other_settings_than_the_kept_rows(tmp_path, tiny, monkeypatch):
    # kept rows were measured with one seed and one count of processes: a resume with
    # others would record those for rows that were not measured with them
    targets.run(out_dir=str(tmp_path), tier=tiny, counts=False, only=["horizon16"],
                echo=lambda *_: None)
    monkeypatch.setattr(targets, "_run_child", lambda *a: pytest.fail("measured"))
    with pytest.raises(ValueError, match=r"resume: .* measured with seed 2008, not 7; give "
                                         r"--seed 2008"):
        targets.run(out_dir=str(tmp_path), tier=tiny, seed=7, resume=True,
                    only=["horizon16"], echo=lambda *_: None)
    with pytest.raises(ValueError, match=r"resume: .* measured with processes 2, not 5"):
        targets.run(out_dir=str(tmp_path), tier=tiny, processes=5, resume=True,
                    only=["horizon16"], echo=lambda *_: None)
    # without resume the output is measured afresh: nothing to refuse
    before = json.loads((tmp_path / "targets.json").read_text())
    assert before["seed"] == 2008 and before["processes"] == 2


def test_command_line_of_a_record_reproduces_it():
    cfg = targets.TIERS["medium"]
    record = dict(tier="medium", processes=cfg["processes"], only=None, out="reports/targets")
    assert targets.command_line(record, cfg) == "hftrace targets --tier medium --publish"
    record.update(processes=5, only=["level", "pitched"], out="/tmp/x")
    assert targets.command_line(record, cfg, counts=False) == (
        "hftrace targets --tier medium --processes 5 --only level,pitched --out /tmp/x "
        "--no-counts")
    # a record written before these keys existed: the default output
    assert targets.command_line(dict(tier="quick", processes=targets.TIERS["quick"]["processes"]),
                                targets.TIERS["quick"]) == "hftrace targets --tier quick"


def test_bad_arguments_name_themselves(tmp_path):
    with pytest.raises(ValueError, match="tier: expected one of"):
        targets.run(out_dir=str(tmp_path), tier="huge")
    with pytest.raises(ValueError, match="processes: expected a positive integer, got 0"):
        targets.run(out_dir=str(tmp_path), processes=0)
    with pytest.raises(ValueError, match="only: unknown row 'random1024'"):
        targets.run(out_dir=str(tmp_path), only=["random1024"])
    # a row the tier does not measure is refused, not skipped with an exit status of 0
    with pytest.raises(ValueError, match="only: row 'random8192' is not in the quick tier, "
                                         "whose rows are random2048, random4096, level"):
        targets.run(out_dir=str(tmp_path), only=["random8192"], echo=lambda *_: None)


def test_command_line_validates_its_options(tmp_path, capsys):
    from bench.cli import main

    with pytest.raises(SystemExit):
        main(["targets", "--processes", "0"])
    assert "--processes" in capsys.readouterr().err
    assert main(["targets", "--only", "random2048,nope", "--out", str(tmp_path)]) == 2
    assert "--only: unknown row 'nope'" in capsys.readouterr().err
    assert main(["targets", "--only", " , ", "--out", str(tmp_path)]) == 2  # not every row
    assert "--only: expected one or more rows, got ' , '" in capsys.readouterr().err
    assert main(["targets", "--full", "--tier", "quick", "--out", str(tmp_path)]) == 2
    assert "--full: contradicts --tier quick" in capsys.readouterr().err
    assert main(["targets", "--publish", "--tier", "quick"]) == 2
    assert "--publish: the quick tier judges nothing" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["targets", "--tier", "huge"])
    assert "--tier" in capsys.readouterr().err
    assert not os.listdir(tmp_path)  # nothing measured on a bad option


@pytest.mark.skipif(not __import__("shutil").which("valgrind"), reason="valgrind not installed")
def test_counts_of_our_kernel_under_callgrind():
    cfg = dict(TINY, count_rays=10)
    counts = targets_counts.count_contender("random", 24, cfg, 2008, "dda_maxmip")
    assert counts["rays"] == 10  # every 12th of 120 rays
    for regime in ("flushed", "warm"):
        assert counts[regime]["instructions"] > 100
    # the warm call finds its lines: no more last-level misses than after the flush
    assert counts["warm"]["ll_misses"] <= counts["flushed"]["ll_misses"]
    assert counts["flushed"]["ll_misses"] > 0


@pytest.mark.skipif(not __import__("shutil").which("valgrind"), reason="valgrind not installed")
def test_counts_of_the_c_peer_inside_embree():
    from algos.peers import embree3 as embree3_peer

    if not embree3_peer.available():
        pytest.skip(embree3_peer.unavailable_reason())
    cfg = dict(TINY, count_rays=18)  # two whole image columns of the level camera
    counts = targets_counts.count_contender("level", 24, cfg, 2008, "embree3 grid x4 coherent",
                                            "embree3")
    assert counts["rays"] == 18
    # Embree's own queries only: the ctypes call that frees the scene adds no dump
    assert counts["flushed"]["instructions"] > 10 and counts["warm"]["instructions"] > 10

"""The benchmark harness: sweep configs, resume after a kill, reports, regress logic,
render and the CLI. Timing values are never asserted; only structure and logic."""
import csv
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import algos
from bench import analysis, plots, sweep
from bench.cli import main
from bench.regress import time_gate as regress

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

TINY = {
    "name": "tiny", "rays": 40, "repeats": 3, "seed": 1,
    "algorithms": ["dda", "midpoint", "runs", "runs_maxmip", "march_linear"],
    "workloads": ["visit", "first_hit"], "surfaces": ["triangles"],
    "run_lengths": [1, 25, "random"],
    "datasets": [{"name": "fbm", "size": 64, "seed": 1}, {"name": "uniform", "size": 48, "seed": 2}],
}


# ---- config validation ---------------------------------------------------------------
@pytest.mark.parametrize("change,message", [
    ({"rayz": 10}, "rayz: unknown key"),
    ({"rays": 0}, "rays: expected an integer >= 8"),
    ({"repeats": 2}, "repeats: expected an integer >= 3"),
    ({"workloads": ["walk"]}, "workloads: unknown workload 'walk'"),
    ({"surfaces": ["smooth"]}, "surfaces: unknown surface 'smooth'"),
    ({"run_lengths": [0.5]}, "run_lengths: 0.5 is neither"),
    # inf passed the check: every group ran, then the report refused all its rows
    ({"run_lengths": [float("inf")]}, "run_lengths: inf is neither"),
    ({"run_lengths": [float("nan")]}, "run_lengths: nan is neither"),
    ({"algorithms": ["bvh"]}, "algorithms: unknown algorithm 'bvh'"),
    ({"datasets": [{"name": "mars"}]}, r"datasets\[0\].name: unknown dataset 'mars'"),
    ({"datasets": [{"name": "fbm", "colour": 1}]}, r"datasets\[0\].colour: unknown key"),
    ({"datasets": [{"name": "fbm", "params": {"oct": 2}}]}, r"datasets\[0\].params.oct: not a parameter"),
    ({"datasets": []}, "datasets: expected a non-empty list"),
])
def test_bad_configs_name_the_key(change, message):
    with pytest.raises(sweep.ConfigError, match=message):
        sweep.load_config({**TINY, **change})


def test_toml_config_and_errors(tmp_path):
    good = tmp_path / "ok.toml"
    good.write_text('name = "t"\nrays = 16\nrepeats = 3\nrun_lengths = [1, "random"]\n'
                    '[[datasets]]\nname = "flat"\nsize = 16\n')
    cfg = sweep.load_config(good)
    assert cfg.rays == 16 and cfg.datasets == [{"name": "flat", "size": 16}]
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(sweep.ConfigError, match="not valid TOML"):
        sweep.load_config(bad)
    with pytest.raises(sweep.ConfigError, match="does not exist"):
        sweep.load_config(tmp_path / "none.toml")


def test_cli_rejects_bad_config_before_work(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text('rays = 16\nrepeats = 3\nsurfaces = ["smooth"]\n')
    assert main(["sweep", str(cfg), "--out", str(tmp_path / "out"), "--no-progress"]) == 2
    assert "surfaces" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# ---- sweeps, resume, reports -----------------------------------------------------------
def _expected_keys(cfg):
    keys = set()
    for ds, workload, surface, r, names in sweep.groups(cfg):
        for n in names:
            keys.add((sweep.dataset_label(ds, cfg.datasets), workload, surface, str(r), n))
    return keys


def test_sweep_rows_and_reports(tmp_path):
    cfg = sweep.load_config(TINY)
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    keys = [sweep.row_key(r) for r in rows]
    assert len(keys) == len(set(keys)) == len(_expected_keys(cfg))
    assert set(keys) == _expected_keys(cfg)
    for column in ("algorithm", "baseline", "workload", "surface", "dataset", "grid", "run_length",
                   "rays", "cells_per_ray", "runs_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
                   "ns_per_ray_ci_high", "speedup"):
        assert column in rows[0]
    assert {r["run_length"] for r in rows} == {"1", "25", "random"}
    exact = [r for r in rows if r["algorithm"] in ("midpoint", "runs")]
    assert all(float(r["agree"]) == 1.0 for r in exact)  # exact kernels agree with the reference
    assert all(float(r["speedup"]) == 1.0 for r in rows if r["algorithm"] == "dda")
    paths = analysis.write_reports(str(tmp_path / "results.csv"))
    text = open(paths["speedup"]).read()
    assert "| r | paper |" in text and "1.80" in text and "## Targets" in text
    assert os.path.getsize(paths["plot"]) > 10_000 and os.path.getsize(paths["cost"]) > 10_000
    env = json.load(open(tmp_path / "env.json"))
    assert {"cpu", "compiler", "numpy", "git_commit"} <= set(env)
    # `hftrace plot` regenerates the same reports elsewhere
    assert main(["plot", str(tmp_path / "results.csv"), "--out", str(tmp_path / "again")]) == 0
    assert open(tmp_path / "again" / "speedup.md").read() == text


def test_plot_keeps_the_title_of_the_run(tmp_path):
    """`hftrace plot` on a sweep's results.csv rewrote its speedup.md as "# hftrace
    reproduce: ...", calling a user's sweep the main study; the title now comes from the
    run's env.json, as the sweep wrote it."""
    cfg = sweep.load_config({**TINY, "name": "mine", "workloads": ["first_hit"],
                             "run_lengths": [25], "datasets": TINY["datasets"][:1]})
    sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert main(["plot", str(tmp_path / "results.csv")]) == 0
    for report in ("speedup.md", "speedup_full.md"):
        first = open(tmp_path / report).readline()
        assert first.startswith("# hftrace sweep mine"), first
    assert analysis.report_title({"reproduce": {"preset": "standard"}}) == \
        "hftrace reproduce (standard preset)"
    assert analysis.report_title(None) == "hftrace results"


def test_run_length_plot_legends_stand_off_the_data(monkeypatch):
    """The legend of run_length_vs_speedup.png stood inside the axes, where it could cover
    lines, the paper's 1.25x was a text over the data points, and dda's line and the line
    styles had no entry (the title told the styles, without dash-dot). Drawn from the
    committed headline results (nothing measured)."""
    import matplotlib.figure

    drawn = {}

    def keep(fig, *args, **kwargs):
        fig.canvas.draw()
        drawn["fig"] = fig

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", keep)
    df = analysis.load(os.path.join(ROOT, "reports", "reproduce-headline", "results.csv"), echo=None)
    plots.plot_speedup(df, "unused.png")
    fig = drawn["fig"]
    ax = fig.axes[0]
    legends = fig.legends
    lines, key = ([t.get_text() for t in legend.get_texts()] for legend in legends)
    shown = plots.plot_kernels(dict.fromkeys(df["algorithm"]))
    assert lines == shown + ["Henning & Stephenson 2004, by r",
                             "Henning & Stephenson 2004,\nall orientations (1.25x)",
                             "dda, the baseline (1.0)"]
    assert key == ["exact", "float, or not claimed exact", "peer (Embree, float32)"]
    assert ax.get_legend() is None and not ax.texts and "dotted" not in ax.get_title()
    # both legends right of the axes and inside the figure
    box, page = ax.get_window_extent(), fig.bbox
    for legend in legends:
        extent = legend.get_window_extent()
        assert extent.x0 > box.x1 and extent.x1 <= page.x1 and extent.y0 >= page.y0, extent


@pytest.mark.parametrize("pairs,panels", [
    ([("first_hit", "bilinear")], [("first_hit", "bilinear")]),
    ([("runs", "-"), ("first_hit", "flat"), ("first_hit", "triangles")],
     [("runs", "-"), ("first_hit", "triangles")]),
    ([("visit", "-"), ("runs", "-"), ("first_hit", "triangles")],
     [("visit", "-"), ("first_hit", "triangles")]),
    ([("first_hit", "triangles")], [("first_hit", "triangles")]),
])
def test_cost_plot_draws_the_workloads_measured(tmp_path, pairs, panels):
    """ns_per_ray_vs_cells.png drew "visit" and "first_hit, triangles" whatever the run
    measured: a sweep of first hits alone had an empty "no rows" panel, one on bilinear
    cells two."""
    import pandas as pd

    rows = [{"workload": w, "surface": s, "algorithm": a, "cells_per_ray": 10.0 + k,
             "ns_per_ray": 100.0 + k} for k, (w, s) in enumerate(pairs) for a in ("dda", "runs")]
    path = tmp_path / "cost.png"
    assert plots.plot_cost(pd.DataFrame(rows), str(path)) == panels
    assert os.path.getsize(path) > 10_000


def test_interrupt_closes_the_progress_bar_first(tmp_path, monkeypatch):
    """Ctrl-C left the bar open: tqdm redrew it below `hftrace: interrupted; ... --resume
    continues` when the interpreter exited, so the message sat above a stale bar."""
    events = []

    class Bar:
        def set_postfix_str(self, text):
            events.append("postfix")

        def update(self, n=1):
            events.append("update")

        def close(self):
            events.append("close")

    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    real = sweep.measure_group
    monkeypatch.setattr(sweep, "_bar", lambda progress, total, desc: Bar())
    monkeypatch.setattr(sweep, "measure_group", interrupted)
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"], "datasets": TINY["datasets"][:1]})
    with pytest.raises(KeyboardInterrupt):
        sweep.run_sweep(cfg, str(tmp_path), progress=True, echo=None)
    assert events[-1] == "close" and events.count("close") == 1
    assert len(list(csv.DictReader(open(tmp_path / "results.csv")))) == 5  # the first group


def test_resumed_run_reports_every_session(tmp_path, monkeypatch):
    """A resumed run's env.json described its last session only (resuming a finished
    reproduce run reported "The sweep took 0 s, 0 % of it inside timed calls" over its 24
    measured groups), and an interrupted session wrote no totals at all."""
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"], "run_lengths": [1, 25],
                             "datasets": TINY["datasets"][:1]})
    real, calls = sweep.measure_group, []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(sweep, "measure_group", interrupted)
    with pytest.raises(KeyboardInterrupt):
        sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    first = json.load(open(tmp_path / "env.json"))["run"]  # the cut session: one group
    assert first["groups"] == 1 and "sessions" not in first
    sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)
    second = json.load(open(tmp_path / "env.json"))["run"]
    assert second["sessions"] == 2 and second["groups"] == 2
    sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)  # nothing left
    third = json.load(open(tmp_path / "env.json"))["run"]
    assert third["sessions"] == 3 and third["groups"] == 2
    assert third["wall_s"] >= second["wall_s"] >= first["wall_s"] > 0
    assert third["timed_s"] == second["timed_s"] and third["last_session"]["groups"] == 0
    text = open(analysis.write_reports(str(tmp_path / "results.csv"), echo=None)["speedup"]).read()
    assert "in 3 sessions (resumed)" in text
    assert sweep.merge_sessions({"groups": 3, "wall_s": 2.0, "timed_s": 1.0, "sessions": 2},
                                {"groups": 1, "wall_s": 2.0, "timed_s": 1.0})["sessions"] == 3


def test_run_length_plot_says_which_speedup_it_draws():
    """The run-length plot's y axis read "geometric mean of paired ratios" for every run,
    but the headline preset and every sweep with `precision` report the median of adjacent
    pairs (docs/METHOD.md, "Paired rounds"; their speedup.md says so)."""
    import pandas as pd

    paired = pd.DataFrame({"regime": ["warm"], "precision": ["0.02"]})
    fixed = pd.DataFrame({"regime": ["flushed"], "precision": [""]})
    assert plots.speedup_axis_label(paired) == "speedup over dda (median of adjacent pairs' ratios)"
    assert plots.speedup_axis_label(fixed) == "speedup over dda (geometric mean of paired ratios)"
    headline = analysis.load(os.path.join(ROOT, "reports", "reproduce-headline", "results.csv"),
                             echo=None)
    assert "median" in plots.speedup_axis_label(headline)


def test_resume_after_kill_loses_and_duplicates_nothing(tmp_path):
    """Kill a sweep mid-way, resume it, and check every row is there exactly once."""
    cfg_path = tmp_path / "c.toml"
    cfg_path.write_text(
        'name = "killme"\nrays = 400\nrepeats = 5\nalgorithms = ["dda", "midpoint", "runs"]\n'
        'workloads = ["visit", "runs", "first_hit"]\nsurfaces = ["triangles", "bilinear"]\n'
        'run_lengths = [1, 2, 5, 25, 100, "random"]\n'
        '[[datasets]]\nname = "fbm"\nsize = 256\nseed = 1\n'
        '[[datasets]]\nname = "terraces"\nsize = 256\nseed = 1\n')
    out = tmp_path / "out"
    results = out / "results.csv"
    cmd = [sys.executable, "-m", "bench.cli", "sweep", str(cfg_path), "--out", str(out), "--no-progress"]
    # bookkeeping only: no cache flushing between timed runs, so a loaded machine is
    # not slowed further (bench/timing.py)
    env = dict(os.environ, HFTRACE_FLUSH_MB="0")
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            env=env)
    deadline = time.time() + 120
    while time.time() < deadline:
        if results.exists() and sum(1 for _ in open(results)) > 10:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = list(csv.DictReader(open(results)))
    cfg = sweep.load_config(cfg_path)
    expected = _expected_keys(cfg)
    assert 0 < len(before) < len(expected), "the kill must land mid-way"
    subprocess.run(cmd + ["--resume"], cwd=ROOT, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, timeout=1800, env=env)
    after = list(csv.DictReader(open(results)))
    keys = [sweep.row_key(r) for r in after]
    assert len(keys) == len(set(keys)), "a row is duplicated"
    assert set(keys) == expected, "a row is lost"
    # rows measured before the kill are kept as they were
    assert [sweep.row_key(r) for r in after[:len(before)]] == [sweep.row_key(r) for r in before]


# ---- regress -----------------------------------------------------------------------------
def _samples(center, spread, n=45, seed=0):
    rng = np.random.Generator(np.random.PCG64(seed))
    return list(center * (1 + spread * rng.standard_normal(n)))


def test_regress_compare_logic():
    """A significant drop beyond the tolerance fails; noise, a drop inside the tolerance
    and a rise pass; the smallest detectable drop grows with the noise."""
    base = {"a": _samples(2.0, 0.02), "b": _samples(1.0, 0.02, seed=1), "c": _samples(1.5, 0.02, seed=2)}
    same = {"a": _samples(2.0, 0.02, seed=5), "b": _samples(1.0, 0.02, seed=6), "c": _samples(1.5, 0.02, seed=7)}
    assert regress.compare(base, same, 0.05) == []
    dropped = dict(same, a=_samples(1.6, 0.02, seed=8))          # -20 %
    del dropped["c"]
    failures = regress.compare(base, dropped, 0.05)
    assert [f["ratio"] for f in failures] == ["a", "c"]
    assert "20." in failures[0]["reason"] or "19." in failures[0]["reason"]
    assert failures[1]["reason"].startswith("not measured") and failures[1]["missing"]
    # a real 3 % drop stays inside a 5 % tolerance; a 10 % one is caught
    assert regress.compare(base, dict(same, a=_samples(1.94, 0.02, seed=9)), 0.05) == []
    assert [f["ratio"] for f in regress.compare(base, dict(same, a=_samples(1.8, 0.02, seed=9)), 0.05)] == ["a"]
    # a 10 % drop inside heavy noise is not significant, and says so
    noisy = regress.assess(_samples(2.0, 0.3), _samples(1.8, 0.3, seed=3), 0.05)
    quiet = regress.assess(_samples(2.0, 0.01), _samples(1.8, 0.01, seed=3), 0.05)
    assert not noisy["regressed"] and quiet["regressed"]
    assert noisy["detectable"] > quiet["detectable"] >= 0.05
    with pytest.raises(ValueError, match="tolerance"):
        regress.compare(base, base, 1.5)


def test_regress_exit_codes(tmp_path, monkeypatch, capsys):
    path = tmp_path / "baseline.json"
    monkeypatch.setattr(regress, "measure", lambda: {"x": _samples(2.0, 0.02), "y": _samples(1.0, 0.02)})
    assert regress.run(str(path), update=True, echo=lambda *_: None) == 0
    assert json.load(open(path))["ratios"] == pytest.approx({"x": 2.0, "y": 1.0}, rel=0.02)
    assert regress.run(str(path), echo=print) == 0
    assert "smallest drop this run could flag" in capsys.readouterr().out
    monkeypatch.setattr(regress, "measure", lambda: {"x": _samples(1.5, 0.02, seed=4), "y": _samples(1.0, 0.02)})
    assert regress.run(str(path), echo=print) == 1
    assert "REGRESSED" in capsys.readouterr().out
    # noise wider than the tolerance: not a pass (a trial saw "all 15 ratios hold", exit 0,
    # beside "the smallest drop this run could flag: 37.4 %")
    monkeypatch.setattr(regress, "measure", lambda: {"x": _samples(2.0, 0.4, seed=5),
                                                     "y": _samples(1.0, 0.02)})
    assert regress.run(str(path), echo=print) == regress.INCONCLUSIVE == 3
    out = capsys.readouterr().out
    assert "inconclusive" in out and "ratios hold" not in out and "other processes" in out
    with pytest.raises(ValueError, match="does not exist"):
        regress.run(str(tmp_path / "missing.json"))


def test_committed_baseline_matches_the_checks():
    data = regress.load_baseline(regress.BASELINE)
    expected = {regress.key(w, s, r, n) for w, s, r, names, _ in regress.CHECKS for n in names}
    assert set(data["samples"]) == expected
    assert all(len(v) >= 30 for v in data["samples"].values())


# ---- render and CLI ---------------------------------------------------------------------
def test_render_writes_exr_png_and_diff(tmp_path):
    import OpenEXR

    from bench.cli import render

    prefix = str(tmp_path / "img")
    paths = render.render_files("fbm", size=48, seed=2, algorithm="runs", width=24, height=16,
                                fog=0.05, out=prefix, diff=("runs", "dda"), echo=lambda *_: None)
    with OpenEXR.File(paths["exr"]) as f:
        channels = f.channels()
        assert set(channels) == {"Z", "N.x", "N.y", "N.z", "cellsVisited", "runsVisited"}
        z = channels["Z"].pixels
        assert z.shape == (16, 24) and np.isfinite(z).any()
    with OpenEXR.File(paths["diff_exr"]) as f:
        dz = f.channels()["dZ"].pixels
        assert np.nanmax(np.abs(dz)) < 1e-3  # two exact kernels: the same depths
    for key in ("png", "diff_png"):
        assert os.path.getsize(paths[key]) > 200


def test_list_columns_align(capsys):
    """Every row's summary starts at one column per section, the long "exact when ..." of
    runs_periodic included (it pushed its summary right: trial10)."""
    assert main(["list"]) == 0
    sections = capsys.readouterr().out.split("intersectors (algos.intersect):")
    for section, registry in zip(sections, (algos.TRAVERSAL_REGISTRY, algos.INTERSECTOR_REGISTRY)):
        starts = {line.index(entry.summary) for line in section.splitlines()
                  for name, entry in registry.items() if line.startswith(f"  {name} ")}
        assert len(starts) == 1, starts


def test_cli_smoke(tmp_path, capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "runs_maxmip" in out and "embree" in out
    assert main(["bench-traverse", "--rays", "40", "--repeats", "3", "--grid", "64",
                 "--run-lengths", "1,25", "--out", str(tmp_path / "bt")]) == 0
    assert (tmp_path / "bt" / "tables.md").exists()
    assert main(["bench-intersect", "--rays", "40", "--repeats", "3", "--datasets", "fbm:64",
                 "--run-lengths", "1", "--algorithms", "dda,runs,embree",
                 "--out", str(tmp_path / "bi")]) == 0
    text = (tmp_path / "bi" / "tables.md").read_text()
    assert "## Targets" in text and "embree" in text
    # without the reference `runs` (a trial's crash: KeyError ('runs', 1) after measuring):
    # tables.md is written, and a target whose rows were not measured is not judged
    assert main(["bench-intersect", "--rays", "16", "--repeats", "3", "--datasets", "fbm:32",
                 "--run-lengths", "1", "--algorithms", "midpoint", "--surfaces", "flat",
                 "--regimes", "warm", "--coherence", "random",
                 "--out", str(tmp_path / "bi2")]) == 0
    text = (tmp_path / "bi2" / "tables.md").read_text()
    assert "not measured" in text and "missed" not in text and "cells / runs per ray" not in text
    assert main(["render", "flat", "--size", "8", "--width", "4", "--height", "3",
                 "--out", str(tmp_path / "r")]) == 0
    assert main(["render", "flat", "--algorithm", "nope"]) == 2


def test_benchmark_suite_runs():
    """`pytest bench/benchmarks --benchmark-only` works: here every benchmark runs once."""
    done = subprocess.run([sys.executable, "-m", "pytest", "bench/benchmarks", "-q", "--benchmark-disable",
                           "-p", "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stdout[-2000:]
    assert " passed" in done.stdout


def test_flush_caches_evicts(monkeypatch):
    """Every cache line of the eviction buffer is written on every call (one word per
    64-byte line), sized by the environment or by the machine's last-level cache; 0 turns
    it off."""
    from bench import timing

    timing._EVICT.clear()
    timing.flush_caches(1 << 20)
    buf = timing._EVICT[1 << 20]
    timing.flush_caches(1 << 20)
    assert buf.size == (1 << 20) // 8 and np.all(buf[::8] == 2.0)
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")
    timing.flush_caches()
    assert np.all(buf[::8] == 2.0) and len(timing._EVICT) == 1
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "2")
    timing.flush_caches()
    assert (2 << 20) in timing._EVICT
    assert timing.last_level_cache_bytes() >= 1 << 20
    timing._EVICT.clear()


# ---- results out of the source tree -------------------------------------------------------
def _tree_state(folder):
    """(path, size, mtime) of every file below ``folder``."""
    return sorted((os.path.join(root, n), os.path.getsize(os.path.join(root, n)),
                   os.path.getmtime(os.path.join(root, n)))
                  for root, _, names in os.walk(folder) for n in names)


def test_default_runs_write_under_results_and_never_under_reports(tmp_path, monkeypatch):
    reports = os.path.join(ROOT, "reports")
    before = _tree_state(reports)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")
    assert main(["bench-traverse", "--rays", "16", "--repeats", "3", "--grid", "32",
                 "--run-lengths", "2", "--algorithms", "dda,runs"]) == 0
    assert main(["render", "flat", "--size", "8", "--width", "4", "--height", "3"]) == 0
    assert main(["shadows", "fbm", "--size", "16", "--no-progress"]) == 0
    written = sorted(os.path.relpath(os.path.join(root, n), tmp_path)
                     for root, _, names in os.walk(tmp_path) for n in names)
    assert "results/bench-traverse/tables.md" in written, written
    assert "results/render/render.exr" in written and "results/shadows/shadows.tif" in written
    assert all(p.startswith("results" + os.sep) for p in written), written
    assert _tree_state(reports) == before


def test_every_output_option_defaults_under_results():
    """No command's --out points into the source tree (reports/ changes only through
    `hftrace reproduce --publish` and `make reports`)."""
    from bench.cli import build_parser

    parser = build_parser()
    commands = [["bench-traverse"], ["bench-intersect"], ["scale"], ["terrain-bench"],
                ["accuracy"], ["stress"], ["horizon"], ["shadows"], ["svf"], ["viewshed"],
                ["render", "fbm"]]
    for argv in commands:
        out = parser.parse_args(argv).out
        assert out.startswith("results" + os.sep + argv[0]), (argv, out)
    # these choose their folder at run time: results/reproduce[-full], results/sweep/<name>,
    # or beside the CSV being plotted
    for argv in (["reproduce"], ["sweep", "c.toml"], ["plot", "results.csv"]):
        assert parser.parse_args(argv).out is None, argv
    assert parser.parse_args(["reproduce", "--publish"]).publish


def test_every_public_function_in_bench_has_a_docstring():
    """A public function or class (no leading underscore) of bench/ states its contract."""
    import ast
    import pathlib

    missing = []
    for path in sorted(pathlib.Path(ROOT, "bench").rglob("*.py")):
        if path.name.startswith("test_"):
            continue
        tree = ast.parse(path.read_text())
        todo = [(node, "") for node in tree.body]
        while todo:
            node, owner = todo.pop()
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
                if ast.get_docstring(node) is None:
                    missing.append(f"{path.relative_to(ROOT)}:{node.lineno} {owner}{node.name}")
                if isinstance(node, ast.ClassDef):
                    todo += [(child, node.name + ".") for child in node.body]
    assert not missing, missing


def test_row_writer_refuses_to_append_to_other_columns(tmp_path):
    """A results file written with other columns (an older version) is never appended to:
    its rows would be misaligned."""
    from bench.report import RowWriter
    path = tmp_path / "results.csv"
    with RowWriter(str(path), ["a", "b"]) as w:
        w.write({"a": 1, "b": 2})
    with pytest.raises(ValueError, match=r"columns \['a', 'b'\] differ"):
        RowWriter(str(path), ["a", "b", "regime"], append=True)
    with RowWriter(str(path), ["a", "b"], append=True) as w:
        w.write({"a": 3, "b": 4})
    assert path.read_text().splitlines() == ["a,b", "1,2", "3,4"]

"""Researchers' kernels in every table (algos.plugins), and results a reader can trust:
load recorded, inconclusive ratios labelled, results never replaced, bad kernels contained.
Every sweep here is tiny (40 rays, 3 repeats, 64^2 fields)."""
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import algos
from algos import plugins
from bench import analysis, load, sweep
from bench.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
EXAMPLE_C = os.path.join(ROOT, "examples", "plugins", "cell_dda.c")

TINY = {"name": "plug", "rays": 40, "repeats": 3, "seed": 3, "workloads": ["visit"],
        "run_lengths": [2, "random"], "datasets": [{"name": "fbm", "size": 64, "seed": 1}]}


@pytest.fixture
def registered():
    """Names registered by a test, unregistered after it (the registry is global)."""
    names = []
    yield names
    for name in names:
        if name in plugins.plugin_names():
            plugins.unregister(name)


@pytest.fixture
def quiet_flush(monkeypatch):
    monkeypatch.setenv("HFTRACE_FLUSH_MB", "0")


def build_example(tmp_path):
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler")
    lib = tmp_path / "cell_dda.so"
    subprocess.run([cc, "-O2", "-std=c99", "-shared", "-fPIC", "-I", os.path.join(ROOT, "cext"),
                    EXAMPLE_C, "-o", str(lib), "-lm"], check=True)
    return lib


def by(rows, name):
    return [r for r in rows if r["algorithm"] == name]


def numpy_dda():
    from examples.plugins.numpy_dda import numpy_dda as fn

    return fn


# ---- the examples ------------------------------------------------------------------------
def test_example_plugins_visit_the_reference_cells():
    """Both examples visit exactly the exact reference's cells on random rays."""
    from examples.plugins.numpy_dda import numpy_dda as fn

    rng = np.random.Generator(np.random.PCG64(5))
    o = rng.uniform(0, 20, (200, 2))
    d = rng.normal(size=(200, 2))
    paths = fn(o, d, (20, 20))
    ref = algos.traverse("midpoint", o, d, (20, 20))
    for k in range(200):
        assert [tuple(c) for c in paths[k]] == [tuple(c) for c in ref[k]], k
    assert plugins.fold_cells(ref[0]) == plugins.fold_cells(np.asarray(ref[0]))


def test_c_plugin_swept_next_to_dda_agrees(tmp_path, registered, quiet_flush, capsys):
    """Done-when: the example C plugin built with the system compiler, registered, swept
    next to dda, in the table with agreement 1.0 (and the NumPy one too)."""
    lib = build_example(tmp_path)
    entry = plugins.load_c_plugin(lib)
    registered += [entry.name, "numpy_dda"]
    from examples.plugins.numpy_dda import register

    register()
    assert entry.name == "cell_dda_c" and entry.plugin.language == "c"
    assert main(["list"]) == 0
    assert "cell_dda_c" in capsys.readouterr().out
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "midpoint", "cell_dda_c", "numpy_dda"]})
    rows = sweep.run_sweep(cfg, str(tmp_path / "out"), progress=False, echo=None)
    for name in ("cell_dda_c", "numpy_dda"):
        assert len(by(rows, name)) == 2
        for row in by(rows, name):
            assert float(row["agree"]) == 1.0 and row["error"] == ""
            assert float(row["ns_per_ray"]) > 0 and float(row["speedup"]) > 0
    paths = analysis.write_reports(str(tmp_path / "out" / "results.csv"))
    text = open(paths["speedup"]).read()
    assert "cell_dda_c" in text and "numpy_dda" in text
    # the C plugin's library path in a config, relative to the config file
    shutil.copy(lib, tmp_path / "again.so")
    plugins.unregister("cell_dda_c")
    toml = tmp_path / "c.toml"
    toml.write_text('rays = 16\nrepeats = 3\nplugins = ["again.so"]\n')
    sweep.load_config(toml)
    assert "cell_dda_c" in algos.TRAVERSALS


def test_wrong_exact_plugin_is_reported(tmp_path, registered, quiet_flush):
    """Done-when: a plugin that claims exactness and skips cells is reported as disagreeing."""
    fn = numpy_dda()

    def wrong(o, d, shape):
        paths = fn(o, d, shape)
        return [p[:-1] if k % 3 == 0 and len(p) > 1 else p for k, p in enumerate(paths)]

    algos.register_traversal("wrong_exact", wrong, exact=True)
    registered.append("wrong_exact")
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "wrong_exact"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    for row in by(rows, "wrong_exact"):
        assert float(row["agree"]) < 1.0
        assert "claims to be exact" in row["error"]
    assert main(["plot", str(tmp_path / "results.csv")]) == 0
    assert "claims to be exact" in open(tmp_path / "speedup.md").read()


def test_raising_and_overrunning_plugins_leave_other_rows(tmp_path, registered, quiet_flush):
    """Done-when: a raising and an overrunning plugin get errors; dda and midpoint rows stay."""
    def raising(o, d, shape):
        raise RuntimeError("kernel exploded")

    def slow(o, d, shape):
        time.sleep(0.3)
        return numpy_dda()(o, d, shape)

    algos.register_traversal("raising", raising)
    algos.register_traversal("slow", slow, time_limit=0.05)
    registered += ["raising", "slow"]
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "midpoint", "raising", "slow"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert all("kernel exploded" in r["error"] for r in by(rows, "raising"))
    assert all("time limit" in r["error"] for r in by(rows, "slow"))
    for name in ("dda", "midpoint"):
        assert len(by(rows, name)) == 2
        assert all(r["error"] == "" and float(r["ns_per_ray"]) > 0 for r in by(rows, name))


@pytest.mark.skipif(not hasattr(os, "fork"), reason="isolation forks")
def test_crashing_plugin_is_contained_under_isolation(tmp_path, registered, quiet_flush):
    """Done-when: a kernel that kills its process takes only its own rows with --isolate."""
    def crash(o, d, shape):
        os.kill(os.getpid(), signal.SIGSEGV)

    algos.register_traversal("crash", crash)
    algos.register_traversal("fine", numpy_dda())
    registered += ["crash", "fine"]
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "midpoint", "crash", "fine"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None, isolate=True)
    # under `make sanitize` ASan's own SEGV handler reports the crash and aborts
    crash_signal = "SIGABRT" if "libasan" in os.environ.get("LD_PRELOAD", "") else "SIGSEGV"
    assert all("crashed its process" in r["error"] and crash_signal in r["error"]
               for r in by(rows, "crash")), [r["error"] for r in by(rows, "crash")]
    for name in ("dda", "midpoint"):
        assert all(r["error"] == "" for r in by(rows, name)) and len(by(rows, name)) == 2
    # each plugin has its own child: the other plugin is measured as usual
    assert [float(r["agree"]) for r in by(rows, "fine")] == [1.0, 1.0]
    assert all(r["error"] == "" for r in by(rows, "fine"))


def test_register_errors_name_the_argument(registered):
    with pytest.raises(ValueError, match="name: 'dda' is a built-in"):
        algos.register_traversal("dda", lambda *a: None)
    with pytest.raises(TypeError, match="fn: expected a callable"):
        algos.register_intersector("mine", 3)
    with pytest.raises(ValueError, match=r"surfaces\[0\]: unknown surface 'smooth'"):
        algos.register_intersector("mine", lambda *a: None, surfaces=["smooth"])
    with pytest.raises(ValueError, match="time_limit"):
        algos.register_traversal("mine", lambda *a: None, time_limit=0)
    with pytest.raises(ValueError, match="does not exist"):
        plugins.load_c_plugin("/nonexistent/lib.so")


def test_python_first_hit_plugin_agrees(tmp_path, registered, quiet_flush):
    """A first-hit plugin wrapping an exact kernel is timed and agrees 1.0."""
    def exact(heights, o, d):
        return algos.intersect("runs", algos.Field(heights), o, d, surface="triangles").t

    algos.register_intersector("wrapped_runs", exact, exact=True, surfaces=["triangles"])
    registered.append("wrapped_runs")
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"],
                             "algorithms": ["dda", "wrapped_runs"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert [float(r["agree"]) for r in by(rows, "wrapped_runs")] == [1.0, 1.0]
    assert all(r["error"] == "" for r in rows)


# ---- load, intervals, results kept -------------------------------------------------------
def test_busy_loop_marks_groups_contended(tmp_path, quiet_flush):
    """Done-when: a busy loop on the other core marks the group contended, and every
    inconclusive ratio of the table is labelled so."""
    if not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2:
        pytest.skip("needs two CPUs: the busy loop on one, the sweep on the other")
    cpus = sorted(os.sched_getaffinity(0))
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"],
                            preexec_fn=lambda: os.sched_setaffinity(0, {cpus[0]}))
    os.sched_setaffinity(0, {cpus[-1]})  # as the CLI pins itself; the loop has the other CPU
    try:
        time.sleep(0.3)
        cfg = sweep.load_config({**TINY, "rays": 2000, "algorithms": ["dda", "dda_f32", "midpoint"],
                                 "datasets": [{"name": "fbm", "size": 128, "seed": 1}]})
        rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    finally:
        os.sched_setaffinity(0, cpus)
        busy.kill()
        busy.wait()
    assert all(r["contended"] == "True" for r in rows)
    # the counters tick every 10 ms: a group of a few ticks reads coarsely, the run does not
    assert np.median([float(r["other_cpu"]) for r in rows]) > load.CONTENDED_CORES
    df = analysis.load(str(tmp_path / "results.csv"))
    table = analysis.pivot_ci(df, "visit", "-")
    for (r, name), g in df.groupby(["run_length", "algorithm"]):
        text = table.loc[r, name]
        v = analysis.verdict(analysis._geomean(g["speedup"]), analysis._geomean(g["speedup_ci_low"]),
                             analysis._geomean(g["speedup_ci_high"]))
        if name != "dda":
            assert v == "inconclusive" and text.endswith("(contended)"), text
    paths = analysis.write_reports(str(tmp_path / "results.csv"))
    assert "ran under contention" in open(paths["speedup"]).read()


def test_verdict_and_ratio_text():
    assert analysis.verdict(1.05, 0.98, 1.10) == "inconclusive"      # wider than ±2 %
    assert analysis.verdict(1.50, 1.10, 1.90) == "inconclusive"
    assert analysis.verdict(1.50, 1.48, 1.52) == "faster"
    assert analysis.verdict(0.70, 0.69, 0.71) == "slower"
    assert analysis.verdict(1.00, 0.99, 1.01) == "same"              # a finding too
    assert analysis.ratio_text(1.05, 0.98, 1.10) == "1.05 ±5.7 % (too few repeats)"
    assert analysis.ratio_text(1.5, 1.48, 1.52) == "1.50 ±1.3 %"


def test_contention_from_counters():
    before = {"wall": 0.0, "busy": 100.0, "own": 10.0, "load": 0.1}
    after = {"wall": 2.0, "busy": 104.0, "own": 12.0, "load": 0.2}
    c = load.contention(before, after)
    assert c["other_cpu"] == 1.0 and c["contended"]
    after = {"wall": 2.0, "busy": 102.2, "own": 12.0, "load": 0.2}
    assert not load.contention(before, after)["contended"]


def test_rerun_refuses_and_resume_checks_config(tmp_path, quiet_flush):
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "midpoint"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    with pytest.raises(ValueError, match="already holds 4 rows.*--resume"):
        sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert len(sweep.read_rows(str(tmp_path / "results.csv"))) == len(rows) == 4
    changed = sweep.load_config({**TINY, "rays": 48, "algorithms": ["dda", "midpoint"]})
    with pytest.raises(ValueError, match="rays = 40, the config says 48"):
        sweep.run_sweep(changed, str(tmp_path), resume=True, progress=False, echo=None)
    # another commit's rows are refused too
    text = (tmp_path / "results.csv").read_text()
    commit = rows[0]["commit"]
    (tmp_path / "results.csv").write_text(text.replace(commit, "0" * 40))
    with pytest.raises(ValueError, match="commit"):
        sweep.run_sweep(cfg, str(tmp_path), resume=True, progress=False, echo=None)


def test_unknown_keys_name_the_closest(tmp_path):
    with pytest.raises(sweep.ConfigError, match="rayz: unknown key; did you mean 'rays'"):
        sweep.load_config({**TINY, "rayz": 3})
    with pytest.raises(sweep.ConfigError, match=r"datasets\[0\].sise: unknown key; did you mean 'size'"):
        sweep.load_config({**TINY, "datasets": [{"name": "fbm", "sise": 3}]})


def test_examples_configs_load():
    folder = os.path.join(ROOT, "examples")
    tomls = [f for f in os.listdir(folder) if f.endswith(".toml")]
    assert tomls
    for name in tomls:
        if "plugin" not in name:
            sweep.load_config(os.path.join(folder, name))


def test_user_errors_are_one_line(tmp_path, capsys, monkeypatch):
    assert main(["plot", str(tmp_path / "missing.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    assert main(["plot", str(tmp_path / "bad.csv")]) == 2
    assert "not a results.csv" in capsys.readouterr().err
    toml = tmp_path / "c.toml"
    toml.write_text('rays = 16\nrepeats = 3\n')

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "run_sweep", interrupted)
    assert main(["sweep", str(toml), "--out", str(tmp_path / "o")]) == 130
    assert "--resume" in capsys.readouterr().err


def test_entry_points_register_kernels(monkeypatch, registered, capsys):
    """A package's ``hftrace.kernels`` entry point is called by the ``hftrace`` command, so
    ``hftrace list`` shows its kernel; a failing one is one warning line."""
    import importlib.metadata as md

    from examples.plugins import numpy_dda as module

    points = [md.EntryPoint("theirs", "examples.plugins.numpy_dda:register", plugins.ENTRY_POINT_GROUP),
              md.EntryPoint("broken", "no_such_module:register", plugins.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(md, "entry_points", lambda group=None: points if group else {})
    registered.append("numpy_dda")
    assert main(["list"]) == 0
    out, err = capsys.readouterr()
    assert "numpy_dda" in out and module.numpy_dda is algos.TRAVERSAL_REGISTRY["numpy_dda"].plugin.fn
    assert "entry point 'broken'" in err and err.count("\n") == 1


def test_reproduce_presets_and_new_run_directory(tmp_path, monkeypatch, quiet_flush):
    """The default preset is the headline (first hit on triangles by run length, 24
    groups); the former quick preset is `standard`; a rerun writes a new directory."""
    from bench.studies import reproduce as R
    from bench.sweep import SweepConfig, groups

    head = R.preset()
    assert head.workloads == ["first_hit"] and head.surfaces == ["triangles"]
    assert len(groups(head)) == 24 and len(groups(R.preset(name="standard"))) == 144
    # every registered intersector but those the headline leaves out (bit-identical to
    # dda_maxmip, or the C Embree peer), which the standard and full presets keep
    assert "dda_maxmip" in head.algorithms and "embree" in head.algorithms
    assert not set(R.HEADLINE_LEAVES_OUT) & set(head.algorithms)
    assert R.preset(name="standard").algorithms is None
    assert R.preset(full=True).rays == 3000
    with pytest.raises(ValueError, match="--preset: unknown preset 'quick'"):
        R.preset(name="quick")
    tiny = SweepConfig(name="reproduce", rays=24, repeats=3, seed=1, workloads=["first_hit"],
                       surfaces=["triangles"], run_lengths=[2],
                       datasets=[{"name": "fbm", "size": 32, "seed": 1}])
    monkeypatch.setattr(R, "preset", lambda full=False, name=None, kernels=None:
                        SweepConfig(**{**tiny.__dict__, "algorithms": kernels}))
    monkeypatch.chdir(tmp_path)
    lines = []
    R.run(progress=False, counts=False, kernels=["dda", "runs"], echo=lines.append)
    assert lines[0].startswith("hftrace reproduce (headline preset): 1 group on") and "min" in lines[0]
    R.run(progress=False, counts=False, kernels=["dda", "runs"], echo=lines.append)
    assert (tmp_path / "results" / "reproduce" / "results.csv").exists()
    assert (tmp_path / "results" / "reproduce.2" / "results.csv").exists()
    import json

    env = json.load(open(tmp_path / "results" / "reproduce" / "env.json"))
    assert 0 <= env["run"]["timed_share"] <= 1 and env["reproduce"]["wall_s"] > 0

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
from bench import analysis, load, plots, sweep
from bench.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
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
    assert all(r["contended"] == "True" for r in rows), [(r["run_length"], r["other_cpu"], r["wall_s"]) for r in rows]
    # every group, however short, is read over a window of at least ten clock ticks
    assert all(float(r["other_cpu"]) > load.CONTENDED_CORES for r in rows), \
        [(r["run_length"], r["other_cpu"], r["wall_s"]) for r in rows]
    df = analysis.load(str(tmp_path / "results.csv"))
    table = analysis.pivot_ci(df, "visit", "-")
    for (r, name), g in df.groupby(["run_length", "algorithm"]):
        text = table.loc[r, name]
        v = analysis.verdict(analysis._geomean(g["speedup"]), analysis._geomean(g["speedup_ci_low"]),
                             analysis._geomean(g["speedup_ci_high"]), contended=True)
        if name != "dda":
            # a narrow interval measured under contention is still no finding
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


def test_contention_window_spans_ten_clock_ticks():
    """A group shorter than a few clock ticks reads 0 or 2 cores at random: the closing
    snapshot waits until the window spans MIN_WINDOW_S, and not longer."""
    before = load.snapshot()
    after = load.snapshot_after(before)
    assert load.MIN_WINDOW_S <= after["wall"] - before["wall"] < load.MIN_WINDOW_S + 0.05
    before = load.snapshot()
    before["wall"] -= 1.0  # a group that ran a second already
    after = load.snapshot_after(before)
    assert after["wall"] - before["wall"] < 1.0 + 0.05


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


def test_entry_point_kernels_answer_the_python_api(monkeypatch, registered, tmp_path):
    """An installed package's kernel answers ``algos.traverse``/``algos.intersect`` after a
    bare ``import algos`` (before, only the ``hftrace`` command loaded entry points, and
    the call said "unknown traversal"); a failing entry point is one RuntimeWarning."""
    import importlib.metadata as md

    (tmp_path / "theirs_pkg.py").write_text(
        "import algos\nfrom examples.plugins.numpy_dda import numpy_dda\n"
        "def register():\n    algos.register_traversal('theirs_walk', numpy_dda)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    points = [md.EntryPoint("theirs", "theirs_pkg:register", plugins.ENTRY_POINT_GROUP),
              md.EntryPoint("broken", "no_such_module:register", plugins.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(md, "entry_points", lambda group=None: points if group else {})
    monkeypatch.setattr(plugins, "_ENTRY_POINTS", {"loaded": False}, raising=False)
    registered.append("theirs_walk")
    o, d = np.array([[0.5, 0.5]]), np.array([[2.0, 3.0]])
    with pytest.warns(RuntimeWarning, match="entry point 'broken'"):
        paths = algos.traverse("theirs_walk", o, d, (4, 4))
    assert paths[0].tolist() == [list(c) for c in algos.reference_cells((0.5, 0.5), (2, 3), (4, 4))]
    # loaded once: a later unknown name does not import the packages again
    with pytest.raises(ValueError, match="unknown traversal 'nobody'"):
        algos.traverse("nobody", o, d, (4, 4))


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
    monkeypatch.setattr(R, "preset", lambda full=False, name=None, kernels=None, flush="warm":
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


# ---- every door: the public calls, the command line, the loaders ------------------------
C_FIRST_HIT = r"""
#include <math.h>
#include "hftrace_plugin.h"
static const hftrace_plugin_info INFO = {HFTRACE_PLUGIN_ABI, "constant_hit", "first_hit", 0,
                                         "triangles", "every ray hits at t = T"};
const hftrace_plugin_info *hftrace_plugin(void) { return &INFO; }
int hftrace_first_hit(const float *heights, int64_t rows, int64_t cols, int surface, int64_t n,
                      const double *o, const double *d, const double *tmin, const double *tmax,
                      double *t, int32_t *hit_cells) {
    (void)heights; (void)rows; (void)cols; (void)surface; (void)o; (void)d; (void)tmin; (void)tmax;
    for (int64_t r = 0; r < n; r++) { t[r] = T; hit_cells[2 * r] = 0; hit_cells[2 * r + 1] = 0; }
    return 0;
}
"""

C_NULL_INFO = r"""
#include <stddef.h>
#include "hftrace_plugin.h"
const hftrace_plugin_info *hftrace_plugin(void) { return NULL; }
"""

C_CHECKSUMS_ONLY = r"""
#include "hftrace_plugin.h"
static const hftrace_plugin_info INFO = {HFTRACE_PLUGIN_ABI, "sums_only", "traversal", 0, "", ""};
const hftrace_plugin_info *hftrace_plugin(void) { return &INFO; }
int hftrace_traverse(int64_t nx, int64_t ny, int64_t n, const double *o, const double *d,
                     const double *tmin, const double *tmax, uint64_t *sums, int64_t *cells) {
    (void)nx; (void)ny; (void)o; (void)d; (void)tmin; (void)tmax;
    for (int64_t r = 0; r < n; r++) { sums[r] = 0; cells[r] = 0; }
    return 0;
}
"""


def build_source(tmp_path, source, name, *defines):
    """A shared library built from ``source`` with the system compiler, at ``name``."""
    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        pytest.skip("no C compiler")
    src = tmp_path / (name + ".c")
    src.write_text(source)
    lib = tmp_path / (name + ".so")
    subprocess.run([cc, "-O1", "-std=c99", "-shared", "-fPIC", "-I", os.path.join(ROOT, "cext"),
                    *defines, str(src), "-o", str(lib)], check=True)
    return lib


def random_rays3(field, n, seed):
    """Seeded first-hit rays over ``field``: origins above its highest point, falling."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = field.heights.shape
    o = np.column_stack([rng.uniform(0, cols - 1, n), rng.uniform(0, rows - 1, n),
                         np.full(n, float(field.heights.max()) + 1.0)])
    d = np.column_stack([rng.normal(size=(n, 2)), -rng.uniform(0.5, 1.5, n)])
    return o, d


class NumbaStyle:
    """A compiled-function stand-in (numba's dispatchers are callable objects, not
    functions): the harness must only call it."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, *args):
        return self.fn(*args)


def test_import_algos_then_plugins_module():
    """``algos.plugins.load_c_plugin`` right after ``import algos`` (a fresh process)."""
    code = "import algos; print(algos.plugins.load_c_plugin.__name__, 'numpy_dda' in algos.TRAVERSALS)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=ROOT), check=True).stdout
    assert out.split() == ["load_c_plugin", "False"]


def test_no_import_circle_between_plugins_and_registry():
    """The layers run registry <- plugin_calls <- plugins: the registry imports neither,
    the calls only the registry, the plugins module the two of them. The C extension
    (`_kernels`, where the kernel ids are written once) sits below them all."""
    import ast

    def local_imports(path):
        """The algos modules a file imports (relative imports, or absolute ones of algos)."""
        tree = ast.parse(open(os.path.join(ROOT, "algos", path)).read())
        names = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level >= 1:
                names |= {node.module} if node.module else {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("algos"):
                names.add(node.module)
            elif isinstance(node, ast.Import):
                names |= {a.name for a in node.names if a.name.startswith("algos")}
        return names

    assert local_imports("registry.py") == {"_kernels"}
    assert local_imports("plugin_calls.py") == {"registry"}
    assert local_imports("plugins.py") == {"registry", "plugin_calls"}


def test_python_intersector_through_intersect_and_render(registered):
    """A registered Python (Numba-style) intersector answers ``algos.intersect`` as the
    kernel it wraps does (t, cell, normal) and renders the same image."""
    field = algos.Field(np.asarray(__import__("datasets_gen").load("fbm", size=48, seed=2).heights,
                                   dtype=np.float32))

    def runs_t(heights, o, d):
        return algos.intersect("runs", algos.Field(heights), o, d).t

    algos.register_intersector("wrapped", NumbaStyle(runs_t), surfaces=["triangles"])
    registered.append("wrapped")
    o, d = random_rays3(field, 300, seed=11)
    want = algos.intersect("runs", field, o, d, outputs=("t", "cell", "normal"))
    got = algos.intersect("wrapped", field, o, d, outputs=("t", "cell", "normal"))
    assert np.isfinite(want.t).sum() > 200
    np.testing.assert_array_equal(got.t, want.t)
    np.testing.assert_array_equal(got.cell, want.cell)
    np.testing.assert_allclose(got.normal, want.normal, atol=1e-12)
    assert algos.intersect("wrapped", field, o, d).cell.shape == (300, 2)  # default outputs
    image = algos.render(field, "wrapped", width=32, height=18, threads=1)
    reference = algos.render(field, "runs", width=32, height=18, threads=1)
    np.testing.assert_array_equal(image.depth, reference.depth)
    np.testing.assert_allclose(image.rgb, reference.rgb, atol=1e-12)
    assert not image.cells_visited.any()  # a plugin reports no statistics
    with pytest.raises(ValueError, match="outputs: kernel 'wrapped' .*no per-ray statistics"):
        algos.intersect("wrapped", field, o, d, outputs=("t", "stats"))
    with pytest.raises(ValueError, match="tmin: kernel 'wrapped' .*takes no ray range"):
        algos.intersect("wrapped", field, o, d, tmin=0.5)
    with pytest.raises(ValueError, match="surface: wrapped supports only triangles"):
        algos.intersect("wrapped", field, o, d, surface="flat")
    with pytest.raises(ValueError, match="fine_level: not an option of wrapped"):
        algos.intersect("wrapped", field, o, d, fine_level=2)


def test_first_hit_plugin_failures_name_the_kernel(registered):
    field = algos.Field(np.zeros((8, 8), np.float32))
    o, d = np.array([[1.0, 1.0, 2.0]]), np.array([[1.0, 0.0, -1.0]])
    algos.register_intersector("short", lambda h, o, d: np.zeros(len(o) + 1))
    algos.register_intersector("boom", lambda h, o, d: 1 / 0)
    registered += ["short", "boom"]
    with pytest.raises(plugins.PluginError, match=r"short: returned t of shape \(2,\); expected \(1,\)"):
        algos.intersect("short", field, o, d)
    with pytest.raises(plugins.PluginError, match="boom: the kernel raised ZeroDivisionError"):
        algos.intersect("boom", field, o, d)
    algos.register_intersector("behind", lambda h, o, d: np.full(len(o), -0.5))
    registered.append("behind")
    with pytest.raises(plugins.PluginError, match=r"behind: returned t\[0\] = -0.5, outside ray "
                                                  r"0's range \[0.0, inf\]"):
        algos.intersect("behind", field, o, d)


def test_python_first_hit_outside_the_footprint_is_refused(registered):
    """A Python kernel's hit whose point lies beyond the field is an error naming the ray
    and the point, not a hit in the border cell it would be clipped to; a hit on the
    footprint's border (a ray entering the box below the surface) stays a hit."""
    field = algos.Field(np.zeros((9, 9), np.float32))
    o, d = np.array([[0.5, 4.5, 3.0], [4.5, 4.5, 10.0]]), np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    algos.register_intersector("far_hit", lambda h, o, d: np.full(len(o), 1e300))
    algos.register_intersector("off_grid", lambda h, o, d: np.array([20.0, 10.0]))
    algos.register_intersector("text_hit", lambda h, o, d: np.array(["a"] * len(o)))
    algos.register_intersector("edge_hit", lambda h, o, d: np.array([7.5, 10.0]))
    registered += ["far_hit", "off_grid", "text_hit", "edge_hit"]
    with pytest.raises(plugins.PluginError, match=r"far_hit: returned t\[0\] = 1e\+300, whose hit "
                                                  r"point .* lies outside the field's footprint "
                                                  r"\[0, 8\] x \[0, 8\]"):
        algos.intersect("far_hit", field, o, d)
    with pytest.raises(plugins.PluginError, match=r"off_grid: returned t\[0\] = 20.0, whose hit "
                                                  r"point \(20.5, 4.5\)"):
        algos.intersect("off_grid", field, o, d)
    with pytest.raises(plugins.PluginError, match=r"text_hit: returned t of dtype <U1; expected"):
        algos.intersect("text_hit", field, o, d)
    hits = algos.intersect("edge_hit", field, o, d)  # x = 8.0 on the east border
    assert hits.t.tolist() == [7.5, 10.0] and hits.cell.tolist() == [[7, 4], [4, 4]]


def test_python_kernel_cannot_change_the_callers_field_or_rays(registered):
    """A Python kernel that writes into its inputs fails in one line naming it; the
    caller's field and rays (which the other kernels reuse) stay as they were."""
    heights = (np.arange(81, dtype=np.float32).reshape(9, 9) % 5)
    field = algos.Field(heights.copy())
    o, d = np.array([[0.5, 0.5, 10.0]]), np.array([[1.0, 1.0, -1.0]])

    def flatten(h, o, d):
        h[:] = 100.0
        return np.full(len(o), np.inf)

    def normalise(o, d, shape):
        d /= np.linalg.norm(d, axis=1)[:, None]
        return [np.zeros((0, 2), np.int64) for _ in o]

    algos.register_intersector("flatten", flatten)
    algos.register_traversal("normalise", normalise)
    registered += ["flatten", "normalise"]
    with pytest.raises(plugins.PluginError, match="flatten: the kernel raised ValueError: "
                                                  "assignment destination is read-only"):
        algos.intersect("flatten", field, o, d)
    np.testing.assert_array_equal(field.heights, heights)
    o2, d2 = np.array([[0.5, 0.5]]), np.array([[2.0, 3.0]])
    with pytest.raises(plugins.PluginError, match="normalise: the kernel raised ValueError"):
        algos.traverse("normalise", o2, d2, (4, 4))
    assert d2.tolist() == [[2.0, 3.0]] and o.tolist() == [[0.5, 0.5, 10.0]]
    run, _ = plugins.prepare_timed_first_hit("flatten", field.heights, o, d, "triangles")
    with pytest.raises(ValueError, match="read-only"):
        run()
    np.testing.assert_array_equal(field.heights, heights)


def test_python_traversal_through_traverse(registered):
    """A registered traversal returning cells serves every output of ``algos.traverse``."""
    from examples.plugins.numpy_dda import register

    register()
    registered.append("numpy_dda")
    rng = np.random.Generator(np.random.PCG64(21))
    o = rng.uniform(0, 30, (150, 2))
    d = rng.normal(size=(150, 2))
    for output in ("cells", "runs", "count"):
        got = algos.traverse("numpy_dda", o, d, (30, 30), output=output)
        want = algos.traverse("midpoint", o, d, (30, 30), output=output)
        if output == "count":
            np.testing.assert_array_equal(got.cells, want.cells)
            np.testing.assert_array_equal(got.runs, want.runs)
        else:
            np.testing.assert_array_equal(got.offsets, want.offsets)
            for k in range(150):
                np.testing.assert_array_equal(got[k], want[k], err_msg=f"ray {k}: o={o[k]!r} d={d[k]!r}")
    with pytest.raises(ValueError, match="tmax: kernel 'numpy_dda' \\(Python plugin\\) takes no ray range"):
        algos.traverse("numpy_dda", o, d, (30, 30), tmax=3.0)
    with pytest.raises(ValueError, match="'numpy_dda' is a 2D traversal .*no first-hit kernel"):
        algos.intersect("numpy_dda", np.zeros((4, 4)), np.zeros((1, 3)), np.ones((1, 3)))
    algos.register_traversal("sums", lambda o, d, shape: np.zeros(len(o), np.uint64))
    algos.register_traversal("outside", lambda o, d, shape: [np.array([[shape[0], 0]])] * len(o))
    registered += ["sums", "outside"]
    with pytest.raises(plugins.PluginError, match="sums: returned visit checksums only"):
        algos.traverse("sums", o, d, (30, 30))
    with pytest.raises(plugins.PluginError, match=r"outside: ray 0: returned cell \(30, 0\) outside"):
        algos.traverse("outside", o, d, (30, 30))


def test_python_traversal_through_walk_timed(registered):
    """``algos.walk_timed`` (the timed visit workload) takes a traversal plugin, its
    checksums those of the exact kernels; the runs workload it lacks is refused."""
    algos.register_traversal("timed_dda", numpy_dda())
    registered.append("timed_dda")
    rng = np.random.Generator(np.random.PCG64(4))
    o, d = rng.uniform(0, 16, (60, 2)), rng.normal(size=(60, 2))
    elapsed, sums = algos.walk_timed("timed_dda", o, d, (16, 16))
    assert elapsed > 0
    np.testing.assert_array_equal(sums, algos.walk_timed("midpoint", o, d, (16, 16))[1])
    with pytest.raises(ValueError, match="workload: kernel 'timed_dda' .* no 'runs' fold"):
        algos.walk_timed("timed_dda", o, d, (16, 16), workload="runs")


def test_c_traversal_through_traverse(tmp_path, registered):
    """The example C plugin (with hftrace_traverse_cells) serves ``algos.traverse``, ray
    ranges included; a library without that export is refused, naming what it lacks."""
    entry = plugins.load_c_plugin(build_example(tmp_path))
    registered.append(entry.name)
    rng = np.random.Generator(np.random.PCG64(8))
    o = rng.uniform(0, 25, (120, 2))
    d = rng.normal(size=(120, 2))
    tmin, tmax = rng.uniform(0, 2, 120), rng.uniform(2, 20, 120)
    for kwargs in ({}, {"tmin": tmin, "tmax": tmax}):
        got = algos.traverse("cell_dda_c", o, d, (25, 25), **kwargs)
        want = algos.traverse("midpoint", o, d, (25, 25), **kwargs)
        np.testing.assert_array_equal(got.offsets, want.offsets)
        np.testing.assert_array_equal(got.cells, want.cells)
    counts = algos.traverse("cell_dda_c", o, d, (25, 25), output="count")
    np.testing.assert_array_equal(counts.runs, algos.traverse("midpoint", o, d, (25, 25), output="count").runs)
    sums_only = plugins.load_c_plugin(build_source(tmp_path, C_CHECKSUMS_ONLY, "sums_only"))
    registered.append(sums_only.name)
    with pytest.raises(ValueError, match="kernel 'sums_only' \\(C plugin .*sums_only.so\\) does not "
                                         "export hftrace_traverse_cells"):
        algos.traverse("sums_only", o, d, (25, 25))


def test_c_first_hit_through_intersect_and_rebuilt_library(tmp_path, registered):
    """A C first-hit plugin answers ``algos.intersect``; rebuilt at the same path and
    loaded again, its new code runs (the loader copies by content hash)."""
    field = algos.Field(np.zeros((6, 6), np.float32))
    o, d = np.array([[1.0, 1.0, 2.0], [2.0, 2.0, 3.0]]), np.array([[1.0, 0.0, -1.0], [0.0, 1.0, -1.0]])
    lib = build_source(tmp_path, C_FIRST_HIT, "constant", "-DT=1.5")
    registered.append(plugins.load_c_plugin(lib).name)
    hits = algos.intersect("constant_hit", field, o, d, outputs=("t", "cell", "normal"))
    assert hits.t.tolist() == [1.5, 1.5] and hits.cell.tolist() == [[0, 0], [0, 0]]
    assert hits.normal.tolist() == [[0.0, 0.0, 1.0]] * 2  # flat ground: up
    build_source(tmp_path, C_FIRST_HIT, "constant", "-DT=2.5")  # same path, new code
    entry = plugins.load_c_plugin(lib)
    assert entry.plugin.path == str(lib) and entry.plugin.loaded_from != str(lib)
    assert algos.intersect("constant_hit", field, o, d).t.tolist() == [2.5, 2.5]


def test_c_plugin_refused_info_names_the_library(tmp_path, registered, capsys):
    """A library whose info declares a built-in name or an unknown surface is refused in
    one line that names the library, from Python and from ``--plugin``."""
    builtin = build_source(tmp_path, C_FIRST_HIT.replace('"constant_hit"', '"runs"'),
                           "takes_runs", "-DT=1.0")
    spline = build_source(tmp_path, C_FIRST_HIT.replace('"triangles"', '"triangles,spline"'),
                          "spline_hit", "-DT=1.0")
    with pytest.raises(plugins.PluginError, match=r"C plugin .*takes_runs.so: .*refused: name: "
                                                  r"'runs' is a built-in kernel"):
        plugins.load_c_plugin(builtin)
    with pytest.raises(plugins.PluginError, match=r"C plugin .*spline_hit.so: .*refused: "
                                                  r"surfaces\[1\]: unknown surface 'spline'"):
        plugins.load_c_plugin(spline)
    assert "constant_hit" not in plugins.plugin_names()
    assert main(["list", "--plugin", str(spline)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "spline_hit.so" in err and "unknown surface" in err


def test_plugin_failures_are_one_line_on_every_route(tmp_path, monkeypatch, registered, capsys):
    """``--plugin MOD:FN`` whose function raises, a C plugin whose hftrace_plugin()
    returns NULL, and the same in a config: one line naming the plugin, no traceback."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "badreg.py").write_text("def register():\n    raise RuntimeError('no GPU\\nhere')\n")
    assert main(["list", "--plugin", "badreg:register"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "badreg:register" in err and "no GPU here" in err
    assert "Traceback" not in err
    lib = build_source(tmp_path, C_NULL_INFO, "null_info")
    assert main(["list", "--plugin", str(lib)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "null_info.so" in err and "returned NULL" in err
    with pytest.raises(plugins.PluginError, match="hftrace_plugin\\(\\) returned NULL"):
        plugins.load_c_plugin(lib)
    (tmp_path / "c.toml").write_text('rays = 16\nrepeats = 3\nplugins = ["null_info.so"]\n')
    assert main(["sweep", str(tmp_path / "c.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "plugins[0]" in err and "returned NULL" in err
    # an installed package's entry point naming that library: one warning line, then on
    import importlib.metadata as md

    class Point:
        name, value = "nullinfo", "theirs:LIBRARY"

        def load(self):
            return str(lib)

    monkeypatch.setattr(md, "entry_points", lambda group=None: [Point()] if group else {})
    assert main(["list"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "entry point 'nullinfo'" in err and "returned NULL" in err


def test_config_module_resolves_from_its_folder_and_the_cwd(tmp_path, monkeypatch, registered):
    """``module:callable`` in a config imports from the config's folder, then the current
    directory, without PYTHONPATH."""
    folder = tmp_path / "configs"
    folder.mkdir()
    (folder / "beside_config.py").write_text(
        "import algos\nfrom examples.plugins.numpy_dda import numpy_dda\n"
        "def register():\n    algos.register_traversal('beside', numpy_dda)\n")
    (tmp_path / "in_cwd.py").write_text(
        "import algos\nfrom examples.plugins.numpy_dda import numpy_dda\n"
        "def register():\n    algos.register_traversal('from_cwd', numpy_dda)\n")
    (folder / "c.toml").write_text('rays = 16\nrepeats = 3\n'
                                   'plugins = ["beside_config:register", "in_cwd:register"]\n')
    monkeypatch.chdir(tmp_path)
    registered += ["beside", "from_cwd"]
    assert str(tmp_path) not in sys.path and str(folder) not in sys.path
    sweep.load_config(str(folder / "c.toml"))
    assert {"beside", "from_cwd"} <= set(algos.TRAVERSALS)
    (folder / "bad.toml").write_text('plugins = ["nowhere_module:register"]\n')
    with pytest.raises(sweep.ConfigError, match="plugins\\[0\\]: plugin nowhere_module:register: "
                                                "cannot import nowhere_module .*looked in"):
        sweep.load_config(str(folder / "bad.toml"))


def test_config_inside_the_package_it_names_resolves_from_any_cwd(tmp_path, monkeypatch,
                                                                   registered):
    """A config inside the package its ``module:callable`` names (the guide's
    ``examples/sweep-plugin.toml`` naming ``examples.plugins.numpy_dda``) resolves from
    any current directory, without PYTHONPATH."""
    package = tmp_path / "mylab" / "kernels"
    package.mkdir(parents=True)
    (tmp_path / "mylab" / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "walk.py").write_text(
        "import algos\nfrom examples.plugins.numpy_dda import numpy_dda\n"
        "def register():\n    algos.register_traversal('lab_walk', numpy_dda)\n")
    (package / "c.toml").write_text('rays = 16\nrepeats = 3\n'
                                    'plugins = ["mylab.kernels.walk:register"]\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    registered += ["lab_walk", "numpy_dda"]
    sweep.load_config(str(package / "c.toml"))
    assert "lab_walk" in algos.TRAVERSALS
    # the guide's own config names its module from the repository's root
    assert plugins.load_plugin_spec("examples.plugins.numpy_dda:register",
                                    base=os.path.join(ROOT, "examples")) == ["numpy_dda"]


def test_reproduce_kernels_accepts_a_registered_traversal(registered, capsys):
    """``--kernels NAME`` of a registered traversal is not "unknown intersector": the
    headline preset says what it lacks, the standard preset takes it."""
    from bench.cli.studies import _reproduce_kernel

    algos.register_traversal("mine", numpy_dda())
    registered.append("mine")
    assert main(["reproduce", "--kernels", "mine", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "unknown intersector" not in err and "'mine' is a 2D traversal" in err
    assert "--preset standard" in err
    _reproduce_kernel("mine", "standard")  # accepted
    with pytest.raises(ValueError, match="unknown intersector 'nope'"):
        _reproduce_kernel("nope", "standard")


def test_regress_reports_a_missing_plugin_as_missing(tmp_path, monkeypatch):
    """A baseline ratio of a plugin not loaded in this run is reported missing, not
    regressed."""
    import json

    from bench.regress import time_gate as gate

    samples = [1.0, 1.01, 0.99, 1.02, 0.98] * 4
    base = {"visit/-/r=1/midpoint": samples, "visit/-/r=1/gone_plugin": samples}
    path = tmp_path / "baseline.json"
    path.write_text(json.dumps({"samples": base, "tolerance": 0.05}))
    monkeypatch.setattr(gate, "pin_to_one_cpu", lambda: None)
    monkeypatch.setattr(gate, "measure", lambda: {"visit/-/r=1/midpoint": samples})
    lines = []
    assert gate.run(str(path), echo=lines.append) == 1
    text = "\n".join(lines)
    assert "1 ratio(s) missing" in text and "'gone_plugin' is not registered" in text
    assert "regressed" not in text.replace("not regressed", "")


def test_plot_line_style_follows_the_exactness_claim(registered):
    """An ``exact=False`` plugin is drawn dashed, an exact one solid, a kernel this
    process does not know dashed (no claim backs it)."""
    algos.register_traversal("approx", numpy_dda(), exact=False)
    algos.register_intersector("claims", lambda h, o, d: np.full(len(o), np.inf), exact=True)
    registered += ["approx", "claims"]
    assert plots._style("approx") == "--"
    assert plots._style("claims") == "-"
    assert plots._style("not_loaded_here") == "--"
    assert plots._style("runs") == "-" and plots._style("dda_f32") == "--"


def test_plot_draws_an_inexact_plugin_dashed(tmp_path, registered, monkeypatch):
    """Through ``plot_speedup`` (what ``hftrace plot`` draws): the line of a plugin
    registered with ``exact=False`` is dashed, an exact one's solid."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.figure

    algos.register_intersector("rough", lambda h, o, d: np.full(len(o), np.inf), exact=False)
    algos.register_intersector("sharp", lambda h, o, d: np.full(len(o), np.inf), exact=True)
    registered += ["rough", "sharp"]
    head = "algorithm,workload,surface,dataset,run_length,speedup,speedup_ci_low," \
           "speedup_ci_high,ns_per_ray,agree\n"
    rows = "".join(f"{a},first_hit,triangles,fbm,{r},1.5,1.4,1.6,10,1.0\n"
                   for a in ("dda", "runs", "rough", "sharp") for r in (1, 2, 25))
    (tmp_path / "r.csv").write_text(head + rows)
    styles = {}

    def keep_styles(fig, *args, **kwargs):
        styles.update((line.get_label(), line.get_linestyle()) for line in fig.axes[0].get_lines())

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", keep_styles)
    plots.plot_speedup(analysis.load(str(tmp_path / "r.csv"), echo=None), str(tmp_path / "p.png"))
    assert styles["rough"] == "--" and styles["sharp"] == "-" and styles["runs"] == "-"


def test_render_command_takes_a_plugin(tmp_path, monkeypatch, registered, capsys):
    """``hftrace render --plugin MOD:FN --algorithm NAME`` draws with the plugin."""
    (tmp_path / "myhits.py").write_text(
        "import algos\n"
        "def hits(h, o, d):\n    return algos.intersect('runs', algos.Field(h), o, d).t\n"
        "def register():\n    algos.register_intersector('my_hits', hits)\n")
    monkeypatch.chdir(tmp_path)
    registered.append("my_hits")
    assert main(["render", "fbm", "--size", "32", "--width", "24", "--height", "14",
                 "--plugin", "myhits:register", "--algorithm", "my_hits",
                 "--out", str(tmp_path / "img"), "--threads", "1"]) == 0, capsys.readouterr().err
    assert (tmp_path / "img.png").exists() and (tmp_path / "img.exr").exists()


@pytest.mark.parametrize("metric", ["instructions", "counters"])
def test_exact_regress_gates_refuse_a_plugin(metric, capsys):
    """The exact gates count hftrace's own C kernels only: ``--plugin`` with them is
    refused (exit 2, one line naming the option and the plugin) instead of passing
    without ever gating the plugin."""
    spec = "examples.plugins.numpy_dda:register"
    assert main(["regress", "--metric", metric, "--plugin", spec]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hftrace: error: --plugin:") and spec in err
    assert "--metric time" in err and len(err.strip().splitlines()) == 1


def test_time_gate_names_a_failing_plugin_in_one_line(monkeypatch, registered, quiet_flush,
                                                      tmp_path, capsys):
    """A plugin that raises during ``hftrace regress`` (time) fails the command with one
    line naming the ratio, the kernel and its error, never a traceback."""
    import functools

    from bench.regress import time_gate as gate

    def exploding(o, d, shape):
        raise RuntimeError("kernel exploded\nsecond line")

    algos.register_traversal("exploding", exploding)
    registered.append("exploding")
    monkeypatch.setattr(gate, "CHECKS", (("visit", "-", 2, ("midpoint",), 40),))
    monkeypatch.setattr(gate, "measure", functools.partial(gate.measure, repeats=3, rounds=1))
    monkeypatch.setattr(gate, "pin_to_one_cpu", lambda: None)
    assert main(["regress", "--baseline", str(tmp_path / "none.json")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "visit/-/r=2/exploding" in err and "kernel exploded second line" in err


def test_multiline_kernel_error_is_one_table_row(tmp_path, registered, quiet_flush):
    """A kernel's error message over several lines, with a pipe, is one line in its row
    and one row of speedup.md's "Kernel errors" table (it split the row in two)."""
    def exploding(o, d, shape):
        raise RuntimeError("kernel | exploded\nsecond line")

    algos.register_traversal("exploding", exploding)
    registered.append("exploding")
    cfg = sweep.load_config({**TINY, "algorithms": ["dda", "exploding"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert [r["error"] for r in by(rows, "exploding")] == \
        ["RuntimeError: kernel | exploded second line"] * 2
    assert main(["plot", str(tmp_path / "results.csv")]) == 0
    text = open(tmp_path / "speedup.md").read()
    table = text.split("## Kernel errors")[1].split("\n\n")[2].splitlines()
    assert table[2:] == [f"| exploding | fbm64 | visit | {r} | RuntimeError: kernel \\| "
                         "exploded second line |" for r in ("2", "random")]


def test_by_dataset_table_marks_error_rows(tmp_path, registered, quiet_flush):
    """speedup.md's by-dataset table says ``error`` where the headline table does: a
    kernel whose exactness claim failed (its timings kept) and one that raised (no
    timings) showed a speedup and a blank cell there."""
    def wrong(h, o, d):
        return algos.intersect("runs", algos.Field(np.array(h)), o, d).t * 1.5

    def raising(h, o, d):
        raise RuntimeError("boom")

    algos.register_intersector("wrong_hits", wrong, exact=True)
    algos.register_intersector("raising_hits", raising, exact=True)
    registered += ["wrong_hits", "raising_hits"]
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"],
                             "algorithms": ["dda", "runs", "wrong_hits", "raising_hits"]})
    sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert main(["plot", str(tmp_path / "results.csv")]) == 0
    text = open(tmp_path / "speedup.md").read()
    headline = text.split("## The paper's measure")[1].split("\n\n")[3].splitlines()
    assert all(line.endswith("| error | error |") for line in headline[2:]), headline
    by_dataset = text.split("## By dataset")[1].split("\n\n")[1].splitlines()
    assert by_dataset[0].endswith("| wrong_hits | raising_hits |"), by_dataset
    assert by_dataset[2].endswith("| error | error |"), by_dataset


def test_swept_plugin_outputs_are_checked_as_the_public_calls_check_them(
        tmp_path, registered, quiet_flush):
    """A sweep refuses what algos.traverse and algos.intersect refuse, with an error in the
    kernel's row naming what was wrong: cells that are not (k, 2) integers or lie outside
    the grid (they were folded into a checksum that merely disagreed), signed or float
    checksums and t that is text ("cannot reshape", "could not convert") or negative."""
    def float_cells(o, d, shape):
        return [np.array([[0.5, 0.0]])] * len(o)

    def off_grid(o, d, shape):
        return [np.array([[shape[0] + 3, 0]])] * len(o)

    def signed_sums(o, d, shape):
        return np.zeros(len(o), dtype=np.int64)

    def text_t(h, o, d):
        return ["x"] * len(o)

    def behind(h, o, d):
        return np.full(len(o), -1.0)

    for fn in (float_cells, off_grid, signed_sums):
        algos.register_traversal(fn.__name__, fn)
    for fn in (text_t, behind):
        algos.register_intersector(fn.__name__, fn)
    registered += ["float_cells", "off_grid", "signed_sums", "text_t", "behind"]
    cfg = sweep.load_config({**TINY, "workloads": ["visit", "first_hit"], "run_lengths": [2],
                             "algorithms": ["dda", "float_cells", "off_grid", "signed_sums",
                                            "text_t", "behind"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    errors = {r["algorithm"]: r["error"] for r in rows}
    assert "ray 0: returned cells of shape (1, 2) and dtype float64" in errors["float_cells"]
    assert "returned cell (66, 0) outside the grid of 63 x 63 cells" in errors["off_grid"]
    assert "returned a (40,) int64 array; checksums are (N,) uint64" in errors["signed_sums"]
    assert "returned t of dtype str; expected (40,) numbers" in errors["text_t"]
    assert "returned t[0] = -1.0, outside ray 0's range" in errors["behind"]


def test_datasets_differing_by_seed_keep_their_own_rows(tmp_path, quiet_flush):
    """Two fields of one generator and size that differ by the seed get their own labels
    (they shared one: the report failed with "Index contains duplicate entries" after the
    whole measurement, and --resume took one field's rows for the other's); one field
    listed twice is refused before any work."""
    two = [{"name": "fbm", "size": 64, "seed": 1}, {"name": "fbm", "size": 64, "seed": 2}]
    cfg = sweep.load_config({**TINY, "run_lengths": [2], "algorithms": ["dda", "midpoint"],
                             "datasets": two})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert sorted({r["dataset"] for r in rows}) == ["fbm64-seed1", "fbm64-seed2"]
    assert main(["plot", str(tmp_path / "results.csv")]) == 0
    assert "Datasets: fbm64-seed1, fbm64-seed2." in open(tmp_path / "speedup.md").read()
    assert sweep._pending(cfg, str(tmp_path), resume=True)[1] == []  # nothing left
    assert sweep.dataset_label(two[0]) == "fbm64"  # alone, the label is unchanged
    with pytest.raises(sweep.ConfigError, match=r"datasets\[1\]: the same dataset as "
                                                r"datasets\[0\]"):
        sweep.load_config({**TINY, "datasets": [two[0], dict(two[0])]})


def test_resume_refuses_a_dataset_with_another_seed(tmp_path, quiet_flush):
    """--resume with a dataset's seed changed is refused, naming the label and both seeds:
    the label does not hold the seed, so the kept rows of the old field passed for the new
    one's and only the missing groups were measured on it."""
    cfg = sweep.load_config({**TINY, "run_lengths": [2], "algorithms": ["dda", "midpoint"]})
    sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert sweep._pending(cfg, str(tmp_path), resume=True)[1] == []
    other = sweep.load_config({**TINY, "run_lengths": [2, 5], "algorithms": ["dda", "midpoint"],
                               "datasets": [{"name": "fbm", "size": 64, "seed": 2}]})
    with pytest.raises(ValueError, match=r"--resume: the rows of fbm64 were measured with "
                                         r"datasets\[0\]\.seed = 1, the config says 2"):
        sweep.run_sweep(other, str(tmp_path), resume=True, progress=False, echo=None)


def test_swept_c_first_hit_before_the_origin_is_an_error(tmp_path, registered, quiet_flush):
    """A C first-hit kernel whose t is -inf (or any t < 0) has an error in its row, as
    algos.intersect refuses it; it passed for a miss that agreed with the reference's."""
    lib = build_source(tmp_path, C_FIRST_HIT.replace('"constant_hit"', '"minus_inf"'),
                       "minus_inf", "-DT=(-INFINITY)")
    plugins.load_c_plugin(lib)
    registered.append("minus_inf")
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"], "run_lengths": [2],
                             "algorithms": ["dda", "minus_inf"]})
    rows = sweep.run_sweep(cfg, str(tmp_path), progress=False, echo=None)
    assert [r["error"] for r in by(rows, "minus_inf")] == \
        ["PluginError: minus_inf: returned t[0] = -inf, outside ray 0's range [0.0, inf]"]


def test_config_refuses_a_kernel_no_group_measures(registered):
    """A kernel in ``algorithms`` that no workload or surface of the config measures is
    refused before any work, naming it and what it takes (it was dropped from every group
    without a word: a first-hit plugin in a visit sweep ran as a table without it)."""
    algos.register_intersector("tri_hits", lambda h, o, d: np.full(len(o), np.inf))
    registered.append("tri_hits")
    with pytest.raises(sweep.ConfigError, match=r"algorithms\[1\]: 'tri_hits' is measured by "
                                                r"no group of this config \(workloads visit; "
                                                r".*it takes first_hit on triangles"):
        sweep.load_config({**TINY, "algorithms": ["dda", "tri_hits"]})
    with pytest.raises(sweep.ConfigError, match=r"'tri_hits' .*surfaces bilinear"):
        sweep.load_config({**TINY, "workloads": ["first_hit"], "surfaces": ["bilinear"],
                           "algorithms": ["tri_hits"]})
    with pytest.raises(sweep.ConfigError, match=r"'runs_maxmip' .*it takes first_hit"):
        sweep.load_config({**TINY, "algorithms": ["dda", "runs_maxmip"]})
    # measured by one of the config's workloads: accepted
    sweep.load_config({**TINY, "workloads": ["visit", "first_hit"],
                       "algorithms": ["midpoint", "tri_hits"]})


def test_register_refuses_a_non_bool_exact_and_names_surfaces(registered):
    """``exact="false"`` was taken as a claim of exactness (``bool("false")``), and
    ``surfaces=None`` raised "'NoneType' object is not iterable", naming no argument."""
    with pytest.raises(TypeError, match="exact: expected True or False, got 'false'"):
        algos.register_traversal("mine", lambda *a: None, exact="false")
    with pytest.raises(TypeError, match="exact: expected True or False, got 'no'"):
        algos.register_intersector("mine", lambda *a: None, exact="no")
    with pytest.raises(TypeError, match="surfaces: expected a sequence of surface names .* "
                                        "got None"):
        algos.register_intersector("mine", lambda *a: None, surfaces=None)
    registered.append("mine")
    assert algos.register_traversal("mine", lambda *a: None, exact=np.bool_(False)).exact is False
    assert algos.register_intersector("mine", lambda *a: None, exact=1).plugin.exact is True


def test_sweep_command_prints_each_kernel_error_once(tmp_path, registered, quiet_flush,
                                                      capsys, monkeypatch):
    """``hftrace sweep`` printed every kernel error twice (the engine's line, then the
    command's own); now once, then where the table of them is, and exits 1."""
    def raising(o, d, shape):
        raise RuntimeError("kernel exploded")

    algos.register_traversal("raising", raising)
    registered.append("raising")
    monkeypatch.setattr("bench.timing.pin_to_one_cpu", lambda: None)
    config = tmp_path / "c.toml"
    config.write_text('name = "once"\nrays = 16\nrepeats = 3\nworkloads = ["visit"]\n'
                      'run_lengths = [2]\nalgorithms = ["dda", "raising"]\n'
                      '[[datasets]]\nname = "fbm"\nsize = 32\nseed = 1\n')
    assert main(["sweep", str(config), "--out", str(tmp_path / "out"), "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert out.count("kernel exploded") == 1, out
    assert "1 row(s) with a kernel error: the Kernel errors table of " in out


def test_resume_refuses_another_build_of_a_c_plugin(tmp_path, registered, quiet_flush):
    """--resume after rebuilding a C plugin at the same path is refused, naming the plugin
    and both builds: hftrace's commit does not cover a plugin's code, so the rows of the
    old build passed for the new one's."""
    lib = build_source(tmp_path, C_FIRST_HIT, "constant_hit", "-DT=1.0")
    plugins.load_c_plugin(lib)
    registered.append("constant_hit")
    cfg = sweep.load_config({**TINY, "workloads": ["first_hit"], "run_lengths": [2],
                             "algorithms": ["dda", "constant_hit"]})
    out = str(tmp_path / "run")
    sweep.run_sweep(cfg, out, progress=False, echo=None)
    first = plugins.plugin_fingerprint("constant_hit")
    assert first.startswith("c:") and sweep._pending(cfg, out, resume=True)[1] == []
    plugins.unregister("constant_hit")
    assert build_source(tmp_path, C_FIRST_HIT, "constant_hit", "-DT=2.0") == lib  # same path
    plugins.load_c_plugin(lib)
    assert plugins.plugin_fingerprint("constant_hit") != first
    more = sweep.load_config({**TINY, "workloads": ["first_hit"], "run_lengths": [2, 5],
                              "algorithms": ["dda", "constant_hit"]})
    with pytest.raises(ValueError, match=r"--resume: the rows of constant_hit were measured "
                                         r"with another version of the plugin \(c:"):
        sweep.run_sweep(more, out, resume=True, progress=False, echo=None)


def test_a_python_plugin_is_known_by_its_source(registered):
    """A Python kernel's fingerprint names its function and hashes its source file; a
    built-in kernel has none."""
    algos.register_intersector("fp_hits", _no_hits)
    registered.append("fp_hits")
    fp = plugins.plugin_fingerprint("fp_hits")
    assert fp.startswith(f"python:{__name__}._no_hits:") and len(fp.rsplit(":", 1)[1]) == 20
    assert plugins.plugin_fingerprint("dda") is None


def _no_hits(h, o, d):
    return np.full(len(o), np.inf)


def test_time_gate_only_measures_and_judges_the_kernels_named(monkeypatch, registered,
                                                             quiet_flush, tmp_path, capsys):
    """``hftrace regress --only NAME`` measures the checks that hold NAME, with NAME alone
    against dda, and judges its ratios alone; ``--update --only`` writes them into the
    baseline and keeps its other ratios; a name no check measures is refused."""
    import functools
    import json

    from bench.regress import time_gate as gate

    spec = "examples.plugins.numpy_dda:register"
    registered.append("numpy_dda")
    monkeypatch.setattr(gate, "CHECKS", (("visit", "-", 2, ("midpoint", "runs"), 40),
                                         ("first_hit", "triangles", 2, ("runs",), 40)))
    monkeypatch.setattr(gate, "measure", functools.partial(gate.measure, repeats=3, rounds=1))
    monkeypatch.setattr(gate, "pin_to_one_cpu", lambda: None)
    base = tmp_path / "mine.json"
    old = [1.0, 1.01, 0.99] * 3
    base.write_text(json.dumps({"samples": {"visit/-/r=2/midpoint": old}, "tolerance": 0.05}))
    assert main(["regress", "--plugin", spec, "--only", "numpy_dda", "--baseline", str(base),
                 "--update"]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "measuring 1 speedup ratios" in out and "wrote 1 ratios" in out and "(2 in all)" in out
    written = json.loads(base.read_text())["samples"]
    assert set(written) == {"visit/-/r=2/midpoint", "visit/-/r=2/numpy_dda"}
    assert written["visit/-/r=2/midpoint"] == old  # kept as it was
    code = main(["regress", "--plugin", spec, "--only", "numpy_dda", "--baseline", str(base)])
    out = capsys.readouterr().out
    assert code in (0, 3) and "visit/-/r=2/numpy_dda" in out and "r=2/midpoint" not in out
    assert main(["regress", "--only", "nope", "--baseline", str(base)]) == 2
    assert "--only: 'nope' is in no check of the time gate" in capsys.readouterr().err
    assert main(["regress", "--metric", "counters", "--only", "runs"]) == 2
    assert "--only: selects the time gate's kernels" in capsys.readouterr().err

"""``hftrace compare`` and ``hftrace bisect`` on a temporary clone of this repository with
injected changes: verdicts, exit statuses and the one-line errors.

The clone's history (each a commit on top of this checkout's HEAD):
  c0  this checkout's HEAD
  c1  a docs-only change (same build as c0: an A/A pair)
  c2  every ray's ``cells_tested`` counter reported one too high (a counter regression)
  c3  a docs-only change on top of c2
and, on side branches from c0: ``loop`` (a busy loop per ray in the C batch entry) and
``broken`` (C that does not compile). Builds are cached per source tree, so c0/c1 and
c2/c3 share theirs: four builds in all, made with HFTRACE_DEBUG=1 (-O0, about a third
of -O3's compile time; the counters do not depend on the optimisation, and the busy loop
shows in instructions either way).
"""
import json
import os
import shutil
import subprocess

import numpy as np
import pytest

from bench import compare as cmp
from bench.cli import main
from bench.regress import instructions_gate

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
HIT_C = os.path.join("cext", "dispatch", "intersect.c")
COUNTER_LINE = "        s[1] = h->cells_tested;\n"
BATCH_END = "        ray_end(b, ray, &h);\n    }\n    return HF_OK;\n"
SPIN = ("        { /* injected: a busy loop per ray */\n"
        "            volatile int spin;\n"
        "            for (spin = 0; spin < 400; ++spin) {}\n"
        "        }\n")

needs_valgrind = pytest.mark.skipif(
    shutil.which("valgrind") is None or "libasan" in os.environ.get("LD_PRELOAD", ""),
    reason="needs valgrind (and no preloaded sanitizer runtime)")


def _git(repo, *args):
    return subprocess.run(["git", "-C", repo, *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def _edit(repo, rel, old, new):
    path = os.path.join(repo, rel)
    with open(path) as f:
        text = f.read()
    assert text.count(old) == 1, f"injection target not unique in {rel}: {old!r}"
    with open(path, "w") as f:
        f.write(text.replace(old, new))


def _commit(repo, message):
    _git(repo, "commit", "-q", "-am", message)
    return _git(repo, "rev-parse", "HEAD")


@pytest.fixture(scope="module")
def history(tmp_path_factory):
    """The clone and its commits {name: sha}; the build cache in a temporary directory."""
    top = subprocess.run(["git", "-C", ROOT, "rev-parse", "--show-toplevel"], capture_output=True,
                         text=True)
    if top.returncode != 0 or os.path.realpath(top.stdout.strip()) != os.path.realpath(ROOT):
        # not a repository's root: e.g. make sanitize's copy of the tree in build/asan,
        # which lies inside the checkout but is no repository of its own
        pytest.skip("this tree is not the root of a git repository")
    base = tmp_path_factory.mktemp("compare")
    repo = str(base / "repo")
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", ROOT, repo], check=True)
    _git(repo, "config", "user.email", "test@example.invalid")
    _git(repo, "config", "user.name", "compare test")
    shas = {"c0": _git(repo, "rev-parse", "HEAD")}
    note = os.path.join(repo, "docs", "CONVENTIONS.md")
    with open(note, "a") as f:
        f.write("\n")
    shas["c1"] = _commit(repo, "docs only")
    _edit(repo, HIT_C, COUNTER_LINE, "        s[1] = h->cells_tested + 1;\n")
    shas["c2"] = _commit(repo, "injected: cells_tested one too high")
    with open(note, "a") as f:
        f.write("\n")
    shas["c3"] = _commit(repo, "docs only, again")
    _git(repo, "checkout", "-q", "-b", "loop", shas["c0"])
    _edit(repo, HIT_C, BATCH_END, SPIN + BATCH_END)
    shas["loop"] = _commit(repo, "injected: a busy loop per ray")
    _git(repo, "checkout", "-q", "-b", "broken", shas["c0"])
    _edit(repo, HIT_C, BATCH_END, "        this is not C;\n" + BATCH_END)
    shas["broken"] = _commit(repo, "injected: a compile error")
    _git(repo, "checkout", "-q", shas["c3"])
    env = {"HFTRACE_BUILD_CACHE": str(base / "cache"), "HFTRACE_DEBUG": "1"}
    old = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    yield repo, shas
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


def _run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def _verdicts(out):
    """{kernel: verdict} from compare's text report."""
    found = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[1] in ("slower", "faster", "same", "inconclusive", "new"):
            found[parts[0]] = parts[1]
    return found


def test_counter_regression_is_slower_and_exits_1(history, capsys, tmp_path):
    repo, shas = history
    out_json = str(tmp_path / "verdict.json")
    status, out, err = _run(capsys, "compare", shas["c1"], shas["c2"], "--repo", repo,
                            "--metric", "counters", "--kernels", "dda,runs,dda_maxmip",
                            "--json", out_json)
    assert status == 1, out + err
    assert _verdicts(out) == {"dda": "slower", "runs": "slower", "dda_maxmip": "slower"}
    assert "cells_tested per ray" in out and "3 kernel(s) slower" in out
    with open(out_json) as f:
        report = json.load(f)
    assert report["status"] == 1 and report["base"]["commit"] == shas["c1"]
    dda = next(r for r in report["results"] if r["kernel"] == "dda")
    # exactly one more tested cell per ray, on every ray
    assert dda["counters"]["head"]["cells_tested"] == pytest.approx(
        dda["counters"]["base"]["cells_tested"] + 1)
    assert dda["counters"]["head"]["cells_visited"] == dda["counters"]["base"]["cells_visited"]


def test_same_code_under_two_commits_is_same_and_exits_0(history, capsys, tmp_path):
    repo, shas = history
    summary = tmp_path / "summary.md"
    os.environ["GITHUB_STEP_SUMMARY"] = str(summary)
    try:
        status, out, err = _run(capsys, "compare", shas["c0"], shas["c1"], "--repo", repo,
                                "--metric", "counters", "--kernels", "dda,runs")
    finally:
        del os.environ["GITHUB_STEP_SUMMARY"]
    assert status == 0, out + err
    assert _verdicts(out) == {"dda": "same", "runs": "same"}
    text = summary.read_text()
    assert "| dda | **same** |" in text and shas["c0"][:10] in text


def test_time_is_measured_on_both_builds(history, capsys, tmp_path):
    """Time only loosely (the machine may be busy): a ratio with an interval around it,
    a verdict word and the smallest detectable change, for the A/A pair."""
    repo, shas = history
    out_json = str(tmp_path / "t.json")
    status, out, err = _run(capsys, "compare", shas["c0"], shas["c1"], "--repo", repo,
                            "--metric", "time", "--kernels", "dda", "--repeats", "5",
                            "--budget", "0.5", "--json", out_json)
    assert status in (0, 1), err
    with open(out_json) as f:
        t = json.load(f)["results"][0]["time"]
    assert 0 < t["low"] <= t["ratio"] <= t["high"] and t["repeats"] >= 5
    assert t["detectable"] > 0.03 and t["verdict"] in ("slower", "faster", "same", "inconclusive")


@needs_valgrind
def test_busy_loop_shows_in_instructions(history, capsys):
    repo, shas = history
    status, out, err = _run(capsys, "compare", shas["c0"], shas["loop"], "--repo", repo,
                            "--metric", "instructions,counters", "--kernels", "dda")
    assert status == 1, out + err
    assert _verdicts(out) == {"dda": "slower"}
    assert "counters identical" in out  # the loop does no algorithmic work


def test_bisect_names_the_injected_commit(history, capsys):
    repo, shas = history
    status, out, err = _run(capsys, "bisect", shas["c0"], shas["c3"], "--repo", repo,
                            "--metric", "counters", "--kernels", "dda")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0] == f"first bad commit: {shas['c2']}"
    assert lines[1].startswith("  dda: cells_tested per ray")


def test_bisect_without_regression(history, capsys):
    repo, shas = history
    status, out, err = _run(capsys, "bisect", shas["c0"], shas["c1"], "--repo", repo,
                            "--metric", "counters", "--kernels", "dda")
    assert status == 0 and out.startswith("no regression between"), out + err


@pytest.mark.parametrize("argv, words", [
    (["compare", "no-such-revision"], ["revision", "'no-such-revision'", "is not a commit"]),
    (["compare", "{c0}", "{broken}"], ["does not build"]),
    (["compare", "{c0}", "{c1}", "--kernels", "warp_drive"], ["kernels", "'warp_drive'"]),
    (["compare", "{c0}", "{c1}", "--metric", "speed"], ["metric", "speed"]),
    (["compare", "{c0}", "{c1}", "--tolerance", "3"], ["tolerance", "3"]),
    (["bisect", "{c3}", "{c0}"], ["bisect", "not a descendant"]),
    (["compare", "{c0}", "{c1}", "--surface", "voxels"], ["surface", "'voxels'", "known: "]),
    (["compare", "{c0}", "{c1}", "--metric", "time", "--repeats", "200000"],
     ["repeats: expected 3 to 100000 pairs, got 200000"]),
    (["compare", "{c0}", "{c1}", "--json", "/nonexistent-folder/v.json"],
     ["--json", "/nonexistent-folder", "does not exist"]),
], ids=["bad-revision", "does-not-build", "unknown-kernel", "bad-metric", "bad-tolerance",
        "bisect-backwards", "unknown-surface", "too-many-repeats", "json-folder-missing"])
def test_errors_are_one_line_and_exit_2(history, capsys, argv, words):
    repo, shas = history
    argv = [a.format(**shas) for a in argv] + ["--repo", repo]
    if "--metric" not in argv:
        argv += ["--metric", "counters"]
    status, out, err = _run(capsys, *argv)
    assert status == 2, out + err
    last = err.strip().splitlines()[-1]
    assert last.startswith("hftrace: error: ") and all(w in last for w in words), err
    assert "Traceback" not in err


def test_json_is_checked_before_anything_is_built(tmp_path, capsys, monkeypatch):
    """A ``--json`` that cannot be written is refused before the builds (which take
    minutes), not after the measure."""
    from bench.regress import revisions

    monkeypatch.setattr(revisions, "build", lambda *a, **k: pytest.fail("built despite --json"))
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", ROOT, "--json",
                            str(tmp_path / "missing" / "v.json"))
    assert status == 2 and err.strip().splitlines() == [
        f"hftrace: error: --json: the folder {tmp_path / 'missing'} does not exist"]


def test_a_missing_head_is_named_before_the_base_is_built(history, capsys, monkeypatch):
    repo, shas = history
    from bench.regress import revisions

    monkeypatch.setattr(revisions, "build", lambda *a, **k: pytest.fail("built the base first"))
    status, out, err = _run(capsys, "compare", shas["c0"], "no-such-head", "--repo", repo)
    assert status == 2 and err.strip().splitlines() == [
        f"hftrace: error: revision: 'no-such-head' is not a commit of {repo}"]


def test_an_unknown_kernel_of_the_working_tree_is_refused_before_the_builds(capsys, monkeypatch):
    """With the working tree as head, its registry is this process's: a kernel it lacks is
    refused at once (the builds take minutes)."""
    from bench.regress import revisions

    monkeypatch.setattr(revisions, "build", lambda *a, **k: pytest.fail("built despite the name"))
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", ROOT, "--kernels", "dda,bogus",
                            "--metric", "counters")
    last = err.strip().splitlines()[-1]
    assert status == 2 and last.startswith("hftrace: error: kernels: 'bogus' is not a C "
                                           "first-hit kernel of the working tree"), err
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", ROOT, "--surface", "voxels",
                            "--metric", "counters")
    last = err.strip().splitlines()[-1]
    assert status == 2 and last.startswith("hftrace: error: surface: 'voxels' is not a cell "
                                           "surface of the working tree (known: "), err


def test_only_new_kernels_is_an_error_not_a_pass():
    """Kernels that the base revision lacks have nothing to be compared with: refused,
    where the command used to exit 0 having measured nothing."""
    from algos.registry import INTERSECTOR_REGISTRY
    from bench import compare as cmp

    class Pkg:
        def __init__(self, names):
            self.INTERSECTOR_REGISTRY = {n: INTERSECTOR_REGISTRY[n] for n in names}

    setup = cmp.Setup(metrics=("counters",), kernels=("ring_maxmip",))
    with pytest.raises(cmp.CompareError, match="ring_maxmip is new in the head revision"):
        cmp.measure(None, None, Pkg(["dda"]), Pkg(["dda", "ring_maxmip"]), setup, inputs=object())


def test_an_unwritable_job_summary_keeps_the_verdict(history, capsys, monkeypatch):
    """Under GitHub Actions a job summary that cannot be written is a warning: the exit
    status stays the verdict's (1 for the counter regression), not the error status."""
    repo, shas = history
    monkeypatch.setenv("GITHUB_STEP_SUMMARY", "/nonexistent-folder/summary.md")
    status, out, err = _run(capsys, "compare", shas["c0"], shas["c2"], "--repo", repo,
                            "--metric", "counters", "--kernels", "dda")
    assert status == 1, out + err
    assert _verdicts(out) == {"dda": "slower"}
    assert "warning: GITHUB_STEP_SUMMARY: cannot write /nonexistent-folder/summary.md" in err


def test_not_a_repository(tmp_path, capsys):
    status, out, err = _run(capsys, "compare", "HEAD", "--repo", str(tmp_path))
    assert status == 2 and err.strip() == f"hftrace: error: repo: {tmp_path} is not inside a git repository"


def test_instructions_without_valgrind(history, capsys, monkeypatch):
    repo, shas = history
    monkeypatch.setattr(instructions_gate, "callgrind_available", lambda: False)
    status, out, err = _run(capsys, "compare", shas["c0"], shas["c1"], "--repo", repo,
                            "--metric", "instructions", "--kernels", "dda")
    assert status == 2 and "valgrind" in err.strip().splitlines()[-1]


@pytest.mark.parametrize("shift, spread, verdict", [
    (0.0, 0.005, "same"), (0.08, 0.005, "slower"), (-0.08, 0.005, "faster"),
    (0.0, 0.2, "inconclusive"), (0.02, 0.005, "same")])
def test_time_verdicts(shift, spread, verdict):
    """The verdict rule on seeded log-ratios: beyond 3 % and significant, or not."""
    rng = np.random.default_rng(7)
    x = shift + spread * rng.standard_normal(40)
    v = cmp.time_verdict(x, 0.03)
    assert v["verdict"] == verdict, (shift, spread, v)
    assert v["low"] < v["ratio"] < v["high"]
    half = max(np.log(v["high"] / v["ratio"]), np.log(v["ratio"] / v["low"]))
    assert v["detectable"] == pytest.approx(np.expm1(np.log1p(0.03) + half))


# ---- the exact gates' baselines: provenance and the rule for a mismatch ----------------

@pytest.fixture()
def gate_env(tmp_path, monkeypatch):
    monkeypatch.setenv("HFTRACE_BUILD_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("HFTRACE_DEBUG", "1")
    return tmp_path


def test_counters_gate_passes_on_its_own_baseline(capsys):
    from bench.regress import counters_gate

    status = counters_gate.run(counters_gate.BASELINE, echo=print)
    out = capsys.readouterr().out
    assert status == 0, out
    assert "counted elsewhere" not in out and "other inputs" not in out


def test_counters_gate_rebuilds_the_baseline_commit_on_an_input_mismatch(gate_env, capsys):
    """A baseline whose recorded inputs differ from this machine's is not trusted: the
    gate counts the baseline's commit, built here, and compares with that (so a doctored
    snapshot cannot fail it)."""
    from bench.regress import baseline, counters_gate

    with open(counters_gate.BASELINE) as f:
        base = json.load(f)
    base["hashes"]["rays"] = "0" * 16
    for case in base["cases"].values():  # a snapshot that would fail if it were used
        case["cells_visited"] = 0
    head = subprocess.run(["git", "-C", ROOT, "rev-parse", "HEAD"], capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("this checkout is not a git repository")
    base["commit"] = head.stdout.strip()
    doctored = gate_env / "counters.json"
    doctored.write_text(json.dumps(base))
    status = counters_gate.run(str(doctored), echo=print)
    out = capsys.readouterr().out
    assert "rays hash 0000000000000000 here" in out and base["commit"][:10] in out
    # the sources at that commit are this checkout's kernels (a clean tree): nothing grew
    assert status == 0, out
    del base["commit"]
    doctored.write_text(json.dumps(base))
    lines = []
    assert counters_gate.run(str(doctored), echo=lines.append) == 2
    assert lines[-1].startswith("hftrace: error: baseline:") and "records no commit" in lines[-1]
    assert baseline.ROOT == ROOT


def test_update_refuses_a_dirty_tree(gate_env, monkeypatch):
    from bench.regress import counters_gate, revisions

    monkeypatch.setattr(revisions, "is_clean", lambda repo: False)
    lines = []
    path = gate_env / "new.json"
    assert counters_gate.run(str(path), update=True, echo=lines.append) == 2
    assert "uncommitted changes" in lines[-1] and not path.exists()


def test_counters_gate_refuses_a_tolerance():
    from bench.regress import counters_gate

    lines = []
    assert counters_gate.run(counters_gate.BASELINE, tolerance=0.05, echo=lines.append) == 2
    assert "exact" in lines[-1]


@pytest.mark.parametrize("command, words", [
    ("compare", ["exit status: 0 when no kernel is slower", "1 when at least one is slower",
                 "2 on an error"]),
    ("bisect", ["exit status: 0 when the search ran", "first bad commit", "2 on an error"])])
def test_help_states_the_exit_statuses(capsys, command, words):
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert all(w in text for w in words), text

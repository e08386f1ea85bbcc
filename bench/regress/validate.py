"""Validation of ``hftrace compare``'s time verdicts: false alarms and detection rates.

``python -m bench.regress.validate --out reports/regress`` (``make validate-compare``)
clones this checkout's HEAD into a temporary directory and commits, on top of it:

- ``aa``: a docs-only change (the same code under a second commit: A/A pairs);
- ``per_ray``: a busy loop per ray in the C batch entry, which every first-hit kernel
  runs, calibrated to cost about ``--ray-slowdown`` (5 %) of ``dda``'s time per ray;
- ``per_tile``: a busy loop in ``dda_compact``'s floor-tile step (its own code: the cell
  walk inside a tile is shared with the max-mipmap kernels), calibrated to about
  ``--tile-slowdown`` (3 %) of that kernel's time;
- a range of docs-only commits with the per-ray loop at a known place, for ``bisect``.

It then runs ``--runs`` (20) compares of each pair, each one ``hftrace compare`` process
as a user runs it (builds cached), and writes ``validation.json`` and ``validation.md``
under ``--out``: per run the verdicts, the ratios and the detectable change, the false
alarms of the A/A pairs, the detection rates, the wall time per compare, the bisect's
answer, and the command. The numbers mean something only on a quiet machine: run it with
nothing else running.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from . import revisions

HIT_C = os.path.join("cext", "dispatch", "intersect.c")
COMPACT_C = os.path.join("cext", "hierarchies", "compact.c")
BATCH_END = "        ray_end(b, ray, &h);\n    }\n    return HF_OK;\n"
TILE_STEP = ("            const int status = hf_floor_walk(h, &ray, ilo, jlo, iw, jw, leaf, 1, &i, "
             "&j, t, &t_in);\n")


def _spin(iterations: int, indent: str) -> str:
    return (f"{indent}{{ /* injected slowdown */\n{indent}    volatile int spin;\n"
            f"{indent}    for (spin = 0; spin < {iterations}; ++spin) {{}}\n{indent}}}\n")


def _git(repo, *args) -> str:
    return subprocess.run(["git", "-C", repo, *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def _inject(repo, rel, anchor, text, before=True):
    path = os.path.join(repo, rel)
    with open(path) as f:
        source = f.read()
    if source.count(anchor) != 1:
        raise RuntimeError(f"validate: the injection anchor is not unique in {rel}")
    with open(path, "w") as f:
        f.write(source.replace(anchor, text + anchor if before else anchor + text))


def _commit(repo, message) -> str:
    _git(repo, "commit", "-q", "-am", message)
    return _git(repo, "rev-parse", "HEAD")


def _docs_commit(repo, k) -> str:
    with open(os.path.join(repo, "docs", "CONVENTIONS.md"), "a") as f:
        f.write("\n")
    return _commit(repo, f"docs only ({k})")


def _branch(repo, name, start):
    _git(repo, "checkout", "-q", "-B", name, start)


def compare_once(repo, base, head, extra=()) -> tuple[dict, float, int]:
    """One ``hftrace compare`` process: (its JSON report, wall seconds, exit status)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "r.json")
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "bench.cli", "compare", base, head, "--repo", repo,
                               "--metric", "time", "--json", out, *extra],
                              capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode not in (0, 1):
            raise RuntimeError(f"validate: compare failed: {proc.stderr.strip()[-300:]}")
        with open(out) as f:
            return json.load(f), wall, proc.returncode


def _calibrate(repo, start, rel, anchor, indent, kernel, target, before, pilot=2000) -> int:
    """Iterations of the busy loop that slow ``kernel`` by ``target``: one pilot compare
    with ``pilot`` iterations, scaled."""
    _branch(repo, "pilot", start)
    _inject(repo, rel, anchor, _spin(pilot, indent), before)
    sha = _commit(repo, "pilot")
    report, _, _ = compare_once(repo, start, sha, ["--kernels", kernel])
    t = report["results"][0]["time"]
    per_iteration = (t["head_ns_per_ray"] - t["base_ns_per_ray"]) / pilot
    if per_iteration <= 0:
        raise RuntimeError("validate: the pilot loop cost nothing measurable; is the machine busy?")
    return max(1, round(target * t["base_ns_per_ray"] / per_iteration))


def _summarise(reports, expect_slower: str | None) -> dict:
    """False alarms (A/A) or detections (injected) over the runs."""
    rows = []
    for report, wall, status in reports:
        rows.append(dict(status=status, wall_s=round(wall, 1),
                         verdicts={r["kernel"]: r["verdict"] for r in report["results"]},
                         ratios={r["kernel"]: round(r["time"]["ratio"], 4) for r in report["results"]},
                         detectable={r["kernel"]: round(r["time"]["detectable"], 4)
                                     for r in report["results"]}))
    out = dict(runs=rows, wall_s_per_compare=[r["wall_s"] for r in rows])
    if expect_slower is None:
        out["false_alarms"] = sum(r["status"] == 1 for r in rows)
        out["kernels_flagged"] = sum(v == "slower" for r in rows for v in r["verdicts"].values())
    elif expect_slower == "all":
        out["caught"] = sum(r["status"] == 1 for r in rows)
        out["caught_per_kernel"] = {k: sum(r["verdicts"][k] == "slower" for r in rows) for k in rows[0]["verdicts"]}
    else:
        out["caught"] = sum(r["verdicts"].get(expect_slower) == "slower" for r in rows)
        out["other_kernels_flagged"] = sum(v == "slower" for r in rows for k, v in r["verdicts"].items()
                                           if k != expect_slower)
    return out


def main(argv=None) -> int:
    """Run the validation compares (A/A, injected slowdowns, a bisect); write reports/regress/."""
    parser = argparse.ArgumentParser(prog="python -m bench.regress.validate", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=os.path.join("results", "regress"))
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--ray-slowdown", type=float, default=0.05)
    parser.add_argument("--tile-slowdown", type=float, default=0.03)
    parser.add_argument("--bisect-commits", type=int, default=8)
    args = parser.parse_args(argv)
    root = revisions.repo_root(os.path.dirname(os.path.abspath(__file__)))
    os.makedirs(args.out, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        os.environ.setdefault("HFTRACE_BUILD_CACHE", os.path.join(tmp, "cache"))
        repo = os.path.join(tmp, "repo")
        subprocess.run(["git", "clone", "-q", root, repo], check=True)
        _git(repo, "config", "user.email", "validate@example.invalid")
        _git(repo, "config", "user.name", "validate")
        start = _git(repo, "rev-parse", "HEAD")
        ray_iters = _calibrate(repo, start, HIT_C, BATCH_END, "        ", "dda", args.ray_slowdown, True)
        tile_iters = _calibrate(repo, start, COMPACT_C, TILE_STEP, "            ", "dda_compact",
                                args.tile_slowdown, True)
        _branch(repo, "aa", start)
        aa = _docs_commit(repo, "A/A")
        _branch(repo, "per_ray", start)
        _inject(repo, HIT_C, BATCH_END, _spin(ray_iters, "        "))
        per_ray = _commit(repo, f"injected: {ray_iters} busy iterations per ray")
        _branch(repo, "per_tile", start)
        _inject(repo, COMPACT_C, TILE_STEP, _spin(tile_iters, "            "))
        per_tile = _commit(repo, f"injected: {tile_iters} busy iterations per dda_compact floor tile")
        results = dict(command="python -m bench.regress.validate " + " ".join(argv or sys.argv[1:]),
                       commit=start, toolchain=revisions.toolchain(), load_before=os.getloadavg(),
                       ray_iterations=ray_iters, tile_iterations=tile_iters)
        results["aa"] = _summarise([compare_once(repo, start, aa) for _ in range(args.runs)], None)
        results["per_ray"] = _summarise([compare_once(repo, start, per_ray) for _ in range(args.runs)], "all")
        results["per_tile"] = _summarise([compare_once(repo, start, per_tile, ["--kernels", "dda_compact"])
                                          for _ in range(args.runs)], "dda_compact")
        # bisect: docs-only commits with the per-ray loop at a known place
        _branch(repo, "range", start)
        where = args.bisect_commits // 2 + 1
        chain = []
        for k in range(1, args.bisect_commits + 1):
            if k == where:
                _inject(repo, HIT_C, BATCH_END, _spin(ray_iters, "        "))
                chain.append(_commit(repo, "injected: the per-ray loop"))
            else:
                chain.append(_docs_commit(repo, k))
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "bench.cli", "bisect", start, chain[-1], "--repo", repo,
                               "--metric", "time", "--kernels", "dda"], capture_output=True, text=True)
        first = proc.stdout.splitlines()[0] if proc.stdout else proc.stderr.strip()
        results["bisect"] = dict(commits=len(chain), injected_at=chain[where - 1], answer=first,
                                 correct=first == f"first bad commit: {chain[where - 1]}",
                                 wall_s=round(time.perf_counter() - t0, 1), output=proc.stdout)
        results["load_after"] = os.getloadavg()
    from ..timing import write_json

    write_json(os.path.join(args.out, "validation.json"), results)
    with open(os.path.join(args.out, "validation.md"), "w") as f:
        f.write(_markdown(results))
    print(_markdown(results))
    return 0


def _markdown(r) -> str:
    walls = r["aa"]["wall_s_per_compare"] + r["per_ray"]["wall_s_per_compare"]
    n = len(r["aa"]["runs"])
    return "\n".join([
        "# hftrace compare: validation", "",
        f"Command: `{r['command']}` at commit {r['commit'][:10]}; {r['toolchain']['compiler']}; "
        f"load average before {r['load_before'][0]:.2f}, after {r['load_after'][0]:.2f}.", "",
        f"- A/A (same code, two commits): {r['aa']['false_alarms']} false alarms in {n} compares "
        f"({r['aa']['kernels_flagged']} kernel verdicts `slower`).",
        f"- Busy loop per ray ({r['ray_iterations']} iterations, about 5 % of `dda`): caught in "
        f"{r['per_ray']['caught']} of {n}; per kernel {r['per_ray']['caught_per_kernel']}.",
        f"- Busy loop per `dda_compact` floor tile ({r['tile_iterations']} iterations, about 3 %): caught in "
        f"{r['per_tile']['caught']} of {n} ({r['per_tile']['other_kernels_flagged']} other verdicts `slower`).",
        f"- Bisect over {r['bisect']['commits']} commits: `{r['bisect']['answer']}` "
        f"({'correct' if r['bisect']['correct'] else 'WRONG'}; {r['bisect']['wall_s']} s).",
        f"- Wall time per compare (default kernels, cached builds): median "
        f"{sorted(walls)[len(walls) // 2]:.0f} s, max {max(walls):.0f} s.", ""])


if __name__ == "__main__":
    sys.exit(main())

"""Counts of ``hftrace targets`` (:mod:`bench.studies.targets`): instructions and
last-level data misses per ray of each contender of a ray row, from callgrind's cache
simulation.

Each contender (the best exact kernel, embreex, the C peer's fastest configuration) runs
in a process of its own (``python -m bench.studies.targets_measure --count-child``)
under ``valgrind --tool=callgrind --cache-sim=yes`` with the fixed cache model of
``bench.studies.compact.CACHE``, on :func:`~bench.studies.targets_measure.counted_rays`:
one flush, then two calls, the first counted as ``flushed`` and the second as ``warm``.
The field and the rays are built natively once per row and loaded by each counted
process (:func:`~bench.studies.targets_measure.save_case`): generating a field under
valgrind would cost minutes.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time

from .targets_measure import _child_env, counted_rays, save_case

__all__ = ["COLLECT", "count_contender", "countable", "row_counts"]

#: What callgrind collects (one ``--toggle-collect`` pattern per process: callgrind keeps
#: only one) and where it dumps (at the entry of each call, so each call's counts are a
#: part of their own; a dump pattern needs its leading ``*``): our C batch entries,
#: ``hf_intersect_batch`` and ``hf_pitched_batch`` (``hf_*t*_batch`` leaves out
#: ``hf_plane_batch``, which the first calls: a nested toggle would switch collection off
#: inside it); Embree's ``rtcIntersect1/4/8/16`` for both peers, split at embreex's
#: ``run`` and at the C peer's ctypes call (``ffi_call``). Embree is thus counted inside
#: its own queries, without the peers' loops around them.
COLLECT = {"ours": ("hf_*t*_batch", "*hf_*t*_batch"),
           "embreex": ("rtcIntersect*", "*EmbreeScene_2run*"),
           "embree3": ("rtcIntersect*", "*ffi_call")}


def _parts(directory, out):
    """The callgrind parts of one run, in order: ``out.1``, ``out.2``, ..., then ``out``."""
    numbered = sorted((f for f in os.listdir(directory)
                       if re.fullmatch(re.escape(os.path.basename(out)) + r"\.\d+", f)),
                      key=lambda f: int(f.rsplit(".", 1)[1]))
    return [os.path.join(directory, f) for f in numbered] + [out]


def count_contender(kind, side, cfg, seed, contender, peer=None, case=None) -> dict:
    """Per-ray instructions and last-level data misses of ``contender`` (a registry
    name, or an ``embree_configs`` label of ``peer``) on the row's ``counted_rays``,
    under callgrind's cache simulation: ``{"flushed": {...}, "warm": {...}, "rays": n}``.
    ``case``: a directory :func:`~bench.studies.targets_measure.save_case` wrote for
    this row (default: written here)."""
    from ..profile import _parse
    from .compact import CACHE

    rays = len(counted_rays(kind, cfg))
    toggle, dump = COLLECT[peer or "ours"]
    cache = [f"--{name}={','.join(str(v) for v in CACHE[name])}" for name in ("I1", "D1", "LL")]
    with tempfile.TemporaryDirectory() as tmp:
        if case is None:
            case = tmp
            save_case(kind, side, cfg, seed, case)
        spec = dict(case=case, contender=contender)
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", "--cache-sim=yes", *cache,
               f"--callgrind-out-file={out}", f"--toggle-collect={toggle}",
               f"--dump-before={dump}",
               sys.executable, "-m", "bench.studies.targets_measure", "--count-child", json.dumps(spec)]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=_child_env())
        if proc.returncode != 0:
            raise RuntimeError(f"valgrind failed ({proc.returncode}): {proc.stderr[-1500:]}")
        parts = [_parse(p)["totals"] for p in _parts(tmp, out)]
    # the two counted calls are the last parts with instructions (a later dump, at the
    # C peer's ctypes call that frees its scene, holds none)
    parts = [t for t in parts if t.get("Ir", 0) > 0]
    if len(parts) < 2:
        raise RuntimeError(f"callgrind collected {len(parts)} calls of {contender}, expected 2 "
                           f"(--toggle-collect={toggle})")
    result = {"rays": rays}
    for regime, t in (("flushed", parts[-2]), ("warm", parts[-1])):
        result[regime] = dict(instructions=t.get("Ir", 0) / rays,
                              ll_misses=(t.get("DLmr", 0) + t.get("DLmw", 0)) / rays)
    return result


def countable(label, side, cfg):
    """The configuration counted for ``label`` under valgrind, and a note: valgrind runs
    no packet wider than 8 (AVX-512), and a triangle BVH is built under it only up to
    ``count_mesh_max_side``. None when nothing comparable can run."""
    note = ""
    match = re.fullmatch(r"(embree3 (grid|triangles) x)(\d+)(.*)", label)
    if match and int(match.group(3)) > 8:
        label = f"{match.group(1)}8{match.group(4)}"
        note = "counted at packet width 8 (valgrind does not emulate AVX-512)"
    if "triangles" in label and side > cfg["count_mesh_max_side"]:
        if label.startswith("embree3"):
            grid = label.replace("triangles", "grid")
            return grid, (f"counted on Embree's grid geometry: a {side}^2 triangle BVH is "
                          f"not built under valgrind in this tier")
        return None, (f"not counted: a {side}^2 triangle BVH is not built under valgrind "
                      f"in this tier")
    return label, note


def row_counts(kind, side, cfg, seed, measured, echo=print) -> dict:
    """Counts of the warm regime's best exact kernel and of each peer's fastest
    configuration: ``{"ours": {...}, "embreex": {...}, "embree3": {...}}``, each with
    ``contender`` and ``note``; an entry is ``{"note": why}`` when it was not counted."""
    from ..profile import callgrind_available

    if not callgrind_available():
        return {"note": "valgrind is not installed: no counts"}
    warm = measured["regimes"]["warm"]
    out = {}
    todo = []
    if warm["best"]:
        todo.append(("ours", warm["best"], None, ""))
    for peer, entry in warm["peers"].items():
        label, note = countable(entry["config"], side, cfg)
        if label is None:
            out[peer] = {"note": note}
        else:
            todo.append((peer, label, peer, note))
    with tempfile.TemporaryDirectory() as case:
        save_case(kind, side, cfg, seed, case)  # once for every contender of the row
        for key, contender, peer, note in todo:
            start = time.perf_counter()
            try:
                out[key] = dict(count_contender(kind, side, cfg, seed, contender, peer, case),
                                contender=contender, note=note)
            except (RuntimeError, OSError) as exc:
                out[key] = {"note": f"not counted: {exc}"[:300]}
            echo(f"    counts {contender}: {time.perf_counter() - start:.0f} s")
    return out

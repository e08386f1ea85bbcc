"""Sweeps: the measurement engine behind ``hftrace sweep`` and ``hftrace reproduce``.

A sweep is a grid of *groups*. A group is one (dataset, workload, surface, run length)
and holds one row per algorithm; its algorithms are timed together on the same rays,
interleaved (``bench.timing.interleaved``), so each row's speedup is a ratio measured
side by side. Rows are appended to ``results.csv`` and flushed as each group finishes,
so a killed sweep loses at most the group it was measuring; ``resume=True`` skips every
row already in the file (the missing ones of a partly written group are measured again,
with their baseline, and only they are appended).

The config (TOML or dict) is read and checked by ``bench.sweep_config``.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import time

import numpy as np

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from datasets_gen.rays import coherent_rays, traversal_rays

from . import load as machine_load
from .report import RowWriter, results_row_check, scan_csv
from .sweep_config import WORKLOADS, ConfigError, SweepConfig, load_config
from .sweep_resume import (  # noqa: F401  (merge_sessions: bench.sweep's API)
    SESSION_TOTALS,
    check_recorded_datasets,
    check_recorded_plugins,
    earlier_sessions,
    merge_sessions,
    plugin_fingerprints,
)
from .timing import (
    WARM_TIMED_CALLS,
    call_rays,
    environment,
    log_ratio_interval,
    median_interval,
    median_ratio_interval,
    noise_floor,
    paired_rounds,
    relative_half_width,
    timed_in_regime,
    write_json,
)

__all__ = ["SweepConfig", "ConfigError", "load_config", "run_sweep", "COLUMNS",
           "RUN_COLUMNS", "config_hash", "new_run", "scan_results", "row_key", "WORKLOADS",
           "measure_group"]

BASELINE = "dda"
COLUMNS = ["algorithm", "baseline", "workload", "surface", "dataset", "grid", "run_length",
           "rays", "cells_per_ray", "runs_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
           "ns_per_ray_ci_high", "speedup", "speedup_ci_low", "speedup_ci_high",
           "ns_per_cell", "ns_per_run", "agree", "repeats", "seed", "contended",
           "other_cpu", "load_before", "load_after", "timed_s", "wall_s", "commit", "error",
           "regime", "coherence", "run_id", "machine", "config_hash", "started",
           "call_rays", "rounds", "precision", "half_width", "stop", "flush_s"]
#: The columns that say which run measured a row: ``run_id`` (12 hex digits of the
#: SHA-256 of the other three, the commit and the process id), the ``machine`` (host name), the
#: ``config_hash`` (of the sweep's config, :func:`config_hash`) and the UTC time the run
#: ``started``. A resumed run keeps its identifier; the readers (``bench.analysis.load``)
#: keep runs apart.
RUN_COLUMNS = ("run_id", "machine", "config_hash", "started")
#: Columns a whole sweep row never leaves empty (``bench.report.scan_csv``)
REQUIRED = ("algorithm", "workload", "dataset", "run_length", "rays", "repeats", "seed")
# ---- the groups ----------------------------------------------------------------------
def dataset_label(ds, datasets=()) -> str:
    """The dataset column of a config entry: name, size and sorted parameters, e.g.
    ``fbm1024-octaves6``; with the seed too, ``fbm1024-seed2``, when another entry of
    ``datasets`` (the config's) differs from it by the seed alone, so that each field's
    rows stay its own (they were one label, merged in the tables and taken for each
    other's on ``--resume``)."""
    def base(entry):
        size = entry.get("size")
        extra = "".join(f"-{k}{v}" for k, v in sorted(entry.get("params", {}).items()))
        return f"{entry['name']}{size if size else ''}{extra}"

    label = base(ds)
    seed = ds.get("seed", 0)
    if any(base(other) == label and other.get("seed", 0) != seed for other in datasets):
        label += f"-seed{seed}"
    return label


def row_key(row) -> tuple:
    """What identifies a row: its group and algorithm."""
    return (str(row["dataset"]), str(row["workload"]), str(row["surface"]),
            str(row["run_length"]), str(row["algorithm"]))


def _algorithms(cfg, workload):
    names = algos.TRAVERSALS if workload != "first_hit" else algos.INTERSECTORS
    chosen = [n for n in (cfg.algorithms or names) if n in names]
    if workload == "runs":  # plugins fold cells (visit); the runs workload folds runs
        chosen = [n for n in chosen if algos.TRAVERSAL_REGISTRY[n].plugin is None]
    if BASELINE not in chosen:
        chosen.insert(0, BASELINE)
    return chosen


def groups(cfg):
    """Every group of the sweep, in order: (dataset dict, workload, surface, r, names)."""
    out = []
    for ds in cfg.datasets:
        for workload in cfg.workloads:
            surfaces = cfg.surfaces if workload == "first_hit" else ["-"]
            for surface in surfaces:
                for r in cfg.run_lengths:
                    names = [n for n in _algorithms(cfg, workload)
                             if workload != "first_hit" or
                             surface in algos.INTERSECTOR_REGISTRY[n].surfaces]
                    out.append((ds, workload, surface, r, names))
    return out


def hit_agreement(t, reference, tolerance) -> float:
    """Fraction of rays with the reference's hit/miss and, where both hit,
    |t - t_ref| <= tolerance (1 + |t_ref|)."""
    hit, ref_hit = np.isfinite(t), np.isfinite(reference)
    both = hit & ref_hit
    close = np.ones(len(t), bool)
    close[both] = np.abs(t[both] - reference[both]) <= tolerance * (1 + np.abs(reference[both]))
    return float(np.mean((hit == ref_hit) & close))


def _prepare(name, workload, field, o, d, shape, surface, mode):
    """(run, output) of one kernel, built in or plugin (``algos.plugins``)."""
    from algos import plugins

    if plugins.is_plugin(name, workload):
        if workload == "first_hit":
            return plugins.prepare_timed_first_hit(name, field.heights, o, d, surface)
        return plugins.prepare_timed_traversal(name, o, d, shape)
    if workload == "first_hit":
        return prepare_timed_intersect(name, field, o, d, surface=surface)
    run, sums = algos.prepare_timed(name, o, d, shape, mode)
    return run, (lambda s=sums: s.copy())


def _time_limits(names, workload):
    """name -> ns a single call of a plugin may take."""
    from algos import plugins

    table = algos.INTERSECTOR_REGISTRY if workload == "first_hit" else algos.TRAVERSAL_REGISTRY
    return {n: int(table[n].plugin.time_limit * 1e9) for n in names
            if plugins.is_plugin(n, workload)}


#: The current field's rays by (kind, r, n, seed) and references by (workload, surface,
#: r, n, seed): groups of other surfaces or workloads reuse them instead of drawing again.
_RAYS: dict = {"field": None, "rays": {}, "refs": {}}


def _group_rays(field, workload, surface, r, rays, seed, coherence="random"):
    """(origins, directions, cells per ray, runs per ray, reference output) of a group,
    the rays drawn once per field, run length, kind (2D or first hit) and coherence and
    reused."""
    if _RAYS["field"] is not field:
        _RAYS.update(field=field, rays={}, refs={})
    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    kind = "3d" if workload == "first_hit" else "2d"
    if kind == "2d" and coherence != "random":
        raise ValueError(f"coherence: the {workload} workload takes random rays only, got {coherence!r}")
    key = (kind, str(r), rays, seed) + (() if coherence == "random" else (coherence,))
    if key not in _RAYS["rays"]:
        _RAYS["rays"][key] = (coherent_rays(field, coherence, r, rays, seed) if kind == "3d"
                              else traversal_rays(shape, r, rays, seed))
    o, d = _RAYS["rays"][key]
    ref_key = (workload, surface) + key
    if ref_key not in _RAYS["refs"]:
        if workload == "first_hit":
            ref = algos.intersect("runs", field, o, d, surface=surface, outputs=("t", "stats"))
            value = (float(ref.stats["cells_visited"].mean()),
                     float(ref.stats["runs_visited"].mean()), ref.t)
        else:
            counts = algos.traverse("midpoint", o, d, shape, output="count")
            mode = "visit" if workload == "visit" else "runs"
            ref_run, ref_sums = algos.prepare_timed("midpoint", o, d, shape, mode)
            ref_run()
            value = (float(counts.cells.mean()), float(counts.runs.mean()), ref_sums)
        _RAYS["refs"][ref_key] = value
    return (o, d) + _RAYS["refs"][ref_key]


#: The ``regime`` recorded in the rows of a paired design, by its ``flush``
#: (``bench.timing.FLUSH_MODES``).
PAIRED_REGIMES = {"warm": "warm", "call": "flushed-per-call", "round": "flushed-per-round",
                  "none": "unflushed"}


#: What one cell test of the baseline costs in cell steps of its walk (``dda`` on
#: triangles, this VM: about 2.7 ns per cell visited and 36 ns per cell tested, fitted on
#: fBm, terraces, uniform noise and Jacksboro): the weight of ``cells_tested`` in
#: :func:`work_per_ray`.
TEST_WEIGHT = 13


def work_per_ray(field, workload, surface, r, rays, seed, coherence="random") -> float:
    """The baseline's exact work per ray on a group's ``rays`` rays, in cell steps: cells
    visited plus :data:`TEST_WEIGHT` times cells tested (``algos.STATS`` of ``dda``; the
    2D workloads: the cells per ray). A count, not a time, so every run sizes a group's
    calls alike."""
    o, d, cells, *_ = _group_rays(field, workload, surface, r, rays, seed, coherence)
    if workload != "first_hit":
        return float(cells)
    got = algos.intersect(BASELINE, field, o, d, surface=surface, outputs=("stats",))
    return float(np.mean(got.stats["cells_visited"]) +
                 TEST_WEIGHT * np.mean(got.stats["cells_tested"]))


def rays_for_cells(cells_per_ray: float, rays: int, call_cells: int, max_factor: int = 16) -> int:
    """The rays of a call doing about ``call_cells`` cell steps: ``rays`` times the power
    of two (from 1/``max_factor`` to ``max_factor``) nearest, in the log, to
    ``call_cells / (rays * cells_per_ray)``; at least 16 rays. ``cells_per_ray``: the work
    per ray (:func:`work_per_ray`)."""
    if not cells_per_ray > 0:
        return rays
    k = round(math.log2(call_cells / (rays * cells_per_ray)))
    k = max(-int(math.log2(max_factor)), min(int(math.log2(max_factor)), k))
    return max(16, int(round(rays * 2.0 ** k)))


def measure_group(field, label, workload, surface, r, names, rays, repeats, seed,
                  keep_samples=False, regime="flushed", coherence="random", precision=None,
                  budget_s=3.0, call_ms=8.0, flush="round", rays_per_call=None,
                  call_cells=None):
    """Rows for one group: every algorithm on the same rays, interleaved. With
    ``keep_samples`` each row also holds ``ratio_samples``, the per-round paired ratios
    time(baseline) / time(algorithm). ``regime`` is the cache regime
    (``bench.timing.REGIMES``) and ``coherence`` the ray batch (``datasets_gen.rays.COHERENCE``; first
    hits only); both are recorded in every row.

    Two designs (docs/METHOD.md, "Paired rounds"):

    * ``precision`` None: ``repeats`` interleaved rounds of ``rays`` rays in ``regime``
      (``bench.timing.timed_in_regime``).
    * ``precision`` a fraction (0.02 is ±2 %): adjacent pairs with the baseline
      (``bench.timing.paired_rounds``: cycles ``B k1 B k2 ... B``). The rays of a timed
      call are ``rays`` doubled until the baseline's call lasts ``call_ms``
      (``bench.timing.call_rays``, recorded in ``call_rays``); the cache state of a
      visit is ``flush`` (``bench.timing.FLUSH_MODES``; ``"warm"``: an untimed call of
      the same kernel first); a kernel's pairs stop when its ratio's 95 % interval is
      within ``precision`` on either side, after at least ``repeats`` pairs, or when the
      group has spent ``budget_s`` seconds (``stop``: precision, budget or rounds;
      ``rounds``: the pairs). ``rays_per_call`` fixes the rays of a call instead (a sweep
      sizes it once, in its noise calibration, so every group of a run times calls of the
      same rays). ``call_cells`` replaces both: the rays of a call are ``rays`` times the
      power of two that brings the baseline's exact work per call nearest to it
      (:func:`work_per_ray`, :func:`rays_for_cells`), a count, so the choice is the same in
      every run, and every group's call stays short (0.2-0.4 ms here).
      ``regime`` is then recorded per :data:`PAIRED_REGIMES`. ``speedup`` is
      the median pair's ratio with its distribution-free interval
      (``bench.timing.median_ratio_interval``).

    With fixed repeats, ``speedup`` and its interval are the geometric mean of the paired
    per-round ratios and Student's t interval of their logs
    (``bench.timing.log_ratio_interval``). In both, ``half_width`` is the interval's
    half-width as a fraction of the speedup, and ``ns_per_ray`` the median per-ray time
    of a timed call with its order-statistic interval (``bench.timing.median_interval``).

    Each row also records the machine's load while the group ran (``bench.load``:
    ``contended``, ``other_cpu``, ``load_before``, ``load_after``), the group's time
    inside timed calls (``timed_s``), flushing (``flush_s``) and its wall time
    (``wall_s``). A kernel that fails (raises, returns an error status, exceeds its time
    limit) gets a row with ``error`` set and no timings; the other rows are kept. A plugin
    that claims to be exact and disagrees with the reference gets an error too. Only a
    failing baseline fails the group (``RuntimeError``)."""
    from algos import plugins

    before = machine_load.snapshot()
    wall0 = time.perf_counter()
    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    mode = "visit" if workload == "visit" else "runs"
    n_rays = rays if rays_per_call is None else int(rays_per_call)
    if precision is not None and call_cells:
        # sized by the baseline's exact work per ray on the configured rays
        n_rays = rays_for_cells(work_per_ray(field, workload, surface, r, rays, seed, coherence),
                                rays, call_cells)
    elif precision is not None and BASELINE in names and rays_per_call is None:
        # the call length: the baseline timed once on the configured rays
        o, d, *_ = _group_rays(field, workload, surface, r, rays, seed, coherence)
        probe, _ = _prepare(BASELINE, workload, field, o, d, shape, surface, mode)
        probe()
        n_rays = call_rays(min(probe(), probe()), rays, call_ms)
    o, d, cells, runs, reference = _group_rays(field, workload, surface, r, n_rays, seed,
                                               coherence)
    jobs, outputs, errors = {}, {}, {}
    for name in names:
        try:
            jobs[name], outputs[name] = _prepare(name, workload, field, o, d, shape, surface, mode)
        except Exception as exc:
            if not plugins.is_plugin(name, workload):
                raise
            errors[name] = f"{type(exc).__name__}: {exc}"
    limits = _time_limits(names, workload)
    flush_s = math.nan
    log_ratios = None
    calls = WARM_TIMED_CALLS if precision is not None and flush == "warm" else 1  # per visit
    if precision is None:
        times = timed_in_regime(jobs, repeats, regime, errors=errors, time_limit_ns=limits)
        stops = {name: "rounds" for name in times}
    else:
        measured = paired_rounds(jobs, BASELINE, precision=precision, budget_s=budget_s,
                                 min_rounds=repeats, flush=flush, seed=seed, errors=errors,
                                 time_limit_ns=limits)
        times, stops, flush_s = measured.times, measured.stop, measured.flush_s
        log_ratios = measured.log_ratios
        regime = PAIRED_REGIMES[flush]
    if BASELINE not in times:
        raise RuntimeError(f"{label} {workload} r={r}: the baseline {BASELINE} failed: "
                           f"{errors.get(BASELINE)}")
    timed = sum(float(np.nansum(v)) for v in times.values()) / 1e9
    wall = time.perf_counter() - wall0  # the group's own time, before any wait for the window
    load = machine_load.contention(before, machine_load.snapshot_after(before))
    out = []
    for name in names:
        common = dict(algorithm=name, baseline=BASELINE, workload=workload, surface=surface,
                      dataset=label, grid=f"{shape[0]}x{shape[1]}", run_length=r, rays=rays,
                      cells_per_ray=round(cells, 2), runs_per_ray=round(runs, 2),
                      repeats=repeats, seed=seed, timed_s=round(timed, 4),
                      wall_s=round(wall, 4), error="", regime=regime, coherence=coherence,
                      call_rays=n_rays, precision="" if precision is None else precision,
                      flush_s=round(flush_s, 4), **load)
        error = errors.get(name)
        got = None
        if error is None:
            try:
                got = outputs[name]()
            except Exception as exc:
                error = f"{type(exc).__name__}: {exc}"
        if error is not None:
            # one line: a kernel's message may span several, which would split the row's
            # cell in the Markdown tables and the command's error lines
            error = " ".join(str(error).split())
            nan = math.nan
            out.append(dict(common, ns_per_ray=nan, ns_per_ray_ci_low=nan,
                            ns_per_ray_ci_high=nan, speedup=nan, speedup_ci_low=nan,
                            speedup_ci_high=nan, ns_per_cell=nan, ns_per_run=nan, agree=nan,
                            half_width=nan, stop="", rounds=0, error=error))
            continue
        per_ray = times[name] / (n_rays * calls)
        median, low, high = median_interval(per_ray)
        if log_ratios is not None:
            speedup, s_low, s_high = median_ratio_interval(log_ratios.get(name, ()))
        else:
            speedup, s_low, s_high = log_ratio_interval(times[BASELINE], times[name])
        if name == BASELINE:
            speedup = s_low = s_high = 1.0
        if workload == "first_hit":
            agree = hit_agreement(got, reference, 1e-4 if _is_peer(name) else 1e-9)
        else:
            agree = float(np.mean(got == reference))
        if plugins.is_plugin(name, workload) and _claims_exact(name, workload) and agree < 1.0:
            common["error"] = (f"claims to be exact but agrees with the exact reference on "
                               f"{100 * agree:.2f} % of rays")
        out.append(dict(
            common, ns_per_ray=round(median, 2), ns_per_ray_ci_low=round(low, 2),
            ns_per_ray_ci_high=round(high, 2), speedup=round(speedup, 4),
            speedup_ci_low=round(s_low, 4), speedup_ci_high=round(s_high, 4),
            ns_per_cell=round(median / cells, 4) if cells else math.nan,
            ns_per_run=round(median / runs, 4) if runs else math.nan,
            agree=round(agree, 6),
            rounds=measured.rounds[name] if log_ratios is not None
            else int(np.isfinite(times[name]).sum()),
            half_width=round(relative_half_width(speedup, s_low, s_high), 5)
            if name != BASELINE else 0.0,
            stop=stops.get(name, "")))
        if keep_samples:
            if log_ratios is not None:
                ratios = np.exp(log_ratios.get(name, np.ones(0)))
            else:
                ratios = times[BASELINE] / times[name]
            out[-1]["ratio_samples"] = ratios[np.isfinite(ratios)].tolist()
    return out


def _is_peer(name):
    """True for Embree's peers (float32, compared at 1e-4 relative)."""
    entry = algos.INTERSECTOR_REGISTRY.get(name)
    return entry is not None and entry.kind == "peer"


def _claims_exact(name, workload):
    table = algos.INTERSECTOR_REGISTRY if workload == "first_hit" else algos.TRAVERSAL_REGISTRY
    return bool(table[name].plugin.exact)


def read_rows(path, bad=None) -> list[dict]:
    """The whole rows of a CSV as dicts of strings; [] when ``path`` does not exist.
    Lines a kill cut short or that are malformed are left out; pass a list as ``bad``
    to receive them as (line number, reason) (``bench.report.scan_csv``)."""
    _, rows, damaged = scan_csv(path)
    if bad is not None:
        bad.extend(damaged)
    return rows


def scan_results(path):
    """(whole rows, damaged lines as (line number, reason)) of a sweep's results.csv."""
    _, rows, bad = scan_csv(path, REQUIRED, results_row_check())
    return rows, bad


def config_hash(cfg) -> str:
    """12 hex digits of the SHA-256 of the config's every key (canonical JSON); ``cfg`` a
    :class:`SweepConfig` or a study's dict of settings."""
    settings = dataclasses.asdict(cfg) if dataclasses.is_dataclass(cfg) else dict(cfg)
    text = json.dumps(settings, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def new_run(cfg, commit) -> dict:
    """The :data:`RUN_COLUMNS` of a run starting now on this machine."""
    import datetime
    import socket

    machine = socket.gethostname() or "unknown"
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    digest = config_hash(cfg)
    # the process id tells apart two runs started in the same microsecond
    key = f"{commit}|{machine}|{digest}|{started}|{os.getpid()}"
    run_id = hashlib.sha256(key.encode()).hexdigest()[:12]
    return {"run_id": run_id, "machine": machine, "config_hash": digest, "started": started}


def load_field(ds) -> algos.Field:
    """The Field of one config dataset entry."""
    return algos.Field(datasets_gen.load(ds["name"], size=ds.get("size"), seed=ds.get("seed", 0),
                                         **ds.get("params", {})).heights)


def _pending(cfg, out_dir, resume, commit=None, run=None, bad=None, check_machine=True):
    """(results.csv path, the groups still to measure with their missing algorithms).

    Without ``resume`` a results.csv that holds rows is never replaced: ``ValueError``
    says to resume or to choose another ``--out``. With ``resume`` the kept rows must have
    been measured with this config's rays, repeats and seed and, when ``commit`` is given
    and the rows record one, the same code commit, by one run on this machine; otherwise
    ``ValueError`` names the mismatch (nothing is measured or removed). A line a kill cut
    short, or a malformed one, is no kept row: its group is measured again (the writer
    sets the line aside), and it is added to ``bad`` as (line number, reason). ``run``
    (:func:`new_run`) takes the kept rows' run identifier, so the resumed run stays one.
    ``check_machine=False`` (Dask: each row names the worker that measured it) skips the
    machine check."""
    os.makedirs(out_dir, exist_ok=True)
    csv_path = os.path.join(out_dir, "results.csv")
    kept, damaged = scan_results(csv_path)
    if bad is not None:
        bad.extend(damaged)
    if (kept or damaged) and not resume:
        cut = (f" and {len(damaged)} damaged line(s) (line {damaged[0][0]}: {damaged[0][1]})"
               if damaged else "")
        raise ValueError(f"--out: {csv_path} already holds {len(kept)} rows{cut}; rerun with "
                         "--resume to continue that run (damaged rows are measured again), "
                         "or choose another --out (results are never replaced)")
    if kept and run is not None:
        runs = list(dict.fromkeys(r.get("run_id", "") for r in kept))
        if len(runs) > 1:
            raise ValueError(f"--resume: {csv_path} holds {len(runs)} runs ({', '.join(runs)}); "
                             "--resume continues one run: choose another --out")
        first = kept[0]
        if check_machine and first.get("machine") and first["machine"] != run["machine"]:
            raise ValueError(f"--resume: {csv_path} was measured on {first['machine']}, this is "
                             f"{run['machine']}; choose another --out rather than mix machines")
        run.update(run_id=first.get("run_id") or run["run_id"],
                   started=first.get("started") or run["started"])
    labels = {dataset_label(ds, cfg.datasets) for ds in cfg.datasets}
    if kept:
        check_recorded_datasets(cfg, out_dir, {row.get("dataset") for row in kept}, dataset_label)
        check_recorded_plugins(cfg, out_dir, {row.get("algorithm") for row in kept})
    for k, row in enumerate(kept):
        if row.get("dataset") not in labels:
            continue
        for key in ("rays", "repeats", "seed"):
            if str(row.get(key)) != str(getattr(cfg, key)):
                raise ValueError(
                    f"--resume: row {k + 1} of {csv_path} was measured with {key} = "
                    f"{row.get(key)}, the config says {getattr(cfg, key)}; choose another "
                    "--out (or restore the config) rather than mix them")
        if cfg.precision is not None and row.get("precision") not in (None, ""):
            # the paired design's precision and cache state set what a row's interval means:
            # rows of two settings in one table would be read as one measure
            flushes = {regime: flush for flush, regime in PAIRED_REGIMES.items()}
            got = {"--precision": f"{100 * float(row['precision']):g}",
                   "--flush": flushes.get(row.get("regime"), row.get("regime"))}
            want = {"--precision": f"{100 * float(cfg.precision):g}", "--flush": cfg.flush}
            for key in got:
                if got[key] != want[key]:
                    raise ValueError(
                        f"--resume: row {k + 1} of {csv_path} was measured with {key} "
                        f"{got[key]}, this run asks {key} {want[key]}; resume with the run's "
                        "setting or choose another --out rather than mix them")
        if commit and row.get("commit") and row["commit"] != commit:
            raise ValueError(
                f"--resume: row {k + 1} of {csv_path} was measured at commit "
                f"{row['commit']}, the code is at {commit}; choose another --out to "
                "measure this code")
    done = {row_key(r) for r in kept}
    todo = []
    for ds, workload, surface, r, names in groups(cfg):
        label = dataset_label(ds, cfg.datasets)
        missing = [n for n in names if (label, workload, surface, str(r), n) not in done]
        if missing:
            todo.append((ds, label, workload, surface, r, names, missing))
    return csv_path, todo


def _report_damaged(csv_path, bad, echo):
    """Say which lines of results.csv were cut short or malformed: they are set aside in
    results.csv.rejected and their groups measured again."""
    if echo:
        for number, reason in bad:
            echo(f"warning: line {number} of {csv_path}: {reason}; set aside in "
                 f"{os.path.basename(csv_path)}.rejected and measured again")


def _bar(progress, total, desc):
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="group", desc=desc, dynamic_ncols=True)


def _write_group(writer, rows, missing, bar, label, commit="", run=None):
    """Append a finished group's rows (only the missing algorithms'), each with the
    commit and the run's identifier (:data:`RUN_COLUMNS`), then tick the bar."""
    for row in rows:
        if row["algorithm"] in missing:
            writer.write(dict(row, commit=commit, **(run or {})))
    if bar is not None:
        bar.set_postfix_str(label)
        bar.update(1)


def _measure_isolated(field, label, workload, surface, r, names, rays, repeats, seed, **design):
    """The plugin kernels of ``names`` measured with the baseline in a child process
    (fork), so a kernel that crashes its process takes only its own rows: they carry an
    error naming the signal or exit status. The child's baseline row is dropped."""
    import multiprocessing
    import signal

    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)

    def child():
        import faulthandler

        faulthandler.disable()  # the parent reports the signal in one line
        try:
            send.send(("rows", measure_group(field, label, workload, surface, r,
                                             [BASELINE] + names, rays, repeats, seed,
                                             **design)))
        except BaseException as exc:  # reported to the parent, which keeps going
            send.send(("error", f"{type(exc).__name__}: {exc}"))
        finally:
            send.close()

    table = algos.INTERSECTOR_REGISTRY if workload == "first_hit" else algos.TRAVERSAL_REGISTRY
    limit = sum(table[n].plugin.time_limit for n in names) * (repeats + 1) + 60
    proc = ctx.Process(target=child, daemon=True)
    proc.start()
    send.close()
    message = None
    if receive.poll(limit):
        try:
            message = receive.recv()
        except EOFError:
            message = None
    proc.join(5)
    if proc.is_alive():
        proc.kill()
        proc.join()
        reason = f"the child process exceeded the time limit ({limit:.0f} s) and was killed"
    elif message is None:
        code = proc.exitcode
        reason = (f"crashed its process (signal {signal.Signals(-code).name})" if code and code < 0
                  else f"its process exited with status {code}")
    elif message[0] == "error":
        reason = message[1]
    if message is not None and message[0] == "rows":
        return [row for row in message[1] if row["algorithm"] != BASELINE]
    return [dict(algorithm=n, baseline=BASELINE, workload=workload, surface=surface,
                 dataset=label, run_length=r, rays=rays, repeats=repeats, seed=seed,
                 error="isolated: " + " ".join(str(reason).split())) for n in names]


def _design(cfg) -> dict:
    """measure_group's keyword arguments for the config's measurement design."""
    if cfg.precision is None:
        return {}
    return {"precision": cfg.precision, "budget_s": cfg.group_budget, "call_ms": cfg.call_ms,
            "flush": cfg.flush, "call_cells": cfg.call_cells}


def prepare_field(ds, todo) -> algos.Field:
    """Load a dataset's field (:func:`load_field`) and build, once, the structures every
    first-hit kernel of its groups in ``todo`` keeps on it (max-mipmaps, cones, Embree's
    scene), on two rays, so that the measure phase measures and the preparation is
    accounted apart (``env.json``: ``run.prepare_s``)."""
    from algos import plugins

    field = load_field(ds)
    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    seen = set()
    for ds_, label_, workload, surface, r, names, _ in todo:
        if ds_ != ds or workload != "first_hit":
            continue
        o, d = coherent_rays(field, "random", r, 2, 0)
        for name in names:
            if (name, surface) in seen or plugins.is_plugin(name, workload):
                continue
            seen.add((name, surface))
            try:
                _prepare(name, workload, field, o, d, shape, surface, "runs")
            except Exception:  # noqa: BLE001 - measure_group reports the kernel's error
                pass
    return field


def wait_until_quiet(limit_s: float, step_s: float = 0.5) -> float:
    """Wait, up to ``limit_s`` seconds, until other processes use at most
    ``bench.load.CONTENDED_CORES`` over one ``step_s`` interval; the seconds waited, or -1
    when the machine stayed busy."""
    start = time.perf_counter()
    while time.perf_counter() - start < limit_s:
        before = machine_load.snapshot()
        time.sleep(step_s)
        other = machine_load.contention(before, machine_load.snapshot())["other_cpu"]
        if other is None or other <= machine_load.CONTENDED_CORES:
            return time.perf_counter() - start
    return -1.0


def calibrate_noise(field, workload, surface, r, cfg, kernels, seconds=1.0) -> dict:
    """The noise floor before measuring (``bench.timing.noise_floor``): the baseline
    against itself on a group's rays, at the call length the sweep will use, for about
    ``seconds``; ``floor`` is the half-width a ratio reaches in the rounds a group of
    ``kernels`` kernels affords in ``cfg.group_budget`` (``call_rays`` and ``call_s``
    recorded with it)."""
    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    mode = "visit" if workload == "visit" else "runs"
    o, d, *_ = _group_rays(field, workload, surface, r, cfg.rays, seed=cfg.seed)
    job, _ = _prepare(BASELINE, workload, field, o, d, shape, surface, mode)
    job()
    if cfg.call_cells:
        n = rays_for_cells(work_per_ray(field, workload, surface, r, cfg.rays, cfg.seed),
                           cfg.rays, cfg.call_cells)
    else:
        # the fastest of five calls: a busy moment only lengthens a call
        n = call_rays(min(job() for _ in range(5)), cfg.rays, cfg.call_ms)
    o, d, *_ = _group_rays(field, workload, surface, r, n, seed=cfg.seed)
    job, _ = _prepare(BASELINE, workload, field, o, d, shape, surface, mode)
    job()
    call_s = min(job(), job()) / 1e9
    # a cycle visits every other kernel and the baseline once per kernel; a visit is its
    # timed calls and, warm, one untimed call (flushing adds about a call's time)
    calls = WARM_TIMED_CALLS + 1 if cfg.flush == "warm" else 2
    cycle_s = 2 * max(kernels - 1, 1) * calls * call_s
    affordable = int(cfg.group_budget / max(cycle_s, 1e-6))
    out = noise_floor(job, seconds=seconds, rounds_affordable=max(affordable, 2),
                      flush=cfg.flush)
    return dict(out, call_rays=n, call_s=round(call_s, 5), kernels=kernels)


def run_sweep(cfg: SweepConfig, out_dir: str, resume=False, progress=True, echo=print,
              isolate=False):
    """Run (or resume) a sweep; returns every row of results.csv afterwards.

    Refuses to replace an existing results.csv unless ``resume`` (then the kept rows must
    match the config and the code's commit: :func:`_pending`). With ``isolate`` the
    plugin kernels of each group (``algos.plugins``) are measured each in a child
    process next to its own baseline run, so a crash is contained; without it they are
    interleaved with the built-in kernels. Each row records the machine's load
    (``bench.load``); the run's totals go into ``env.json`` under ``"run"``."""
    from algos import plugins

    env = environment()
    commit = env.get("git_commit", "")
    run = new_run(cfg, commit)
    bad = []
    csv_path, todo = _pending(cfg, out_dir, resume, commit=commit, run=run, bad=bad)
    _report_damaged(csv_path, bad, echo)
    env["run_identity"] = run  # the RUN_COLUMNS of every row this session writes
    env["datasets"] = cfg.datasets  # what each label is, for --resume to check
    env["plugins"] = plugin_fingerprints(cfg)  # which build of each plugin, likewise
    env["sweep_name"] = cfg.name  # the reports' title when `hftrace plot` rewrites them
    env["load_before"] = machine_load.load_average()
    earlier = earlier_sessions(out_dir, run) if resume else None
    write_json(os.path.join(out_dir, "env.json"), env)
    bar = _bar(progress, len(todo), cfg.name)
    fields_cache = {}
    start = time.perf_counter()
    timed = contended = 0
    failed = []
    design = _design(cfg)
    preparing = 0.0  # loading fields and building their structures: not measuring
    if cfg.precision is not None and todo:
        # the noise floor and the rays of a call, once per run: the baseline against
        # itself on the first group's rays
        ds, label, workload, surface, r, names, _ = todo[0]
        p0 = time.perf_counter()
        fields_cache[label] = prepare_field(ds, todo)
        preparing += time.perf_counter() - p0
        env["noise"] = calibrate_noise(fields_cache[label], workload, surface, r, cfg,
                                       len(names))
        env["noise"]["load"] = machine_load.load_average()
        if not cfg.call_cells:  # sized by cells, every group sizes its own calls
            design["rays_per_call"] = env["noise"]["call_rays"]
        write_json(os.path.join(out_dir, "env.json"), env)
    measure0 = time.perf_counter()
    # contended groups are measured again once the machine is quiet, within this allowance
    spare = 0.25 * len(todo) * cfg.group_budget if cfg.precision is not None else 0.0
    remeasured = finished = 0
    flushing = 0.0
    try:  # the bar closes before an interrupt's message, not redrawn after it
        with RowWriter(csv_path, COLUMNS, append=resume, required=REQUIRED,
                       check=results_row_check()) as writer:
            for ds, label, workload, surface, r, names, missing in todo:
                if label not in fields_cache:
                    fields_cache.clear()  # one field in memory at a time
                    p0 = time.perf_counter()
                    fields_cache[label] = prepare_field(ds, todo)
                    preparing += time.perf_counter() - p0
                field_ = fields_cache[label]
                own = [n for n in names if not (isolate and plugins.is_plugin(n, workload))]
                isolated = [n for n in names if n not in own and n in missing]
                measured = measure_group(field_, label, workload, surface, r, own, cfg.rays,
                                         cfg.repeats, cfg.seed, **design)
                while measured[0]["contended"] and spare > measured[0]["wall_s"]:
                    # contention is never a finding: wait for a quiet machine, then measure again
                    waited = wait_until_quiet(min(5.0, spare - measured[0]["wall_s"]))
                    spare -= measured[0]["wall_s"] + waited
                    if spare <= 0 or waited < 0:
                        break
                    timed += measured[0]["timed_s"]
                    remeasured += 1
                    measured = measure_group(field_, label, workload, surface, r, own, cfg.rays,
                                             cfg.repeats, cfg.seed, **design)
                for name in isolated:  # one child per plugin: a crash takes only its rows
                    measured += _measure_isolated(field_, label, workload, surface, r, [name],
                                                  cfg.rays, cfg.repeats, cfg.seed, **design)
                timed += measured[0]["timed_s"]
                if not math.isnan(measured[0]["flush_s"]):
                    flushing += measured[0]["flush_s"]
                contended += bool(measured[0]["contended"])
                failed += [f"{label} {workload} r={r} {row['algorithm']}: {row['error']}"
                           for row in measured if row.get("error")]
                _write_group(writer, measured, missing, bar, f"{label} {workload} {surface} r={r}",
                             commit=commit, run=run)
                finished += 1
    finally:
        if bar is not None:
            bar.close()
        # the session's totals, an interrupted one's too (its groups written so far)
        wall = time.perf_counter() - start
        measure = time.perf_counter() - measure0 - preparing
        env["run"] = {"groups": finished, "wall_s": round(wall, 2), "timed_s": round(timed, 2),
                      "timed_share": round(timed / wall, 4) if wall > 0 else None,
                      "measure_s": round(measure, 2), "flush_s": round(flushing, 2),
                      "prepare_s": round(preparing, 2),
                      "timed_share_of_measure": round(timed / measure, 4) if measure > 0 else None,
                      "contended_groups": contended, "remeasured_groups": remeasured,
                      "precision": cfg.precision, "group_budget_s": cfg.group_budget,
                      "load_after": machine_load.load_average()}
        if earlier:
            env["run"] = merge_sessions(earlier, env["run"])
        write_json(os.path.join(out_dir, "env.json"), env)
    if echo and todo:
        echo(f"{len(todo)} groups measured in {wall:.1f} s, {100 * timed / max(wall, 1e-9):.0f} % "
             f"of it inside timed calls")
        if contended:
            echo(f"warning: {contended} of {len(todo)} groups ran while other processes used "
                 "the CPUs (column contended): their cells are labelled contended, not findings")
        for line in failed:
            echo(f"error: {line}")
    return read_rows(csv_path)

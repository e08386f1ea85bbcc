"""Sweeps: the measurement engine behind ``hftrace sweep`` and ``hftrace reproduce``.

A sweep is a grid of *groups*. A group is one (dataset, workload, surface, run length)
and holds one row per algorithm; its algorithms are timed together on the same rays,
interleaved (``bench.timing.interleaved``), so each row's speedup is a ratio measured
side by side. Rows are appended to ``results.csv`` and flushed as each group finishes,
so a killed sweep loses at most the group it was measuring; ``resume=True`` skips every
row already in the file (the missing ones of a partly written group are measured again,
with their baseline, and only they are appended).

Config (TOML or dict), every key checked before any work starts:

    name = "my-sweep"                 # output directory name under reports/
    rays = 2000                       # rays per group
    repeats = 7                       # interleaved repeats (>= 3)
    seed = 2004
    algorithms = ["dda", "runs"]      # default: every algorithm of each workload
    workloads = ["visit", "runs", "first_hit"]
    surfaces = ["triangles"]          # for first_hit
    run_lengths = [1, 2, 25, "random"]
    [[datasets]]
    name = "fbm"                      # a generator or an embedded field
    size = 1024
    seed = 1
    params = { octaves = 6 }          # generator parameters
"""
from __future__ import annotations

import csv
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from datasets_gen import rays as raysets

from .report import RowWriter
from .timing import environment, interleaved, median_ci, ratio_ci, write_json

__all__ = ["SweepConfig", "ConfigError", "load_config", "run_sweep", "run_sweep_dask", "COLUMNS",
           "row_key", "WORKLOADS", "first_hit_rays", "traversal_rays", "measure_group",
           "dask_client"]

WORKLOADS = ("visit", "runs", "first_hit")
BASELINE = "dda"
COLUMNS = ["algorithm", "baseline", "workload", "surface", "dataset", "grid", "run_length",
           "rays", "cells_per_ray", "runs_per_ray", "ns_per_ray", "ns_per_ray_ci_low",
           "ns_per_ray_ci_high", "speedup", "speedup_ci_low", "speedup_ci_high",
           "ns_per_cell", "ns_per_run", "agree", "repeats", "seed"]
_KEYS = {"name", "rays", "repeats", "seed", "algorithms", "workloads", "surfaces",
         "run_lengths", "datasets"}
_DATASET_KEYS = {"name", "size", "seed", "params"}


class ConfigError(ValueError):
    """A sweep configuration that cannot run; the message names the key."""


@dataclass
class SweepConfig:
    """A sweep: the grid of groups (datasets x workloads x surfaces x run lengths) and how
    each is measured (rays, interleaved repeats, seed, algorithms). Build it with
    :func:`load_config`, which checks every key (module docstring)."""

    name: str = "sweep"
    rays: int = 2000
    repeats: int = 7
    seed: int = 2004
    algorithms: list | None = None
    workloads: list = field(default_factory=lambda: list(WORKLOADS))
    surfaces: list = field(default_factory=lambda: ["triangles"])
    run_lengths: list = field(default_factory=lambda: [1, 2, 5, 25, 100, "random"])
    datasets: list = field(default_factory=lambda: [{"name": "fbm", "size": 1024, "seed": 1}])


def _check_int(key, value, low):
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ConfigError(f"{key}: expected an integer >= {low}, got {value!r}")


def load_config(source) -> SweepConfig:
    """A validated SweepConfig from a TOML path or a dict."""
    if isinstance(source, (str, os.PathLike)):
        try:
            import tomllib
        except ModuleNotFoundError:  # Python 3.10
            import tomli as tomllib
        path = os.fspath(source)
        if not os.path.isfile(path):
            raise ConfigError(f"config: {path} does not exist")
        try:
            with open(path, "rb") as f:
                data = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"config: {path} is not valid TOML ({exc})") from None
    else:
        data = dict(source)
    unknown = set(data) - _KEYS
    if unknown:
        raise ConfigError(f"{sorted(unknown)[0]}: unknown key; valid keys are {', '.join(sorted(_KEYS))}")
    cfg = SweepConfig(**{k: v for k, v in data.items()})
    if not isinstance(cfg.name, str) or not cfg.name or "/" in cfg.name:
        raise ConfigError(f"name: expected a plain directory name, got {cfg.name!r}")
    _check_int("rays", cfg.rays, 8)
    _check_int("repeats", cfg.repeats, 3)
    _check_int("seed", cfg.seed, 0)
    for key in ("workloads", "surfaces", "run_lengths", "datasets"):
        if not isinstance(getattr(cfg, key), list) or not getattr(cfg, key):
            raise ConfigError(f"{key}: expected a non-empty list")
    for w in cfg.workloads:
        if w not in WORKLOADS:
            raise ConfigError(f"workloads: unknown workload {w!r}; valid: {', '.join(WORKLOADS)}")
    for s in cfg.surfaces:
        if s not in algos.SURFACES:
            raise ConfigError(f"surfaces: unknown surface {s!r}; valid: {', '.join(algos.SURFACES)}")
    for r in cfg.run_lengths:
        if r != "random" and (isinstance(r, bool) or not isinstance(r, (int, float)) or not r >= 1):
            raise ConfigError(f"run_lengths: {r!r} is neither a number >= 1 nor \"random\"")
    if cfg.algorithms is not None:
        if not isinstance(cfg.algorithms, list) or not cfg.algorithms:
            raise ConfigError("algorithms: expected a non-empty list of names")
        valid = set(algos.TRAVERSALS) | set(algos.INTERSECTORS)
        for a in cfg.algorithms:
            if a not in valid:
                raise ConfigError(f"algorithms: unknown algorithm {a!r}; valid: {', '.join(sorted(valid))}")
    for k, ds in enumerate(cfg.datasets):
        where = f"datasets[{k}]"
        if not isinstance(ds, dict):
            raise ConfigError(f"{where}: expected a table with name, size, seed, params")
        extra = set(ds) - _DATASET_KEYS
        if extra:
            raise ConfigError(f"{where}.{sorted(extra)[0]}: unknown key; valid: {', '.join(sorted(_DATASET_KEYS))}")
        name = ds.get("name")
        if name not in datasets_gen.GENERATORS and name not in datasets_gen.EMBEDDED:
            raise ConfigError(f"{where}.name: unknown dataset {name!r}")
        if "size" in ds:
            _check_int(f"{where}.size", ds["size"], 2)
        if "seed" in ds:
            _check_int(f"{where}.seed", ds["seed"], 0)
        params = ds.get("params", {})
        if not isinstance(params, dict):
            raise ConfigError(f"{where}.params: expected a table")
        allowed = (datasets_gen.GENERATORS[name].defaults if name in datasets_gen.GENERATORS
                   else datasets_gen.EMBEDDED[name][1])
        for p in params:
            if p not in allowed:
                raise ConfigError(f"{where}.params.{p}: not a parameter of {name}; it takes "
                                  f"{', '.join(allowed) or 'none'}")
    return cfg


# ---- the groups ----------------------------------------------------------------------
def dataset_label(ds) -> str:
    """The dataset column of a config entry: name, size and sorted parameters, e.g.
    ``fbm1024-octaves6``."""
    size = ds.get("size")
    extra = "".join(f"-{k}{v}" for k, v in sorted(ds.get("params", {}).items()))
    return f"{ds['name']}{size if size else ''}{extra}"


def row_key(row) -> tuple:
    """What identifies a row: its group and algorithm."""
    return (str(row["dataset"]), str(row["workload"]), str(row["surface"]),
            str(row["run_length"]), str(row["algorithm"]))


def _algorithms(cfg, workload):
    names = algos.TRAVERSALS if workload != "first_hit" else algos.INTERSECTORS
    chosen = [n for n in (cfg.algorithms or names) if n in names]
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


def traversal_rays(shape, r, n, seed):
    """The 2D rays of a traversal group: ``datasets_gen.rays.by_run_length`` with origins
    inside ``shape`` (nx, ny) and parallel rays consecutive; (origins, directions)."""
    rs = raysets.by_run_length(r, n, shape, seed, origins="inside", order="octant")
    return rs.origins, rs.directions


def first_hit_rays(field, r, n, seed):
    """First-hit rays: the traversal rays of ``field``'s grid, each falling at an elevation
    drawn from 5 to 20 degrees, from one cell above the field's highest point;
    (origins, directions) of shape (n, 3), unit directions."""
    rows, cols = field.heights.shape
    rs = raysets.by_run_length(r, n, (cols - 1, rows - 1), seed, origins="inside",
                               order="octant", elevation=(5.0, 20.0),
                               height=float(field.heights.max()) + 1.0)
    return rs.origins, rs.directions


def hit_agreement(t, reference, tolerance) -> float:
    """Fraction of rays with the reference's hit/miss and, where both hit,
    |t - t_ref| <= tolerance (1 + |t_ref|)."""
    hit, ref_hit = np.isfinite(t), np.isfinite(reference)
    both = hit & ref_hit
    close = np.ones(len(t), bool)
    close[both] = np.abs(t[both] - reference[both]) <= tolerance * (1 + np.abs(reference[both]))
    return float(np.mean((hit == ref_hit) & close))


def measure_group(field, label, workload, surface, r, names, rays, repeats, seed,
                  keep_samples=False):
    """Rows for one group: every algorithm on the same rays, interleaved. With
    ``keep_samples`` each row also holds ``ratio_samples``, the per-repeat paired ratios
    time(baseline) / time(algorithm)."""
    rows_, cols_ = field.heights.shape
    shape = (cols_ - 1, rows_ - 1)
    jobs, outputs = {}, {}
    if workload == "first_hit":
        o, d = first_hit_rays(field, r, rays, seed)
        ref = algos.intersect("runs", field, o, d, surface=surface, outputs=("t", "stats"))
        cells = float(ref.stats["cells_visited"].mean())
        runs = float(ref.stats["runs_visited"].mean())
        for name in names:
            jobs[name], outputs[name] = prepare_timed_intersect(name, field, o, d, surface=surface)
        reference = ref.t
    else:
        o, d = traversal_rays(shape, r, rays, seed)
        counts = algos.traverse("midpoint", o, d, shape, output="count")
        cells, runs = float(counts.cells.mean()), float(counts.runs.mean())
        mode = "visit" if workload == "visit" else "runs"
        for name in names:
            run, sums = algos.prepare_timed(name, o, d, shape, mode)
            jobs[name], outputs[name] = run, (lambda s=sums: s.copy())
        ref_run, ref_sums = algos.prepare_timed("midpoint", o, d, shape, mode)
        ref_run()
        reference = ref_sums
    times = interleaved(jobs, repeats)
    out = []
    for name in names:
        per_ray = times[name] / rays
        median, low, high = median_ci(per_ray, seed=seed)
        speedup, s_low, s_high = ratio_ci(times[BASELINE], times[name], seed=seed)
        got = outputs[name]()
        if workload == "first_hit":
            agree = hit_agreement(got, reference, 1e-4 if name == "embree" else 1e-9)
        else:
            agree = float(np.mean(got == reference))
        out.append(dict(
            algorithm=name, baseline=BASELINE, workload=workload, surface=surface,
            dataset=label, grid=f"{shape[0]}x{shape[1]}", run_length=r, rays=rays,
            cells_per_ray=round(cells, 2), runs_per_ray=round(runs, 2),
            ns_per_ray=round(median, 2), ns_per_ray_ci_low=round(low, 2),
            ns_per_ray_ci_high=round(high, 2), speedup=round(speedup, 4),
            speedup_ci_low=round(s_low, 4), speedup_ci_high=round(s_high, 4),
            ns_per_cell=round(median / cells, 4) if cells else math.nan,
            ns_per_run=round(median / runs, 4) if runs else math.nan,
            agree=round(agree, 6), repeats=repeats, seed=seed))
        if keep_samples:
            out[-1]["ratio_samples"] = (times[BASELINE] / times[name]).tolist()
    return out


def read_rows(path) -> list[dict]:
    """The rows of a CSV as dicts of strings; [] when ``path`` does not exist."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def load_field(ds) -> algos.Field:
    """The Field of one config dataset entry."""
    return algos.Field(datasets_gen.load(ds["name"], size=ds.get("size"), seed=ds.get("seed", 0),
                                         **ds.get("params", {})).heights)


def _pending(cfg, out_dir, resume):
    """(results.csv path, the groups still to measure with their missing algorithms);
    without ``resume`` an old results.csv is removed."""
    os.makedirs(out_dir, exist_ok=True)
    csv_path = os.path.join(out_dir, "results.csv")
    done = {row_key(r) for r in read_rows(csv_path)} if resume else set()
    if not resume and os.path.exists(csv_path):
        os.remove(csv_path)
    todo = []
    for ds, workload, surface, r, names in groups(cfg):
        label = dataset_label(ds)
        missing = [n for n in names if (label, workload, surface, str(r), n) not in done]
        if missing:
            todo.append((ds, label, workload, surface, r, names, missing))
    return csv_path, todo


def _bar(progress, total, desc):
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="group", desc=desc, dynamic_ncols=True)


def _write_group(writer, rows, missing, bar, label):
    """Append a finished group's rows (only the missing algorithms'), then tick the bar."""
    for row in rows:
        if row["algorithm"] in missing:
            writer.write(row)
    if bar is not None:
        bar.set_postfix_str(label)
        bar.update(1)


def measure_task(ds, label, workload, surface, r, names, rays, repeats, seed):
    """One group on a Dask worker: load the field there, measure, return the rows and the
    worker's environment. Module-level (importable) so any worker can run it."""
    rows = measure_group(load_field(ds), label, workload, surface, r, names, rays,
                         repeats, seed)
    import socket

    return rows, dict(environment(), hostname=socket.gethostname(), pid=os.getpid())


def dask_client(address: str, memory_limit=None):
    """A distributed Client: ``local:N`` starts a LocalCluster of N single-threaded
    worker processes (each limited to ``memory_limit``, e.g. "600MiB", when given);
    anything else is a scheduler address."""
    from dask.distributed import Client, LocalCluster

    if address.startswith("local:"):
        try:
            n = int(address.split(":", 1)[1])
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"--dask: expected local:N with N >= 1, got {address!r}")
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None,
                               **({"memory_limit": memory_limit} if memory_limit else {}))
        return Client(cluster), cluster
    return Client(address), None


def run_sweep_dask(cfg: SweepConfig, out_dir: str, address: str, resume=False, progress=True,
                   echo=print):
    """The sweep with each group as one task on a Dask worker (single-threaded workers:
    a group's interleaving, hence its ratios, is the serial sweep's). The driver appends
    a group's rows to results.csv as soon as the group comes back, so a killed driver
    loses no finished group and ``resume`` skips it; a killed worker's task is rerun by
    the scheduler and its rows are written once, by the driver. Each worker's environment
    goes into env.json under "workers"."""
    csv_path, todo = _pending(cfg, out_dir, resume)
    from dask.distributed import as_completed

    client, cluster = dask_client(address)
    env = dict(environment(), dask_address=address, workers={})
    try:
        futures = {}
        for item in todo:
            ds, label, workload, surface, r, names, missing = item
            future = client.submit(measure_task, ds, label, workload, surface, r, names,
                                   cfg.rays, cfg.repeats, cfg.seed, pure=False)
            futures[future] = item
        bar = _bar(progress, len(todo), f"{cfg.name} (dask)")
        start = time.perf_counter()
        with RowWriter(csv_path, COLUMNS, append=resume) as writer:
            for future in as_completed(futures):
                ds, label, workload, surface, r, names, missing = futures[future]
                rows, worker_env = future.result()
                worker = worker_env.get("hostname", "") + f" pid {worker_env.get('pid', '')}"
                env["workers"].setdefault(worker, worker_env)
                write_json(os.path.join(out_dir, "env.json"), env)
                _write_group(writer, rows, missing, bar, f"{label} {workload} {surface} r={r}")
        if bar is not None:
            bar.close()
        if echo and todo:
            echo(f"{len(todo)} groups measured on {address} in {time.perf_counter() - start:.1f} s")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    write_json(os.path.join(out_dir, "env.json"), env)
    return read_rows(csv_path)


def run_sweep(cfg: SweepConfig, out_dir: str, resume=False, progress=True, echo=print):
    """Run (or resume) a sweep; returns every row of results.csv afterwards."""
    csv_path, todo = _pending(cfg, out_dir, resume)
    write_json(os.path.join(out_dir, "env.json"), environment())
    bar = _bar(progress, len(todo), cfg.name)
    fields_cache = {}
    start = time.perf_counter()
    with RowWriter(csv_path, COLUMNS, append=resume) as writer:
        for ds, label, workload, surface, r, names, missing in todo:
            if label not in fields_cache:
                fields_cache.clear()  # one field in memory at a time
                fields_cache[label] = load_field(ds)
            field_ = fields_cache[label]
            measured = measure_group(field_, label, workload, surface, r, names, cfg.rays,
                                     cfg.repeats, cfg.seed)
            _write_group(writer, measured, missing, bar, f"{label} {workload} {surface} r={r}")
    if bar is not None:
        bar.close()
    if echo and todo:
        echo(f"{len(todo)} groups measured in {time.perf_counter() - start:.1f} s")
    return read_rows(csv_path)

"""The sweep config: read from TOML or a dict, every key checked before any work starts.

    name = "my-sweep"                 # output directory results/sweep/<name>
    rays = 2000                       # rays per group
    repeats = 7                       # interleaved repeats (>= 3); with precision, the fewest rounds
    precision = 0.02                  # optional: sequential paired rounds to +-2 % (docs/METHOD.md)
    group_budget = 3.0                # with precision: seconds a group may spend measuring
    call_ms = 8.0                     # with precision: the baseline's call is at least this long
    call_cells = 100000               # optional, with precision: a call's work, in cell steps
    flush = "warm"                    # with precision: "warm" (own untimed call first), "call", "round", "none"
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

Every key, its type, default and meaning: ``docs/sweeps.md``; examples in ``examples/``.
An unknown key is an error naming it and the closest valid key.
"""
from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass, field

import algos
import datasets_gen

from .timing import FLUSH_MODES

__all__ = ["SweepConfig", "ConfigError", "load_config", "WORKLOADS"]

WORKLOADS = ("visit", "runs", "first_hit")
_KEYS = {"name", "rays", "repeats", "seed", "algorithms", "workloads", "surfaces",
         "run_lengths", "datasets", "plugins", "precision", "group_budget", "call_ms", "flush",
         "call_cells"}
_DATASET_KEYS = {"name", "size", "seed", "params"}


class ConfigError(ValueError):
    """A sweep configuration that cannot run; the message names the key."""


def _unknown_key(where, key, valid):
    """The error for an unknown config key: names it and the closest valid key."""
    close = difflib.get_close_matches(str(key), sorted(valid), n=1, cutoff=0.5)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return ConfigError(f"{where}{key}: unknown key; {hint}valid keys are {', '.join(sorted(valid))}")


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
    plugins: list = field(default_factory=list)
    precision: float | None = None
    group_budget: float = 3.0
    call_ms: float = 8.0
    flush: str = "warm"
    call_cells: int | None = None


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
        raise _unknown_key("", sorted(unknown)[0], _KEYS)
    cfg = SweepConfig(**{k: v for k, v in data.items()})
    if not isinstance(cfg.plugins, list) or not all(isinstance(p, str) for p in cfg.plugins):
        raise ConfigError("plugins: expected a list of strings (library paths or module:callable)")
    if cfg.plugins:
        from algos.plugins import PluginError, load_plugin_spec

        # library paths and modules resolve from the config's folder (then the current
        # directory), so a documented config runs as written from any directory
        base = os.path.dirname(os.path.abspath(os.fspath(source))) \
            if isinstance(source, (str, os.PathLike)) else os.getcwd()
        for k, spec in enumerate(cfg.plugins):
            try:
                load_plugin_spec(spec, base=base)
            except (ValueError, PluginError) as exc:
                raise ConfigError(f"plugins[{k}]: {exc}") from None
    if not isinstance(cfg.name, str) or not cfg.name or "/" in cfg.name:
        raise ConfigError(f"name: expected a plain directory name, got {cfg.name!r}")
    _check_int("rays", cfg.rays, 8)
    _check_int("repeats", cfg.repeats, 3)
    _check_int("seed", cfg.seed, 0)
    if cfg.precision is not None and (isinstance(cfg.precision, bool) or not isinstance(
            cfg.precision, (int, float)) or not 0 < cfg.precision < 1):
        raise ConfigError(f"precision: expected a fraction in (0, 1) (0.02 is ±2 %), got "
                          f"{cfg.precision!r}")
    if cfg.flush not in FLUSH_MODES:
        raise ConfigError(f"flush: expected one of {', '.join(FLUSH_MODES)}, got {cfg.flush!r}")
    if cfg.call_cells is not None:
        _check_int("call_cells", cfg.call_cells, 1)
    for key in ("group_budget", "call_ms"):
        value = getattr(cfg, key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise ConfigError(f"{key}: expected a positive number, got {value!r}")
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
        # finite: inf passed here, every group ran, and the report refused every row
        if r != "random" and (isinstance(r, bool) or not isinstance(r, (int, float)) or not r >= 1
                              or not math.isfinite(r)):
            raise ConfigError(f"run_lengths: {r!r} is neither a finite number >= 1 nor \"random\"")
    if cfg.algorithms is not None:
        if not isinstance(cfg.algorithms, list) or not cfg.algorithms:
            raise ConfigError("algorithms: expected a non-empty list of names")
        valid = set(algos.TRAVERSALS) | set(algos.INTERSECTORS)
        for a in cfg.algorithms:
            if a not in valid:
                raise ConfigError(f"algorithms: unknown algorithm {a!r}; valid: {', '.join(sorted(valid))}")
        for k, a in enumerate(cfg.algorithms):
            _check_measured(f"algorithms[{k}]", a, cfg.workloads, cfg.surfaces)
    for k, ds in enumerate(cfg.datasets):
        where = f"datasets[{k}]"
        if not isinstance(ds, dict):
            raise ConfigError(f"{where}: expected a table with name, size, seed, params")
        same = [j for j, other in enumerate(cfg.datasets[:k]) if _same_dataset(other, ds)]
        if same:
            raise ConfigError(f"{where}: the same dataset as datasets[{same[0]}] (name, size, "
                              "seed and params); list each field once")
        extra = set(ds) - _DATASET_KEYS
        if extra:
            raise _unknown_key(f"{where}.", sorted(extra)[0], _DATASET_KEYS)
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
                close = difflib.get_close_matches(str(p), list(allowed), n=1, cutoff=0.5)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ConfigError(f"{where}.params.{p}: not a parameter of {name}{hint}; it "
                                  f"takes {', '.join(allowed) or 'none'}")
    return cfg


def _same_dataset(a, b) -> bool:
    """Whether two dataset entries name the same field (the seed defaults to 0)."""
    if not isinstance(a, dict) or not isinstance(b, dict):
        return False
    return (a.get("name"), a.get("size"), a.get("seed", 0), a.get("params", {})) == \
        (b.get("name"), b.get("size"), b.get("seed", 0), b.get("params", {}))


def _check_measured(where, name, workloads, surfaces):
    """ConfigError when no group of the config measures the kernel ``name`` (a first-hit
    kernel with only the visit workload, or none of its surfaces): it was left out of
    every group without a word, and its table had no column for it."""
    traversal = algos.TRAVERSAL_REGISTRY.get(name)
    hit = algos.INTERSECTOR_REGISTRY.get(name)
    offers = []
    if traversal is not None:
        offers += ["visit"] + (["runs"] if traversal.plugin is None else [])
    if hit is not None:
        offers += [f"first_hit on {', '.join(hit.surfaces)}"]
    measured = (traversal is not None and "visit" in workloads) or \
        (traversal is not None and traversal.plugin is None and "runs" in workloads) or \
        (hit is not None and "first_hit" in workloads and
         any(s in hit.surfaces for s in surfaces))
    if not measured:
        raise ConfigError(f"{where}: {name!r} is measured by no group of this config "
                          f"(workloads {', '.join(workloads)}; surfaces "
                          f"{', '.join(surfaces)}): it takes {'; '.join(offers)}")

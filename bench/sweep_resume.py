"""What ``hftrace sweep --resume`` checks beyond the rows themselves: that the kept rows
were measured on the fields and with the plugin code the run recorded in its
``env.json`` (``bench.sweep._pending``). A label holds a dataset's name, size and
parameters but not its seed, and hftrace's commit does not cover a plugin's code, so
neither is visible in the rows. And the run's totals over its sessions."""
from __future__ import annotations

import json
import os

from .sweep_config import _same_dataset


def recorded_env(out_dir) -> dict:
    """The ``env.json`` a run wrote in ``out_dir``, or {} when there is none (or it is not
    JSON)."""
    try:
        with open(os.path.join(out_dir, "env.json")) as f:
            env = json.load(f)
    except (OSError, ValueError):
        return {}
    return env if isinstance(env, dict) else {}


def check_recorded_datasets(cfg, out_dir, measured, dataset_label):
    """ValueError when a dataset of ``cfg`` has the label of kept rows (``measured``) but
    another seed than the run recorded in its ``env.json`` (``"datasets"``): the label
    holds the name, size and parameters, not the seed, so the kept rows would pass for
    the other field's. Runs whose env.json records no datasets are not checked.
    ``dataset_label``: :func:`bench.sweep.dataset_label`."""
    recorded = recorded_env(out_dir).get("datasets")
    if not isinstance(recorded, list) or not all(isinstance(d, dict) for d in recorded):
        return
    before = {dataset_label(ds, recorded): ds for ds in recorded}
    for k, ds in enumerate(cfg.datasets):
        label = dataset_label(ds, cfg.datasets)
        old = before.get(label)
        if label in measured and old is not None and not _same_dataset(old, ds):
            raise ValueError(
                f"--resume: the rows of {label} were measured with datasets[{k}].seed = "
                f"{old.get('seed', 0)}, the config says {ds.get('seed', 0)}; choose another "
                "--out (or restore the config) rather than mix them")


def plugin_fingerprints(cfg) -> dict:
    """{plugin name: :func:`algos.plugins.plugin_fingerprint`} for the config's plugin
    kernels."""
    from algos.plugins import plugin_fingerprint

    found = {name: plugin_fingerprint(name) for name in cfg.algorithms}
    return {name: fp for name, fp in found.items() if fp is not None}


def check_recorded_plugins(cfg, out_dir, measured):
    """ValueError when a plugin kernel with kept rows (``measured``) is not the build or
    edit the run recorded in its ``env.json`` (``"plugins"``): hftrace's commit does not
    cover a plugin's code, so rows of two versions would pass for one. Runs whose
    env.json records no plugins are not checked."""
    recorded = recorded_env(out_dir).get("plugins")
    if not isinstance(recorded, dict):
        return
    for name, now in plugin_fingerprints(cfg).items():
        before = recorded.get(name)
        if name in measured and before is not None and before != now:
            raise ValueError(
                f"--resume: the rows of {name} were measured with another version of the "
                f"plugin ({before}; now {now}); choose another --out to measure this one "
                "(or restore the plugin) rather than mix them")


#: The totals of ``env.json``'s ``"run"`` that add up over the sessions of a resumed run.
SESSION_TOTALS = ("groups", "wall_s", "timed_s", "measure_s", "flush_s", "prepare_s",
                  "contended_groups", "remeasured_groups")


def earlier_sessions(out_dir, run):
    """The ``"run"`` totals that ``env.json`` holds for this run (same ``run_id``) from the
    sessions before a ``--resume``, or None."""
    old = recorded_env(out_dir)
    same = (old.get("run_identity") or {}).get("run_id") == run["run_id"]
    return old.get("run") if same and isinstance(old.get("run"), dict) else None


def merge_sessions(earlier: dict, latest: dict) -> dict:
    """One run's totals over its sessions: a resumed run's ``env.json`` described only its
    last session (a resume with nothing left to measure: "The sweep took 0 s, 0 % of it
    inside timed calls"). Totals add up, the shares are recomputed and ``sessions`` counts
    them; the rest is the latest session's, and ``last_session`` keeps its own totals."""
    merged = dict(latest)
    merged["last_session"] = {k: v for k, v in latest.items() if k != "last_session"}
    for key in SESSION_TOTALS:
        if isinstance(earlier.get(key), (int, float)) and isinstance(latest.get(key), (int, float)):
            merged[key] = round(earlier[key] + latest[key], 2)
    merged["sessions"] = int(earlier.get("sessions", 1)) + 1
    wall, timed, measure = merged.get("wall_s"), merged.get("timed_s"), merged.get("measure_s")
    if wall is not None and timed is not None:
        merged["timed_share"] = round(timed / wall, 4) if wall > 0 else None
    if measure is not None and timed is not None:
        merged["timed_share_of_measure"] = round(timed / measure, 4) if measure > 0 else None
    return merged

"""What ``hftrace sweep --resume`` checks beyond the rows themselves: that the kept rows
were measured on the fields and with the plugin code the run recorded in its
``env.json`` (``bench.sweep._pending``). A label holds a dataset's name, size and
parameters but not its seed, and hftrace's commit does not cover a plugin's code, so
neither is visible in the rows."""
from __future__ import annotations

import json
import os

from .sweep_config import _same_dataset


def check_recorded_datasets(cfg, out_dir, measured, dataset_label):
    """ValueError when a dataset of ``cfg`` has the label of kept rows (``measured``) but
    another seed than the run recorded in its ``env.json`` (``"datasets"``): the label
    holds the name, size and parameters, not the seed, so the kept rows would pass for
    the other field's. Runs whose env.json records no datasets are not checked.
    ``dataset_label``: :func:`bench.sweep.dataset_label`."""
    path = os.path.join(out_dir, "env.json")
    try:
        with open(path) as f:
            recorded = json.load(f).get("datasets")
    except (OSError, ValueError):
        return
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
    path = os.path.join(out_dir, "env.json")
    try:
        with open(path) as f:
            recorded = json.load(f).get("plugins")
    except (OSError, ValueError):
        return
    if not isinstance(recorded, dict):
        return
    for name, now in plugin_fingerprints(cfg).items():
        before = recorded.get(name)
        if name in measured and before is not None and before != now:
            raise ValueError(
                f"--resume: the rows of {name} were measured with another version of the "
                f"plugin ({before}; now {now}); choose another --out to measure this one "
                "(or restore the plugin) rather than mix them")

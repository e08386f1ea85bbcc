"""Sweeps beyond one machine: each group measured on a Dask worker (``hftrace sweep --dask``),
its rows written once by the driver, and the client the terrain products' Dask path shares.
"""
from __future__ import annotations

import os
import time

from .report import RowWriter, results_row_check
from .sweep import (
    COLUMNS,
    REQUIRED,
    _bar,
    _design,
    _pending,
    _report_damaged,
    _write_group,
    load_field,
    measure_group,
    new_run,
    read_rows,
)
from .sweep_config import SweepConfig
from .timing import environment, write_json

__all__ = ["run_sweep_dask", "dask_client", "close_client", "measure_task"]


def measure_task(ds, label, workload, surface, r, names, rays, repeats, seed, **design):
    """One group on a Dask worker: load the field there, measure (``design``: the
    sequential design's arguments of :func:`measure_group`), return the rows and the
    worker's environment. Module-level (importable) so any worker can run it."""
    rows = measure_group(load_field(ds), label, workload, surface, r, names, rays,
                         repeats, seed, **design)
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
        # no dashboard, and the scheduler's remaining HTTP routes on a free port: by default
        # they bind 8787, and where that is taken (another cluster, a notebook) Dask warns
        # on stderr, which the CLI's output would carry
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None,
                               scheduler_kwargs={"dashboard": False, "dashboard_address": ":0"},
                               **({"memory_limit": memory_limit} if memory_limit else {}))
        client = Client(cluster)
        # a task's exception reaches the driver, which reports it in one line: the local
        # workers' own "Compute Failed" log (the task, its arguments and the traceback)
        # would print the same error first as a dump
        client.run(quiet_task_failures)
        return client, cluster
    return Client(address), None


class _NotTaskFailures:
    """A logging filter that drops a Dask worker's "Compute Failed" records."""

    def filter(self, record) -> bool:
        return not str(record.msg).startswith("Compute Failed")


def quiet_task_failures() -> None:
    """On a worker of our own LocalCluster: stop logging the failed tasks whose
    exceptions the driver re-raises (every other worker message is kept)."""
    import logging

    for name in ("distributed.worker", "distributed.worker.state_machine"):
        log = logging.getLogger(name)
        if not any(isinstance(f, _NotTaskFailures) for f in log.filters):
            log.addFilter(_NotTaskFailures())


def _distributed_levels(level):
    """Set every "distributed" logger that has a level of its own (the package's config
    gives some, e.g. distributed.client) to ``level``; return the levels it had."""
    import logging

    names = ["distributed"] + [n for n in logging.root.manager.loggerDict
                               if n.startswith("distributed.")]
    before = {}
    for name in names:
        log = logging.getLogger(name)
        if name == "distributed" or log.level != logging.NOTSET:
            before[name] = log.level
            log.setLevel(level)
    return before


def _quiet_teardown() -> None:
    """On a worker of our own LocalCluster that is about to be closed: log only critical
    records. A heartbeat in flight when the cluster closes logs "Failed to communicate with
    scheduler" with a traceback; it is shutdown noise, not a fault of the run."""
    import logging

    _distributed_levels(logging.CRITICAL)


def close_client(client, cluster) -> None:
    """Close ``client`` and, when :func:`dask_client` started it, ``cluster``. Our own local
    cluster is closed quietly (its workers, and the scheduler in this process, log only
    critical records while they shut down), so an error the driver reports stays one line;
    a remote scheduler's logging is left alone."""
    import logging

    if cluster is None:
        client.close()
        return
    try:
        client.run(_quiet_teardown)
    except Exception:  # a worker already gone: nothing of it left to quiet
        pass
    before = _distributed_levels(logging.CRITICAL)
    try:
        client.close()
        cluster.close()
    finally:
        for name, level in before.items():
            logging.getLogger(name).setLevel(level)


def run_sweep_dask(cfg: SweepConfig, out_dir: str, address: str, resume=False, progress=True,
                   echo=print):
    """The sweep with each group as one task on a Dask worker (single-threaded workers:
    a group's interleaving, hence its ratios, is the serial sweep's). The driver appends
    a group's rows to results.csv as soon as the group comes back, so a killed driver
    loses no finished group and ``resume`` skips it; a killed worker's task is rerun by
    the scheduler and its rows are written once, by the driver. Each worker's environment
    goes into env.json under "workers"."""
    commit = environment().get("git_commit", "")
    run = new_run(cfg, commit)
    bad = []
    csv_path, todo = _pending(cfg, out_dir, resume, commit=commit, run=run, bad=bad,
                              check_machine=False)
    _report_damaged(csv_path, bad, echo)
    from dask.distributed import as_completed

    client, cluster = dask_client(address)
    env = dict(environment(), dask_address=address, workers={}, datasets=cfg.datasets)
    try:
        futures = {}
        for item in todo:
            ds, label, workload, surface, r, names, missing = item
            future = client.submit(measure_task, ds, label, workload, surface, r, names,
                                   cfg.rays, cfg.repeats, cfg.seed, pure=False, **_design(cfg))
            futures[future] = item
        bar = _bar(progress, len(todo), f"{cfg.name} (dask)")
        start = time.perf_counter()
        with RowWriter(csv_path, COLUMNS, append=resume, required=REQUIRED,
                       check=results_row_check()) as writer:
            # this client's loop: as_completed otherwise tracks the futures on the default
            # client's, and a second client in the process then waits on an event bound
            # to another loop ("bound to a different event loop")
            for future in as_completed(futures, loop=client.loop):
                ds, label, workload, surface, r, names, missing = futures[future]
                rows, worker_env = future.result()
                worker = worker_env.get("hostname", "") + f" pid {worker_env.get('pid', '')}"
                env["workers"].setdefault(worker, worker_env)
                write_json(os.path.join(out_dir, "env.json"), env)
                # the rows were measured on the worker's machine
                _write_group(writer, rows, missing, bar, f"{label} {workload} {surface} r={r}",
                             commit=commit, run=dict(run, machine=worker_env.get("hostname")
                                                     or run["machine"]))
        if bar is not None:
            bar.close()
        if echo and todo:
            echo(f"{len(todo)} groups measured on {address} in {time.perf_counter() - start:.1f} s")
    finally:
        close_client(client, cluster)
    write_json(os.path.join(out_dir, "env.json"), env)
    return read_rows(csv_path)

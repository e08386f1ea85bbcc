"""The machine's load around a measurement: is anyone else using the CPUs?

A timing taken while other processes compete for the cores, the caches and the memory
bus is not comparable with a quiet one. Every group of a sweep is bracketed by two
:func:`snapshot` calls; :func:`contention` turns them into the CPU time *other*
processes took per second of wall time (all CPUs' busy time from ``/proc/stat`` minus
this process's own from ``/proc/self/stat``), and the 1-minute load average
(``/proc/loadavg``). A group is *contended* when others used more than
:data:`CONTENDED_CORES` cores on average while it ran (a busy loop on the other core of a
2-core machine uses 1.0), or when the load average exceeded the CPUs this process may use.
Where ``/proc`` cannot be read (not Linux) nothing is marked and the columns stay empty.
The counters advance in clock ticks (10 ms): over a span of one or two ticks the figure
reads 0 or 2 cores at random. :func:`snapshot_after` therefore closes a window no shorter
than :data:`MIN_WINDOW_S`, waiting out the rest after a short group, so that a busy loop
is never read as a quiet machine (an error of at most about two ticks, 0.2 cores).
"""
from __future__ import annotations

import os
import time

__all__ = ["snapshot", "snapshot_after", "contention", "CONTENDED_CORES", "MIN_WINDOW_S",
           "load_average"]

#: Other processes' average CPU use (in cores) above which a group is marked contended.
CONTENDED_CORES = 0.5
#: The shortest window (seconds) over which other processes' CPU use is read: ten clock
#: ticks, so that the tick granularity moves the figure by at most about 0.2 cores.
MIN_WINDOW_S = 0.1


def load_average() -> float | None:
    """The 1-minute load average (``/proc/loadavg``), or None where unreadable."""
    try:
        with open("/proc/loadavg") as f:
            return float(f.read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def _busy_seconds() -> float | None:
    """Busy CPU time of every CPU since boot, in seconds (``/proc/stat``: all but idle and
    iowait)."""
    try:
        with open("/proc/stat") as f:
            fields = f.readline().split()
        values = [int(v) for v in fields[1:]]
    except (OSError, ValueError, IndexError):
        return None
    idle = values[3] + (values[4] if len(values) > 4 else 0)
    # guest time is already inside user time
    busy = sum(values[:8]) - idle
    return busy / os.sysconf("SC_CLK_TCK")


def _own_seconds() -> float:
    """This process's CPU time (user + system, all threads), in seconds."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def snapshot() -> dict:
    """The counters :func:`contention` compares: wall clock, all CPUs' busy time, this
    process's CPU time and the load average."""
    return {"wall": time.monotonic(), "busy": _busy_seconds(), "own": _own_seconds(),
            "load": load_average()}


def snapshot_after(before: dict, min_window_s: float = MIN_WINDOW_S) -> dict:
    """The closing :func:`snapshot` of a window opened by ``before``, taken no earlier than
    ``min_window_s`` seconds after it (this process sleeps out the rest, so only others'
    work fills it)."""
    rest = min_window_s - (time.monotonic() - before["wall"])
    if rest > 0:
        time.sleep(rest)
    return snapshot()


def contention(before: dict, after: dict) -> dict:
    """What other processes did between two snapshots.

    Returns
    -------
    dict
        ``other_cpu``: their CPU time per second of wall time (cores; None when
        ``/proc/stat`` is unreadable); ``load_before`` and ``load_after``: 1-minute load
        averages; ``contended``: True when ``other_cpu`` > :data:`CONTENDED_CORES` or the
        load average exceeded the CPUs this process may run on.
    """
    wall = after["wall"] - before["wall"]
    other = None
    if before["busy"] is not None and after["busy"] is not None and wall > 0:
        other = max(0.0, (after["busy"] - before["busy"]) - (after["own"] - before["own"])) / wall
        other = min(other, float(os.cpu_count() or 1))  # clock-tick granularity on short spans
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count() or 1
    # a pinned process may run on one CPU while the machine has more: compare the load
    # with the whole machine's CPUs
    cpus = max(cpus, os.cpu_count() or 1)
    loads = [x for x in (before["load"], after["load"]) if x is not None]
    contended = bool((other is not None and other > CONTENDED_CORES) or
                     (loads and max(loads) > cpus))
    return {"other_cpu": None if other is None else round(other, 3),
            "load_before": before["load"], "load_after": after["load"],
            "contended": contended}

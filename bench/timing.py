"""Side-by-side timing: interleaved repeats, paired rounds, their intervals, environment.

Method (docs/METHOD.md): every algorithm in a comparison is timed on the same rays,
in the same process, on one thread; the clock (CLOCK_MONOTONIC) runs in C around the
whole batch. Two designs:

* :func:`interleaved` (the studies' fixed repeats): A B C A B C ... with the starting
  algorithm rotated each repeat, after one untimed warm-up round, with the caches flushed
  before every timed run (so no kernel inherits the cache lines its predecessor left,
  which on the same rays are its own).
* :func:`paired_rounds` (the sweeps and ``hftrace compare``): adjacent pairs with the
  baseline, ``B k1 B k2 B ...``, each visit warm by default (an untimed call of the same
  kernel first), each kernel's pairs stopping once the distribution-free interval of
  its median paired ratio (:func:`median_ratio_interval`) is as precise as asked, or the
  budget is spent.

With fixed repeats a speedup is the geometric mean of the per-repeat paired ratios with
Student's t interval of their logs (:func:`log_ratio_interval`); in paired rounds it is
the median pair's ratio; a time per ray is the median with its order-statistic interval.
"""
from __future__ import annotations

import functools
import json
import math
import os
import platform
import subprocess
import sys
import sysconfig
import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

__all__ = ["interleaved", "median_ci", "ratio_ci", "environment", "pin_to_one_cpu",
           "flush_caches", "cache_sizes", "last_level_cache_bytes", "resident_bytes",
           "write_json", "REGIMES", "timed_in_regime", "paired_rounds", "PairedTimes",
           "log_ratio_interval", "relative_half_width", "median_interval", "call_rays",
           "noise_floor", "FLUSH_MODES", "STOPS", "median_ratio_interval",
           "WARM_TIMED_CALLS"]


def cache_sizes() -> dict:
    """{"L1d", "L2", "L3"} bytes of this machine's data caches (sysfs), where readable."""
    out = {}
    base = "/sys/devices/system/cpu/cpu0/cache"
    try:
        for entry in sorted(os.listdir(base)):
            def read(name):
                with open(os.path.join(base, entry, name)) as f:
                    return f.read().strip()
            if read("type") == "Instruction":
                continue
            text = read("size").upper()
            scale = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}.get(text[-1:], 1)
            level = read("level")
            out[f"L{level}" + ("d" if level == "1" else "")] = int(text.rstrip("KMG")) * scale
    except (OSError, ValueError):
        pass
    return out


def last_level_cache_bytes() -> int:
    """The largest CPU data cache of this machine (sysfs), or 32 MiB when it cannot be read."""
    return max(cache_sizes().values(), default=0) or 32 << 20


def pin_to_one_cpu() -> int | None:
    """Restrict this process to one CPU (the last in its affinity; Linux), so every
    contender of a comparison runs single-threaded on the same core. Returns that CPU, or
    None where affinity cannot be set."""
    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[-1]})
        return cpus[-1]
    return None


def resident_bytes() -> int:
    """This process's resident memory now (``/proc/self/statm``), or 0 where unreadable."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
    except (OSError, ValueError, IndexError):
        return 0
    return pages * os.sysconf("SC_PAGE_SIZE")


_EVICT: dict = {}


#: The eviction buffer's size in units of the last-level cache (sysfs). Writing the LLC's
#: size in new lines displaces every older line under (pseudo-)LRU replacement; the half
#: more covers hashed set selection and lines kept by inclusive L2s.
FLUSH_FACTOR = 1.5
#: Bytes between the writes of a flush: one 8-byte write per 64-byte cache line.
CACHE_LINE = 64


def flush_caches(nbytes: int | None = None) -> None:
    """Evict the caches: write one word in every cache line of a buffer of
    :data:`FLUSH_FACTOR` times the last-level cache (at least 32 MiB), so the next timed
    run starts cold whatever ran before it. A line is fetched and dirtied whichever word
    is written, so the strided write evicts as much as writing every byte at an eighth of
    the arithmetic (measured, 32 MiB L3: 14 ms per flush of 48 MiB, against 52 ms for the
    former full write of 128 MiB; docs/METHOD.md, "Timing"). ``$HFTRACE_FLUSH_MB``
    overrides the size; 0 turns flushing off (tests that only check sweep bookkeeping)."""
    if nbytes is None and os.environ.get("HFTRACE_FLUSH_MB"):
        nbytes = int(float(os.environ["HFTRACE_FLUSH_MB"]) * (1 << 20))
        if nbytes <= 0:
            return
    nbytes = nbytes or max(int(FLUSH_FACTOR * last_level_cache_bytes()), 32 << 20)
    buf = _EVICT.get(nbytes)
    if buf is None:
        buf = _EVICT[nbytes] = np.zeros(nbytes // 8)
    lines = buf[:: CACHE_LINE // 8]
    np.add(lines, 1.0, out=lines)


def _guarded_call(jobs, name, errors, time_limit_ns, drop):
    """One call of ``jobs[name]``: its elapsed ns, or None when it failed. Without
    ``errors`` an exception propagates; with it, a job that raises or exceeds its entry
    of ``time_limit_ns`` (name -> ns) is reported in ``errors[name]`` and ``drop(name)``
    takes it out of the caller's rotation."""
    if errors is None:
        return jobs[name]()
    try:
        elapsed = jobs[name]()
    except Exception as exc:  # a kernel's failure is its row's error, not the run's
        errors[name] = f"{type(exc).__name__}: {exc}".strip()
        drop(name)
        return None
    limit = (time_limit_ns or {}).get(name)
    if limit is not None and elapsed > limit:
        errors[name] = (f"exceeded the time limit: one call took {elapsed / 1e9:.3g} s, "
                        f"limit {limit / 1e9:.3g} s")
        drop(name)
        return None
    return elapsed


def interleaved(jobs: dict[str, Callable[[], int]], repeats: int,
                flush: bool = True, errors: dict | None = None,
                time_limit_ns: dict | None = None) -> dict[str, np.ndarray]:
    """Run each job ``repeats`` times, interleaved and rotated; each job returns its own
    elapsed nanoseconds (measured in C). One untimed warm-up round comes first. With
    ``flush`` the caches are evicted before every timed run: interleaving on the same
    rays otherwise hands each job the lines its predecessor loaded (measured: `dda`
    right after Embree, whose BVH evicts the field, took 1.9x its time after `midpoint`).

    With ``errors`` (a dict), a job that raises, or takes longer than its entry of
    ``time_limit_ns`` (name -> ns) in one call, is dropped from the rotation and
    ``errors[name]`` says why; the other jobs go on, and the result holds only the jobs
    that finished every repeat. Without it an exception propagates."""
    names = list(jobs)

    def call(name):
        return _guarded_call(jobs, name, errors, time_limit_ns, names.remove)

    for name in list(names):  # warm-up: branch predictors, page faults
        call(name)
    times = {name: [] for name in names}
    for rep in range(repeats):
        order = list(names)
        shift = rep % max(len(order), 1)
        for name in order[shift:] + order[:shift]:
            if name not in names:
                continue
            if flush:
                flush_caches()
            elapsed = call(name)
            if elapsed is not None:
                times[name].append(elapsed)
    return {name: np.asarray(times[name], dtype=np.float64) for name in names}


#: The cache regimes of a timed comparison (docs/METHOD.md, "Cache regimes"): "flushed",
#: every timed run starts with the caches evicted; "warm", every timed run follows an
#: untimed run of the same kernel on the same rays, so it finds its own lines cached.
REGIMES = ("flushed", "warm")


def timed_in_regime(jobs: dict[str, Callable[[], int]], repeats: int, regime: str = "flushed",
                    errors: dict | None = None, time_limit_ns: dict | None = None):
    """:func:`interleaved` in one of :data:`REGIMES`: ``"flushed"`` is ``interleaved``
    with ``flush=True``; ``"warm"`` runs each job twice in a row, untimed then timed,
    without flushing (each kernel warmed on its own rays)."""
    if regime == "flushed":
        return interleaved(jobs, repeats, flush=True, errors=errors, time_limit_ns=time_limit_ns)
    if regime == "warm":
        def twice(job):
            return lambda: (job(), job())[1]

        return interleaved({name: twice(job) for name, job in jobs.items()}, repeats,
                           flush=False, errors=errors, time_limit_ns=time_limit_ns)
    raise ValueError(f"regime: expected one of {', '.join(REGIMES)}, got {regime!r}")


def _bootstrap(stat: Callable[[np.ndarray], float], samples: Sequence[np.ndarray],
               n_boot: int, seed: int) -> tuple[float, float]:
    rng = np.random.Generator(np.random.PCG64(seed))
    values = np.empty(n_boot)
    for b in range(n_boot):
        values[b] = stat(*[s[rng.integers(0, len(s), len(s))] for s in samples])
    return float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5))


def _resamples(rng, n: int, n_boot: int) -> np.ndarray:
    """(n_boot, n) bootstrap indices: the same draws, in the same order, as ``n_boot``
    successive ``rng.integers(0, n, n)`` calls (one call, vectorised)."""
    return rng.integers(0, n, (n_boot, n))


def median_ci(x: np.ndarray, n_boot: int = 2000, seed: int = 0):
    """Median and its bootstrap 95 % interval (vectorised over the resamples: the
    per-resample loop had cost more than the timed calls of a group)."""
    x = np.asarray(x, dtype=np.float64)
    rng = np.random.Generator(np.random.PCG64(seed))
    values = np.median(x[_resamples(rng, len(x), n_boot)], axis=1)
    return (float(np.median(x)), float(np.percentile(values, 2.5)),
            float(np.percentile(values, 97.5)))


def ratio_ci(numerator: np.ndarray, denominator: np.ndarray, n_boot: int = 2000,
             seed: int = 0):
    """median(numerator) / median(denominator) and its bootstrap 95 % interval,
    resampling the paired repeats (they were measured side by side)."""
    paired = len(numerator) == len(denominator)

    def stat(a, b):
        return float(np.median(a) / np.median(b))

    if paired:
        rng = np.random.Generator(np.random.PCG64(seed))
        idx = _resamples(rng, len(numerator), n_boot)
        num, den = np.asarray(numerator, np.float64), np.asarray(denominator, np.float64)
        values = np.median(num[idx], axis=1) / np.median(den[idx], axis=1)
        low, high = float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5))
    else:
        low, high = _bootstrap(stat, [numerator, denominator], n_boot, seed)
    return stat(numerator, denominator), low, high



# ---- paired, sequential rounds (the sweep's design; docs/METHOD.md, "Paired rounds") ----
#: The cache state of a timed call in :func:`paired_rounds` (docs/METHOD.md, "Cache regimes
#: compared"): ``"warm"``, one untimed call of the same kernel on the same rays first, so the
#: timed calls find the lines the kernel itself left, whichever kernel ran before it (then
#: :data:`WARM_TIMED_CALLS` timed calls, summed); ``"call"``, the caches flushed before every
#: timed call; ``"round"``, once before every cycle of calls; ``"none"``, never.
FLUSH_MODES = ("warm", "call", "round", "none")
#: The timed calls of a visit in the warm state, after its untimed call: three keep the
#: timed share of a visit at three quarters.
WARM_TIMED_CALLS = 3
#: Why a kernel left the rotation: its interval reached the precision asked for, the
#: group's time budget was spent, or the largest number of pairs was reached.
STOPS = ("precision", "budget", "rounds")


def median_ratio_interval(log_ratios, confidence: float = 0.95):
    """The speedup of paired timings from their per-pair log-ratios ``log(t_baseline /
    t_kernel)``: ``exp`` of their median and of its distribution-free ``confidence``
    interval (the binomial order statistics of :func:`median_interval`). Neither the
    normality of the log-ratios nor their variance is assumed, so a heavy tail (a call
    that an interrupt lengthened) widens nothing but its own rank.

    Parameters
    ----------
    log_ratios : array_like, shape (n,)
        One value per pair; NaN and infinite values are left out.

    Returns
    -------
    (speedup, low, high) : floats
        NaN for fewer than 2 finite values.
    """
    x = np.asarray(log_ratios, np.float64)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return math.nan, math.nan, math.nan
    m, lo, hi = median_interval(x, confidence)
    return math.exp(m), math.exp(lo), math.exp(hi)


def log_ratio_interval(baseline: np.ndarray, kernel: np.ndarray, confidence: float = 0.95):
    """The speedup ``t_baseline / t_kernel`` of paired timings and its ``confidence``
    interval: ``exp`` of the mean of the per-round log-ratios ``log(t_baseline /
    t_kernel)`` and of Student's t interval of that mean (``scipy.stats.t``). The studies
    with fixed repeats use it; the sweeps' paired rounds use the median
    (:func:`median_ratio_interval`).

    Parameters
    ----------
    baseline, kernel : array_like, shape (n,)
        Paired times (any unit, the same for both), element k of each measured in the
        same round. Rounds where either is NaN are left out.

    Returns
    -------
    (speedup, low, high) : floats
        The geometric mean of the paired ratios and its interval; NaN for fewer than 2
        complete pairs.
    """
    from scipy import stats

    b, k = np.asarray(baseline, np.float64), np.asarray(kernel, np.float64)
    if b.shape != k.shape:
        raise ValueError(f"kernel: expected the baseline's shape {b.shape} (paired rounds), "
                         f"got {k.shape}")
    ok = np.isfinite(b) & np.isfinite(k) & (b > 0) & (k > 0)
    logs = np.log(b[ok]) - np.log(k[ok])
    n = len(logs)
    if n < 2:
        return math.nan, math.nan, math.nan
    mean = float(logs.mean())
    half = float(stats.t.ppf(0.5 + confidence / 2, n - 1) * logs.std(ddof=1) / math.sqrt(n))
    return math.exp(mean), math.exp(mean - half), math.exp(mean + half)


def relative_half_width(speedup, low, high) -> float:
    """Half the interval's width as a fraction of the speedup (``0.02`` is ``±2 %``);
    NaN when any is missing."""
    values = [float(v) for v in (speedup, low, high)]
    if not all(np.isfinite(values)) or values[0] <= 0:
        return math.nan
    return (values[2] - values[1]) / (2.0 * values[0])


def median_interval(x: np.ndarray, confidence: float = 0.95):
    """The median of ``x`` and its distribution-free ``confidence`` interval: the order
    statistics ``x_(j)`` and ``x_(n+1-j)`` with ``j`` the largest index whose binomial
    tail ``P(Binom(n, 1/2) <= j - 1)`` is at most ``(1 - confidence) / 2``
    (``scipy.stats.binom``). With too few values for any such ``j`` the interval is the
    range. NaN values are left out; (nan, nan, nan) when none is left."""
    x = np.sort(np.asarray(x, np.float64)[np.isfinite(np.asarray(x, np.float64))])
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan
    k = _median_rank(n, float(confidence))
    return float(np.median(x)), float(x[k]), float(x[n - 1 - k])


@functools.lru_cache(maxsize=4096)
def _median_rank(n: int, confidence: float) -> int:
    """The 0-based rank of the lower bound of :func:`median_interval` for ``n`` values
    (the sequential rounds ask for it after every cycle)."""
    from scipy import stats

    tail = (1 - confidence) / 2
    k = int(stats.binom.ppf(tail, n, 0.5))
    if stats.binom.cdf(k, n, 0.5) > tail:
        k -= 1
    return max(k, 0)


@dataclass
class PairedTimes:
    """What :func:`paired_rounds` measured.

    ``times``: name -> float64 array (visits,) of ns per timed visit (the sum of its timed
    calls); ``log_ratios``: name -> float64 array (pairs,) of ``log(t_baseline / t_kernel)``
    per pair (the baseline's own entry is empty); ``rounds``: name -> its pairs (the
    baseline: its visits); ``stop``: name -> one of :data:`STOPS`; ``timed_s``: seconds
    inside timed calls; ``flush_s``: seconds spent preparing the cache state (flushing, or
    the untimed calls of the warm state); ``wall_s``: the whole, warm-up included."""

    times: dict
    log_ratios: dict
    rounds: dict
    stop: dict
    timed_s: float
    flush_s: float
    wall_s: float


def paired_rounds(jobs: dict[str, Callable[[], int]], baseline: str, precision: float = 0.02,
                  budget_s: float = 3.0, min_rounds: int = 8, max_rounds: int = 5000,
                  flush: str = "warm", seed: int = 0, errors: dict | None = None,
                  time_limit_ns: dict | None = None, confidence: float = 0.95) -> PairedTimes:
    """Time every job against the baseline in adjacent pairs on the same rays, until each
    ratio is as precise as asked (docs/METHOD.md, "Paired rounds").

    The calls run in cycles ``B k1 B k2 B ... kn B``: the kernels still in the rotation,
    in an order drawn afresh each cycle (seeded by ``seed``), each between two visits of
    the baseline ``B``. A kernel's pair is its visit and the geometric mean of the two
    baseline visits around it, so a machine state that drifts over a few milliseconds
    cancels to first order, and every visit of the baseline serves two pairs. A visit
    prepares the cache per :data:`FLUSH_MODES` (default ``"warm"``) and returns the
    nanoseconds of its timed calls, measured in C. One untimed call of every job comes
    first.

    From pair ``min_rounds`` on, a kernel leaves the rotation once the ``confidence``
    interval of its speedup (:func:`median_ratio_interval`: the median pair and its
    distribution-free interval) is at most ``precision`` wide on either side
    (:func:`relative_half_width`): stop ``"precision"``. When ``budget_s`` seconds of wall
    time are spent (``min_rounds`` pairs are always measured), or after ``max_rounds``
    pairs, the kernels still in the rotation stop with ``"budget"`` or ``"rounds"``.

    ``errors`` and ``time_limit_ns``: as in :func:`interleaved` (a failing job leaves the
    rotation and ``errors[name]`` says why; without ``errors`` its exception propagates).
    """
    if flush not in FLUSH_MODES:
        raise ValueError(f"flush: expected one of {', '.join(FLUSH_MODES)}, got {flush!r}")
    if baseline not in jobs:
        raise ValueError(f"baseline: {baseline!r} is not among the jobs ({', '.join(jobs)})")
    if not (precision > 0):
        raise ValueError(f"precision: expected a positive fraction (0.02 is ±2 %), got {precision!r}")
    if min_rounds < 2 or max_rounds < min_rounds:
        raise ValueError(f"min_rounds, max_rounds: expected 2 <= min_rounds <= max_rounds, "
                         f"got {min_rounds}, {max_rounds}")
    start = time.perf_counter()
    rng = np.random.Generator(np.random.PCG64(seed))
    failed = set()
    spent = {"timed": 0.0, "prepare": 0.0}

    def call(name):
        return _guarded_call(jobs, name, errors, time_limit_ns, failed.add)

    def visit(name):
        total = 0
        p0 = time.perf_counter()
        if flush == "warm" and call(name) is None:
            return None
        for _ in range(WARM_TIMED_CALLS if flush == "warm" else 1):
            if flush == "call":
                flush_caches()
            spent["prepare"] += time.perf_counter() - p0
            elapsed = call(name)
            p0 = time.perf_counter()
            if elapsed is None:
                return None
            total += elapsed
        spent["timed"] += total / 1e9
        return float(total)

    for name in list(jobs):  # warm-up: branch predictors, page faults
        call(name)
    alive = [n for n in jobs if n != baseline and n not in failed]
    times = {name: [] for name in jobs}
    logs = {name: [] for name in jobs}
    stop = {}
    pairs = 0
    if flush == "round":
        p0 = time.perf_counter()
        flush_caches()
        spent["prepare"] += time.perf_counter() - p0
    before = visit(baseline) if baseline not in failed else None
    if before is not None:
        times[baseline].append(before)
    while before is not None:
        if not alive and (len(jobs) > 1 or len(times[baseline]) >= min_rounds):
            break
        for name in [alive[k] for k in rng.permutation(len(alive))] or [None]:
            got = visit(name) if name is not None else None
            after = visit(baseline)
            if after is None:
                before = None
                break
            times[baseline].append(after)
            if got is not None:
                times[name].append(got)
                logs[name].append(0.5 * (math.log(before) + math.log(after)) - math.log(got))
            before = after
        if flush == "round":
            p0 = time.perf_counter()
            flush_caches()
            spent["prepare"] += time.perf_counter() - p0
        pairs += 1
        alive = [n for n in alive if n not in failed]
        elapsed_s = time.perf_counter() - start
        if pairs >= min_rounds:
            for name in list(alive):
                s, lo, hi = median_ratio_interval(logs[name], confidence)
                if relative_half_width(s, lo, hi) <= precision:
                    stop[name] = "precision"
                    alive.remove(name)
            if alive and (elapsed_s >= budget_s or pairs >= max_rounds):
                for name in alive:
                    stop[name] = "budget" if elapsed_s >= budget_s else "rounds"
                alive = []
                break
    kept = [name for name in jobs if name not in failed]
    stop.setdefault(baseline, "precision" if all(stop.get(n) == "precision" for n in kept
                                                 if n != baseline) else "budget")
    return PairedTimes(
        times={n: np.asarray(times[n], np.float64) for n in kept},
        log_ratios={n: np.asarray(logs[n], np.float64) for n in kept},
        rounds={n: len(times[n]) if n == baseline else len(logs[n]) for n in kept},
        stop={n: stop.get(n, "rounds") for n in kept},
        timed_s=spent["timed"], flush_s=spent["prepare"], wall_s=time.perf_counter() - start)


def call_rays(first_call_ns: float, rays: int, call_ms: float, max_factor: int = 16) -> int:
    """The rays of a timed call: ``rays`` doubled until a call of the baseline, which took
    ``first_call_ns`` on ``rays``, lasts at least ``call_ms`` milliseconds (at most
    ``max_factor`` times ``rays``). A power of two of ``rays`` keeps the choice
    reproducible from run to run when the timing shifts a little."""
    factor = 1
    while factor < max_factor and first_call_ns * factor < call_ms * 1e6:
        factor *= 2
    return rays * factor


def noise_floor(job: Callable[[], int], seconds: float = 1.0, rounds_affordable: int = 40,
                confidence: float = 0.95, flush: str = "warm") -> dict:
    """The smallest effect this machine resolves now: the job against itself under
    another name (A/A), in :func:`paired_rounds`' design for about ``seconds``. Returns
    ``{"log_sd": the spread of one paired log-ratio (1.4826 times its median absolute
    deviation, robust to the tail the median ignores), "pairs": how many, "floor": the
    relative half-width the median's interval reaches in ``rounds_affordable`` pairs at
    that spread (the median's large-sample variance, pi/2 times the mean's)}``."""
    from scipy import stats

    # an even share of the time: the A/A design of paired_rounds at its shortest
    got = paired_rounds({"baseline": job, "again": job}, "baseline", precision=1e-9,
                        budget_s=seconds, min_rounds=10, max_rounds=2000, flush=flush)
    logs = got.log_ratios["again"]
    sd = float(1.4826 * np.median(np.abs(logs - np.median(logs)))) if len(logs) else math.nan
    n = max(int(rounds_affordable), 2)
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    floor = math.expm1(z * math.sqrt(math.pi / 2) * sd / math.sqrt(n))
    return {"log_sd": round(sd, 5), "pairs": len(logs), "floor": round(floor, 5),
            "rounds_affordable": n}


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _git_commit() -> str:
    here = os.path.dirname(os.path.abspath(__file__))
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                             text=True, timeout=5)
        commit = out.stdout.strip()
        # reports/ holds the outputs being regenerated: changes there are not the code's
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                ".", ":(exclude)reports"],
                               cwd=os.path.dirname(here), capture_output=True, text=True,
                               timeout=5).stdout
        return commit + ("+dirty" if dirty.strip() else "") if commit else "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def environment() -> dict:
    """What a reader needs to judge the numbers: CPU, compiler, flags, versions, commit."""
    import numpy

    return {
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "os": platform.platform(),
        "python": sys.version.split()[0],
        "numpy": numpy.__version__,
        "compiler": sysconfig.get_config_var("CC") or "unknown",
        "cflags": "-O3 -std=c99 (setup.py); HFTRACE_DEBUG/HFTRACE_SANITIZE builds differ",
        "debug_build": os.environ.get("HFTRACE_DEBUG") == "1"
        or os.environ.get("HFTRACE_SANITIZE") == "1",
        "git_commit": _git_commit(),
        "threads": 1,
        **_embree_info(),
    }


def _embree_info() -> dict:
    """The peer's versions and its scene flag (benchmarks time the non-robust scene)."""
    try:
        import importlib.metadata

        from algos.peers.embree import ROBUST, embree_version

        return {"embreex": importlib.metadata.version("embreex"), "embree": embree_version(),
                "embree_robust": ROBUST,
                "embree_query": "DISTANCE (tfar only), far bound per ray, buffers preallocated"}
    except Exception as exc:  # the peer is optional for the report
        return {"embreex": f"unavailable ({exc.__class__.__name__})"}


def write_json(path, data) -> None:
    """Write ``data`` as indented, key-sorted JSON to ``path`` atomically (a temporary file
    renamed over it), so a reader never sees half a file."""
    tmp = f"{path}.tmp"
    with open(tmp, "w") as f:
        json.dump(data, f, indent=2, sort_keys=True)
        f.write("\n")
    os.replace(tmp, path)

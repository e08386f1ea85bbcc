"""``hftrace terrain-bench``, part "every azimuth fast": the horizon at RVT's 16
equally spaced azimuths on Jacksboro (unlimited distance, one thread), per azimuth class
and path, with the walk's counts; and the sky-view factor at short and long radii against
RVT (rvt-py's own vectorised code when it imports) and against a NumPy baseline of RVT's
method, side by side in one process, one thread.

Regime: single thread (``threads=1``; the CLI also pins the process to one CPU), every
contender run in the same process, interleaved, median of ``repeats``. RVT's SVF is not
the same quantity to the last digit: it samples the DEM at integer-rounded pixels along
each direction (3 samples per pixel of radius) and takes their largest slope, where
hftrace takes the supremum over the two-triangle surface. The comparison is of time at
the same task size (directions, radius, DEM), not of values.
"""
from __future__ import annotations

import math
import time

import numpy as np

import algos.terrain as T
import datasets_gen

__all__ = ["run_azimuths", "numpy_rvt_svf", "rvt_svf", "SIXTEEN"]

#: RVT's default directions: 0, 22.5, ..., 337.5 degrees
SIXTEEN = tuple(22.5 * k for k in range(16))
#: the sky-view factor radii (pixels) of the comparison: short and long
RADII = (10, 100)


# ---- the peers ---------------------------------------------------------------------------

def numpy_rvt_svf(h, n_directions=16, radius=10):
    """RVT's sky-view factor method, written here in vectorised NumPy (the baseline when
    rvt-py is absent): along each of ``n_directions`` directions, the DEM is sampled at the
    integer-rounded offsets of radii 1, 1 + 1/3, ..., ``radius`` pixels (each offset once),
    the largest slope (dz / offset length) is kept, and SVF = 1 - mean sin(max(atan, 0)).
    Edges are padded by reflection, as RVT does. (rows, cols) float64 in, same out."""
    h = np.asarray(h, dtype=np.float64)
    rows, cols = h.shape
    pad = np.pad(h, radius, mode="reflect")
    radii = 1.0 + np.arange(3 * (radius - 1) + 1) / 3.0
    total = np.zeros_like(h)
    for k in range(n_directions):
        angle = 2.0 * math.pi * k / n_directions
        offsets = sorted({(int(round(math.cos(angle) * r)), int(round(math.sin(angle) * r)))
                          for r in radii} - {(0, 0)}, key=lambda o: math.hypot(*o))
        best = np.full_like(h, -np.inf)
        for ox, oy in offsets:
            shifted = pad[radius + oy:radius + oy + rows, radius + ox:radius + ox + cols]
            np.maximum(best, (shifted - h) / math.hypot(ox, oy), out=best)
        total += np.sin(np.maximum(np.arctan(best), 0.0))
    return 1.0 - total / n_directions


def rvt_svf():
    """rvt-py's ``sky_view_factor_compute`` as ``f(h, n_directions, radius)``, or None when
    it does not import (the Makefile's peers step installs it: ``pip install --no-deps rvt-py``)."""
    try:
        import rvt.vis
    except Exception:  # ImportError, or a missing dependency of rvt-py itself
        return None

    def run(h, n_directions=16, radius=10):
        return rvt.vis.sky_view_factor_compute(h, radius_max=radius, num_directions=n_directions)
    return run


# ---- the study ---------------------------------------------------------------------------

def _timed(call):
    t0 = time.perf_counter()
    value = call()
    return time.perf_counter() - t0, value


def _horizon_section(size, repeats, baseline, echo):
    """The 16 azimuths on Jacksboro at ``size``: lines and CSV rows."""
    hf = datasets_gen.load("jacksboro", size=size)
    rows, cols = hf.heights.shape
    n = rows * cols
    walls = [_timed(lambda: T.horizon(hf, SIXTEEN, threads=1))[0] for _ in range(repeats)]
    wall = float(np.median(walls))
    echo(f"    16 azimuths: {wall:.2f} s")
    csv_rows = [dict(workload="horizon16", dataset=f"jacksboro{size}", algorithm="default",
                     azimuth="all", field_seconds=wall, vertices=n)]
    lines = [f"## Horizon at RVT's 16 azimuths, Jacksboro {rows} x {cols}, unlimited distance, "
             "one thread", "",
             f"`algos.horizon(field, [0, 22.5, ..., 337.5], threads=1)` (default paths): "
             f"**{wall:.2f} s** wall-clock (median of {repeats}), frames and output included. "
             "Target: <= 20 s. Exact at the given azimuths.", "",
             "`chain` skips along strips parallel to the direction (docs/terrain.md): its "
             "skips are stretches of strip, its tests strip bins, and it steps past cells by "
             "their highest corner.", "",
             "| azimuth | path | seconds | ns per vertex | cells / vertex | skips / vertex "
             "| tests / vertex | cells stepped past / vertex | vertices with a borrowed bound |",
             "|---|---|---|---|---|---|---|---|---|"]
    by_class = {"rational": 0.0, "irrational": 0.0}
    for az in SIXTEEN:
        seconds, (_, s) = _timed(lambda: T.horizon(hf, az, threads=1, return_stats=True))
        cls = "rational" if T.azimuth_direction(az).rational is not None else "irrational"
        by_class[cls] += seconds
        lines.append(f"| {az:g} | `{s.algorithm}` | {seconds:.2f} | {1e9 * seconds / n:.0f} | "
                     f"{s.cells / n:.1f} | {s.skips / n:.1f} | {s.tile_tests / n:.1f} | "
                     f"{s.cell_skips / n:.1f} | {100 * s.bounded / n:.1f} % |")
        csv_rows.append(dict(workload="horizon16", dataset=f"jacksboro{size}", algorithm=s.algorithm,
                             azimuth=az, field_seconds=seconds, vertices=n,
                             cells_per_vertex=s.cells / n, skips_per_vertex=s.skips / n,
                             tile_tests_per_vertex=s.tile_tests / n,
                             cell_skips_per_vertex=s.cell_skips / n))
    lines += ["", f"By class (one azimuth at a time): rational (0, 45, ...: the sweep) "
              f"{by_class['rational']:.2f} s; irrational (22.5 + k 45: the chain walk) "
              f"{by_class['irrational']:.2f} s.", ""]
    if baseline:  # the path the irrational azimuths took before: one of them
        seconds, (_, s) = _timed(lambda: T.horizon(hf, 22.5, algorithm="dda_maxmip", threads=1,
                                                   return_stats=True))
        lines += [f"Before (`dda_maxmip`, the previous default for irrational azimuths) at 22.5: "
                  f"{seconds:.2f} s, {s.cells / n:.1f} cells and {s.skips / n:.1f} skipped tiles "
                  "per vertex.", ""]
        csv_rows.append(dict(workload="horizon16", dataset=f"jacksboro{size}",
                             algorithm="dda_maxmip", azimuth=22.5, field_seconds=seconds,
                             vertices=n, cells_per_vertex=s.cells / n,
                             skips_per_vertex=s.skips / n))
    lines += ["Snapping, explicit (`snap_denominator=N`): every azimuth moved to a rational "
              "direction, the sweep for all 16.", "",
              "| snap_denominator | seconds | largest change (deg) |", "|---|---|---|"]
    for q in (5, 12):
        seconds, (_, s) = _timed(lambda: T.horizon(hf, SIXTEEN, threads=1, snap_denominator=q,
                                                   return_stats=True))
        lines.append(f"| {q} | {seconds:.2f} | {s.snap_max_change_deg:.3f} |")
        csv_rows.append(dict(workload="horizon16_snapped", dataset=f"jacksboro{size}",
                             algorithm=s.algorithm, azimuth=f"snap{q}",
                             field_seconds=seconds, vertices=n))
    return lines + [""], csv_rows


def _svf_section(svf_size, radii, repeats, echo):
    """hftrace's SVF against RVT and the NumPy baseline at each radius: lines, CSV rows."""
    h = np.ascontiguousarray(datasets_gen.load("fbm", size=svf_size, seed=1).heights,
                             dtype=np.float64)
    peers = {"hftrace": lambda r: T.sky_view_factor(h, 16, float(r), threads=1, return_stats=True)}
    rvt = rvt_svf()
    if rvt is not None:
        peers["rvt-py"] = lambda r: rvt(h, 16, r)
    peers["numpy (RVT's method)"] = lambda r: numpy_rvt_svf(h, 16, r)
    lines = [f"## Sky-view factor, 16 directions, fBm {h.shape[0]} x {h.shape[1]} (seed 1), "
             "one thread, same process", "",
             "RVT samples the DEM at integer-rounded pixels along each direction and keeps the "
             "largest slope; hftrace takes the exact supremum over the two-triangle surface. "
             "The values differ by construction: this compares time at the same task size.",
             "" if rvt is not None else "rvt-py does not import here (the Makefile's peers step): the "
             "NumPy baseline of its method stands in.", "",
             "| radius (pixels) | " + " | ".join(f"{p} (s)" for p in peers)
             + " | hftrace path | hftrace vs RVT |", "|---" * (len(peers) + 3) + "|"]
    csv_rows = []
    for r in radii:
        times = {p: [] for p in peers}
        for _ in range(repeats):  # interleaved
            for p, call in peers.items():
                seconds, value = _timed(lambda: call(r))
                times[p].append(seconds)
                if p == "hftrace":
                    path = value[1].algorithm
        med = {p: float(np.median(v)) for p, v in times.items()}
        peer = "rvt-py" if "rvt-py" in med else "numpy (RVT's method)"
        ratio = med[peer] / med["hftrace"]
        echo(f"    svf radius {r}: hftrace {med['hftrace']:.3f} s, {peer} {med[peer]:.3f} s")
        lines.append(f"| {r} | " + " | ".join(f"{med[p]:.3f}" for p in peers)
                     + f" | `{path}` | **{ratio:.1f}x** ({peer}) |")
        for p in peers:
            csv_rows.append(dict(workload=f"svf16_r{r}", dataset=f"fbm{h.shape[0]}",
                                 algorithm=p, field_seconds=med[p], vertices=h.size,
                                 azimuth="16"))
    return lines + ["", "Target: hftrace >= 3x RVT at both radii."], csv_rows


def run_azimuths(size=2048, svf_size=512, radii=RADII, repeats=3, baseline=True, echo=print):
    """The section's markdown lines and CSV rows (module docstring). ``baseline``: also time
    the previous path (``dda_maxmip``) on one irrational azimuth."""
    import os

    echo(f"  every azimuth fast: jacksboro {size}, svf {svf_size}^2")
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    lines = ["# Every azimuth fast", "",
             f"Load average at the start: {load[0]:.2f}, {load[1]:.2f}, {load[2]:.2f} "
             "(timings on a loaded machine are indicative only). Command: "
             "`hftrace terrain-bench` (or `--quick` for the small tier).", ""]
    hz_lines, hz_rows = _horizon_section(size, repeats, baseline, echo)
    svf_lines, svf_rows = _svf_section(svf_size, radii, repeats, echo)
    return lines + hz_lines + svf_lines, hz_rows + svf_rows

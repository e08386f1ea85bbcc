"""Parallel rays at work, the shared pieces: terrain products timed against each other and
against the peers, group by group.

Two studies use them: ``bench.studies.parallel_rays`` (the "parallel rays" part of
``hftrace reproduce``) and ``bench.studies.terrain_targets`` (``hftrace terrain-bench``).

Method: single thread, pinned CPU, interleaved repeats with flushed caches
(``bench.timing.interleaved``), C clocks around the kernels. Per-vertex methods too slow for
every vertex of a big field run on a sample of evenly spread row bands. Their time is
reported per vertex and scaled to the field, and this is stated next to each figure. The
sweep always does every vertex.
"""
from __future__ import annotations

import math

import numpy as np

import algos.terrain as T
from algos.intersect import prepare_timed_intersect
from datasets_gen.rays import orthographic_rays

from ..timing import interleaved

__all__ = ["RUN_LENGTHS", "HORIZON_METHODS", "HIT_METHODS", "PARALLEL_COLUMNS",
           "azimuth_for_run_length", "sample_ranges", "horizon_group",
           "hit_group", "observer_up", "xrspatial_viewshed", "gdal_viewshed", "los_margins"]

RUN_LENGTHS = (1, 2, 5, 25, 100)
HORIZON_METHODS = ("sweep", "pattern", "dda", "dda_maxmip", "march", "embree")
HIT_METHODS = ("dda", "runs", "runs_periodic", "dda_maxmip", "runs_maxmip", "embree")
PARALLEL_COLUMNS = ["workload", "dataset", "run_length", "azimuth", "algorithm", "vertices",
                    "ns_per_vertex", "field_seconds", "speedup_vs_dda", "max_err_deg",
                    "p99_err_deg", "agree_1e9", "ns_samples"]



def azimuth_for_run_length(r) -> float:
    """The azimuth whose octant slope is exactly 1/r (east-south-east; rational (r, 1))."""
    return 90.0 + math.degrees(math.atan2(1, r))


def sample_ranges(rows, cols, n_vertices, bands=32):
    """About n_vertices in ``bands`` contiguous pieces of rows spread evenly down the field,
    each centred in its row (whole rows when a band needs more), as C-order ranges."""
    per = max(1, int(n_vertices) // bands)
    out = []
    for row in np.linspace(0, rows - 1, bands).astype(int):
        length = min(per, (rows - row) * cols)
        start = row * cols + max(0, (cols - length) // 2)
        if out and start < out[-1][1]:
            start = out[-1][1]
        stop = min(start + length, rows * cols)
        if stop > start:
            out.append((start, stop))
    return out


def _err(values, exact):
    ok = np.isfinite(exact) & ~np.isnan(values)
    both_empty = ok & (exact == -np.inf) & (values == -np.inf)
    valid = ok & np.isfinite(values) & np.isfinite(exact)
    a, b = np.arctan(values[valid]), np.arctan(exact[valid])
    diff = np.abs(a - b)
    n = int(ok.sum())
    agree = (np.sum(diff <= 1e-9) + np.sum(both_empty)) / max(n, 1)
    mismatch = int(np.sum(ok & (np.isinf(values) != np.isinf(exact))))
    worst = np.inf if mismatch else (float(np.degrees(diff.max())) if len(diff) else 0.0)
    p99 = float(np.degrees(np.percentile(diff, 99))) if len(diff) else 0.0
    return worst, float(agree), p99


def _samples(values) -> str:
    """Per-repeat ns per vertex, ";"-separated (the intervals of parallel.md's ratios)."""
    return ";".join(f"{v:.4g}" for v in np.asarray(values, dtype=float))


def horizon_group(h, azimuth, methods, sample, repeats, embree_sample=2048):
    """Time every method on one azimuth; rows with ns per vertex and error against the
    sweep (or the plain walk when the azimuth is not rational)."""
    rows, cols = h.shape
    ranges = sample_ranges(rows, cols, sample) if sample and sample < h.size else None
    e_ranges = sample_ranges(rows, cols, embree_sample)
    jobs, values, counts = {}, {}, {}
    for name in methods:
        use = e_ranges if name == "embree" else ranges
        run, vals, n = T.prepare_horizon_timed(h, azimuth, name, ranges=use)
        jobs[name], values[name], counts[name] = run, vals, n
    times = interleaved(jobs, repeats)
    exact_name = "sweep" if "sweep" in methods else "dda"
    exact = values[exact_name]()
    per = {name: float(np.median(times[name])) / counts[name] for name in methods}
    out = []
    for name in methods:
        err, agree, p99 = _err(values[name](), exact)
        out.append(dict(algorithm=name, vertices=counts[name], ns_per_vertex=per[name],
                        field_seconds=per[name] * h.size / 1e9,
                        speedup_vs_dda=per.get("dda", float("nan")) / per[name],
                        max_err_deg=err, p99_err_deg=p99, agree_1e9=agree,
                        ns_samples=_samples(times[name] / counts[name])))
    return out


def hit_group(field, r, methods, n, repeats, seed):
    """Time every method on one batch of orthographic first hits at slope 1/r; rows with
    ns per ray and the fraction of rays agreeing with ``runs`` (1e-4 relative)."""
    h = field.heights
    o, d = orthographic_rays((h.shape[1] - 1, h.shape[0] - 1), r, n, seed, top=field.hmax)
    jobs, hits = {}, {}
    for name in methods:
        jobs[name], hits[name] = prepare_timed_intersect(name, field, o, d, surface="triangles")
    times = interleaved(jobs, repeats)
    ref = hits["runs"]()
    per = {name: float(np.median(times[name])) / n for name in methods}
    out = []
    for name in methods:
        t = hits[name]()
        with np.errstate(invalid="ignore"):
            same = (np.isinf(t) & np.isinf(ref)) | (np.abs(t - ref) <= 1e-4 * (1 + np.abs(ref)))
        out.append(dict(algorithm=name, vertices=n, ns_per_vertex=per[name],
                        field_seconds=float("nan"), speedup_vs_dda=per["dda"] / per[name],
                        max_err_deg=float("nan"), p99_err_deg=float("nan"),
                        agree_1e9=float(np.mean(same)), ns_samples=_samples(times[name] / n)))
    return out



def observer_up(hf, observer):
    """The observer's (x, y) in the north-up array (rows flipped when north is +y)."""
    if hf.north == "+y":
        return observer[0], hf.shape[0] - 1 - observer[1]
    return observer


# ---- peers -------------------------------------------------------------------------------

def xrspatial_viewshed(h, observer, observer_height, target_height=0.0):
    """xarray-spatial's viewshed on the same grid (x = column, y = row, unit spacing), as a
    bool array; None when xarray-spatial is not installed."""
    try:
        import xarray as xr
        from xrspatial import viewshed as xrs_viewshed
    except ImportError:
        return None
    rows, cols = h.shape
    da = xr.DataArray(np.asarray(h, dtype=np.float64), dims=("y", "x"),
                      coords={"y": np.arange(rows, dtype=float), "x": np.arange(cols, dtype=float)})
    out = xrs_viewshed(da, x=float(observer[0]), y=float(observer[1]),
                       observer_elev=float(observer_height), target_elev=float(target_height))
    return np.asarray(out.values) > -1


def gdal_viewshed(h, observer, observer_height, target_height=0.0):
    """GDAL's ViewshedGenerate on the same grid, or None when osgeo does not import."""
    try:
        from osgeo import gdal
    except ImportError:
        return None
    rows, cols = h.shape
    src = gdal.GetDriverByName("MEM").Create("", cols, rows, 1, gdal.GDT_Float64)
    src.SetGeoTransform((0.0, 1.0, 0.0, 0.0, 1.0, 1.0))  # pixel corners: x = col, y = row
    src.GetRasterBand(1).WriteArray(np.asarray(h, float))
    out = gdal.ViewshedGenerate(src.GetRasterBand(1), "MEM", "", [], observer[0] + 0.5,
                                observer[1] + 0.5, observer_height, target_height, 255, 0,
                                0, 0, 0, gdal.GVM_Edge, 0.0)
    return out.GetRasterBand(1).ReadAsArray() == 255


def los_margins(h, observer, z0, targets, target_height=0.0):
    """Float margins max(s - segment) over each target's breakpoints (positive: blocked),
    and the height range of the cell where that maximum is, for the agreement analysis."""
    rows, cols = h.shape
    ox, oy = observer
    margins, ranges = [], []
    for v in targets:
        j, i = divmod(int(v), cols)
        dx, dy = i - ox, j - oy
        ts = [np.arange(1, 1) * 1.0]
        for o, dd, n in ((ox, dx, cols), (oy, dy, rows)):
            if dd:
                k = np.arange(0, n)
                t = (k - o) / dd
                ts.append(t[(t > 0) & (t < 1)])
        if dx != dy:
            k = np.arange(-(rows - 1), cols)
            t = (k - (ox - oy)) / (dx - dy)
            ts.append(t[(t > 0) & (t < 1)])
        t = np.concatenate(ts)
        if len(t) == 0:
            margins.append(-np.inf)
            ranges.append(0.0)
            continue
        x, y = ox + t * dx, oy + t * dy
        ci = np.clip(np.floor(x).astype(int), 0, cols - 2)
        cj = np.clip(np.floor(y).astype(int), 0, rows - 2)
        u, w = x - ci, y - cj
        h00, h10 = h[cj, ci], h[cj, ci + 1]
        h01, h11 = h[cj + 1, ci], h[cj + 1, ci + 1]
        s = np.where(u >= w, h00 + (h10 - h00) * u + (h11 - h10) * w,
                     h00 + (h11 - h01) * u + (h01 - h00) * w)
        zt = h[j, i] + target_height
        m = s - (z0 + (zt - z0) * t)
        k = int(np.argmax(m))
        margins.append(float(m[k]))
        corners = (h00[k], h10[k], h01[k], h11[k])
        ranges.append(float(max(corners) - min(corners)))
    return np.array(margins), np.array(ranges)



"""``algos.intersect``: first hits of rays on a height field, every intersector.

Validation and conversion live here; the C layer (``cext/dispatch/intersect.c``) trusts its inputs.
"""
from __future__ import annotations

import numbers
import time
from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np

from . import _kernels, plugin_calls
from .accel.compact import compact_for
from .accel.cone import cone_for, relaxed_cone_for
from .accel.mipmap import mip_levels
from .field import HeightField, as_field, bound_kind
from .parallel import resolve_threads, run_ranges, split
from .registry import SURFACES, get_intersector
from .traverse import DEFAULT_MAX_DENOMINATOR, MAX_DENOMINATOR
from .validate import check_rays3, check_rising_from_below, check_t

__all__ = ["Hits", "intersect", "HIT_OUTPUTS", "STATS"]

#: Outputs ``intersect`` can compute; each only on request.
HIT_OUTPUTS = ("t", "cell", "normal", "stats")
#: Per-ray statistics, the columns of ``Hits.stats``.
STATS = ("cells_visited", "cells_tested", "runs_visited", "runs_culled", "tiles_skipped")
#: Rays per packet that ``packet_maxmip`` takes (its option ``packet_width``).
PACKET_WIDTHS = (1, 2, 4, 8)


@dataclass
class Hits:
    """First hits of N rays. Fields not asked for are None.

    ``t``: (N,) float64, ``inf`` on a miss. ``cell``: (N, 2) int32 ``(i, j)``,
    ``(-1, -1)`` on a miss. ``normal``: (N, 3) unit normals (up-facing on the surface,
    horizontal and facing the ray on a wall), NaN on a miss. ``stats``: dict of (N,)
    int64 arrays named in :data:`STATS`. ``elapsed_ns``: the C loop's time.
    """

    algorithm: str
    surface: str
    t: np.ndarray | None = None
    cell: np.ndarray | None = None
    normal: np.ndarray | None = None
    stats: dict | None = None
    elapsed_ns: int = 0
    extra: dict = dc_field(default_factory=dict)

    @property
    def hit(self) -> np.ndarray:
        """True where the ray hit (needs ``t``)."""
        if self.t is None:
            raise ValueError("hit: ask for the 't' output")
        return np.isfinite(self.t)


def _plugin_hits(hits, algorithm, fld, o, d, lo, hi, outputs) -> Hits:
    """``intersect`` for a registered plugin: its t and cells, normals where the surface
    is continuous (``algos.plugins``)."""
    plugin = algorithm.plugin
    if "stats" in outputs:
        raise ValueError(f"outputs: kernel {plugin.describe(algorithm.name)} reports no "
                         "per-ray statistics; leave 'stats' out")
    if "normal" in outputs and hits.surface not in ("triangles", "bilinear"):
        raise ValueError(f"outputs: kernel {plugin.describe(algorithm.name)} returns t only, "
                         f"and on {hits.surface!r} (a surface with walls) t does not tell a "
                         "wall from a top: leave 'normal' out, or use triangles or bilinear")
    heights = fld.cell_heights
    start = time.perf_counter_ns()
    t, cell = plugin_calls.first_hits(algorithm.name, heights, o, d, hits.surface, lo, hi)
    hits.elapsed_ns = time.perf_counter_ns() - start
    hits.t = t if "t" in outputs else None
    hits.cell = cell if "cell" in outputs else None
    if "normal" in outputs:
        hits.normal = plugin_calls.surface_normals(heights, hits.surface, o, d, t, cell, lo)
    return hits


def _options(algorithm, given: dict) -> dict:
    known = dict(algorithm.options or {})
    unknown = set(given) - set(known)
    if unknown:
        name = sorted(unknown)[0]
        raise ValueError(f"{name}: not an option of {algorithm.name}; it takes "
                         f"{', '.join(known) or 'no options'}")
    known.update(given)
    for name, value in known.items():
        if name.startswith("cull_"):
            if not isinstance(value, (bool, np.bool_)):
                raise TypeError(f"{name}: expected True or False, got {value!r}")
        elif name == "max_denominator":
            if value is None:
                known[name] = DEFAULT_MAX_DENOMINATOR
            elif isinstance(value, bool) or not isinstance(value, numbers.Integral) or \
                    not 1 <= value <= MAX_DENOMINATOR:
                raise ValueError(f"max_denominator: expected an integer in [1, 2**24], got {value!r}")
        elif name in ("march_steps", "march_refinements", "fine_level"):
            low = 1 if name == "march_steps" else 0
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
        elif name == "packet_width":
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or \
                    value not in PACKET_WIDTHS:
                raise ValueError(f"packet_width: expected one of {PACKET_WIDTHS}, got {value!r}")
        elif name == "march_growth":
            if not (isinstance(value, numbers.Real) and value >= 1):
                raise ValueError(f"march_growth: expected a number >= 1, got {value!r}")
        elif name == "march_first_fraction":
            if not (isinstance(value, numbers.Real) and 0 < value <= 1):
                raise ValueError(f"march_first_fraction: expected a number in (0, 1], got {value!r}")
        elif name == "march_min_step":
            if not (isinstance(value, numbers.Real) and value >= 0):
                raise ValueError(f"march_min_step: expected a number >= 0, got {value!r}")
    return known


def intersect(name, heights, origins, directions, surface="triangles", tmin=None, tmax=None,
              outputs=("t", "cell"), threads=None, **options) -> Hits:
    """First hits of rays ``o + t d`` on the solid ``{z <= s(x, y)}`` of a height field.

    Parameters
    ----------
    name : str
        A name in ``algos.INTERSECTORS``.
    heights : array_like (rows, cols), algos.HeightField or xarray.DataArray
        ``H[j, i]`` is the height at ``(x=i, y=j)`` in cell units; at least 2 x 2, finite.
        Heights are held in float32 (every kernel and the brute force read them so): a
        float64 height is rounded to the nearest float32 (``0.1`` becomes
        ``0.100000001490116``; a relative change below 6e-8), and one beyond float32's
        range is refused. Rays are float64. Pass an :class:`algos.HeightField`
        (``algos.Field`` and ``datasets_gen.HeightField`` are the same class) to build
        acceleration structures once and reuse them; its :attr:`~algos.HeightField.cell_heights`
        are used (heights in a map unit are divided
        by the square pixel size; rectangular pixels and voids are refused). Anything else
        raises TypeError naming ``heights`` and what is accepted.
    origins, directions : array_like, shape (N, 3)
        Rays in (x, y, z); any real dtype and layout. Directions must not be zero: each
        one's largest absolute component lies in ``[2**-400, 2**400]`` (``t`` is in units of
        ``d``), and ``|origins| <= 2**30``; rays outside raise ValueError naming the ray.
    surface : {"flat", "plane3", "triangles", "bilinear"}
    tmin, tmax : None, float or (N,) array
        Default ``[0, inf)``.
    outputs : iterable of {"t", "cell", "normal", "stats"}
        Only these are computed.
    threads : None or int
        Threads to split the rays over (``None``: every core in the process's affinity;
        embreex's peer included). Results are bit-identical for every value.
    **options
        Per-intersector options (see ``algos.INTERSECTOR_REGISTRY[name].options``):
        ``cull_cells``, ``cull_runs`` (switch culling off, for checks),
        ``max_denominator`` (runs_periodic: its walk follows the slope's best rational
        approximation p/q, q <= max_denominator, but its hits stay the caller's ray's,
        exact for every value, a small one only costs more cells: docs/kernels.md, "A
        user's max_denominator in first hits"), ``fine_level`` (the maxmip kernels: the
        floor level whose 2^fine_level tiles are walked cell by cell or run by run; a
        value above the field's top mip level is clamped to it),
        ``packet_width`` (packet_maxmip: 1, 2, 4 or 8 consecutive rays per packet), and the
        marching parameters ``march_steps``, ``march_refinements``, ``march_growth``,
        ``march_first_fraction``, ``march_min_step``.

    Registered plugins (``algos.plugins``) are called on the calling thread. They give
    ``t`` and ``cell`` (a Python kernel's cell is the one holding the hit point, by the
    half-open rule toward the direction of travel), ``normal`` on the continuous surfaces
    (``triangles``, ``bilinear``: the surface's up-facing normal at the hit); ``stats``,
    and a ray range for a Python kernel, are refused with an error naming the kernel.
    The BVH peers (``embree``, ``embree3``) count no cells either: ``stats`` is refused
    for them too (ValueError naming the peer).

    Returns
    -------
    Hits
        The smallest ``t`` in ``[t0, t1]`` with ``z(t) <= s(x(t), y(t))``, where
        ``[t0, t1]`` is ``[tmin, tmax]`` clipped to the box ``[0, cols-1] x
        [0, rows-1]`` (docs/CONVENTIONS.md, "The first hit"); a ray that starts inside the
        solid hits at ``t0``. ``flat`` and ``plane3`` jump at cell borders, so their hits
        can lie on vertical walls.
    """
    algorithm = get_intersector(name)
    if surface not in SURFACES:
        raise ValueError(f"surface: unknown surface {surface!r}; valid surfaces are {', '.join(SURFACES)}")
    if surface not in algorithm.surfaces:
        raise ValueError(f"surface: {name} supports only {', '.join(algorithm.surfaces)}, not {surface!r}")
    if isinstance(outputs, str):
        outputs = (outputs,)
    try:
        outputs = tuple(outputs)
    except TypeError:
        raise TypeError(f"outputs: expected an iterable of {', '.join(HIT_OUTPUTS)}, got "
                        f"{outputs!r}") from None
    for out in outputs:
        if out not in HIT_OUTPUTS:
            raise ValueError(f"outputs: unknown output {out!r}; valid outputs are {', '.join(HIT_OUTPUTS)}")
    opts = _options(algorithm, options)
    fld = as_field(heights)
    o, d = check_rays3(origins, directions)
    n = len(o)
    lo = check_t(tmin, "tmin", n)
    hi = check_t(tmax, "tmax", n)
    check_rising_from_below(d, lo, hi)
    hits = Hits(name, surface)
    nthreads = resolve_threads(threads)
    if algorithm.plugin is not None:
        return _plugin_hits(hits, algorithm, fld, o, d, lo, hi, outputs)

    if algorithm.kind == "peer" and "stats" in outputs:
        # zeros would read as a kernel that visits no cell (found by a new user's trial)
        raise ValueError(f"outputs: {algorithm.name} (a BVH peer) reports no per-ray "
                         "statistics; leave 'stats' out")
    if algorithm.name == "embree3":
        from .peers.embree3 import embree3_hits

        t, cell, normal, elapsed = embree3_hits(fld, o, d, lo, hi, threads=nthreads, **opts)
    elif algorithm.kind == "peer":
        from .peers.embree import embree_hits

        t, cell, normal, elapsed = embree_hits(fld, o, d, lo, hi, threads=nthreads)
    if algorithm.kind == "peer":
        hits.elapsed_ns = elapsed
        hits.t = t if "t" in outputs else None
        hits.cell = cell if "cell" in outputs else None
        hits.normal = normal if "normal" in outputs else None
        return hits

    scale = _subnormal_scale(d)
    asked = outputs
    if scale is not None:
        o, d, lo, hi = _rescaled(scale, o, d, lo, hi)
        outputs = tuple(outputs) + ("t",)  # to tell a hit beyond the float range
    run = prepare_intersect(algorithm, fld, surface, o, d, lo, hi, outputs, opts, nthreads)
    hits.elapsed_ns = run()
    hits.t, hits.cell, hits.normal, stats = run.outputs
    if scale is not None:
        hits.t, hits.cell, hits.normal = _scaled_back(scale, hits.t, hits.cell, hits.normal)
        if "t" not in asked:
            hits.t = None
    if stats is not None:
        hits.stats = {k: stats[:, i].copy() for i, k in enumerate(STATS)}
    return hits


def _subnormal_scale(d):
    """Per ray, the power of two ``k`` (int (n,) array) that makes every nonzero horizontal
    component of ``2**k d`` normal, or None when no ray has a subnormal one.

    The C walks take ``+-DBL_MAX`` for ``1 / d`` where it overflows (``hf_inverse``,
    cext/surfaces/cell_test.h): right for a face the ray starts on (``t = 0``) and for
    faces it never reaches, but a face it does reach, at ``t = offset / |d|`` in the float
    range (an origin outside the box, within 4 cells of its face, moving in with
    ``|dx| < 2**-1022``), came out at ``offset * DBL_MAX``: up to ``2**52`` times too early
    or too late. ``o + t d = o + (t / 2**k) (2**k d)``, and scaling by a power of two is
    exact, so the scaled ray hits at ``t / 2**k``, which is scaled back. ``k <= 52``; the
    rays' largest component stays below ``2**452``."""
    small = np.abs(d[:, :2])
    sub = (small > 0) & (small < np.finfo(np.float64).tiny)
    if not sub.any():
        return None
    k = np.zeros(len(d), np.int64)
    rows = sub.any(axis=1)
    _, e = np.frexp(np.where(sub, small, np.inf).min(axis=1)[rows])  # m = f 2**e, f >= 1/2
    k[rows] = -1021 - e  # f 2**-1021 >= 2**-1022
    return k


def _rescaled(k, o, d, lo, hi):
    """The rays ``o + t (2**k d)`` on ``[tmin, tmax] / 2**k`` (None stays None)."""
    d = np.ldexp(d, k[:, None])
    lo = None if lo is None else np.ldexp(lo, -k)
    hi = None if hi is None else np.ldexp(hi, -k)
    return o, d, lo, hi


def _scaled_back(k, t, cell, normal):
    """The hit records of the rays ``_rescaled`` gave: ``t * 2**k``. A hit whose ``t``
    then passes the float64 range (an origin outside the box entering it with
    ``|dx| = 5e-324`` at ``t = 5e323``) is a miss, as the brute force reports it."""
    hit = np.isfinite(t)
    with np.errstate(over="ignore"):
        t = np.ldexp(t, k)
    lost = hit & ~np.isfinite(t)
    if lost.any():
        if cell is not None:
            cell[lost] = -1
        if normal is not None:
            normal[lost] = np.nan
    return t, cell, normal


class _Prepared:
    """One validated call, ready to run (and re-run, for timing) in C."""

    def __init__(self, algorithm, fld: HeightField, surface, o, d, lo, hi, outputs, opts, threads=1):
        n = len(o)
        self.n, self.threads = n, threads
        self.t = np.empty(n) if "t" in outputs else None
        self.cell = np.empty((n, 2), np.int32) if "cell" in outputs else None
        self.normal = np.empty((n, 3)) if "normal" in outputs else None
        self.stats = np.empty((n, 5), np.int64) if "stats" in outputs else None
        uses = set(algorithm.structures)
        kind = bound_kind(surface)
        lean = (fld.lean and algorithm.name == "runs_maxmip"
                and not opts.get("cull_runs", False))
        if lean:
            # the lean layout: no cell maxima, mipmap levels from fine_level up
            opts = dict(opts, cull_cells=False)
        hmin, hmax = fld.zrange_for(kind)
        # run culling reads the range maxima; built on request even where the registry
        # leaves it off by default (runs_maxmip)
        run_culling = bool(opts.get("cull_runs", False)) and algorithm.traversal in (
            "runs", "runs_f64", "runs_periodic")
        row_max = fld.row_max_for(kind) if run_culling else None
        col_max = fld.col_max_for(kind) if run_culling else None
        fine_level = int(opts.get("fine_level", 0))
        if "mip" in uses:
            levels = mip_levels(fld.rows - 1, fld.cols - 1)
            fine_level = min(fine_level, levels - 1)
            mip = fld.mip_for(kind, from_level=fine_level if lean else 0)
        else:
            mip = None
        cellmax = None if lean else fld.cellmax_for(kind)
        # the cone kernel's structure (algos.accel.cone), passed before the common arguments
        if "cone" in uses:
            self.cone = cone_for(fld, kind)
        elif "cone_relaxed" in uses:
            self.cone = relaxed_cone_for(fld, kind)
        else:
            self.cone = None
        # dda_compact's tree (algos.accel.compact), passed before the common arguments
        self.compact = compact_for(fld, kind) if "compact" in uses else None
        q = int(opts.get("max_denominator") or 0)
        pattern = np.zeros(q + 1, np.int32) if q else None
        march = (int(opts.get("march_steps", 128)), int(opts.get("march_refinements", 16)),
                 float(opts.get("march_growth", 1.02)),
                 float(opts.get("march_first_fraction", 1 / 580)),
                 float(opts.get("march_min_step", 0.0)))
        # the C call: kernel ids, then the field, the rays, the options and the outputs
        # (cext/binding/intersect.c, intersect_args)
        field = (fld.cell_heights, cellmax, hmin, hmax, row_max, col_max, mip)
        options = (int(bool(opts.get("cull_cells", False))), q, pattern, march, fine_level,
                   int(opts.get("packet_width", 4)))
        self.args = (algorithm.kernel_id, SURFACES.index(surface), field, (o, d, lo, hi),
                     options, (self.t, self.cell, self.normal, self.stats))

    def _part(self, a, b):
        """Rays [a, b) in C (views of every per-ray array; a private pattern scratch)."""
        kernel, surface, field, rays, options, outputs = self.args
        rays, outputs = ([None if x is None else x[a:b] for x in group] for group in (rays, outputs))
        pattern = options[2]
        if pattern is not None:
            options = options[:2] + (np.zeros_like(pattern),) + options[3:]
        args = (kernel, surface, field, tuple(rays), options, tuple(outputs))
        try:
            return self._kernel(args)
        except RuntimeError as exc:
            raise RuntimeError(f"{exc} (ray index counted from ray {a})") from None

    def __call__(self) -> int:
        """Trace the batch; the elapsed ns: the C clock on one thread, else the wall time
        of the whole pool."""
        if len(split(self.n, self.threads)) == 1:
            return self._kernel(self.args)
        start = time.perf_counter_ns()
        run_ranges(self.n, self.threads, self._part)
        return time.perf_counter_ns() - start

    def _kernel(self, args) -> int:
        if self.cone is not None:
            return _kernels.intersect_cone(self.cone, *args)
        if self.compact is not None:
            return _kernels.intersect_compact(self.compact, *args)
        return _kernels.intersect(*args)

    @property
    def outputs(self):
        return self.t, self.cell, self.normal, self.stats


def prepare_intersect(algorithm, fld, surface, o, d, lo, hi, outputs, opts, threads=1):
    return _Prepared(algorithm, fld, surface, o, d, lo, hi, outputs, opts, threads)


def prepare_timed_intersect(name, heights, origins, directions, surface="triangles",
                            outputs=("t",), threads=1, **options):
    """Validate once; return ``(run, hits)`` where each ``run()`` traces the batch again
    and returns its elapsed nanoseconds (C clock, or around embreex's loop for the peer;
    the pool's wall time with ``threads`` > 1), and ``hits()`` gives the latest t.
    Acceleration structures are built here, not in ``run``."""
    algorithm = get_intersector(name)
    fld = as_field(heights)
    o, d = check_rays3(origins, directions)
    if algorithm.name == "embree3":
        from .peers.embree3 import embree3_timed

        return embree3_timed(fld, o, d, threads=resolve_threads(threads),
                             **_options(algorithm, options))
    if algorithm.kind == "peer":
        from .peers.embree import embree_timed

        # the peer's fastest documented configuration (algos.peers.embree.embree_timed)
        return embree_timed(fld, o, d, threads=resolve_threads(threads))
    if algorithm.plugin is not None:
        _options(algorithm, options)  # a plugin takes none: an option given is refused
        return plugin_calls.prepare_timed_first_hit(name, fld.cell_heights, o, d, surface)
    if surface not in algorithm.surfaces:
        raise ValueError(f"surface: {name} supports only {', '.join(algorithm.surfaces)}")
    opts = _options(algorithm, options)
    prepared = prepare_intersect(algorithm, fld, surface, o, d, None, None, outputs, opts,
                                 resolve_threads(threads))
    return prepared, lambda: prepared.t

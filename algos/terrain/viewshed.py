"""Viewsheds: which vertices an observer sees, or the heights it takes to see them
(:func:`viewshed`)."""
from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .. import _kernels
from ..accel.mipmap import terrain_mipmap
from ..field import HeightField, is_dask, is_dataarray
from ..georef import WGS84_SEMI_MAJOR_AXIS_M
from ..parallel import resolve_threads
from ..validate import check_length
from .algorithms import VIEWSHED_ALGORITHMS
from .curvature import _NO_UNIT_CURVATURE, DEFAULT_REFRACTION, _check_refraction
from .dataarray import _attr, _to_dataarray
from .grid import _check_surface, _prepare, _run_ranges
from .observers import (
    DEFAULT_OBSERVER_HEIGHT,
    VIEWSHED_MODES,
    VIEWSHED_UINT8_NODATA,
    _height_above,
    _observers,
    _output_value,
    _surface_float,
    _thicken,
    _touches_void,
)
from .reference import line_of_sight_exact, surface_exact
from .stats import TerrainStats, check_return_stats, returned, with_stats
from .tiled import tiled_viewshed

__all__ = ["viewshed"]


def _rounding_scale(h):
    """The field's part of the rounding bound on a line-of-sight gap: a few ulps of the
    heights involved, plus the surface slope times the error of a crossing's position.
    The observer adds |z0| + target_height."""
    rows, cols = h.shape
    grad = float(max(np.abs(np.diff(h, axis=0)).max(), np.abs(np.diff(h, axis=1)).max()))
    return float(np.abs(h).max()) + (grad + 1.0) * (rows + cols)


def _viewshed_one(h, ox, oy, oh, th, drop, algorithm, threads, mip, stats, scale):
    rows, cols = h.shape
    z0 = _surface_float(h, ox, oy) + oh
    out = np.empty(rows * cols, dtype=np.uint8)
    eps = 64 * np.finfo(float).eps * (scale + abs(z0) + abs(th))
    used = mip if algorithm == "dda_maxmip" else None

    def call(start, stop):
        return _kernels.viewshed(h, used, ox, oy, z0, th, drop, eps, start, stop, out)

    for ns, cells, skips in _run_ranges(rows * cols, threads, call):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
    unsure = np.flatnonzero(out == 2)
    if len(unsure):
        hl = h.tolist()
        for v in unsure:
            out[v] = 0 if _seen_exact(hl, ox, oy, oh, th, drop, int(v)) else 1
        stats.exact_resolved += len(unsure)
    return (out == 0).reshape(rows, cols)


def _seen_exact(hl, ox, oy, oh, th, drop, v):
    """Whether vertex v (C order) is visible, in rational arithmetic of the float inputs:
    how :func:`_viewshed_one` settles a vertex the float walk leaves uncertain."""
    j, i = divmod(v, len(hl[0]))
    fx, fy = Fraction(ox), Fraction(oy)
    z0e = surface_exact(hl, fx, fy) + Fraction(oh)
    return line_of_sight_exact(hl, (fx, fy), z0e, (i, j), Fraction(hl[j][i]) + Fraction(th),
                               Fraction(drop))


def _seen_one(h, hl, used, ox, oy, oh, th, drop, scale, v, buf):
    """Visibility of the one vertex v (C order) exactly as :func:`_viewshed_one` decides
    it (the same float walk and margin, the same exact fallback); buf a uint8 scratch of
    rows * cols."""
    z0 = _surface_float(h, ox, oy) + oh
    eps = 64 * np.finfo(float).eps * (scale + abs(z0) + abs(th))
    _kernels.viewshed(h, used, ox, oy, z0, th, drop, eps, v, v + 1, buf)
    if buf[v] != 2:
        return bool(buf[v] == 0)
    return _seen_exact(hl, ox, oy, oh, th, drop, v)


def _smallest_seen(g0, seen):
    """The smallest float64 g >= 0 with ``seen(g)``, searched from the estimate g0 >= 0 in
    steps of one ulp, doubling (seen is monotone: a higher target or eye sees more)."""
    def value(b):
        return float(np.int64(b).view(np.float64))
    top = int(np.float64(np.finfo(np.float64).max).view(np.int64))
    b = int(np.float64(g0).view(np.int64))
    if seen(g0):
        if b == 0 or not seen(value(b - 1)):
            return g0
        hi, step = b - 1, 2
        while True:
            lo = max(hi - step, 0)
            if not seen(value(lo)):
                break
            if lo == 0:
                return 0.0
            hi, step = lo, step * 2
    else:
        lo, step = b, 1
        while True:
            hi = min(lo + step, top)
            if seen(value(hi)):
                break
            if hi == top:
                raise RuntimeError(f"viewshed: no finite height sees the vertex (from {g0!r})")
            lo, step = hi, step * 2
    while hi - lo > 1:  # seen(lo) false, seen(hi) true
        mid = (lo + hi) // 2
        if seen(value(mid)):
            hi = mid
        else:
            lo = mid
    return value(hi)


def _exact_thresholds(out, wanted, h, ox, oy, oh, th, drop, kind, z_scale, algorithm, mip,
                      scale, threads):
    """Round the thresholds ``out`` (field unit, C order flat view) at the ``wanted``
    vertices to the smallest float64 at which :func:`viewshed`'s normal mode, given that
    value as ``target_height`` (kind 0) or ``observer_height`` (kind 1), says visible.
    The float walk's bound is within a few thousand ulps; the zeros are checked in one
    normal-mode pass, the others one vertex at a time (about 2 log2(ulps off) tests)."""
    used = mip if algorithm == "dda_maxmip" else None
    rows, cols = h.shape
    zero = wanted & (out == 0)
    if zero.any():
        stats = TerrainStats(algorithm)
        at0 = _viewshed_one(h, ox, oy, oh if kind == 0 else 0.0, 0.0 if kind == 0 else th,
                            drop, algorithm, threads, used, stats, scale).ravel()
        wanted = wanted & ~(zero & at0)
    todo = np.flatnonzero(wanted)
    if not len(todo):
        return
    hl = h.tolist()
    buf = np.empty(rows * cols, dtype=np.uint8)
    for v in todo:
        v = int(v)
        if kind == 0:
            def seen(g):
                return _seen_one(h, hl, used, ox, oy, oh, g / z_scale, drop, scale, v, buf)
        else:
            def seen(g):
                return _seen_one(h, hl, used, ox, oy, g / z_scale, th, drop, scale, v, buf)
        out[v] = _smallest_seen(float(out[v]), seen)


def _viewshed_threshold(h, ox, oy, z0, th, drop, kind, algorithm, threads, mip, stats):
    """The C walk's bound per vertex (cext/terrain/terrain.h, hf_viewshed_threshold): kind 0 the
    target top, 1 the eye; -inf where nothing lies between observer and vertex."""
    rows, cols = h.shape
    out = np.empty(rows * cols, dtype=np.float64)
    used = mip if algorithm == "dda_maxmip" else None

    def call(start, stop):
        return _kernels.viewshed_threshold(h, used, ox, oy, z0, th, drop, kind, start, stop, out)

    for ns, cells, skips in _run_ranges(rows * cols, threads, call):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
    return out.reshape(rows, cols)


def viewshed(heights, observer, observer_height=None, target_height=0.0, max_distance=None,
             curvature=False, refraction=DEFAULT_REFRACTION, *, algorithm=None,
             surface="triangles", spacing=None, earth_radius=WGS84_SEMI_MAJOR_AXIS_M,
             threads=None, progress=None, mode="normal", visible_value=None,
             invisible_value=None, out_of_range_value=None, exact=False, return_stats=False):
    """Which vertices an observer sees, or what it would take to see them.

    Vertex v is visible when the segment from the eye E = (ox, oy, s(ox, oy) +
    observer_height) to the target top (i, j, H[j, i] + target_height) never passes
    strictly below the surface, and, with ``max_distance``, when v lies within that
    horizontal distance. A line of sight is unchanged by scaling x, y and z, so
    rectangular pixels are exact too.

    The maths of the other modes. Let t in (0, 1) run along the segment, and let
    (t_k, sigma_k) be its breakpoints (package docstring: the surface is linear between
    them), sigma_k lowered by the curvature drop. The gap between segment and surface is
    linear on every piece, so the segment clears the surface exactly when
    z0 + (z1 - z0) t_k >= sigma_k for every k (z0 the eye, z1 the target top, lowered like
    the surface). Raising only the target top, that reads z1 >= z0 + M with
    M = max_k (sigma_k - z0) / t_k, the steepest slope from the eye to a breakpoint; so
    the smallest target height h >= 0 above the ground H(v) (lowered) that is visible is
    ``max(0, z0 + M - H(v))``, and 0 when nothing lies between. Raising only the eye,
    it reads z0 >= N with N = max_k (sigma_k - z1 t_k) / (1 - t_k), so the smallest
    observer height >= 0 that sees the target top is ``max(0, N - s(ox, oy))``. At those
    heights the segment touches the surface, which counts as visible: the set of heights
    that see v is [threshold, inf). The walk computes M and N in float64, so the returned
    threshold is within about 1e-9 (relative to the heights involved) of the exact one,
    on either side: given back as ``target_height`` (``observer_height``) in the normal
    mode, exactly at the threshold, the vertex may be reported invisible. With
    ``exact=True`` the threshold is rounded to the smallest float64 at which the normal
    mode says visible, so the set is exactly [threshold, inf) for the normal mode's test
    (see ``exact``). One C walk per vertex finds M or N, skipping
    max-mipmap tiles that lie below the line the bound found so far defines
    (``cext/terrain/terrain.c``, ``hf_viewshed_threshold``); ``algos.terrain.reference`` holds the
    rational-arithmetic reference and the tests check both against brute force.

    Parameters
    ----------
    heights, spacing, algorithm, surface, threads
        As in :func:`horizon`. A one-row or one-column array is a line: its surface is
        the polyline through its samples, and observers must lie on it (a DataArray of
        that shape is refused: it has no pixel size along its short side). Heights in
        map units are used as given (a line of sight does not change when z is scaled),
        so an exact tie of the stored heights stays one on 30 m pixels; only with
        ``curvature`` are they divided by the pixel size, as :func:`horizon` does.
    observer : (x, y) or (N, 2) array
        Grid coordinates (column, row; fractions allowed) of the stored array, counted the
        same way on every input; a georeferenced field converts map coordinates with
        :meth:`HeightField.map_to_grid`.
    observer_height : float, optional
        The eye above the surface, in the field's unit (default 1.75: metres for a metre
        DEM). Negative puts the eye below the ground, as GDAL and xarray-spatial allow:
        the surface on the ray's first linear piece (the triangle the ray leaves the
        observer through, the peers' "observer's own cell") then does not block, and the
        rest is as above. For heights >= 0 that piece can never block, so the rule is the
        same for every height. Must be left out (None) with ``mode="observer"``, which
        computes it.
    target_height : float
        The target above the surface, in the field's unit. Negative puts the target top
        below the ground; as for the eye, the ray's last linear piece (the target's own
        triangle) then does not block. Must be 0 with ``mode="dem"`` or ``"ground"``,
        which compute it.
    max_distance : float, optional
        Horizontal length in the field's unit; None: unlimited. Vertices beyond it are
        *out of range*.
    curvature : bool
        Lower the surface at map distance d by (1 - refraction) d^2 / (2 R), as GDAL's
        and GRASS's viewsheds do, applied at the breakpoints. Needs a real unit (a raw
        array's spacing, in metres, or a field whose ``unit_metres`` is known) and square
        pixels.
    refraction : float
        The refraction coefficient in [0, 1); default 1/7, as GDAL (``gdal_viewshed``
        ``-cc 0.85714``) and GRASS (``r.viewshed refraction_coeff=0.14286``). Another
        value without ``curvature=True`` raises ValueError (it would be ignored).
    earth_radius : float
        R in metres (default the WGS 84 semi-major axis, as GDAL;
        :data:`algos.georef.WGS84_SEMI_MAJOR_AXIS_M`), converted to the field's unit with
        its ``unit_metres`` (1 for a raw array: spacing in metres).
    progress : callable, optional
        Called as ``progress(done, total)`` after each observer (in memory only).
    mode : {"normal", "dem", "ground", "observer", "angle"}
        What each vertex gets (one observer for every mode but "normal"):

        * ``"normal"``: visibility (GDAL's ``-om NORMAL``);
        * ``"ground"``: the smallest target height >= 0 above the ground at which the
          vertex is visible, in the field's unit (GDAL's ``-om GROUND``);
        * ``"dem"``: that target's elevation, H(v) + the ground value, in the field's
          unit (GDAL's ``-om DEM``);
        * ``"observer"``: the smallest observer height >= 0 above the ground from which
          the target top (with ``target_height``) is visible, in the field's unit:
          xarray-spatial's ``min_observable_height``, exactly rather than by bisection;
        * ``"angle"``: the vertical view angle from the eye to the target top, radians
          above the horizontal, ``atan2(dz, d)`` over map distance d (curvature lowers the
          target); +-pi/2 (0 at equal heights) at a vertex under the eye. The angle does
          not depend on visibility: combine with ``"normal"`` for xarray-spatial's
          output (its angle is ``90 + degrees(angle)``, -1 where invisible).
    visible_value, invisible_value, out_of_range_value : float, optional
        GDAL's ``-vv``, ``-iv`` and ``-ov``. In mode ``"normal"`` (one observer), giving
        any of them returns these values instead of a bool; the others default to 1, 0
        and 0. ``out_of_range_value`` also applies to the other modes (default NaN
        there); the visible and invisible values do not.
    exact : bool
        Modes ``"ground"``, ``"dem"`` and ``"observer"``: round each threshold (in the
        field's unit, the value returned; for ``"dem"`` the ground value, then added to
        H(v)) to the smallest float64 g at which ``viewshed`` in the normal mode, given g
        as ``target_height`` (``observer_height`` for ``"observer"``) and the same other
        arguments, says visible: visible at g and, for g > 0, not at the next float64
        below. The normal mode decides such touching lines of sight in rational
        arithmetic, so this costs several rational walks per vertex with a positive
        threshold (milliseconds each in Python): meant for small fields or windows.
        Ignored by the other modes.
    return_stats : bool
        Also return the call's :class:`~algos.terrain.stats.TerrainStats` (the algorithm,
        C time, cells walked, tiles skipped, vertices settled exactly): ``(result,
        stats)``. Default False. Refused (ValueError) for a dask input.

    Returns
    -------
    ndarray (rows, cols), in the input's orientation
        * ``"normal"``, no values given: bool (one observer; True visible) or uint16
          (the count of observers that see the vertex). A void vertex is False (0): the
          field's ``nodata_mask`` marks it, and writers store it as nodata.
        * ``"normal"`` with values: uint8 when all three values are integers in
          [0, 254], voids 255 (:data:`VIEWSHED_UINT8_NODATA`, the files' nodata;
          a DataArray records it as its nodata, ``rio.nodata`` with rioxarray, else
          the ``_FillValue`` attribute); otherwise float64, voids NaN.
        * other modes: float64, voids NaN, out of range ``out_of_range_value``.

        A DataArray gives a DataArray, with the mode, unit and values as attributes.
        With ``return_stats``, the pair ``(that, TerrainStats)``.

    Raises
    ------
    ValueError
        An observer outside the footprint or on a cell touching a void (its ground
        height is unknown); a mode other than "normal", or output values, with several
        observers or on a dask array (the tiled viewshed gives visibility only); and
        every bad argument, named.

    A dask array (or a HeightField holding one) gives a lazy result chunked like it, with
    one task per observer (its window of ``max_distance``, the whole array when unlimited,
    computed in memory) and one per chunk (:func:`algos.terrain.tiled.tiled_viewshed`); an observer
    on a cell touching a void raises when it is computed.
    """
    if mode not in VIEWSHED_MODES:
        raise ValueError(f"mode: expected one of {', '.join(VIEWSHED_MODES)}, got {mode!r}")
    check_return_stats(return_stats, heights)
    if mode == "observer" and observer_height is not None:
        raise ValueError(f"observer_height: mode='observer' computes the observer height; "
                         f"leave observer_height out (None), got {observer_height!r}")
    values_given = any(v is not None for v in (visible_value, invisible_value,
                                               out_of_range_value))
    if mode != "normal":
        for name, value in (("visible_value", visible_value),
                            ("invisible_value", invisible_value)):
            if value is not None:
                raise ValueError(f"{name}: applies to mode='normal' only (mode={mode!r} "
                                 "gives a number per vertex)")
    if is_dataarray(heights):
        if heights.ndim == 2 and min(heights.shape) == 1:
            raise ValueError(f"heights: a one-row or one-column DataArray {heights.shape} has no "
                             "pixel size along its short side; pass its values "
                             "(np.asarray(heights)) with spacing=(dx, dy)")
        unit = {"normal": "1 visible, 0 not" if np.ndim(observer) == 1
                else "observers that see the vertex", "angle": "radians",
                "ground": "height unit", "dem": "height unit", "observer": "height unit"}[mode]
        if mode == "normal" and values_given:
            unit = "output values"
        if mode in ("ground", "dem", "observer"):
            unit = HeightField.from_dataarray(heights).unit
        shown = DEFAULT_OBSERVER_HEIGHT if observer_height is None and mode != "observer" \
            else observer_height
        attrs = dict(units=unit, mode=mode, observer_height=_attr(shown),
                     target_height=target_height, max_distance=_attr(max_distance),
                     curvature=int(bool(curvature)), refraction=float(refraction))
        for name, value in (("visible_value", visible_value),
                            ("invisible_value", invisible_value),
                            ("out_of_range_value", out_of_range_value)):
            if value is not None:
                attrs[name] = value
        out, stats = _to_dataarray(heights, lambda f: with_stats(
            viewshed, f, observer, observer_height, target_height, max_distance, curvature, refraction,
            algorithm=algorithm, surface=surface, earth_radius=earth_radius, threads=threads,
            mode=mode, visible_value=visible_value, invisible_value=invisible_value,
            out_of_range_value=out_of_range_value, exact=exact), "viewshed", attrs)
        return returned(out, stats, return_stats)
    if is_dask(heights) or (isinstance(heights, HeightField) and is_dask(heights.heights)):
        if mode != "normal" or values_given:
            raise ValueError(f"mode: the tiled (dask) viewshed gives visibility only (mode "
                             f"'normal', no output values), got mode={mode!r}"
                             f"{' with output values' if values_given else ''}; compute "
                             "the observer's window in memory instead")
    if is_dask(heights):
        return tiled_viewshed(viewshed, heights, observer, max_distance, spacing,
                              observer_height=observer_height, target_height=target_height,
                              algorithm=algorithm, surface=surface, curvature=curvature,
                              refraction=refraction, earth_radius=earth_radius,
                              threads=threads)
    _check_surface(surface)
    heights, crop = _thicken(heights, observer)
    # without curvature a line of sight is unchanged by scaling z: the heights stay in
    # their own unit, so that a tie on a DEM with 30 m pixels is the tie it is in cells
    grid = _prepare(heights, spacing, divide=bool(curvature))
    h = grid.h
    given = np.asarray(observer, dtype=np.float64) if np.ndim(observer) else observer
    obs, single = _observers(given, h)
    if not single and (mode != "normal" or values_given):
        raise ValueError(f"observer: mode={mode!r}{' and output values need' if values_given else ' needs'}"
                         f" one observer, got {len(obs)} (several give a count)")
    if grid.field is not None:
        obs = np.column_stack([obs[:, 0], grid.field.north_up_row(obs[:, 1])])
    if grid.void is not None:
        for k, (x, y) in enumerate(obs):
            if _touches_void(grid.void, x, y):
                raise ValueError(f"observer[{k}]: ({np.atleast_2d(given)[k][0]:g}, "
                                 f"{np.atleast_2d(given)[k][1]:g}) stands on a cell touching a "
                                 "void (nodata) vertex: its ground height is unknown")
    oh = _height_above(DEFAULT_OBSERVER_HEIGHT if observer_height is None else observer_height,
                       "observer_height") / grid.z_scale
    th = _height_above(target_height, "target_height") / grid.z_scale
    if mode in ("dem", "ground") and th != 0:
        raise ValueError(f"target_height: mode={mode!r} computes the target height; leave "
                         f"target_height at 0, got {target_height!r}")
    md = check_length(max_distance, "max_distance")
    if not isinstance(exact, (bool, np.bool_)):
        raise TypeError(f"exact: expected a bool, got {exact!r}")
    if not isinstance(curvature, (bool, np.bool_)):
        raise TypeError(f"curvature: expected a bool, got {curvature!r}")
    r = _check_refraction(curvature, refraction)
    drop = 0.0
    if curvature:
        if not grid.has_unit:
            raise ValueError(_NO_UNIT_CURVATURE)
        if not grid.square:
            raise ValueError(f"curvature: needs square pixels, got {grid.dx:g} x {grid.dy:g}; "
                             "resample first (e.g. gdalwarp -tr D D)")
        radius = float(earth_radius)
        if not (math.isfinite(radius) and radius > 0):
            raise ValueError(f"earth_radius: expected a positive length, got {earth_radius!r}")
        radius /= grid.unit_metres
        drop = (1.0 - r) / (2.0 * radius / grid.dx)
    if mode == "normal":
        vv = 1.0 if visible_value is None else _output_value(visible_value, "visible_value")
        iv = 0.0 if invisible_value is None else _output_value(invisible_value, "invisible_value")
        ov = 0.0 if out_of_range_value is None else _output_value(out_of_range_value,
                                                                   "out_of_range_value")
    else:
        ov = math.nan if out_of_range_value is None else _output_value(
            out_of_range_value, "out_of_range_value", allow_nan=True)
    if algorithm is None or algorithm == "auto":
        algorithm = "dda_maxmip"
    if algorithm not in VIEWSHED_ALGORITHMS:
        raise ValueError(f"algorithm: expected one of {sorted(VIEWSHED_ALGORITHMS)} or 'auto', "
                         f"got {algorithm!r}")
    nthreads = resolve_threads(threads)
    stats = TerrainStats(algorithm)
    mip = terrain_mipmap(h) if algorithm == "dda_maxmip" and mode not in ("angle",) else None
    jj, ii = np.mgrid[0:h.shape[0], 0:h.shape[1]]

    def in_range(ox, oy):
        if md is None:
            return np.ones(h.shape, dtype=bool)
        if grid.square:
            mdc = md / grid.dx
            return (ii - ox) ** 2 + (jj - oy) ** 2 <= mdc * mdc
        return ((ii - ox) * grid.dx) ** 2 + ((jj - oy) * grid.dy) ** 2 <= md * md

    if mode != "normal":
        ox, oy = (float(v) for v in obs[0])
        ground = _surface_float(h, ox, oy)
        z0 = ground + oh
        sink = drop * ((ii - ox) ** 2 + (jj - oy) ** 2)  # the drop at each vertex, cells
        with np.errstate(invalid="ignore"):
            if mode in ("dem", "ground"):
                m = _viewshed_threshold(h, ox, oy, z0, 0.0, drop, 0, algorithm, nthreads, mip,
                                        stats)
                need = np.maximum(0.0, z0 + m - (h - sink))  # -inf: nothing between, 0
                out = need if mode == "ground" else h + need
            elif mode == "observer":
                n = _viewshed_threshold(h, ox, oy, z0, th, drop, 1, algorithm, nthreads, mip,
                                        stats)
                out = np.maximum(0.0, n - ground)
            else:
                stats.algorithm = "closed form"  # the angle needs no walk
                dist = np.hypot((ii - ox) * grid.dx, (jj - oy) * grid.dy) / grid.z_scale
                out = np.arctan2(h + th - sink - z0, dist)
        if mode != "angle":
            out = np.ascontiguousarray(out * grid.z_scale)
        within = in_range(ox, oy)
        if mode in ("ground", "dem", "observer") and exact:
            if mode == "dem":
                out = np.ascontiguousarray(need * grid.z_scale)
            wanted = within if grid.void is None else within & ~grid.void
            valid = h if grid.void is None else np.where(grid.void, h[~grid.void].min(), h)
            _exact_thresholds(out.ravel(), wanted.ravel(), h, ox, oy, oh, th, drop,
                              0 if mode != "observer" else 1, grid.z_scale, algorithm, mip,
                              _rounding_scale(valid), nthreads)
            if mode == "dem":
                out = h * grid.z_scale + out
        out = np.where(within, out, ov)
        grid.voids_to(out, math.nan)
        if progress is not None:
            progress(1, 1)
        result = np.ascontiguousarray(grid.to_north_up(out))
        return returned(result if crop is None else np.ascontiguousarray(result[crop]), stats,
                        return_stats)
    count = np.zeros(h.shape, dtype=np.uint16)
    valid = h if grid.void is None else np.where(grid.void, h[~grid.void].min(), h)
    scale = _rounding_scale(valid)
    for k, (ox, oy) in enumerate(obs):
        seen = _viewshed_one(h, float(ox), float(oy), oh, th, drop, algorithm, nthreads, mip,
                             stats, scale)
        within = in_range(ox, oy)
        if values_given:
            values = np.where(within, np.where(seen, vv, iv), ov)
        seen &= within
        count += seen
        if progress is not None:
            progress(k + 1, len(obs))
    grid.voids_to(count, 0)
    if values_given:
        small = all(v == int(v) and 0 <= v < VIEWSHED_UINT8_NODATA for v in (vv, iv, ov))
        result = values.astype(np.uint8) if small else values
        grid.voids_to(result, VIEWSHED_UINT8_NODATA if small else math.nan)
    else:
        result = count.astype(bool) if single else count
    result = np.ascontiguousarray(grid.to_north_up(result))
    return returned(result if crop is None else np.ascontiguousarray(result[crop]), stats,
                    return_stats)

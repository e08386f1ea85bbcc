"""Rasterisers of a height field, the seeds' other road, and image comparison.

The tracers answer "what does this pixel's ray hit first?"; a rasteriser answers "which
pixels does this cell cover?". Five rasterisers run in C (``cext/raster/raster.c``,
``cext/raster/watkins.c``, ``cext/raster/warnock.c``; docs/rendering.md explains each on a height field):

``zbuffer``
    Scan conversion of the field's two triangles per cell (the split of CONVENTIONS
    "triangles", Embree's vertices) with a depth buffer, as in the Portuguese lecture:
    trapezoids with horizontal edges, edge trackers with the sub-pixel start, depth
    advanced by a constant increment along each span. The depth interpolated is 1/w (w the
    distance along the viewing direction), which is affine in screen space, so it is
    perspective-correct: at a pixel centre the depth equals the first hit of that pixel's
    primary ray up to rounding. Top-left fill rule: no cracks, no double hits. Cells whose
    four corners lie outside one plane of the view frustum are culled.
``painter``
    The reverse painter of the Czech visibility chapter: cells in wavefronts of growing
    Manhattan distance from the camera's cell (a front-to-back order read off the grid, no
    sorting), each drawn through a coverage mask; it stops when the mask is full. Same
    triangles, same fill rule, so it draws the image ``zbuffer`` draws.
``floating_horizon``
    The chapter's algorithm for surfaces z = F(x, y), shaded column form: each image
    column marches front to back over the field in steps of ``step`` cells and draws only
    above its current horizon. Approximate by design (see :func:`render`).
``watkins``
    The chapter's scanline algorithm (Watkins 1970): per image row an active list of the
    projected triangles crossing it; their edge crossings, sorted, cut the row into spans
    over which the covering triangles do not change, and one depth decision per span picks
    the visible one (the triangles of a height field never pass through each other, so the
    depth order inside a span is fixed).
``warnock``
    The chapter's area subdivision (Warnock 1969): a screen region is classified against
    the projected bounds of a min-max mipmap's tiles (Tevs et al. 2008) as empty, hidden
    behind a surrounding triangle, simple enough to draw (a few cells, or at most 16 x 16
    pixels: a depth test per pixel centre) or too complex, then split in four; tiles larger than
    the region are replaced by their children, so the tile hierarchy follows the regions.

``zbuffer``, ``painter``, ``watkins`` and ``warnock`` are exact (:data:`EXACT_RASTERISERS`).
All of them draw the box's side faces below the surface ("skirts") where the camera sees
them, because the tracers report a ray that enters the footprint below the surface as a
hit on that wall (CONVENTIONS "The first hit").

The camera is the pinhole of :mod:`algos.camera` (``position``, ``look_at``, horizontal
``fov`` in degrees, ``up = +z``, so never rolled; a vertical view takes the frame of a
camera heading north), shared with ``datasets_gen.rays.pinhole`` and :func:`algos.render`,
and the images are those of ``hftrace render``: ``t`` is the ray parameter of the pixel's unit
direction (a distance), ``cell`` the hit cell, ``normal`` the unit normal.
"""
from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass, field

import numpy as np

from . import _kernels
from .camera import MAX_COORDINATE, pinhole_frame, primary_directions
from .field import as_field
from .parallel import resolve_threads, run_ranges, split

__all__ = ["RASTERISERS", "EXACT_RASTERISERS", "Image", "pinhole_frame", "render",
           "hidden_lines", "trace", "diff_images", "COUNTS", "MAX_COORDINATE", "fuzz_one"]

#: the rasterisers
RASTERISERS = ("zbuffer", "painter", "floating_horizon", "watkins", "warnock")
#: the exact ones: the same pixels as an exact tracer (see :func:`render`)
EXACT_RASTERISERS = ("zbuffer", "painter", "watkins", "warnock")
#: their ids in C (cext/raster/raster.h, enum hf_raster_algorithm)
_C_ID = {"zbuffer": 0, "painter": 1, "floating_horizon": 2, "watkins": 4, "warnock": 5}
#: the C id of the floating horizon's hidden-line drawing (:func:`hidden_lines`)
_HIDDEN_LINES = 3

#: the cost model's counts, in the C order (cext/raster/raster.h, enum hf_raster_count). For
#: ``watkins``: ``cells`` looked at, ``cells_culled`` by the frustum, ``triangles`` in the
#: edge table, ``samples`` the spans decided, ``fragments`` the depths compared to decide
#: them. For ``warnock``: ``cells`` the tile bounds computed (a cell is a tile of level 0),
#: ``cells_culled`` the tiles dropped (outside a region or hidden behind a surrounding
#: triangle), ``cells_drawn`` and ``triangles`` those drawn with a depth test,
#: ``samples`` the regions classified.
COUNTS = ("cells", "cells_culled", "cells_drawn", "triangles", "fragments", "pixels_written",
          "samples", "stopped_full")

#: geometry nearer than this (cells, along the viewing direction) is clipped away
NEAR = 1e-4


@dataclass
class Image:
    """One rendered image, ``(height, width)`` pixels, row 0 at the top.

    Attributes
    ----------
    t : ndarray (height, width) float64
        Ray parameter of the pixel's unit direction at the hit (a distance in cells);
        ``inf`` where nothing is hit.
    cell : ndarray (height, width, 2) int32
        ``(i, j)`` of the hit cell, ``(-1, -1)`` where nothing is hit.
    normal : ndarray (height, width, 3) float64 or None
        Unit normal (up for the surface, horizontal and facing the ray on a wall); NaN
        where nothing is hit.
    counts : dict
        The cost model: for a rasteriser ``COUNTS``; for a tracer the sums of its per-ray
        statistics (``algos.STATS``).
    elapsed_ns : int
        Wall time of the C loop.
    coverage : ndarray (height, width) int32 or None
        ``render(..., coverage=True)`` of ``zbuffer``: front-facing fragments per pixel.
    lines : ndarray (height, width) bool or None
        :func:`hidden_lines`: the drawing; ``t``, ``cell`` and ``normal`` are set on its
        pixels only.
    """

    algorithm: str
    t: np.ndarray
    cell: np.ndarray
    normal: np.ndarray | None
    counts: dict = field(default_factory=dict)
    elapsed_ns: int = 0
    coverage: np.ndarray | None = None
    lines: np.ndarray | None = None


def _surface_at(h: np.ndarray, x: float, y: float) -> float:
    """The triangles surface s(x, y) inside the footprint (CONVENTIONS, Cell surfaces)."""
    rows, cols = h.shape
    i = min(int(math.floor(x)), cols - 2)
    j = min(int(math.floor(y)), rows - 2)
    u, v = x - i, y - j
    h00, h10 = float(h[j, i]), float(h[j, i + 1])
    h01, h11 = float(h[j + 1, i]), float(h[j + 1, i + 1])
    if u >= v:
        return h00 + (h10 - h00) * u + (h11 - h10) * v
    return h00 + (h11 - h01) * u + (h01 - h00) * v


#: The narrowest field of view the rasterisers take, degrees. Narrower, the projection's
#: scale (half the image over tan(fov / 2)) times the field's coordinates leaves the
#: floating range, and a z-buffer drawn at fov 1e-300 picked a farther cell than the
#: exact trace (the fuzzer's find); at 1e-30 it still agreed. The ray tracers take any
#: fov in (0, 180).
MIN_RASTER_FOV = 1e-9


def _setup(heights, position, look_at, fov, width, height):
    """The field, the camera (see :func:`pinhole_frame`) and the skirts' lower edge,
    validated: a camera at or below the surface inside the footprint, and a field of view
    narrower than :data:`MIN_RASTER_FOV`, are refused."""
    fld = as_field(heights)
    h = fld.cell_heights  # cell units; refuses rectangular pixels and voids
    frame, sx, sy = pinhole_frame(position, look_at, fov, width, height)
    if float(fov) < MIN_RASTER_FOV:
        raise ValueError(f"fov: the rasterisers need at least {MIN_RASTER_FOV:g} degrees (a "
                         f"narrower view's projection leaves the floating range), got {fov}")
    px, py, pz = (float(v) for v in frame[:3])
    rows, cols = h.shape
    if 0 <= px <= cols - 1 and 0 <= py <= rows - 1 and not pz > _surface_at(h, px, py):
        raise ValueError(f"position: ({px}, {py}, {pz}) is at or below the surface "
                         f"({_surface_at(h, px, py)}); every ray would hit at t = 0")
    # the skirts reach far enough down that the rays they miss lie within about 1e-6 rad
    # of the vertical vanishing point
    reach = (rows + cols) + abs(pz - fld.hmin) + abs(px) + abs(py) + 1.0
    z_bottom = fld.hmin - 1e6 * reach
    return fld, frame, sx, sy, z_bottom


def render(algorithm, heights, position, look_at, fov, width, height, *,
           outputs=("t", "cell", "normal"), step=0.5, coverage=False, threads=1) -> Image:
    """An image of the ``triangles`` surface by a rasteriser.

    Parameters
    ----------
    algorithm : {"zbuffer", "painter", "floating_horizon", "watkins", "warnock"}
    heights : array_like (rows, cols) or algos.Field
        ``H[j, i]`` is the height at ``(x=i, y=j)``, in cell units; at least 2 x 2, finite.
        A HeightField is drawn from its ``cell_heights`` (heights in the pixel size's unit
        divided by the square pixel size; rectangular pixels and voids raise ValueError).
    position, look_at : array_like (3,)
        The pinhole camera, in cells; ``up`` is ``+z``.
    fov : float
        Horizontal field of view, degrees in (0, 180).
    width, height : int
        Image size in pixels, each in [1, 2^24].
    outputs : iterable of {"t", "cell", "normal"}
        ``t`` and ``cell`` are always computed; ``normal`` only when asked for.
    step : float
        ``floating_horizon`` only: the march step in cells of horizontal distance, in
        [1e-3, 64].
    coverage : bool
        ``zbuffer`` only: also count, per pixel, the front-facing fragments (the
        watertightness check: 1 everywhere a single sheet of surface is in view).
    threads : None or int
        Threads drawing disjoint parts of the image (``None``: every core in the
        process's affinity): ``zbuffer``, ``painter``, ``watkins`` and ``warnock`` one band
        of rows per thread (each band culls and projects the cells again, so the speedup
        is below the thread count), ``floating_horizon`` ranges of columns. The image is bit-identical for
        every value; ``counts`` are summed over the parts and ``elapsed_ns`` is the C
        clock on one part, else the wall time of the pool. Default 1.

    Returns
    -------
    Image
        ``zbuffer``, ``painter``, ``watkins`` and ``warnock`` agree with an exact tracer
        (``algos.intersect`` on ``datasets_gen.rays.pinhole`` rays) on every pixel except
        those whose centre lies within rounding of a projected triangle edge; depths agree
        to rounding. ``watkins`` and ``warnock`` evaluate an edge's position on a row and
        a pixel's depth directly (from the triangle's plane), where the zbuffer steps them
        incrementally, so they agree with the zbuffer on the same terms. ``watkins`` and
        ``warnock`` allocate a table once per call (the triangles holding a pixel centre;
        the min-max mipmap) and raise MemoryError when that fails.
        ``floating_horizon`` is approximate. For a level camera (``look_at`` at the
        height of ``position``) each column is a vertical plane and a pixel's sample lies
        on its own ray's ground track; its depth is then the exact hit's ground distance
        rounded up to the next sample, so
        ``0 <= t - t_exact <= step * |d| / |d_ground|`` wherever the surface along the
        ray is continuous and seen from above, with ``d`` the pixel's direction.
        Silhouettes thinner than a step can be missed. With pitch the column's rays fan
        out and the march follows the ray above the current horizon only: the error grows
        with the pitch (measured on a 65^2 random field, 64x48, fov 60, step 0.25: cells
        differ on 9 % of the pixels at 20 degrees, 40 % at 55), and a view holding the
        vertical (``|pitch|`` plus half the vertical field of view at 90 degrees or more,
        a nadir view included) is refused.

    Raises
    ------
    ValueError
        Unknown algorithm or output; a bad camera (see :func:`pinhole_frame`); a field of
        view narrower than :data:`MIN_RASTER_FOV`; a camera at or below the surface inside
        the footprint (every ray would hit at t = 0);
        ``step`` out of range; ``floating_horizon`` with the vertical in view.
    TypeError
        Non-integer image sizes, a non-numeric height array.
    """
    if algorithm not in RASTERISERS:
        raise ValueError(f"algorithm: unknown rasteriser {algorithm!r}; valid rasterisers are "
                         f"{', '.join(RASTERISERS)}")
    if isinstance(outputs, str):
        outputs = (outputs,)
    for out in outputs:
        if out not in ("t", "cell", "normal"):
            raise ValueError(f"outputs: unknown output {out!r}; valid outputs are t, cell, normal")
    step = float(step)
    if not 1e-3 <= step <= 64:
        raise ValueError(f"step: expected cells in [1e-3, 64], got {step}")
    fld, frame, sx, sy, z_bottom = _setup(heights, position, look_at, fov, width, height)
    if algorithm == "floating_horizon":
        # each column marches along the ground: the vertical must lie outside the view
        pitch = math.degrees(math.asin(min(1.0, abs(float(frame[5])))))
        half_v = math.degrees(math.atan(float(frame[13])))
        if not pitch + half_v < 90:
            raise ValueError(
                f"look_at: floating_horizon needs the straight-down (and straight-up) "
                f"direction outside the view, |pitch| + half the vertical field of view "
                f"below 90 degrees; here {pitch:.6g} + {half_v:.6g}. Steep and nadir views "
                f"render with {', '.join(EXACT_RASTERISERS)}")
    h = fld.cell_heights
    width, height = len(sx), len(sy)
    t = np.empty((height, width), dtype=np.float64)
    cell = np.empty((height, width, 2), dtype=np.int32)
    normal = np.empty((height, width, 3), dtype=np.float64) if "normal" in outputs else None
    cover = (np.empty((height, width), dtype=np.int32)
             if coverage and algorithm == "zbuffer" else None)
    primitive = np.empty((height, width), dtype=np.int64)
    mask = np.empty((height, width), dtype=np.uint8) if algorithm == "painter" else None
    by_columns = algorithm == "floating_horizon"
    kernel_id = _C_ID[algorithm]

    def part(begin, end):
        region = (0, height, begin, end) if by_columns else (begin, end, 0, width)
        counts = np.zeros(len(COUNTS), dtype=np.int64)
        elapsed = _kernels.raster(kernel_id, h, fld.hmin, fld.hmax, frame, sx, sy, NEAR,
                                  z_bottom, step, region, t, cell, normal, cover, primitive,
                                  mask, counts)
        return counts, elapsed

    n_threads = resolve_threads(threads)
    # zbuffer and painter: one band per thread (every band revisits the cells)
    chunks, smallest = (None, 16) if by_columns else (1, 8)
    n = width if by_columns else height
    if len(split(n, n_threads, chunks, smallest)) == 1:
        parts = [part(0, n)]
        elapsed = parts[0][1]
    else:
        start = time.perf_counter_ns()
        parts = run_ranges(n, n_threads, part, chunks, smallest)
        elapsed = time.perf_counter_ns() - start
    counts = sum(p[0] for p in parts)
    if algorithm == "painter":  # stopped full: every band did
        counts[COUNTS.index("stopped_full")] = int(all(p[0][7] for p in parts))
    return Image(algorithm, t, cell, normal, dict(zip(COUNTS, (int(c) for c in counts))),
                 int(elapsed), cover)


def hidden_lines(heights, position, look_at, fov, width, height, *,
                 outputs=("t", "cell", "normal")) -> Image:
    """The floating horizon's hidden-line drawing of the grid (the Czech chapter).

    The row sections ``y = j`` are drawn front to back (in order of distance from the
    camera's y, each side of it separately), zig-zagging through the column segments
    that join consecutive rows; at every image column a segment spans, its point is
    drawn when it lies above the upper or below the lower horizon of the sections drawn
    before (one point per column and segment; a segment reaching behind the near plane
    is left out). Approximate by design: the surface between two sections hides nothing.

    Parameters and errors as :func:`render`. Returns an :class:`Image` whose ``lines``
    marks the drawn pixels; there ``t`` is the ray parameter of the pixel's direction at
    the drawn point's depth and ``cell`` a cell the segment borders (``normal`` that of
    its lower triangle); elsewhere ``t`` is ``inf`` and ``cell`` ``(-1, -1)``.
    """
    if isinstance(outputs, str):
        outputs = (outputs,)
    for out in outputs:
        if out not in ("t", "cell", "normal"):
            raise ValueError(f"outputs: unknown output {out!r}; valid outputs are t, cell, normal")
    fld, frame, sx, sy, z_bottom = _setup(heights, position, look_at, fov, width, height)
    width, height = len(sx), len(sy)
    t = np.empty((height, width), dtype=np.float64)
    cell = np.empty((height, width, 2), dtype=np.int32)
    normal = np.empty((height, width, 3), dtype=np.float64) if "normal" in outputs else None
    primitive = np.empty((height, width), dtype=np.int64)
    lines = np.empty((height, width), dtype=np.uint8)
    counts = np.zeros(len(COUNTS), dtype=np.int64)
    elapsed = _kernels.raster(_HIDDEN_LINES, fld.cell_heights, fld.hmin, fld.hmax, frame, sx, sy,
                              NEAR, z_bottom, 0.5, (0, height, 0, width), t, cell, normal,
                              None, primitive, lines, counts)
    return Image("hidden_lines", t, cell, normal, dict(zip(COUNTS, (int(c) for c in counts))),
                 int(elapsed), None, lines.astype(bool))


def trace(algorithm, heights, position, look_at, fov, width, height, *, threads=None,
          outputs=("t", "cell", "normal")) -> Image:
    """The same image by a tracer: ``algos.intersect(algorithm, ...)`` on the pinhole's
    primary rays (``triangles`` surface), as ``hftrace render`` draws it.

    ``counts`` holds the sums of the per-ray statistics (``algos.STATS``) and ``rays``."""
    from .intersect import intersect

    frame, sx, sy = pinhole_frame(position, look_at, fov, width, height)
    d = primary_directions(frame, sx, sy)
    o = np.broadcast_to(frame[:3], d.shape)
    hits = intersect(algorithm, heights, o, d, surface="triangles",
                     outputs=tuple(outputs) + ("stats",), threads=threads)
    shape = (len(sy), len(sx))
    counts = {k: int(np.sum(v)) for k, v in hits.stats.items()}
    counts["rays"] = int(d.shape[0])
    return Image(algorithm, hits.t.reshape(shape), hits.cell.reshape(shape + (2,)),
                 hits.normal.reshape(shape + (3,)) if "normal" in outputs else None,
                 counts, int(hits.elapsed_ns))


def diff_images(a: Image, b: Image) -> dict:
    """Compare two images of the same view.

    Returns
    -------
    dict
        ``pixels``; ``cell_differs``: the fraction of pixels whose hit cell differs (a
        hit against a miss counts); ``hit_by_one``: pixels hit in one image only;
        ``depth_max_abs``, ``depth_mean_abs``, ``depth_median_abs``, ``depth_max_rel``:
        statistics of ``|t_a - t_b|`` (relative: over ``t_b``) over the pixels hit in both
        (0 when there are none); ``both_hit``: how many those are.

    Raises
    ------
    ValueError
        The images differ in size.
    """
    if a.t.shape != b.t.shape:
        raise ValueError(f"b: image of {b.t.shape[1]} x {b.t.shape[0]} pixels, a is "
                         f"{a.t.shape[1]} x {a.t.shape[0]}")
    pixels = a.t.size
    differs = np.any(a.cell != b.cell, axis=-1)
    hit_a, hit_b = np.isfinite(a.t), np.isfinite(b.t)
    both = hit_a & hit_b
    dz = np.abs(a.t[both] - b.t[both])
    rel = dz / np.maximum(b.t[both], 1e-300)
    return {
        "pixels": int(pixels),
        "cell_differs": float(differs.sum()) / pixels,
        "hit_by_one": int((hit_a != hit_b).sum()),
        "both_hit": int(both.sum()),
        "depth_max_abs": float(dz.max()) if dz.size else 0.0,
        "depth_mean_abs": float(dz.mean()) if dz.size else 0.0,
        "depth_median_abs": float(np.median(dz)) if dz.size else 0.0,
        "depth_max_rel": float(rel.max()) if rel.size else 0.0,
    }


# ---- fuzzing ---------------------------------------------------------------------------

_FUZZ_VALUES = (0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.0, 1e-300, 1e300, 2.0 ** 30, -(2.0 ** 30),
                math.nan, math.inf, -math.inf, 1 / 3, 1e-9, 1 - 2 ** -53)


def fuzz_one(data: bytes) -> None:
    """The fuzz decoder's branch for the rasterisers: turn ``data`` into one call of
    :func:`render` and check its invariants; raise AssertionError on a finding.

    The bytes give the rasteriser (or :func:`hidden_lines`) and its thread count (1 to
    3), a field of up to 9 x 9 samples, a camera (position,
    look_at, fov; doubles from the bytes or from a table of hazards: NaN, infinities,
    zeros, huge and tiny values), an image of up to 17 x 17 pixels and the march step.
    Invariants: the call returns or raises ValueError/TypeError; the heights are unmodified;
    ``t`` is positive or ``inf``; a hit has a cell inside the grid and a unit normal, a
    miss has cell (-1, -1); ``painter``, ``watkins`` and ``warnock`` draw the cells
    ``zbuffer`` draws wherever their depths are not tied within 1e-9 (a pixel centre on a
    projected edge, where the zbuffer's incremental edges may round the other way, is the
    documented exception: there the two cells must border each other).
    """
    pos = 0

    def take(n):
        nonlocal pos
        chunk = data[pos:pos + n].ljust(n, b"\0")
        pos += n
        return chunk

    def number():
        tag = take(1)[0]
        if tag < 32:
            return _FUZZ_VALUES[tag % len(_FUZZ_VALUES)]
        if tag < 232:
            return float(struct.unpack("<h", take(2))[0]) / 16.0
        return struct.unpack("<d", take(8))[0]

    algorithm = (RASTERISERS + ("hidden_lines",))[take(1)[0] % (len(RASTERISERS) + 1)]
    threads = 1 + take(1)[0] % 3
    rows, cols = 2 + take(1)[0] % 8, 2 + take(1)[0] % 8
    heights = np.array([struct.unpack("<b", take(1))[0] / 8.0 for _ in range(rows * cols)],
                       dtype=np.float32).reshape(rows, cols)
    position = [number() for _ in range(3)]
    look_at = [number() for _ in range(3)]
    choice = take(1)[0] % 3  # a hazard, a common field of view, or any in (0, 180)
    fov = number() if choice == 0 else (60.0 if choice == 1 else 0.5 + 0.7 * take(1)[0])
    width, height = 1 + take(1)[0] % 17, 1 + take(1)[0] % 17
    step = [0.5, 0.25, 1.0, 1e-3, 64.0, 0.0][take(1)[0] % 6]
    before = heights.copy()
    try:
        if algorithm == "hidden_lines":
            image = hidden_lines(heights, position, look_at, fov, width, height)
        else:
            image = render(algorithm, heights, position, look_at, fov, width, height, step=step,
                           threads=threads)
    except (ValueError, TypeError):
        assert np.array_equal(heights, before), "render modified the heights"
        return
    assert np.array_equal(heights, before), "render modified the heights"
    hit = np.isfinite(image.t)
    assert not np.isnan(image.t).any() and (image.t[hit] >= 0).all(), "t: NaN or negative"
    ci, cj = image.cell[..., 0], image.cell[..., 1]
    assert ((ci[hit] >= 0) & (ci[hit] < cols - 1) & (cj[hit] >= 0) & (cj[hit] < rows - 1)).all()
    assert (ci[~hit] == -1).all() and (cj[~hit] == -1).all()
    lengths = np.linalg.norm(image.normal[hit], axis=-1)
    assert np.allclose(lengths, 1.0), "normal: not unit"
    if algorithm in ("painter", "watkins", "warnock"):
        other = render("zbuffer", heights, position, look_at, fov, width, height)
        same_cell = np.all(other.cell == image.cell, axis=-1)
        close = np.isclose(other.t, image.t, rtol=1e-9, atol=0) | ~(hit | np.isfinite(other.t))
        if algorithm == "painter":
            assert (same_cell | close).all(), "painter and zbuffer disagree beyond a depth tie"
        else:
            # on a projected edge the two may pick the neighbours on either side of it, or
            # (on a silhouette) a hit and a miss where the hit region's border runs
            both = hit & np.isfinite(other.t)
            step = np.abs(other.cell - image.cell).max(axis=-1)
            border = np.zeros_like(hit)
            for covered in (hit, np.isfinite(other.t)):
                padded = np.pad(covered, 1, mode="edge")
                border |= ((padded[1:-1, 1:-1] != padded[:-2, 1:-1])
                           | (padded[1:-1, 1:-1] != padded[2:, 1:-1])
                           | (padded[1:-1, 1:-1] != padded[1:-1, :-2])
                           | (padded[1:-1, 1:-1] != padded[1:-1, 2:]))
            edge = (both & (step <= 1)) | (~both & border)
            assert (same_cell | close | edge).all(), (
                f"{algorithm} and zbuffer disagree beyond a depth tie or an edge")

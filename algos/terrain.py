"""Terrain products from parallel rays: horizon angles, cast shadows, sky-view factor,
openness and viewsheds, on the two-triangle surface (docs/CONVENTIONS.md, "Terrain
products").

The maths
---------
Along any straight line the two-triangle surface is piecewise linear, with breakpoints
where the line crosses a grid line x = k or y = k or a cell diagonal. At a breakpoint the
surface is the linear interpolation between the two ends of the edge or diagonal crossed.

* **Horizon.** For a vertex v and a horizontal ray from it, the ratio (s(t) - H(v)) / t on
  a linear piece s = a + b t is (a - H(v)) / t + b, monotone in t. Its supremum over a
  piece is therefore at one of the piece's ends. The first piece starts at v itself, where
  s(0) = H(v): there the ratio is the constant b, so the slope limit at t -> 0+ is the
  ratio at the first breakpoint. The horizon tangent is the maximum of the ratio over
  the breakpoints in (0, T], where T is the edge of the footprint or max_distance. The
  value at max_distance interpolates the two breakpoints around it. The angle is atan of
  that maximum, and -pi/2 when there is no breakpoint. Every method evaluates these same
  points in float64, so its angles agree with the exact reference
  (:mod:`algos.terrain_ref`) to rounding (1e-12 in the tests).
* **Shared patterns.** Rays from lattice vertices in one direction are translates of each
  other, so their breakpoints, relative to the start vertex, are the same list: one
  pattern per azimuth serves every vertex (``algorithm="pattern"``).
* **Rational sweep.** For a slope p/q in lowest terms, the line from vertex (i, j) passes
  exactly through (i + q, j + p). The vertices therefore lie on shared lines, and one
  period's breakpoints repeat along each line. Sweeping every line from its far end while
  keeping the upper convex hull of the points passed (Dozier & Frew 1990) gives each
  vertex its horizon as the tangent from it to that hull, in amortised O(1) per point
  (``algorithm="sweep"``; unlimited distance only).
* **Borrowed lower bounds** (``algorithm="chain"``). For a convergent p/q of the octant
  slope, the vertex w = v + (q, p) lies |q b - p a| cells off v's ray (a, b the unit
  octant direction), so w's ray runs alongside v's. The surface point of v's own ray at
  w's occluder distance (plus the distance from v to w along the ray) is a lower bound of
  v's supremum; the max-mipmap walk (Tevs et al. 2008) starts from it, skips every tile
  that cannot beat it, and returns the maximum over v's own breakpoints, as the plain
  walk does. Vertices are taken far-first, in blocks of rows that borrow only within
  themselves, so the result is the same for every thread count.
* **Row-vectorised patterns** (``algorithm="rows"``): the shared pattern in the grid's
  own frame, with the breakpoints outermost and a contiguous row of vertices innermost;
  the same expressions, so the same bits as ``"pattern"``.
* **Line of sight.** The gap between the surface and a straight segment is linear on every
  piece, so the segment passes strictly below the surface if and only if it does at a
  breakpoint. The target vertex itself never counts. Breakpoints within a rounding bound of
  the segment are decided exactly, in rational arithmetic.
* **Viewshed thresholds.** With breakpoints (t_k, sigma_k), t_k in (0, 1), on the segment
  from the eye (height z0) to the target top (z1), the segment clears the surface exactly
  when z0 + (z1 - z0) t_k >= sigma_k for all k. So the smallest target height h >= 0
  above the ground H(v) that is visible is max(0, z0 + M - H(v)) with
  M = max_k (sigma_k - z0) / t_k (the steepest slope from the eye to a breakpoint), and
  the smallest observer height is max(0, N - s(o)) with
  N = max_k (sigma_k - z1 t_k) / (1 - t_k); both are 0 when nothing lies between. At the
  threshold the segment touches the surface, which counts as visible. One walk per
  vertex finds M or N, skipping mipmap tiles below the line the bound so far defines
  (:func:`viewshed`, modes "ground", "dem" and "observer").

Curvature
---------
With ``curvature=True`` a surface point at map distance D from the vertex is lowered by
(1 - refraction) D^2 / (2 R), as GDAL and GRASS lower it. In cell space on square pixels
(x = X / dx, heights z = Z / dx, so D = t dx for the cell distance t) that is kappa t^2
with kappa = (1 - refraction) dx / (2 R), R in the field's unit. The horizon tangent is
then the supremum of g(t) = (s(t) - H(v) - kappa t^2) / t, and on a linear piece
s = a + b t

    g(t) = (a - H(v)) / t + b - kappa t,

which is no longer monotone. When a < H(v) it is concave, with g'(t) = (H(v) - a) / t^2 -
kappa, and peaks at t* = sqrt((H(v) - a) / kappa), where g(t*) = b - 2 sqrt(kappa (H(v) -
a)). So the supremum over a piece is at one of its ends, or at t* when t* lies inside the
piece (when a >= H(v), g is convex or decreasing and the ends suffice). On the first
piece a = H(v) and g = b - kappa t, whose supremum is the slope limit b at t -> 0+, as
without curvature. The exact paths evaluate all three kinds of candidate: every
breakpoint, every piece's interior peak (between consecutive breakpoints, the piece's end
at max_distance included) and the first piece's slope limit, in float64; the exact
reference (:mod:`algos.terrain_ref`) does the same in rational arithmetic, deciding
t0 < t* < t1 exactly through the squares. The peak is computed from the piece's slope as
b - 2 sqrt(kappa (b t0 - r0)) (r0 = s(t0) - H(v)): an error in b moves it by only
(1 - t0 / t*) times that error, so short pieces stay accurate.

Which path runs. The shared pattern and the per-vertex walks ("pattern", "dda",
"dda_maxmip") take kappa and remain exact. The early stop of the pattern and the marcher
and the max-mipmap's tile skips stay valid, since the lowered surface never rises above
the unlowered maximum; a walk that skips a tile visits the tile's exit, so that the next
piece has its start. The marcher ("march", a baseline) lowers each sample. The rational
sweep is not extended: for a line through vertices, with s the position along it and
w = z - kappa s^2, the lowered ratio from O to T at distance d is (w_T - w_O) / d +
2 kappa s_O, so the horizon is a tangent to the upper hull of w, but w is piecewise
concave (not piecewise linear) and its hull is no longer the hull of the breakpoints.
``algorithm=None`` therefore routes curvature to "pattern" (max_distance <= 384 cells) or
"dda_maxmip", and an explicit "sweep" (or the "embree" peer) raises; ``LAST_STATS``
names the path that ran. A negative kappa raises the surface instead (the mirror of a
lowered surface, for negative openness): there is no interior peak (g is convex on every
piece), and the early stop and tile skips are turned off.

Azimuths are degrees clockwise from north, and north is the -y edge (row 0), as in
north-up rasters. An azimuth within 1e-9 degrees of a direction with slope p/q,
q <= :data:`MAX_SNAP_DENOMINATOR`, is taken as exactly that direction by every method.
:func:`rational_azimuths` yields such azimuths, so that the exact sweep applies.

Units
-----
Heights are in the same linear unit as the pixel size ``spacing = (dx, dy)`` (or one
number for square pixels): metres over a metre grid. A raw array without ``spacing`` is
in cell units (``spacing=1``); a :class:`~algos.field.HeightField` or a DataArray carries
its own. ``max_distance``, ``observer_height`` and ``target_height`` are lengths in that
unit; angles come back in radians (``horizon(units="degrees")`` for degrees; openness
defaults to degrees).

The kernels work in cell space: x = X / dx, y = Y / dy, z = Z / dx for map coordinates
(X east, Y along the rows, Z up). On square pixels this is one uniform scale, which
changes no angle. On rectangular pixels, a map azimuth A (map unit direction
e = (sin A, -cos A)) maps to the fixed cell-space direction c = (e_x / dx, e_y / dy) / |.|,
and a point at cell-space distance t along c lies at map distance m t, with the constant
m = hypot(c_x dx, c_y dy). So the map horizon tangent (Z(p) - Z(v)) / (m t) is the
cell-space one (z(p) - z(v)) / t times dx / m, the same constant for every point of the
ray: the supremum is attained at the same breakpoint, and every exact method stays exact
(max_distance D becomes D / m cells). A line of sight is unchanged by scaling x, y and z,
so the viewshed needs only the heights in cells; curvature, which depends on the map
distance, needs square pixels. ``tests/test_georef.py`` checks rectangular pixels against
a brute-force horizon written in map space.

Orientation: a field whose rows run north (a south-up raster, the embedded DEM) is
flipped to north-up by :meth:`HeightField.to_north_up`, the one place that does it, and
every result is flipped back: outputs are on the input's grid and orientation.

Voids
-----
A void vertex (NaN in a raw array, ``nodata_mask`` in a HeightField) is nodata in every
output: NaN in horizons and sky-view factors, False in shadows and single viewsheds, 0 in
viewshed counts, NaN in the viewshed's other modes and 255 in its uint8 output values
(their writers store nodata there: :mod:`datasets_gen.raster`).
For the rays, **a void blocks nothing**: it is an infinitely deep pit. Every point of a
cell touching a void vertex lies below anything a ray could see, except the edges between
two valid vertices, which keep their heights (they belong to the neighbouring valid
cells as well). It is computed as a pit :data:`VOID_HEIGHT` (-1e28 cells) deep, whose
breakpoints lose to every valid one. So no valid vertex that does not touch a void sees
a different value than on the same DEM with the void replaced by a much lower height
(tested), and no void raises what is behind it, unlike a fill. An observer standing on a
cell that touches a void is refused (its ground height is unknown). Filling stays
available and explicit (``HeightField.filled``, ``load_file(nodata_policy=...)``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from . import _kernels
from .field import HeightField, is_dask, is_dataarray, max_mipmap
from .georef import WGS84_SEMI_MAJOR_AXIS_M
from .parallel import resolve_threads, run_ranges
from .terrain_ref import line_of_sight_exact, surface_exact
from .tiled import tiled_product, tiled_viewshed
from .validate import check_length, check_spacing

__all__ = ["horizon", "shadows", "sky_view_factor", "openness", "viewshed",
           "rational_azimuths",
           "azimuth_direction", "HORIZON_ALGORITHMS", "VIEWSHED_ALGORITHMS", "TerrainAlgorithm",
           "MAX_SNAP_DENOMINATOR", "DEFAULT_REFRACTION", "TerrainStats", "Grid",
           "VOID_HEIGHT", "VIEWSHED_MODES", "ANGLE_UNITS", "OPENNESS_KINDS",
           "CURVATURE_REFUSED", "snap_azimuths", "chain_neighbours"]

#: Azimuths this close to a small rational slope are taken as exactly that slope.
MAX_SNAP_DENOMINATOR = 128
SNAP_TOLERANCE_DEG = 1e-9
#: The default refraction coefficient of curvature, as in GDAL and GRASS (1/7).
DEFAULT_REFRACTION = 1.0 / 7.0
#: Breakpoints between early-stop checks in the pattern walk.
PATTERN_STOP_EVERY = 32
#: Heights (in cells) beyond this magnitude are refused: slopes between them stay finite.
HEIGHT_LIMIT = 1e30
#: The default algorithm is "pattern" up to this max_distance (cells), measured.
PATTERN_MAX_DISTANCE = 384
#: The units a horizon angle can be given in (the DataArray attribute ``units``).
ANGLE_UNITS = ("radians", "degrees")
#: Algorithms that refuse curvature, and why.
CURVATURE_REFUSED = {
    "sweep": "the upper hull of the breakpoints misses the peaks inside pieces",
    "rows": "the row-vectorised pattern evaluates breakpoints only",
    "chain": "its borrowed lower bounds and tile skips assume no drop",
    "embree": "the peer traces straight rays over the unlowered mesh",
}


@dataclass(frozen=True)
class TerrainAlgorithm:
    """One way to compute a terrain product.

    exact: agrees with the exact reference to rounding on every input it accepts.
    rational_only: needs every azimuth to snap to a rational slope.
    max_distance: accepts a finite max_distance.
    """

    name: str
    exact: bool
    rational_only: bool
    max_distance: bool
    summary: str
    citation: str = ""


HORIZON_ALGORITHMS: dict[str, TerrainAlgorithm] = {a.name: a for a in (
    TerrainAlgorithm("sweep", True, True, False,
                     "one sweep per line of a rational direction, upper convex hull",
                     "Dozier & Frew 1990"),
    TerrainAlgorithm("pattern", True, False, True,
                     "per-vertex walk over one shared breakpoint pattern per azimuth"),
    TerrainAlgorithm("rows", True, False, True,
                     "one shared breakpoint pattern per azimuth, a row of vertices at a time "
                     "(vectorised)"),
    TerrainAlgorithm("chain", True, False, True,
                     "per-vertex max-mipmap walk started from a lower bound borrowed from a "
                     "vertex further along almost the same line (continued-fraction "
                     "convergents of the slope)", "Tevs et al. 2008"),
    TerrainAlgorithm("dda", True, False, True,
                     "per-vertex cell walk (Amanatides & Woo) over every breakpoint",
                     "Amanatides & Woo 1987"),
    TerrainAlgorithm("dda_maxmip", True, False, True,
                     "per-vertex cell walk that skips max-mipmap tiles below the horizon",
                     "Tevs et al. 2008"),
    TerrainAlgorithm("march", False, False, True,
                     "GRASS r.horizon-style fixed-step marcher (baseline)",
                     "Hofierka & Suri 2002 (r.horizon)"),
    TerrainAlgorithm("embree", False, False, True,
                     "HORAYZON-style: Embree occlusion rays, bisection over elevation (peer)",
                     "Steger et al. 2022 (HORAYZON)"),
)}

VIEWSHED_ALGORITHMS: dict[str, TerrainAlgorithm] = {a.name: a for a in (
    TerrainAlgorithm("dda", True, False, True, "line-of-sight cell walk per target"),
    TerrainAlgorithm("dda_maxmip", True, False, True,
                     "line-of-sight walk per target, skipping mipmap tiles below the segment"),
)}


@dataclass
class TerrainStats:
    """What the last call did: C time, cells evaluated, tiles skipped, vertices resolved
    exactly (viewshed), per algorithm.

    ``algorithm``: the algorithms that ran, distinct, in azimuth order, joined by "+"
    ("sweep+chain"); ``paths``: the algorithm of each azimuth (horizon products).
    ``tile_tests``, ``bounded``: mipmap tiles tested, and vertices that started with a
    borrowed lower bound (``chain``). ``snapped_azimuths``, ``snap_max_change_deg``: the
    azimuths actually used and the largest move, in degrees, when snapping was asked for
    (``snap_denominator``); empty and 0.0 otherwise."""

    algorithm: str = ""
    ns: int = 0
    cells: int = 0
    skips: int = 0
    exact_resolved: int = 0
    paths: tuple = ()
    tile_tests: int = 0
    bounded: int = 0
    snapped_azimuths: tuple = ()
    snap_max_change_deg: float = 0.0


#: Statistics of the most recent product call in this thread of control.
LAST_STATS = TerrainStats()


# ---- inputs --------------------------------------------------------------------------

@dataclass
class Grid:
    """A terrain product's view of its input: the kernels' heights and how map units
    relate to them.

    ``h``: float64 C-contiguous heights in *cell units*, north-up (row 0 north), voids
    replaced by :data:`VOID_HEIGHT`. ``dx, dy``: the pixel size in ``unit``; ``z_scale``:
    map units per cell height unit (``h = heights / z_scale``; ``dx`` unless the heights
    already are in cells). ``has_unit``: lengths are in a real unit (a raw array's
    spacing, taken in metres, or a field's unit with its metres factor
    ``HeightField.unit_metres``), so curvature applies; ``unit_metres``: metres per unit.
    ``void``: north-up bool mask or None.
    ``field``: the HeightField (orientation, georeferencing), or None for a raw array.
    """

    h: np.ndarray
    dx: float
    dy: float
    z_scale: float
    has_unit: bool
    void: np.ndarray | None
    field: object
    unit_metres: float = 1.0

    @property
    def square(self) -> bool:
        return self.dx == self.dy

    def to_north_up(self, array):
        """Stored orientation <-> north-up (the field's own rule; raw arrays are north-up)."""
        return array if self.field is None else self.field.to_north_up(array)

    def cell_azimuth(self, azimuth: float) -> float:
        """The azimuth, in cell space, of the map azimuth ``azimuth`` (degrees): the
        direction (sin A / dx, -cos A / dy). The identity on square pixels."""
        if self.square:
            return azimuth
        a = math.radians(azimuth)
        return math.degrees(math.atan2(math.sin(a) / self.dx, math.cos(a) / self.dy)) % 360.0

    def map_azimuth(self, cell_azimuth: float) -> float:
        """The inverse of :meth:`cell_azimuth`."""
        if self.square:
            return cell_azimuth
        a = math.radians(cell_azimuth)
        return math.degrees(math.atan2(math.sin(a) * self.dx, math.cos(a) * self.dy)) % 360.0

    def stretch(self, d: "Direction") -> float:
        """Map length per unit of cell-space distance along the direction ``d``:
        ``hypot(ux dx, uy dy)`` for the unit cell direction (ux, uy); ``dx`` on square
        pixels."""
        return self.dx if self.square else math.hypot(d.dx * self.dx, d.dy * self.dy)

    def voids_to(self, out, value):
        """Set the void vertices (north-up) of ``out`` (..., rows, cols) to ``value``."""
        if self.void is not None:
            out[..., self.void] = value
        return out


#: What a void vertex becomes in the kernels' heights (cell units): a pit so deep that
#: every point of a cell touching it, except the edges between two valid vertices, lies
#: below anything a ray could see. That is the limit of an infinitely deep pit, to
#: rounding: "a void blocks nothing" (module docstring, "Voids").
VOID_HEIGHT = -1e28
#: Valid heights (cell units) must stay within this when a field has voids.
VOID_HEIGHT_LIMIT = 1e18


def _prepare(heights, spacing, *, name="heights") -> Grid:
    """The :class:`Grid` of a raw array (north-up; ``spacing``: None for cell units, or
    the pixel size in the heights' unit) or of a HeightField (its own spacing, units,
    orientation and voids; ``spacing`` must then be left out or agree)."""
    field = None
    if is_dataarray(heights):
        heights = HeightField.from_dataarray(heights)
    if isinstance(heights, HeightField):
        field = heights
        if spacing is not None and check_spacing(spacing) != (field.dx, field.dy):
            raise ValueError(f"spacing: {spacing!r}, but {field.name} carries its own pixel "
                             f"size ({field.dx:g}, {field.dy:g}) {field.unit}; leave spacing out")
        dx, dy = field.dx, field.dy
        # a real unit (metres per unit known): "cell" and "map unit" are none
        has_unit = field.unit_metres is not None
        z_scale = dx
        divisor = 1.0 if field.height_unit == "cell" else dx
        raw = field.heights
        void = field.nodata_mask
        unit_metres = field.unit_metres if has_unit else 1.0
    else:
        if isinstance(heights, (str, bytes, dict)) or heights is None:
            raise TypeError(f"{name}: expected a 2D array of real numbers, an algos.HeightField "
                            f"or an xarray.DataArray, got {type(heights).__name__}")
        has_unit = spacing is not None
        dx, dy = check_spacing(spacing) if has_unit else (1.0, 1.0)
        z_scale = divisor = dx
        raw = heights
        void = None
        unit_metres = 1.0
    if isinstance(raw, np.ndarray) and raw.dtype.kind not in "fiub":
        raise TypeError(f"{name}: expected a real numeric array, got dtype {raw.dtype}")
    h = np.asarray(raw)
    if h.dtype.kind not in "fiub":
        raise TypeError(f"{name}: expected a real numeric array, got dtype {h.dtype}")
    if h.ndim != 2:
        raise ValueError(f"{name}: expected a 2D array (rows, cols), got shape {h.shape}")
    if h.shape[0] < 2 or h.shape[1] < 2 or max(h.shape) > _kernels.MAX_GRID_SIDE:
        raise ValueError(f"{name}: each side must be in [2, {_kernels.MAX_GRID_SIDE}], got {h.shape}")
    # aligned too: buffers from elsewhere (a Dask worker's deserialised block) need not be
    h = np.require(h, dtype=np.float64, requirements=["C", "A"])
    if divisor != 1.0:
        h = h / divisor
    nan = np.isnan(h)
    if void is None and nan.any():
        void = nan  # a raw array's NaN is a void
    elif void is not None:
        void = np.asarray(void, dtype=bool)
    check = h if void is None else np.where(void, 0.0, h)
    bad = ~np.isfinite(check)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(f"{name}: non-finite value {h[row, col]} at (row {row}, col {col})")
    limit = HEIGHT_LIMIT if void is None else VOID_HEIGHT_LIMIT
    bad = np.abs(check) > limit
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(f"{name}: {h[row, col]} at (row {row}, col {col}) exceeds the "
                         f"documented limit |h| <= {limit:g} cells (differences and slopes "
                         "must not overflow)")
    if void is not None:
        if void.all():
            raise ValueError(f"{name}: every sample is nodata")
        h = np.where(void, VOID_HEIGHT, h)
    if field is not None and not field.north_up:
        h = np.ascontiguousarray(field.to_north_up(h))
        void = None if void is None else np.ascontiguousarray(field.to_north_up(void))
    return Grid(h, dx, dy, z_scale, has_unit, void, field, unit_metres)


def _run_ranges(n, threads, call):
    """call(start, stop) over [0, n) split into contiguous vertex ranges (algos.parallel)."""
    return run_ranges(n, threads, call, chunks_per_thread=4, min_chunk=1024)


# ---- directions ------------------------------------------------------------------------

@dataclass(frozen=True)
class Direction:
    """An azimuth as a unit direction (dx, dy) in grid coordinates, and its octant frame:
    mirror x when sx < 0, mirror y when sy < 0, then swap x and y when swap, which maps it to
    (a, b) with a >= b >= 0. rational: (q, p) when the octant slope is exactly p / q."""

    azimuth: float
    dx: float
    dy: float
    sx: int
    sy: int
    swap: bool
    a: float
    b: float
    rational: tuple[int, int] | None

    @property
    def anti(self) -> bool:
        """In the octant frame, the cells are split on u + v = 1 instead of u = v."""
        return (self.sx < 0) != (self.sy < 0)


def azimuth_direction(azimuth) -> Direction:
    """The :class:`Direction` of an azimuth in degrees (clockwise from north = -y)."""
    try:
        az = float(azimuth)
    except (TypeError, ValueError):
        raise TypeError(f"azimuth: expected a number, got {azimuth!r}") from None
    if not math.isfinite(az):
        raise ValueError(f"azimuth: expected a finite number of degrees, got {azimuth!r}")
    az = az % 360.0
    rad = math.radians(az)
    ux, uy = math.sin(rad), -math.cos(rad)
    ax, ay = abs(ux), abs(uy)
    big, small = max(ax, ay), min(ax, ay)
    rational = None
    frac = Fraction(small / big).limit_denominator(MAX_SNAP_DENOMINATOR)
    q, p = frac.denominator, frac.numerator
    if abs(math.degrees(math.atan2(p, q) - math.atan2(small, big))) <= SNAP_TOLERANCE_DEG:
        rational = (q, p)
        norm = math.hypot(q, p)
        big, small = q / norm, p / norm
        if ax >= ay:
            ax, ay = big, small
        else:
            ax, ay = small, big
        # exact zeros keep the half-open cell rules exact along grid lines
    sx = 1 if ux > 0 and ax > 0 else -1 if ux < 0 and ax > 0 else 0
    sy = 1 if uy > 0 and ay > 0 else -1 if uy < 0 and ay > 0 else 0
    swap = ay > ax
    return Direction(az, sx * ax if sx else 0.0, sy * ay if sy else 0.0, sx, sy, swap,
                     max(ax, ay), min(ax, ay), rational)


def rational_azimuths(n: int, max_denominator: int = 5) -> np.ndarray:
    """``n`` azimuths (degrees) near 0, 360/n, 2*360/n, ..., each moved to the nearest
    direction whose octant slope is p/q with q <= max_denominator, so that the exact sweep
    applies.

    The sweep reads about 2 q (or 2 (q + p) against the diagonals) breakpoints per vertex,
    so small denominators are fast. The default 5 moves 16 azimuths by at most 0.70
    degrees (22.5 becomes atan(2/5) = 21.80); 12 moves them by at most 0.12 degrees
    (atan(5/12) = 22.62) at about 2.4 times the cost."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n: expected a positive int, got {n!r}")
    if not 1 <= max_denominator <= MAX_SNAP_DENOMINATOR:
        raise ValueError(f"max_denominator: expected 1..{MAX_SNAP_DENOMINATOR}, got {max_denominator}")
    candidates = sorted({math.degrees(math.atan2(p, q))
                         for q in range(1, max_denominator + 1) for p in range(0, q + 1)
                         if math.gcd(p, q) == 1})
    out = []
    for k in range(n):
        az = 360.0 * k / n
        octant, rest = divmod(az, 45.0)
        octant = int(octant) % 8
        # within an octant, the angle from its start (even octants) or to its end (odd)
        offset = rest if octant % 2 == 0 else 45.0 - rest
        best = min(candidates, key=lambda c: (abs(c - offset), c))
        snapped = octant * 45.0 + (best if octant % 2 == 0 else 45.0 - best)
        out.append(snapped % 360.0)
    return np.array(out)


def _snap_cell_azimuth(azimuth: float, max_denominator: int) -> float:
    """The direction nearest ``azimuth`` (degrees, cell space) whose octant slope is p/q
    with q <= max_denominator (ties: the smaller q, then the smaller angle)."""
    octant, rest = divmod(azimuth % 360.0, 45.0)
    octant = int(octant) % 8
    offset = rest if octant % 2 == 0 else 45.0 - rest  # degrees from the octant's axis
    ratio = math.tan(math.radians(offset))
    best = None
    for q in range(1, max_denominator + 1):
        for p in {math.floor(ratio * q), math.ceil(ratio * q)}:
            if 0 <= p <= q and math.gcd(p, q) == 1:
                angle = math.degrees(math.atan2(p, q))
                key = (abs(angle - offset), q, angle)
                if best is None or key < best:
                    best = key
    angle = best[2]
    return (octant * 45.0 + (angle if octant % 2 == 0 else 45.0 - angle)) % 360.0


def snap_azimuths(azimuths, max_denominator, spacing=None, *, name="max_denominator"):
    """Move each azimuth to the nearest direction whose slope *in cell space* is p/q with
    q <= ``max_denominator``, where the exact sweep applies at unlimited distance.

    Parameters
    ----------
    azimuths : float or sequence of floats
        Degrees clockwise from north.
    max_denominator : int
        1 to :data:`MAX_SNAP_DENOMINATOR`. A larger one moves less and costs more: the
        sweep reads about 2 q breakpoints per vertex.
    spacing : float or (dx, dy), optional
        The pixel size; on rectangular pixels an azimuth is snapped in cell space and
        mapped back (:meth:`Grid.cell_azimuth`).
    name : str
        The argument named in errors (the products pass ``"snap_denominator"``).

    Returns
    -------
    (float64 array (K,), float)
        The snapped azimuths (degrees, in [0, 360)) and the largest angular change, in
        degrees of map azimuth.

    Raises
    ------
    ValueError, TypeError
        Naming ``max_denominator``, ``azimuths[k]`` or ``spacing``.
    """
    if isinstance(max_denominator, bool) or not isinstance(max_denominator, (int, np.integer)) \
            or not 1 <= max_denominator <= MAX_SNAP_DENOMINATOR:
        raise ValueError(f"{name}: expected an int in 1..{MAX_SNAP_DENOMINATOR}, "
                         f"got {max_denominator!r}")
    dx, dy = check_spacing(spacing) if spacing is not None else (1.0, 1.0)
    grid = Grid(np.zeros((2, 2)), dx, dy, dx, True, None, None)
    out, change = [], 0.0
    for a in _azimuth_list(azimuths):
        snapped = grid.map_azimuth(_snap_cell_azimuth(grid.cell_azimuth(a % 360.0),
                                                      int(max_denominator)))
        out.append(snapped)
        change = max(change, abs((snapped - a + 180.0) % 360.0 - 180.0))
    return np.array(out), change


def _field_spacing(heights, spacing):
    """(dx, dy) of a product's input: a HeightField's or DataArray's own, else ``spacing``
    (cell units when None)."""
    field = heights if isinstance(heights, HeightField) else None
    if field is None and is_dataarray(heights):
        field = HeightField.from_dataarray(heights)
    if field is not None:
        return field.dx, field.dy
    return check_spacing(spacing) if spacing is not None else (1.0, 1.0)


def _path_attrs(snap):
    """The attributes a product's DataArray or file records about how it was computed:
    ``algorithm`` and ``paths`` (one per azimuth, comma-separated) from
    :data:`LAST_STATS`, and with snapping (``snap``: (snapped azimuths, largest change)),
    ``snapped_azimuths`` and ``snap_max_change_deg``."""
    attrs = dict(algorithm=LAST_STATS.algorithm, paths=",".join(LAST_STATS.paths))
    if snap is None and LAST_STATS.snapped_azimuths:
        snap = (LAST_STATS.snapped_azimuths, LAST_STATS.snap_max_change_deg)
    if snap is not None:
        attrs.update(snapped_azimuths=[float(a) for a in snap[0]],
                     snap_max_change_deg=float(snap[1]))
    return attrs


# ---- frames and patterns ---------------------------------------------------------------------

def _to_frame(a: np.ndarray, d: Direction) -> np.ndarray:
    if d.sx < 0:
        a = a[:, ::-1]
    if d.sy < 0:
        a = a[::-1, :]
    if d.swap:
        a = a.T
    return a


def _from_frame(a: np.ndarray, d: Direction) -> np.ndarray:
    if d.swap:
        a = a.T
    if d.sy < 0:
        a = a[::-1, :]
    if d.sx < 0:
        a = a[:, ::-1]
    return a


def _period_pattern(q: int, p: int, anti: bool):
    """The breakpoints of one period of the direction (q, p) in the octant frame, from a
    vertex (exclusive) to the next vertex (q, p) (inclusive): a list of
    (T, xa, ya, xb, yb, w) with T an exact Fraction in (0, 1], sorted, without repeats."""
    points = {}

    def add(T, xa, ya, xb, yb, w):
        if w == 0:
            xb, yb = xa, ya
        points.setdefault(T, (T, xa, ya, xb, yb, w))

    for X in range(1, q + 1):  # x = X
        y = Fraction(X * p, q)
        y0 = math.floor(y)
        add(Fraction(X, q), X, y0, X, y0 + 1, y - y0)
    for Y in range(1, p + 1):  # y = Y
        x = Fraction(Y * q, p)
        x0 = math.floor(x)
        add(Fraction(Y, p), x0, Y, x0 + 1, Y, x - x0)
    if not anti and q != p:  # x - y = c, c = 1 .. q - p
        for c in range(1, q - p + 1):
            T = Fraction(c, q - p)
            x = T * q
            x0 = math.floor(x)
            add(T, x0, x0 - c, x0 + 1, x0 - c + 1, x - x0)
    if anti:  # x + y = c, c = 1 .. q + p (c = 0 is the start vertex)
        for c in range(1, q + p + 1):
            T = Fraction(c, q + p)
            x = T * q
            x0 = math.floor(x)
            y0 = c - 1 - x0
            u = x - x0
            if u == 0:  # a vertex: (x0, c - x0)
                add(T, x0, c - x0, x0, c - x0, Fraction(0))
            else:  # from (x0, y0 + 1) at u = 0 to (x0 + 1, y0) at u = 1
                add(T, x0, y0 + 1, x0 + 1, y0, u)
    return [points[T] for T in sorted(points)]


def _pattern_arrays(entries):
    cols = list(zip(*entries))
    T = np.array([float(v) for v in cols[0]])
    xa, ya, xb, yb = (np.array(c, dtype=np.int64) for c in cols[1:5])
    w = np.array([float(v) for v in cols[5]])
    return T, xa, ya, xb, yb, w


def _float_pattern(a: float, b: float, anti: bool, t_max: float):
    """Breakpoints of the octant direction (a, b) (unit, a >= b >= 0) up to distance t_max
    and one beyond, as arrays (t, xa, ya, xb, yb, w), sorted by t."""
    parts = []
    n = int(math.ceil(t_max * a)) + 2
    X = np.arange(1, n + 1, dtype=np.float64)
    t = X / a
    y = t * b
    y0 = np.floor(y)
    parts.append((t, X, y0, X, y0 + 1, y - y0))
    if b > 0:
        n = int(math.ceil(t_max * b)) + 2
        Y = np.arange(1, n + 1, dtype=np.float64)
        t = Y / b
        x = t * a
        x0 = np.floor(x)
        parts.append((t, x0, Y, x0 + 1, Y, x - x0))
    rate = (a + b) if anti else (a - b)
    if rate > 0:
        n = int(math.ceil(t_max * rate)) + 2
        C = np.arange(1, n + 1, dtype=np.float64)
        t = C / rate
        x = t * a
        x0 = np.floor(x)
        u = x - x0
        if anti:
            parts.append((t, x0, C - x0, x0 + 1, C - 1 - x0, u))
        else:
            parts.append((t, x0, x0 - C, x0 + 1, x0 - C + 1, u))
    t, xa, ya, xb, yb, w = (np.concatenate(c) for c in zip(*parts))
    order = np.argsort(t, kind="stable")
    t, xa, ya, xb, yb, w = (v[order] for v in (t, xa, ya, xb, yb, w))
    zero = w == 0
    xb = np.where(zero, xa, xb)
    yb = np.where(zero, ya, yb)
    keep = np.searchsorted(t, t_max, side="right") + 1
    return (t[:keep], xa[:keep].astype(np.int64), ya[:keep].astype(np.int64),
            xb[:keep].astype(np.int64), yb[:keep].astype(np.int64), w[:keep])


def _shared_pattern(d: Direction, rows: int, cols: int, max_distance):
    """The pattern of direction d in its octant frame (rows, cols of that frame)."""
    reach = math.hypot(rows - 1, cols - 1)  # no ray inside the footprint is longer
    t_max = reach if max_distance is None else min(max_distance, reach)
    if d.rational is not None:
        q, p = d.rational
        period = _period_pattern(q, p, d.anti)
        norm = math.hypot(q, p)
        T, xa, ya, xb, yb, w = _pattern_arrays(period)
        periods = int(math.ceil(t_max / norm)) + 1
        m = np.repeat(np.arange(periods), len(T))
        t = (np.tile(T, periods) + m) * norm
        xa, xb = np.tile(xa, periods) + m * q, np.tile(xb, periods) + m * q
        ya, yb = np.tile(ya, periods) + m * p, np.tile(yb, periods) + m * p
        w = np.tile(w, periods)
        keep = np.searchsorted(t, t_max * (1 + 1e-15), side="right") + 1
        t, xa, ya, xb, yb, w = (v[:keep] for v in (t, xa, ya, xb, yb, w))
    else:
        t, xa, ya, xb, yb, w = _float_pattern(d.a, d.b, d.anti, t_max)
    mx = np.maximum.accumulate(np.maximum(xa, xb))
    my = np.maximum.accumulate(np.maximum(ya, yb))
    limit_x = np.searchsorted(mx, np.arange(cols), side="right").astype(np.int64)
    limit_y = np.searchsorted(my, np.arange(rows), side="right").astype(np.int64)
    end_k, end_f, end_inv = -1, 0.0, 0.0
    if max_distance is not None and max_distance < reach:
        k = int(np.searchsorted(t, max_distance, side="right")) - 1
        if 0 <= k < len(t) - 1:
            end_k = k
            end_f = (max_distance - t[k]) / (t[k + 1] - t[k])
            end_inv = 1.0 / max_distance
        elif k < 0:
            # max_distance before the first breakpoint: the surface is linear from v to it,
            # so the ratio over (0, max_distance] is the ratio at that breakpoint; with
            # max_distance 0 the set is empty
            cap = 1 if max_distance > 0 else 0
            limit_x = np.minimum(limit_x, cap)
            limit_y = np.minimum(limit_y, cap)
    return dict(inv_t=1.0 / t, xa=xa, ya=ya, xb=xb, yb=yb, w=w, limit_x=limit_x,
                limit_y=limit_y, end_k=end_k, end_f=end_f, end_inv=end_inv, t=t)


def _mipmap(h: np.ndarray):
    """(data, offset, rows, cols): the max-mipmap of the cell maxima in float64 (the
    levels of :func:`algos.field.max_mipmap`, concatenated for the C walks)."""
    cell = np.maximum(np.maximum(h[:-1, :-1], h[:-1, 1:]), np.maximum(h[1:, :-1], h[1:, 1:]))
    levels = max_mipmap(cell)
    offset = np.cumsum([0] + [lv.size for lv in levels[:-1]]).astype(np.int64)
    return (np.ascontiguousarray(np.concatenate([lv.ravel() for lv in levels])), offset,
            np.array([lv.shape[0] for lv in levels], dtype=np.int64),
            np.array([lv.shape[1] for lv in levels], dtype=np.int64))


# ---- horizon ---------------------------------------------------------------------------

def _sweep(hf, d: Direction, out, threads=1):
    """The rational sweep over the whole octant-frame field hf into out, its lines split
    over threads (each line writes its own vertices); returns ns (summed over threads)."""
    q, p = d.rational
    T, xa, ya, xb, yb, w = _pattern_arrays(_period_pattern(q, p, d.anti))
    mx, my = np.maximum(xa, xb), np.maximum(ya, yb)
    n_lines = q * (hf.shape[0] - 1) + p * (hf.shape[1] - 1) + 1
    return sum(run_ranges(n_lines, threads, lambda a, b: _kernels.horizon_sweep(
        hf, q, p, T, xa, ya, xb, yb, w, mx, my, math.hypot(q, p), a, b, out)[0],
        chunks_per_thread=4, min_chunk=64))


def _pattern_walk(hf, pat, zmax, start, stop, out, kappa=0.0):
    """The shared-pattern walk of octant-frame vertices [start, stop); returns ns."""
    return _kernels.horizon_pattern(
        hf, pat["inv_t"], pat["xa"], pat["ya"], pat["xb"], pat["yb"], pat["w"],
        pat["limit_x"], pat["limit_y"], pat["end_k"], pat["end_f"], pat["end_inv"], zmax,
        PATTERN_STOP_EVERY, start, stop, out, kappa)[0]


#: Rows per block of the chain walk: a vertex borrows only from neighbours in its own
#: block, so that results do not depend on how blocks are shared among threads.
CHAIN_BLOCK_ROWS = 256
#: Largest denominator of the convergents the chain walk borrows along, and their largest
#: distance (cells) across the ray.
CHAIN_MAX_DENOMINATOR = 1024
CHAIN_MAX_OFFSET = 0.5


def _rows_pattern(h, d: Direction, max_distance, threads):
    """The shared pattern of ``d`` in the grid's own frame, row by row, vectorised over each
    row's vertices (``hf_horizon_rows``): the octant-frame pattern's offsets mapped back
    to the grid, so no frame copy is made. Bit-identical to the pattern walk. Returns
    (tangents (rows, cols), ns)."""
    rows, cols = h.shape
    fr, fc = (cols, rows) if d.swap else (rows, cols)
    pat = _shared_pattern(d, fr, fc, max_distance)
    mx = np.maximum.accumulate(np.maximum(pat["xa"], pat["xb"])).astype(np.int64)
    my = np.maximum.accumulate(np.maximum(pat["ya"], pat["yb"])).astype(np.int64)
    xa, ya, xb, yb = pat["xa"], pat["ya"], pat["xb"], pat["yb"]
    rx, ry = mx, my
    if d.swap:  # the frame's x is the grid's y
        xa, ya, xb, yb, rx, ry = ya, xa, yb, xb, my, mx
    sx, sy = (-1 if d.sx < 0 else 1), (-1 if d.sy < 0 else 1)
    if pat["end_k"] >= 0:
        n_main = pat["end_k"] + 1
    else:  # no end between breakpoints: as many as any vertex can use (the pattern's limits)
        n_main = int(min(pat["limit_x"][-1], pat["limit_y"][-1]))
    out = np.empty(rows * cols)
    ns = sum(run_ranges(rows, threads, lambda a, b: _kernels.horizon_rows(
        h, pat["inv_t"], np.ascontiguousarray(sx * xa), np.ascontiguousarray(sy * ya),
        np.ascontiguousarray(sx * xb), np.ascontiguousarray(sy * yb), pat["w"], rx, ry, sx, sy,
        n_main, pat["end_k"], pat["end_f"], pat["end_inv"], a, b, out)[0],
        chunks_per_thread=4, min_chunk=8))
    return out.reshape(rows, cols), ns


def _convergents(x: float, max_denominator: int):
    """The continued-fraction convergents p/q of x >= 0 with q <= max_denominator, as
    (q, p) pairs in order of q."""
    out, (p0, q0, p1, q1) = [], (0, 1, 1, 0)
    for _ in range(64):
        a = math.floor(x)
        p0, q0, p1, q1 = p1, q1, a * p1 + p0, a * q1 + q0
        if q1 > max_denominator:
            break
        out.append((q1, p1))
        frac = x - a
        if frac <= 0.0:
            break
        x = 1.0 / frac
    return out


def chain_neighbours(d: Direction, max_denominator=CHAIN_MAX_DENOMINATOR,
                     max_offset=CHAIN_MAX_OFFSET):
    """The offsets (gx, gy) and distances along ``d`` of the vertices the chain walk borrows
    lower bounds from: v + (gx, gy) for each convergent p/q of the octant slope
    (q <= max_denominator) whose line passes within ``max_offset`` cells of v's ray
    (|q b - p a| for the octant direction (a, b)); nearest across first. For a rational
    direction the last is its own period (q, p), on the ray itself."""
    found = []
    for q, p in _convergents(d.b / d.a, max_denominator):
        across = abs(q * d.b - p * d.a)
        if across > max_offset:
            continue
        fx, fy = (p, q) if d.swap else (q, p)
        gx, gy = (-fx if d.sx < 0 else fx), (-fy if d.sy < 0 else fy)
        found.append((across, gx, gy, q * d.a + p * d.b))
    found.sort()
    return (np.array([f[1] for f in found], dtype=np.int64),
            np.array([f[2] for f in found], dtype=np.int64),
            np.array([f[3] for f in found], dtype=np.float64))


def _chain(h, d: Direction, max_distance, threads, mip, stats):
    """The chain walk of every vertex (grid frame): ``hf_horizon_chain``. Returns the
    tangents (rows, cols) and adds the walk's counts to ``stats``."""
    rows, cols = h.shape
    nb_x, nb_y, nb_d = chain_neighbours(d)
    out = np.empty(rows * cols)
    occ = np.full(rows * cols, np.nan)
    md = math.inf if max_distance is None else float(max_distance)
    n_blocks = -(-rows // CHAIN_BLOCK_ROWS)
    for ns, cells, skips, tests, bounded in run_ranges(
            n_blocks, threads, lambda a, b: _kernels.horizon_chain(
                h, mip, d.dx, d.dy, md, nb_x, nb_y, nb_d, CHAIN_BLOCK_ROWS, a, b, out, occ),
            chunks_per_thread=1, min_chunk=1):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
        stats.tile_tests += tests
        stats.bounded += bounded
    return out.reshape(rows, cols)


def _horizon_one(h, d: Direction, algorithm, max_distance, threads, mip, stats, march_step,
                 embree_tolerance, kappa=0.0):
    rows, cols = h.shape
    if algorithm == "chain":
        return _chain(h, d, max_distance, threads, mip, stats)
    if algorithm == "rows":
        out, ns = _rows_pattern(h, d, max_distance, threads)
        stats.ns += ns
        return out
    if algorithm in ("sweep", "pattern"):
        hf = np.ascontiguousarray(_to_frame(h, d))
        fr, fc = hf.shape
        out = np.empty(fr * fc)
        if algorithm == "sweep":
            stats.ns += _sweep(hf, d, out, threads)
        else:
            pat = _shared_pattern(d, fr, fc, max_distance)
            zmax = float(hf.max())
            stats.ns += sum(_run_ranges(fr * fc, threads,
                                        lambda a, b: _pattern_walk(hf, pat, zmax, a, b, out,
                                                                   kappa)))
        return _from_frame(out.reshape(fr, fc), d)
    out = np.empty(rows * cols)
    md = math.inf if max_distance is None else max_distance
    if algorithm in ("dda", "dda_maxmip"):
        def call(start, stop):
            return _kernels.horizon_walk(h, mip if algorithm == "dda_maxmip" else None,
                                         d.dx, d.dy, md, start, stop, out, kappa)
    elif algorithm == "march":
        zmax = float(h.max())

        def call(start, stop):
            return _kernels.horizon_march(h, d.dx, d.dy, march_step, md, zmax, start, stop, out,
                                          kappa)
    elif algorithm == "embree":
        from .embree_peer import embree_horizon_tangents

        t0 = time.perf_counter_ns()
        out[:] = embree_horizon_tangents(h, d.dx, d.dy, md, tolerance=embree_tolerance,
                                        threads=threads).ravel()
        stats.ns += time.perf_counter_ns() - t0
        return out.reshape(rows, cols)
    else:  # pragma: no cover - checked by the caller
        raise AssertionError(algorithm)
    for ns, cells, skips in _run_ranges(rows * cols, threads, call):
        stats.ns += ns
        stats.cells += cells
        stats.skips += skips
    return out.reshape(rows, cols)


def _auto_path(d: Direction, max_distance, curvature=False) -> str:
    """The default algorithm of one direction, by measurement (docs in :func:`horizon`):
    the sweep for a rational direction at unlimited distance; the row-vectorised pattern
    up to max_distance 384 cells; the chain walk otherwise (every other direction at
    unlimited distance, and longer radii). With curvature, whose peaks inside pieces
    neither the sweep, the rows nor the chain evaluate (:data:`CURVATURE_REFUSED`): the
    shared pattern up to 384 cells, the mipmap walk beyond."""
    if curvature:
        return "pattern" if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE \
            else "dda_maxmip"
    if max_distance is None and d.rational is not None:
        return "sweep"
    if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE:
        return "rows"
    return "chain"


def _pick_horizon_algorithm(algorithm, directions, max_distance, curvature=False):
    if curvature and algorithm in CURVATURE_REFUSED:
        raise ValueError(f"curvature: algorithm={algorithm!r} does not apply curvature "
                         f"({CURVATURE_REFUSED[algorithm]}); use 'pattern', 'dda', "
                         "'dda_maxmip' or 'auto'")
    if algorithm is None or algorithm == "auto":
        # curvature: the sweep's hull of breakpoints no longer holds (module docstring,
        # "Curvature"), so the exact per-vertex paths run
        # chosen by measurement (reports/terrain/targets.md, jacksboro 2048): the sweep
        # wherever it applies (157 ns per vertex against 4184 for dda_maxmip); else the
        # shared pattern up to max_distance 384 (431 against 1149 ns at 32 cells, 1569
        # against 2450 at 128, 4349 against 4068 at 512), the mipmap walk beyond
        if max_distance is None and all(d.rational is not None for d in directions) \
                and not curvature:
            return "sweep"
        return "pattern" if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE \
            else "dda_maxmip"
    if algorithm not in HORIZON_ALGORITHMS:
        raise ValueError(f"algorithm: expected one of {sorted(HORIZON_ALGORITHMS)} or 'auto', "
                         f"got {algorithm!r}")
    info = HORIZON_ALGORITHMS[algorithm]
    if info.rational_only:
        for k, d in enumerate(directions):
            if d.rational is None:
                raise ValueError(
                    f"azimuths[{k}]: {d.azimuth} is not a rational direction (slope p/q with "
                    f"q <= {MAX_SNAP_DENOMINATOR}); algorithm={algorithm!r} needs one "
                    f"(see algos.rational_azimuths)")
    if max_distance is not None and not info.max_distance:
        raise ValueError(f"max_distance: algorithm={algorithm!r} supports only unlimited distance")
    return algorithm


def _check_surface(surface):
    if surface != "triangles":
        raise ValueError(f"surface: the terrain products are defined on 'triangles' (the "
                         f"default), got {surface!r}")


def _azimuth_list(azimuths):
    scalar = np.ndim(azimuths) == 0
    az = np.atleast_1d(np.asarray(azimuths, dtype=object if scalar else None))
    if az.ndim != 1 or len(az) == 0:
        raise ValueError(f"azimuths: expected a number or a non-empty 1D sequence, got shape {az.shape}")
    out = []
    for k, a in enumerate(az):
        if isinstance(a, (bool, np.bool_)):
            raise TypeError(f"azimuths[{k}]: expected a number of degrees, got {a!r}")
        try:
            a = float(a)
        except (TypeError, ValueError):
            raise TypeError(f"azimuths[{k}]: azimuth: expected a number, got {a!r}") from None
        if not math.isfinite(a):
            raise ValueError(f"azimuths[{k}]: azimuth: expected a finite number of degrees, "
                             f"got {a!r}")
        out.append(a)
    return out


#: Why curvature refuses a grid without a real unit, and how to give one.
_NO_UNIT_CURVATURE = (
    "curvature: needs spacing in a real unit, to convert the earth's radius: give a raw "
    "array's spacing (taken in metres), a field with a CRS, or HeightField(..., spacing=D, "
    "unit='m') (units: 'm', 'km', 'ft', 'US survey foot'; on the command line --unit next to "
    "--spacing); a field in cell units or in an unnamed 'map unit' has none")


def _curvature_kappa(grid: Grid, curvature, refraction, earth_radius) -> float:
    """kappa, the drop per squared cell distance in cell height units:
    (1 - refraction) dx / (2 R), R in the field's unit; 0 without curvature. Validated as
    :func:`viewshed` does (square pixels, a real unit)."""
    if not isinstance(curvature, (bool, np.bool_)):
        raise TypeError(f"curvature: expected a bool, got {curvature!r}")
    if not curvature:
        return 0.0
    if not grid.has_unit:
        raise ValueError(_NO_UNIT_CURVATURE)
    if not grid.square:
        raise ValueError(f"curvature: needs square pixels, got {grid.dx:g} x {grid.dy:g}; "
                         "resample first (e.g. gdalwarp -tr D D)")
    try:
        r = float(refraction)
    except (TypeError, ValueError):
        raise TypeError(f"refraction: expected a number, got {refraction!r}") from None
    if not (math.isfinite(r) and 0 <= r < 1):
        raise ValueError(f"refraction: expected a coefficient in [0, 1), got {refraction!r}")
    try:
        radius = float(earth_radius)
    except (TypeError, ValueError):
        raise TypeError(f"earth_radius: expected a number of metres, got {earth_radius!r}") from None
    if not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"earth_radius: expected a positive length, got {earth_radius!r}")
    radius /= grid.unit_metres
    return (1.0 - r) * grid.dx / (2.0 * radius)


def _check_units(units):
    if units not in ANGLE_UNITS:
        raise ValueError(f"units: expected one of {ANGLE_UNITS}, got {units!r}")
    return units


def _horizon_angles(grid: Grid, azimuths, max_distance, kappa, *, algorithm, threads,
                    march_step, embree_tolerance, progress, tangents=False):
    """The horizon angles (radians, north-up, (len(azimuths), rows, cols)) of a prepared
    grid with curvature kappa (cell units; negative raises the surface, for
    :func:`openness`), voids not yet set; also returns the algorithms that ran ("+"
    joined, :class:`TerrainStats`). ``tangents``: the map tangents, not their angles."""
    h = grid.h
    directions = []
    for k, a in enumerate(_azimuth_list(azimuths)):
        directions.append(azimuth_direction(grid.cell_azimuth(a)))
    md = check_length(max_distance, "max_distance")
    # per direction: the distance limit in cells and the factor from cell-space tangents
    # (cell heights over cell distance) to map tangents (module docstring, "Units")
    limits, factors = [], []
    for d in directions:
        stretch = grid.stretch(d)
        limits.append(None if md is None else md / stretch)
        factors.append(1.0 if grid.square else grid.z_scale / stretch)
    step = float(march_step)
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"march_step: expected a positive number of cells, got {march_step!r}")
    curved = kappa != 0.0
    name = _pick_horizon_algorithm(algorithm, directions,
                                   None if md is None else max(limits), curvature=curved)
    if algorithm is None or algorithm == "auto":  # chosen per direction
        paths = [_auto_path(d, limits[k], curved) for k, d in enumerate(directions)]
    else:
        paths = [name] * len(directions)
    nthreads = resolve_threads(threads)
    stats = TerrainStats("+".join(dict.fromkeys(paths)), paths=tuple(paths))
    mip = _mipmap(h) if {"dda_maxmip", "chain"} & set(paths) else None
    out = np.empty((len(directions),) + h.shape)
    for k, d in enumerate(directions):
        out[k] = _horizon_one(h, d, paths[k], limits[k], nthreads, mip, stats, step,
                              embree_tolerance, kappa)
        if factors[k] != 1.0:
            out[k] *= factors[k]
        if progress is not None:
            progress(k + 1, len(directions))
    if not tangents:
        np.arctan(out, out=out)
    LAST_STATS.__dict__.update(stats.__dict__)
    return out, stats.algorithm


def horizon(heights, azimuths, max_distance=None, *, algorithm=None, surface="triangles",
            spacing=None, units="radians", curvature=False, refraction=DEFAULT_REFRACTION,
            earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, march_step=1.0,
            embree_tolerance=1e-4, progress=None, snap_denominator=None, _tangents=False):
    """Horizon elevation angles (radians by default) seen from every vertex.

    For each azimuth, the horizon of vertex v is the supremum, over the surface points p on
    the horizontal ray from v with 0 < dist(p, v) <= max_distance inside the footprint
    [0, cols-1] x [0, rows-1], of atan2(s(p) - H(v), dist), with heights and distances in
    the same linear unit; -pi/2 where there is none. On the two triangles the supremum is
    attained at a breakpoint of the ray (an edge or diagonal crossing, or the far end), or
    is the slope limit at dist -> 0+, which equals the ratio at the first breakpoint
    (module docstring). It is computed exactly, up to float64 rounding, by every exact
    algorithm, on square and rectangular pixels alike (module docstring, "Units").

    With ``curvature``, each surface point at map distance D is first lowered by
    (1 - refraction) D^2 / (2 R), as in :func:`viewshed`; the supremum then also looks
    inside the linear pieces (module docstring, "Curvature"), and stays exact.

    Parameters
    ----------
    heights : (rows, cols) array, HeightField or xarray.DataArray
        A raw array is north-up (row 0 north) and in the unit of ``spacing``; NaN marks a
        void. A HeightField or DataArray carries its own spacing, CRS, orientation and
        voids.
    azimuths : float or sequence of floats
        Degrees clockwise from north (north is row 0 of a north-up array).
    max_distance : float, optional
        A length in the field's unit (cells when there is no spacing). None: unlimited.
    algorithm : str, optional
        A key of :data:`HORIZON_ALGORITHMS`, or None/"auto", chosen per azimuth (by
        measurement): "sweep" for a direction rational in cell space at unlimited
        distance, "rows" for max_distance <= 384 cells, "chain" otherwise; with curvature,
        "pattern" up to 384 cells and "dda_maxmip" beyond. The path of each azimuth is
        recorded in :data:`LAST_STATS` (``algorithm``, ``paths``) and in a DataArray's
        attrs ``algorithm`` and ``paths``. With curvature, the algorithms of
        :data:`CURVATURE_REFUSED` raise.
    spacing : float or (dx, dy), optional
        The pixel size of a raw array, in the unit of its heights; None means cell units.
        A HeightField carries its own (giving a different one raises).
    units : {"radians", "degrees"}
        The unit of the angles returned (and of a DataArray's ``units`` attribute).
    curvature : bool
        Lower the surface for the earth's curvature and refraction. Default False: the
        horizon-based products of RVT (sky-view factor, openness) have no curvature, and
        over the radii they are used at it is negligible (the drop is 0.07 m at 1 km,
        6.7 m at 10 km); GRASS r.horizon applies it by default, so pass True to compare
        with it. Needs a real unit (a raw array's spacing, in metres, or a field
        whose ``unit_metres`` is known) and square pixels.
    refraction : float
        The refraction coefficient in [0, 1); default 1/7, GDAL's and GRASS's
        (:data:`DEFAULT_REFRACTION`).
    earth_radius : float
        R in metres (default the WGS 84 semi-major axis, as GDAL), converted to the
        field's unit with its ``unit_metres`` (1 for a raw array).
    threads : None or int
        Vertices are split over threads; results are identical for every value.
    march_step, embree_tolerance : the baselines' step (cells) and angle tolerance (rad).
    progress : callable, optional
        Called as ``progress(done, total)`` after each azimuth (in memory only; a
        command's progress bar).
    snap_denominator : int, optional
        Snap each azimuth to the nearest direction whose slope in cell space is p/q with
        q <= snap_denominator (:func:`snap_azimuths`), so that the rational sweep applies.
        Default None: no snapping, the horizons are exact at the azimuths given. The
        azimuths used and the largest change are recorded (``LAST_STATS``; DataArray
        attrs ``snapped_azimuths``, ``snap_max_change_deg``).

    Returns
    -------
    float64 array (len(azimuths), rows, cols)
        Angles in [-pi/2, pi/2] radians (or [-90, 90] degrees), in the input's
        orientation; -pi/2 (-90) where the ray has no point; NaN at void vertices. A
        DataArray gives a DataArray with an ``azimuth`` dimension, the input's coords, CRS
        and attrs, ``units`` (the unit), ``curvature`` (0 or 1) and ``refraction``.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: bad heights (a non-finite value other than a NaN void, too
        large, too small), azimuths, lengths, algorithm, surface, units, curvature,
        refraction, earth_radius or threads.

    A dask array (or a HeightField or DataArray holding one) gives a lazy dask array,
    computed tile by tile with a halo of ``max_distance`` (which must be finite):
    :mod:`algos.tiled`.
    """
    _check_units(units)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    snap = None
    if snap_denominator is not None:
        snap = snap_azimuths(azimuths, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
    if is_dataarray(heights):
        az = _azimuth_list(azimuths)
        out = _to_dataarray(heights, lambda f: horizon(
            f, az if snap is None else snap[0], max_distance, algorithm=algorithm,
            surface=surface, threads=threads, march_step=march_step,
            embree_tolerance=embree_tolerance, units=units, **curve),
            "horizon", dict(units=units, max_distance=_attr(max_distance),
                            **_curvature_attrs(curvature, refraction)), ("azimuth", az))
        return _with_path_attrs(out, snap)
    if snap is not None:
        out = horizon(heights, snap[0], max_distance, algorithm=algorithm, surface=surface,
                      spacing=spacing, units=units, threads=threads, march_step=march_step,
                      embree_tolerance=embree_tolerance, progress=progress,
                      _tangents=_tangents, **curve)
        if not is_dask(out):
            _record_snap(snap)
        return out
    if is_dask(heights):
        return _tiled_horizon(heights, azimuths, max_distance, spacing, dict(
            algorithm=algorithm, surface=surface, threads=threads, march_step=march_step,
            embree_tolerance=embree_tolerance, units=units, **curve))
    _check_surface(surface)
    grid = _prepare(heights, spacing)
    kappa = _curvature_kappa(grid, curvature, refraction, earth_radius)
    out, _ = _horizon_angles(grid, azimuths, max_distance, kappa, algorithm=algorithm,
                             threads=threads, march_step=march_step,
                             embree_tolerance=embree_tolerance, progress=progress,
                             tangents=_tangents)
    if units == "degrees" and not _tangents:
        np.degrees(out, out=out)
    grid.voids_to(out, np.nan)
    return np.ascontiguousarray(grid.to_north_up(out))


def _curvature_attrs(curvature, refraction):
    """The curvature parameters as file/DataArray attributes."""
    out = dict(curvature=int(bool(curvature)))
    if curvature:
        out["refraction"] = float(refraction)
    return out


def shadows(heights, azimuth, elevation, *, max_distance=None, algorithm=None,
            surface="triangles", spacing=None, curvature=False, refraction=DEFAULT_REFRACTION,
            earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, snap_denominator=None):
    """Cast shadows under a sun at ``azimuth`` and ``elevation`` (degrees).

    A vertex is in shadow when its horizon along the sun's azimuth (:func:`horizon`) is
    strictly above the sun's elevation; a tie is lit.

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads
        As in :func:`horizon` (``max_distance`` a length in the field's unit).
    curvature, refraction, earth_radius
        As in :func:`horizon`: the surface lowered for the earth's curvature. Default
        False, as the horizon; it matters for long shadows at a low sun, over tens of
        kilometres.
    azimuth : float
        Degrees clockwise from north.
    elevation : float
        Degrees above the horizontal, in [-90, 90].
    snap_denominator : int, optional
        As in :func:`horizon`: the sun's azimuth snapped to a rational cell direction,
        recorded (``LAST_STATS``, DataArray attrs). Default None: no snapping.

    Returns
    -------
    bool array (rows, cols)
        True in shadow, in the input's orientation. A void vertex is False (its own
        value is unknown: the field's ``nodata_mask`` marks it; writers store it as
        nodata). A DataArray gives a DataArray (input's coords, CRS and attrs).
    """
    try:
        el = float(elevation)
    except (TypeError, ValueError):
        raise TypeError(f"elevation: expected a number of degrees, got {elevation!r}") from None
    if not -90.0 <= el <= 90.0:
        raise ValueError(f"elevation: expected degrees in [-90, 90], got {elevation!r}")
    if np.ndim(azimuth) != 0:
        raise ValueError("azimuth: expected one number (the sun's azimuth)")
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    snap, used = None, azimuth
    if snap_denominator is not None:
        snap = snap_azimuths(azimuth, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
        used = float(snap[0][0])
    if is_dataarray(heights):
        out = _to_dataarray(heights, lambda f: shadows(
            f, used, el, max_distance=max_distance, algorithm=algorithm, surface=surface,
            threads=threads, **curve), "shadows",
            dict(units="1 in shadow, 0 lit", azimuth=float(azimuth), elevation=el,
                 max_distance=_attr(max_distance), **_curvature_attrs(curvature, refraction)))
        return _with_path_attrs(out, snap)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: shadows(b, used, el, **kw), heights,
                             max_distance, spacing, bool, algorithm=algorithm,
                             surface=surface, threads=threads, **curve)
    angles = horizon(heights, used, max_distance, algorithm=algorithm, surface=surface,
                     spacing=spacing, threads=threads, **curve)[0]
    _record_snap(snap)
    with np.errstate(invalid="ignore"):
        return angles > math.radians(el)  # NaN (a void) compares False


def sky_view_factor(heights, n_azimuths=16, max_distance=None, *, rational=False,
                    azimuths=None, algorithm=None, surface="triangles", spacing=None,
                    curvature=False, refraction=DEFAULT_REFRACTION,
                    earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, progress=None,
                    snap_denominator=None):
    """Sky-view factor (Zaksek et al. 2011, as in RVT): 1 - mean_k sin(max(horizon_k, 0)).

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads
        As in :func:`horizon` (``max_distance`` a length in the field's unit).
    n_azimuths : int
        Equally spaced azimuths starting at north.
    rational : bool
        Move each azimuth to the nearest direction whose slope *in cell space* is p/q with
        q <= 5 (:func:`rational_azimuths`), where the exact sweep applies. On rectangular
        pixels the map azimuths are then those directions' images.
    azimuths : sequence of float, optional
        Explicit azimuths (degrees), instead of ``n_azimuths``.
    curvature, refraction, earth_radius
        As in :func:`horizon`. Default False, as RVT's sky-view factor (Zaksek et al.
        2011), which has no curvature; with unlimited distance the exact sweep does not
        apply and a per-vertex walk runs (:func:`horizon`).
    progress : callable, optional
        Called as ``progress(done, total)`` after each azimuth (in memory only).
    snap_denominator : int, optional
        As in :func:`horizon`: every azimuth snapped to a rational cell direction with
        q <= snap_denominator, recorded (``LAST_STATS``, DataArray attrs). Default None:
        no snapping (``rational=True`` is the older spelling of snap_denominator=5 for
        the equally spaced azimuths).

    Returns
    -------
    float64 array (rows, cols)
        Dimensionless, in [0, 1]; NaN at void vertices; the input's orientation. A
        DataArray gives a DataArray (input's coords, CRS and attrs, and the algorithm of
        each azimuth: attrs ``algorithm`` and ``paths``).
    """
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    if azimuths is None:
        if isinstance(n_azimuths, bool) or not isinstance(n_azimuths, (int, np.integer)) or n_azimuths < 1:
            raise ValueError(f"n_azimuths: expected a positive int, got {n_azimuths!r}")
        azimuths = np.arange(n_azimuths) * (360.0 / n_azimuths)
        if rational:
            azimuths = _rational_map_azimuths(heights, spacing, n_azimuths)
    snap = None
    if snap_denominator is not None:
        snap = snap_azimuths(azimuths, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
        azimuths = snap[0]
    if is_dataarray(heights):
        az = _azimuth_list(azimuths)
        out = _to_dataarray(heights, lambda f: sky_view_factor(
            f, azimuths=az, max_distance=max_distance, algorithm=algorithm, surface=surface,
            threads=threads, **curve), "sky_view_factor",
            dict(units="1", n_azimuths=len(az), max_distance=_attr(max_distance),
                 **_curvature_attrs(curvature, refraction)))
        return _with_path_attrs(out, snap)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: sky_view_factor(b, azimuths=azimuths, **kw),
                             heights, max_distance, spacing, np.float64, algorithm=algorithm,
                             surface=surface, threads=threads, **curve)
    tangents = horizon(heights, azimuths, max_distance, algorithm=algorithm, surface=surface,
                       spacing=spacing, threads=threads, progress=progress, _tangents=True,
                       **curve)
    _record_snap(snap)
    # one azimuth at a time, so each pass stays in the cache (the layers summed in order,
    # as np.mean over the first axis does)
    total = _sin_of_positive_atan(tangents[0])
    for k in range(1, len(tangents)):
        total += _sin_of_positive_atan(tangents[k])
    total /= len(tangents)
    return 1.0 - total


def _sin_of_positive_atan(x):
    """sin(max(atan(x), 0)) = max(x, 0) / sqrt(1 + max(x, 0)^2), in place, NaN kept: no
    transcendental function (the sky-view factor's inner step; equal to the angle form
    to rounding). Tangents beyond 1e150 give 1 (their square would overflow)."""
    np.maximum(x, 0.0, out=x)
    np.minimum(x, 1e150, out=x)
    root = np.multiply(x, x)
    root += 1.0
    np.sqrt(root, out=root)
    np.divide(x, root, out=x)
    return x


OPENNESS_KINDS = ("positive", "negative")


def openness(heights, kind="positive", n_azimuths=16, max_distance=None, *, azimuths=None,
             rational=False, units="degrees", algorithm=None, surface="triangles",
             spacing=None, curvature=False, refraction=DEFAULT_REFRACTION,
             earth_radius=WGS84_SEMI_MAJOR_AXIS_M, threads=None, progress=None,
             snap_denominator=None):
    """Topographic openness (Yokoyama, Shirasawa & Pike 2002), positive or negative.

    Positive openness is the mean over the azimuths of 90 deg minus the horizon angle
    (:func:`horizon`, the largest elevation angle within ``max_distance``): how far the
    sky opens above a vertex. Negative openness is the mean of 90 deg plus the smallest
    elevation angle within ``max_distance``, which is the positive openness of the
    mirrored terrain -H: how far the ground opens below. Both come from the exact
    horizons, so they are exact to rounding. A flat plane gives 90 deg for both; ridges
    raise positive openness above 90, valleys lower it.

    An azimuth along which a vertex has no surface point (a vertex on the edge of the
    footprint looking out, or a ray that meets only voids) has no elevation angle and is
    left out of that vertex's mean; a vertex with none left is NaN. RVT instead pads the
    DEM by reflection, which makes its edge values differ.

    Parameters
    ----------
    heights, max_distance, algorithm, surface, spacing, threads, progress
        As in :func:`sky_view_factor`. Yokoyama et al. name the radius L; RVT's default is
        10 pixels (``svf_r_max``), here None means unlimited.
    kind : {"positive", "negative"}
    n_azimuths : int
        Equally spaced azimuths from north; default 16, RVT's (Yokoyama et al. used 8).
    azimuths, rational
        As in :func:`sky_view_factor`.
    units : {"degrees", "radians"}
        Default degrees, the unit of Yokoyama et al. and RVT (``horizon`` defaults to
        radians).
    curvature, refraction, earth_radius
        As in :func:`horizon` (default False, as RVT). For negative openness the mirrored
        terrain is raised, not lowered, by the drop, so that both read the same lowered
        surface.
    snap_denominator : int, optional
        As in :func:`horizon`: every azimuth snapped to a rational cell direction with
        q <= snap_denominator, recorded (``LAST_STATS``, DataArray attrs). Default None.

    Returns
    -------
    float64 array (rows, cols)
        In [0, 180] degrees ([0, pi] radians); NaN at void vertices; the input's
        orientation. A DataArray gives a DataArray with ``units``, ``kind`` and the
        parameters as attrs.

    Raises
    ------
    ValueError, TypeError
        Naming the argument: ``kind``, ``units``, and everything :func:`horizon` checks.
    """
    if kind not in OPENNESS_KINDS:
        raise ValueError(f"kind: expected one of {OPENNESS_KINDS}, got {kind!r}")
    _check_units(units)
    curve = dict(curvature=curvature, refraction=refraction, earth_radius=earth_radius)
    if azimuths is None:
        if isinstance(n_azimuths, bool) or not isinstance(n_azimuths, (int, np.integer)) or n_azimuths < 1:
            raise ValueError(f"n_azimuths: expected a positive int, got {n_azimuths!r}")
        azimuths = np.arange(n_azimuths) * (360.0 / n_azimuths)
        if rational:
            azimuths = _rational_map_azimuths(heights, spacing, n_azimuths)
    snap = None
    if snap_denominator is not None:
        snap = snap_azimuths(azimuths, snap_denominator, _field_spacing(heights, spacing),
                             name="snap_denominator")
        azimuths = snap[0]
    options = dict(kind=kind, units=units, algorithm=algorithm, surface=surface,
                   threads=threads, **curve)
    if is_dataarray(heights):
        az = _azimuth_list(azimuths)
        out = _to_dataarray(heights, lambda f: openness(
            f, azimuths=az, max_distance=max_distance, **options), "openness",
            dict(units=units, kind=kind, n_azimuths=len(az), max_distance=_attr(max_distance),
                 **_curvature_attrs(curvature, refraction)))
        return _with_path_attrs(out, snap)
    if is_dask(heights):
        return tiled_product(lambda b, **kw: openness(b, azimuths=azimuths, **kw), heights,
                             max_distance, spacing, np.float64, **options)
    _check_surface(surface)
    grid = _prepare(heights, spacing)
    kappa = _curvature_kappa(grid, curvature, refraction, earth_radius)
    if kind == "negative":
        # the mirrored terrain: -H, voids kept as pits; its drop mirrored too (raised)
        mirrored = -grid.h if grid.void is None else np.where(grid.void, VOID_HEIGHT, -grid.h)
        grid = Grid(np.ascontiguousarray(mirrored), grid.dx, grid.dy, grid.z_scale,
                    grid.has_unit, grid.void, grid.field, grid.unit_metres)
        kappa = -kappa
    angles, _ = _horizon_angles(grid, azimuths, max_distance, kappa, algorithm=algorithm,
                                threads=threads, march_step=1.0, embree_tolerance=1e-4,
                                progress=progress)
    _record_snap(snap)
    seen = angles > -math.pi / 2  # an azimuth with a surface point
    count = seen.sum(axis=0)
    mean = np.where(seen, angles, 0.0).sum(axis=0) / np.maximum(count, 1)
    # 90 minus the mean angle (not the mean of 90 minus each): a flat plane gives 90 exactly
    out = 90.0 - np.degrees(mean) if units == "degrees" else math.pi / 2 - mean
    out[count == 0] = np.nan
    grid.voids_to(out, np.nan)
    return np.ascontiguousarray(grid.to_north_up(out))


def _rational_map_azimuths(heights, spacing, n):
    """:func:`rational_azimuths` taken in cell space: on square pixels they are the map
    azimuths; on rectangular ones, each equally spaced map azimuth goes to cell space, to
    the nearest rational cell direction (q <= 5) and back."""
    field = heights if isinstance(heights, HeightField) else None
    if field is None and is_dataarray(heights):
        field = HeightField.from_dataarray(heights)
    dx, dy = (field.dx, field.dy) if field is not None else (
        check_spacing(spacing) if spacing is not None else (1.0, 1.0))
    if dx == dy:
        return rational_azimuths(n)
    grid = Grid(np.zeros((2, 2)), dx, dy, dx, True, None, None)
    candidates = rational_azimuths(8 * 5 * 6 * 4, 5)  # every slope p/q, q <= 5, in all octants
    candidates = np.unique(np.round(candidates, 12))
    out = []
    for k in range(n):
        cell = grid.cell_azimuth(360.0 * k / n)
        gap = np.abs((candidates - cell + 180.0) % 360.0 - 180.0)
        out.append(grid.map_azimuth(float(candidates[int(np.argmin(gap))])))
    return np.array(out)


def _tiled_horizon(heights, azimuths, max_distance, spacing, options):
    """horizon() of a dask array: one tiled map per azimuth, stacked."""
    import dask.array as da

    az = np.atleast_1d(np.asarray(azimuths, dtype=float))
    layers = [tiled_product(lambda b, a=a, **kw: horizon(b, [a], **kw)[0], heights,
                            max_distance, spacing, np.float64, **options) for a in az]
    return da.stack(layers)


def _record_snap(snap):
    """Put the snapping of the call just made into :data:`LAST_STATS`."""
    if snap is not None:
        LAST_STATS.snapped_azimuths = tuple(float(a) for a in snap[0])
        LAST_STATS.snap_max_change_deg = float(snap[1])


def _with_path_attrs(out, snap):
    """``out`` (a DataArray) with :func:`_path_attrs`; a lazy one records only the
    snapping (its algorithms are chosen when it is computed, tile by tile)."""
    if not is_dask(out.data):
        _record_snap(snap)
    if is_dask(out.data):
        if snap is not None:
            out.attrs.update({k: v for k, v in _path_attrs(snap).items()
                              if k.startswith("snap")})
        return out
    out.attrs.update(_path_attrs(snap))
    return out


def _attr(value):
    """A parameter as a file/DataArray attribute (None as 'none')."""
    return "none" if value is None else value


def _to_dataarray(template, compute, product, attrs, extra_dim=None):
    """Run ``compute(HeightField)`` on a DataArray's field and wrap the result like the
    input: same dims, coords, attrs and CRS (rioxarray), plus ``attrs`` (units and the
    product's parameters). A dask-backed input gives a dask-backed (lazy) output."""
    import xarray as xr

    field = HeightField.from_dataarray(template)
    values = compute(field)
    dims, coords = template.dims, dict(template.coords)
    if extra_dim is not None:
        dims = (extra_dim[0],) + tuple(dims)
        coords[extra_dim[0]] = np.asarray(extra_dim[1], dtype=float)
    # the input's nodata value describes its heights, not the product: voids are NaN in a
    # float product, and a bool or count product has no fill value
    kept = {k: v for k, v in template.attrs.items() if k not in ("_FillValue", "nodata",
                                                                 "missing_value")}
    out = xr.DataArray(values, dims=dims, coords=coords, name=product,
                       attrs={**kept, "product": product, **{k: v for k, v in attrs.items()}})
    crs = getattr(getattr(template, "rio", None), "crs", None) if hasattr(template, "rio") else None
    if crs is not None:
        out = out.rio.write_crs(crs)
        out = out.rio.write_nodata(np.nan if np.dtype(out.dtype).kind == "f" else None,
                                   encoded=False)
    if product == "viewshed" and out.dtype == np.uint8:
        # the output values' viewshed stores its voids as 255: the file's nodata
        if hasattr(out, "rio"):
            out = out.rio.write_nodata(VIEWSHED_UINT8_NODATA, encoded=False)
        else:
            out.attrs["_FillValue"] = VIEWSHED_UINT8_NODATA
    return out


# ---- viewshed --------------------------------------------------------------------------

def _observers(observer, h):
    rows, cols = h.shape
    obs = np.asarray(observer, dtype=np.float64) if not isinstance(observer, np.ndarray) \
        else observer.astype(np.float64)
    single = obs.ndim == 1
    obs = np.atleast_2d(obs)
    if obs.ndim != 2 or obs.shape[1] != 2 or obs.shape[0] == 0:
        raise ValueError(f"observer: expected (x, y) or an (N, 2) array, got shape {np.shape(observer)}")
    for k, (x, y) in enumerate(obs):
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"observer[{k}]: non-finite position ({x}, {y})")
        if not (0 <= x <= cols - 1 and 0 <= y <= rows - 1):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}]")
    return obs, single


def _surface_float(h, x, y):
    rows, cols = h.shape
    i = min(max(int(math.floor(x)), 0), cols - 2)
    j = min(max(int(math.floor(y)), 0), rows - 2)
    u, v = x - i, y - j
    h00, h10, h01, h11 = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
    if u >= v:
        return float(h00 + (h10 - h00) * u + (h11 - h10) * v)
    return float(h00 + (h11 - h01) * u + (h01 - h00) * v)


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


def _touches_void(void, x, y):
    """Whether the grid point (x, y) lies in a cell one of whose corners is a void."""
    rows, cols = void.shape
    i0, j0 = int(math.floor(x)), int(math.floor(y))
    i_lo, i_hi = max(0, i0 - (x == i0)), min(cols - 1, i0 + 1)
    j_lo, j_hi = max(0, j0 - (y == j0)), min(rows - 1, j0 + 1)
    if x == i0 and y == j0:
        return bool(void[j0, i0])  # on a vertex: its own height is the observer's ground
    return bool(void[j_lo:j_hi + 1, i_lo:i_hi + 1].any())


#: What :func:`viewshed` returns per vertex (``mode``); see its docstring.
VIEWSHED_MODES = ("normal", "dem", "ground", "observer", "angle")
#: The observer's eye above the surface when ``observer_height`` is left out.
DEFAULT_OBSERVER_HEIGHT = 1.75
#: A uint8 viewshed with output values stores its voids as this (datasets_gen.raster).
VIEWSHED_UINT8_NODATA = 255


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


def _output_value(value, name, allow_nan=False):
    """An output value as a float: a real number, finite (NaN too where allowed)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                     np.floating)):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) or (allow_nan and math.isnan(v))):
        raise ValueError(f"{name}: expected a finite number{' or NaN' if allow_nan else ''}, "
                         f"got {value!r}")
    return v


def _height_above(value, name):
    """A height above the ground as a float: any finite number (negative: below it)."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite length (negative: below the ground), "
                         f"got {value!r}")
    return v


def _thicken(heights, observer):
    """A one-row or one-column array repeated to two rows (columns), and the slice that
    crops a result back; ``(heights, None)`` for any other input (a HeightField has two
    samples a side at least). Along the one line the repeated field's surface is the
    polyline through the samples, the line's own surface; observers must lie on it."""
    if isinstance(heights, (HeightField, str, bytes, dict)) or heights is None:
        return heights, None
    shape = np.shape(heights)
    if len(shape) != 2 or min(shape) != 1 or max(shape) > _kernels.MAX_GRID_SIDE:
        return heights, None
    rows, cols = shape
    for k, (x, y) in enumerate(np.atleast_2d(np.asarray(observer, dtype=np.float64))):
        if not ((y == 0 and 0 <= x <= cols - 1) if rows == 1 else (x == 0 and 0 <= y <= rows - 1)):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}] of a one-"
                             f"{'row' if rows == 1 else 'column'} raster (a line)")
    axis = 0 if rows == 1 else 1
    crop = (slice(0, 1), slice(None)) if axis == 0 else (slice(None), slice(0, 1))
    return np.repeat(np.asarray(heights), 2, axis=axis), crop


def viewshed(heights, observer, observer_height=None, target_height=0.0, max_distance=None,
             curvature=False, refraction=DEFAULT_REFRACTION, *, algorithm=None,
             surface="triangles", spacing=None, earth_radius=WGS84_SEMI_MAJOR_AXIS_M,
             threads=None, progress=None, mode="normal", visible_value=None,
             invisible_value=None, out_of_range_value=None, exact=False):
    """Which vertices an observer sees, or what it would take to see them.

    Vertex v is visible when the segment from the eye E = (ox, oy, s(ox, oy) +
    observer_height) to the target top (i, j, H[j, i] + target_height) never passes
    strictly below the surface, and, with ``max_distance``, when v lies within that
    horizontal distance. A line of sight is unchanged by scaling x, y and z, so
    rectangular pixels are exact too.

    The maths of the other modes. Let t in (0, 1) run along the segment, and let
    (t_k, sigma_k) be its breakpoints (module docstring: the surface is linear between
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
    (``cext/terrain/terrain.c``, ``hf_viewshed_threshold``); ``algos.terrain_ref`` holds the
    rational-arithmetic reference and the tests check both against brute force.

    Parameters
    ----------
    heights, spacing, algorithm, surface, threads
        As in :func:`horizon`. A one-row or one-column array is a line: its surface is
        the polyline through its samples, and observers must lie on it (a DataArray of
        that shape is refused: it has no pixel size along its short side).
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
        ``-cc 0.85714``) and GRASS (``r.viewshed refraction_coeff=0.14286``).
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

    Raises
    ------
    ValueError
        An observer outside the footprint or on a cell touching a void (its ground
        height is unknown); a mode other than "normal", or output values, with several
        observers or on a dask array (the tiled viewshed gives visibility only); and
        every bad argument, named.

    A dask array (or a HeightField holding one) gives a lazy result chunked like it, with
    one task per observer (its window of ``max_distance``, the whole array when unlimited,
    computed in memory) and one per chunk (:func:`algos.tiled.tiled_viewshed`); an observer
    on a cell touching a void raises when it is computed.
    """
    if mode not in VIEWSHED_MODES:
        raise ValueError(f"mode: expected one of {', '.join(VIEWSHED_MODES)}, got {mode!r}")
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
        return _to_dataarray(heights, lambda f: viewshed(
            f, observer, observer_height, target_height, max_distance, curvature, refraction,
            algorithm=algorithm, surface=surface, earth_radius=earth_radius, threads=threads,
            mode=mode, visible_value=visible_value, invisible_value=invisible_value,
            out_of_range_value=out_of_range_value, exact=exact), "viewshed", attrs)
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
    grid = _prepare(heights, spacing)
    h = grid.h
    given = np.asarray(observer, dtype=np.float64) if np.ndim(observer) else observer
    obs, single = _observers(given, h)
    if not single and (mode != "normal" or values_given):
        raise ValueError(f"observer: mode={mode!r}{' and output values' if values_given else ''}"
                         f" need one observer, got {len(obs)} (several give a count)")
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
    drop = 0.0
    if curvature:
        if not grid.has_unit:
            raise ValueError(_NO_UNIT_CURVATURE)
        if not grid.square:
            raise ValueError(f"curvature: needs square pixels, got {grid.dx:g} x {grid.dy:g}; "
                             "resample first (e.g. gdalwarp -tr D D)")
        r = float(refraction)
        if not (math.isfinite(r) and 0 <= r < 1):
            raise ValueError(f"refraction: expected a coefficient in [0, 1), got {refraction!r}")
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
    mip = _mipmap(h) if algorithm == "dda_maxmip" and mode not in ("angle",) else None
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
        LAST_STATS.__dict__.update(stats.__dict__)
        result = np.ascontiguousarray(grid.to_north_up(out))
        return result if crop is None else np.ascontiguousarray(result[crop])
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
    LAST_STATS.__dict__.update(stats.__dict__)
    if values_given:
        small = all(v == int(v) and 0 <= v < VIEWSHED_UINT8_NODATA for v in (vv, iv, ov))
        result = values.astype(np.uint8) if small else values
        grid.voids_to(result, VIEWSHED_UINT8_NODATA if small else math.nan)
    else:
        result = count.astype(bool) if single else count
    result = np.ascontiguousarray(grid.to_north_up(result))
    return result if crop is None else np.ascontiguousarray(result[crop])


# ---- timing entry for the benchmarks ------------------------------------------------------

def prepare_horizon_timed(heights, azimuth, algorithm, ranges=None, max_distance=None,
                          march_step=1.0, embree_tolerance=1e-4):
    """Validate and build once; return ``(run, values, n_vertices)``. Each ``run()``
    computes the horizon tangents of one azimuth again, single-threaded, and returns the
    nanoseconds measured around the C loop (around embreex's queries and the bisection for
    the Embree peer). ``values()`` gives the tangents of the latest run, NaN outside the
    vertices computed. ``ranges``: [(start, stop), ...] of C-order vertex indices, a
    sample for the per-vertex methods; the sweep always covers every vertex (it is one
    pass over shared lines; so do ``rows``, one pass per row, and ``chain``, whose
    vertices borrow from each other), and n_vertices says how many were computed."""
    h = _prepare(heights, None).h
    d = azimuth_direction(azimuth)
    name = _pick_horizon_algorithm(algorithm, [d], max_distance)
    rows, cols = h.shape
    n_all = rows * cols
    if name in ("rows", "chain"):
        mip = _mipmap(h) if name == "chain" else None
        latest = [np.full((rows, cols), np.nan)]

        def run():
            stats = TerrainStats(name)
            latest[0] = _horizon_one(h, d, name, max_distance, 1, mip, stats, march_step,
                                     embree_tolerance)
            return stats.ns
        return run, (lambda: latest[0].ravel().copy()), n_all
    ranges = [(0, n_all)] if ranges is None or name == "sweep" else \
        [(int(a), int(b)) for a, b in ranges]
    n_vertices = sum(b - a for a, b in ranges)
    md = math.inf if max_distance is None else float(max_distance)
    out = np.full(n_all, np.nan)
    if name in ("sweep", "pattern"):
        hf = np.ascontiguousarray(_to_frame(h, d))
        fr, fc = hf.shape
        frame_out = np.full(fr * fc, np.nan)
        # the sample's vertices, in the frame: ranges index the original C order
        if name == "sweep":
            def run():
                return _sweep(hf, d, frame_out)
        else:
            pat = _shared_pattern(d, fr, fc, max_distance)
            zmax = float(hf.max())
            index = _from_frame(np.arange(fr * fc).reshape(fr, fc), d).ravel()
            wanted = np.concatenate([index[a:b] for a, b in ranges])
            wanted.sort()
            # contiguous runs of frame indices
            breaks = np.flatnonzero(np.diff(wanted) != 1) + 1
            frame_ranges = [(int(s[0]), int(s[-1]) + 1) for s in np.split(wanted, breaks)]

            def run():
                return sum(_pattern_walk(hf, pat, zmax, a, b, frame_out) for a, b in frame_ranges)

        def values():
            full = _from_frame(frame_out.reshape(fr, fc), d).ravel()
            res = np.full(n_all, np.nan)
            for a, b in ranges:
                res[a:b] = full[a:b]
            return res
        return run, values, n_vertices
    if name in ("dda", "dda_maxmip", "march"):
        mip = _mipmap(h) if name == "dda_maxmip" else None
        zmax = float(h.max())

        def run():
            total = 0
            for a, b in ranges:
                if name == "march":
                    total += _kernels.horizon_march(h, d.dx, d.dy, march_step, md, zmax, a, b, out)[0]
                else:
                    total += _kernels.horizon_walk(h, mip, d.dx, d.dy, md, a, b, out)[0]
            return total
        return run, (lambda: out.copy()), n_vertices
    from .embree_peer import embree_horizon

    peer = embree_horizon(h)  # built once per field, outside the timed call
    vertices = np.concatenate([np.arange(a, b) for a, b in ranges])

    def run():
        start = time.perf_counter_ns()
        out[vertices] = peer.tangents(d.dx, d.dy, md, embree_tolerance, vertices)
        return time.perf_counter_ns() - start
    return run, (lambda: out.copy()), n_vertices

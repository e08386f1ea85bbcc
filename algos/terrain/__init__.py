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
  (:mod:`algos.terrain.reference`) to rounding (1e-12 in the tests).
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
reference (:mod:`algos.terrain.reference`) does the same in rational arithmetic, deciding
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
"dda_maxmip", and an explicit "sweep" (or the "embree" peer) raises; the statistics
(``return_stats=True``) name the path that ran. A negative kappa raises the surface instead (the mirror of a
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
distance, needs square pixels. ``tests/gis/test_georef.py`` checks rectangular pixels against
a brute-force horizon written in map space.

Orientation: a field whose rows run north (a south-up raster, the embedded DEM) is
flipped to north-up by :meth:`HeightField.to_north_up`, the one place that does it, and
every result is flipped back: outputs are on the input's grid and orientation.

Statistics
----------
Every product takes ``return_stats=True`` and then returns ``(result, stats)``, where
``stats`` is a :class:`~algos.terrain.stats.TerrainStats`: the algorithm of each azimuth
(``paths``), the C time, cells, tile skips and the snapping of that one call. Nothing is
kept in module state, so calls on several threads (dask tiles) never mix their figures.
A DataArray result also records ``algorithm``, ``paths`` and the snapping in its attrs.

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

from .algorithms import HORIZON_ALGORITHMS, PATTERN_MAX_DISTANCE, VIEWSHED_ALGORITHMS, TerrainAlgorithm  # noqa: F401
from .azimuths import rational_azimuths, snap_azimuths
from .curvature import CURVATURE_REFUSED, DEFAULT_REFRACTION
from .directions import MAX_SNAP_DENOMINATOR, SNAP_TOLERANCE_DEG, Direction, azimuth_direction  # noqa: F401
from .grid import HEIGHT_LIMIT, VOID_HEIGHT, VOID_HEIGHT_LIMIT, Grid, _prepare  # noqa: F401
from .horizon import ANGLE_UNITS, horizon
from .observers import DEFAULT_OBSERVER_HEIGHT, VIEWSHED_MODES, VIEWSHED_UINT8_NODATA, _surface_float, _touches_void  # noqa: F401
from .openness import OPENNESS_KINDS, openness
from .patterns import PATTERN_STOP_EVERY  # noqa: F401
from .reference import horizon_reference, line_of_sight_exact, surface_exact, viewshed_reference  # noqa: F401
from .shadows import shadows
from .sky_view import _sin_of_positive_atan, sky_view_factor  # noqa: F401
from .stats import TerrainStats
from .tiled import halo_depth, tiled_product, tiled_viewshed, viewshed_window  # noqa: F401
from .viewshed import viewshed
from .walks import CHAIN_BLOCK_ROWS, CHAIN_MAX_DENOMINATOR, CHAIN_MAX_OFFSET, chain_neighbours, prepare_horizon_timed  # noqa: F401

__all__ = ["horizon", "shadows", "sky_view_factor", "openness", "viewshed",
           "rational_azimuths",
           "azimuth_direction", "HORIZON_ALGORITHMS", "VIEWSHED_ALGORITHMS", "TerrainAlgorithm",
           "MAX_SNAP_DENOMINATOR", "DEFAULT_REFRACTION", "TerrainStats", "Grid",
           "VOID_HEIGHT", "VIEWSHED_MODES", "ANGLE_UNITS", "OPENNESS_KINDS",
           "CURVATURE_REFUSED", "snap_azimuths", "chain_neighbours"]

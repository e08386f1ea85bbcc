"""A terrain product's view of its input (:class:`Grid`): validated heights in cell
units, north-up, voids as deep pits, and the pixel size that relates them to the map."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _kernels
from ..field import HeightField, is_dataarray
from ..parallel import run_ranges
from ..validate import check_spacing

__all__ = ["Grid", "VOID_HEIGHT", "VOID_HEIGHT_LIMIT", "HEIGHT_LIMIT"]

#: Heights (in cells) beyond this magnitude are refused: slopes between them stay finite.
HEIGHT_LIMIT = 1e30


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

    def stretch(self, d) -> float:
        """Map length per unit of cell-space distance along the direction ``d`` (a
        :class:`~algos.terrain.directions.Direction`):
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
#: rounding: "a void blocks nothing" (package docstring, "Voids").
VOID_HEIGHT = -1e28
#: Valid heights (cell units) must stay within this when a field has voids.
VOID_HEIGHT_LIMIT = 1e18


def _prepare(heights, spacing, *, name="heights", divide=True) -> Grid:
    """The :class:`Grid` of a raw array (north-up; ``spacing``: None for cell units, or
    the pixel size in the heights' unit) or of a HeightField (its own spacing, units,
    orientation and voids; ``spacing`` must then be left out or agree).

    ``divide=False`` keeps heights given in map units as they are (``z_scale`` 1), for a
    caller whose answer does not change when z is scaled (a line of sight without
    curvature): dividing them by ``dx`` would round them (1 / 30 is no float64), and an
    exact tie of the stored heights would no longer be one. Heights already in cells are
    unchanged either way."""
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
        if np.ma.isMaskedArray(heights):  # the mask marks voids, as a HeightField's does
            raw = np.ma.getdata(heights)
            void = np.ma.getmaskarray(heights) | np.isnan(raw)
            void = void if void.any() else None
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
    if not divide and divisor != 1.0:
        divisor = z_scale = 1.0
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


def _check_surface(surface):
    if surface != "triangles":
        raise ValueError(f"surface: the terrain products are defined on 'triangles' (the "
                         f"default), got {surface!r}")


def _field_spacing(heights, spacing):
    """(dx, dy) of a product's input: a HeightField's or DataArray's own, else ``spacing``
    (cell units when None)."""
    field = heights if isinstance(heights, HeightField) else None
    if field is None and is_dataarray(heights):
        field = HeightField.from_dataarray(heights)
    if field is not None:
        return field.dx, field.dy
    return check_spacing(spacing) if spacing is not None else (1.0, 1.0)

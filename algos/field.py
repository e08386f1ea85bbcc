"""The height-field type every public function takes (:class:`HeightField`, also
``algos.Field`` and ``datasets_gen.HeightField``): heights, their spacing, unit, CRS,
geotransform, orientation and nodata mask, plus the acceleration structures of first
hits, each built on first use and kept (build once per field, build only what the
requested kernels use). First hits and renders read :attr:`HeightField.cell_heights`,
the heights in cell units.

Structures (all float32; ``nx = cols - 1``, ``ny = rows - 1`` cells):

* ``cellmax`` (ny, nx): an upper bound of each cell's surface, so a ray whose lowest z
  over a cell is above it cannot hit there. For ``flat``, ``triangles`` and ``bilinear``
  it is the maximum of the four corners (each surface stays within their hull); the
  ``plane3`` plane through three corners reaches ``h10 + h01 - h00`` at the fourth, so
  its bound includes that value (and so do its ``hmin``/``hmax``). ``4 nx ny`` bytes per
  bound kind.
* ``row_max`` / ``col_max``: range maxima of ``cellmax`` along rows (runs along x) and
  along columns (runs along y), answered in O(1) for a run spanning two blocks of
  ``2**RMQ_BLOCK_SHIFT`` (8) cells: per-cell prefix and suffix maxima within blocks plus a
  sparse table over block maxima (``cext/surfaces/cell_test.h``, ``hf_rmq_query``). About
  ``(3 + log2(nx / 8) / 8) * 4 nx ny`` bytes per direction (the column one keeps a
  transposed copy of ``cellmax``).
* ``mip``: the maximum mipmap (Tevs, Ihrke & Seidel 2008): level 0 is ``cellmax``, level
  k holds maxima over 2^k x 2^k cells, sizes rounded up so every grid size works. About
  ``4/3 * 4 nx ny`` bytes.

Bytes per cell each intersector needs besides the heights (4 B per sample, float32; a
memory-mapped ``.npy`` is used in place, never copied):

=====================================  =========================================
dda, dda_f32, midpoint, runs*          4 (cellmax)
runs* with ``cull_runs=True``          4 + about 2 x (12 + log2(n / 8) / 2)
dda_maxmip, runs_maxmip                4 x 4/3 (cellmax is mip level 0)
runs_maxmip on ``Field(lean=True)``    4 x 4/3 / 4^fine_level (0.08 at level 3)
marching                               0
embree                                 measured: ``build_stats["embree"]``
=====================================  =========================================

Validation, ``cellmax`` and every mipmap level are built in streaming passes over bands
of ``BAND_SAMPLES`` samples, so the extra memory of those builds is their result plus a
few MiB. The range-maximum tables of run culling are built whole (temporaries about as
large as the tables): on a field near the memory limit, leave ``cull_runs`` off or use
the lean layout.

``Field(heights, lean=True)`` is the layout for fields near the memory limit:
``runs_maxmip`` then runs without per-cell culling (measured about 5 % slower at fbm
2048^2, reports/scaling) on mipmap levels from ``fine_level`` up, built from the heights
directly; the other intersectors build what they need as usual.
"""
from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np

from . import hugepages
from .accel.maxima import BAND_SAMPLES, RMQ_BLOCK_SHIFT, band_rows, cellmax_rows, range_max
from .accel.mipmap import max_mipmap, tile_max_rows
from .decode import decode
from .georef import (
    LINEAR_UNITS,
    UNIT_ALIASES,
    check_crs,
    check_dataarray_georeferencing,
    check_height_units,
    crs_unit,
    pixel_size,
    unit_name,
)
from .validate import as_float_array, check_heights, check_spacing

__all__ = ["HeightField", "Field", "RMQ_BLOCK_SHIFT", "as_field", "bound_kind", "max_mipmap",
           "is_dask", "is_dataarray", "BAND_SAMPLES"]


def is_dask(x) -> bool:
    """A dask array (or a HeightField or DataArray holding one)."""
    x = getattr(x, "heights", x)
    x = getattr(x, "data", x) if is_dataarray(x) else x
    return type(x).__module__.split(".")[0] == "dask" and hasattr(x, "map_overlap")


def is_dataarray(x) -> bool:
    """An ``xarray.DataArray`` (checked without importing xarray)."""
    return type(x).__name__ == "DataArray" and type(x).__module__.split(".")[0] == "xarray"


_LEGACY = ("HeightField(heights, name, spacing, unit, params) with positional spacing and "
           "unit held heights in cell units; that form is gone. Heights are now in the unit "
           "of the pixel size: HeightField(heights_in_metres, name, spacing=30.0, unit='m'), "
           "or, for heights already in cells, HeightField(cells, name, spacing=30.0, "
           "unit='m', height_unit='cell')")


@dataclass(eq=False, init=False)
class HeightField:
    """A height field: heights on a regular grid, where it lies, what is missing, and its
    acceleration structures for first hits (built on first use and kept).

    The one type every public function takes: :func:`algos.traverse` (as its grid),
    :func:`algos.intersect`, the terrain products and the renderer.
    ``datasets_gen.HeightField`` and ``algos.Field`` are this class.

    Parameters
    ----------
    heights : array_like (rows, cols) or dask array
        ``heights[j, i]`` is the height of vertex ``(x=i, y=j)``. NumPy input is kept as
        C-contiguous float32 (not copied when it already is, so a memory-mapped file stays
        mapped); a dask array stays lazy. NaN marks a void unless ``nodata_mask`` is given;
        a NumPy masked array's masked samples are voids too (its values there are never
        read as heights). Finite float64 heights beyond float32's range (3.4e38) raise.
    name : str
    spacing : float or (dx, dy)
        Pixel size, positive lengths in ``unit`` (x along columns, y along rows). 1 means
        cell units.
    unit : str, optional
        The linear unit of ``spacing`` and of every length a product takes
        (``max_distance``, ``observer_height``, ``target_height``): one of
        :data:`algos.georef.LINEAR_UNITS` (``"m"``, ``"km"``, ``"ft"``, the international
        foot of 0.3048 m, ``"US survey foot"``, 1200/3937 m) or an alias of
        :data:`algos.georef.UNIT_ALIASES` (``"metre"``, ``"meter"``, ``"foot"``,
        ``"us-ft"``, ...), stored under its main name. Default ``"cell"`` for spacing 1,
        else ``"map unit"``: these two are no real unit, and curvature refuses them.
        With a ``crs`` its linear unit (rasterio's ``CRS.linear_units_factor``) is the
        field's unit; a ``unit`` that names another raises.
    height_unit : str, optional
        The unit of ``heights``: ``unit`` (the default: heights in the same linear unit as
        the pixel size, as in a DEM) or ``"cell"`` (heights in multiples of the pixel size,
        the kernels' own unit, square pixels only: how generated fields and the embedded
        DEM are stored, so that the kernels' studies read them unchanged).
    crs : rasterio CRS, WKT or EPSG string, optional
        A projected CRS (its linear unit becomes ``unit``). A geographic CRS (degrees)
        is refused, as :func:`datasets_gen.load_file` refuses such a file, with the
        ``gdalwarp`` command that reprojects it.
    transform : affine.Affine, optional
        The geotransform of the stored array (pixel corners); when given, ``spacing`` and
        ``north`` come from it. Rotated or sheared transforms are refused.
    nodata_mask : bool array (rows, cols), optional
        True at void vertices (nodata). Default: where the heights are not finite.
    north : {"-y", "+y"}
        Where north is in the stored array: ``"-y"`` (row 0 is the northern edge, as in a
        north-up raster) or ``"+y"`` (rows run north: a south-up raster, or the embedded
        DEM). The terrain products work north-up and return arrays in the stored
        orientation; :meth:`to_north_up` is the one place that flips.
    params : dict
        Where the field came from (generator parameters, file path, ...).
    lean : bool
        The lean first-hit layout of ``runs_maxmip`` (module docstring).

    Attributes
    ----------
    spacing : float or (dx, dy)
        One number for square pixels, else the pair; :attr:`dx` and :attr:`dy` always.
    rows, cols, shape : the grid's size in samples.
    cell_heights : float32 heights in cell units (first hits and renders).
    unit_metres : float or None
        Metres per ``unit`` (None for ``"cell"`` and ``"map unit"``); mirrored in
        ``params["unit_metres"]``, where a disagreeing value given raises.

    Raises
    ------
    TypeError
        Heights that are not real numbers, or the old positional form
        ``HeightField(heights, name, spacing, unit)``, whose heights were in cell units.
    ValueError
        A shape outside [2, 2**24] per side, a bad spacing or transform, a unit outside
        the accepted names or contradicting the CRS's, a geographic CRS, a finite height
        beyond float32's range that is not a void (naming the sample and its value).
    """

    heights: object
    name: str = "heights"
    spacing: object = 1.0
    unit: str = "cell"
    height_unit: str = "cell"
    crs: object = None
    transform: object = None
    nodata_mask: object = None
    north: str = "-y"
    params: dict = dc_field(default_factory=dict)
    lean: bool = False

    def __init__(self, heights, name="heights", *legacy, spacing=None, unit=None,
                 height_unit=None, crs=None, transform=None, nodata_mask=None, north=None,
                 params=None, lean=False):
        if legacy:
            raise TypeError(f"HeightField: {_LEGACY}")
        if isinstance(heights, HeightField):
            raise TypeError("heights: already a HeightField (use dataclasses.replace to "
                            "change it)")
        if is_dataarray(heights):
            raise TypeError("heights: an xarray.DataArray; use HeightField.from_dataarray")
        declared = None  # voids the caller marked: a masked array's mask, nodata_mask
        if np.ma.isMaskedArray(heights):
            # the mask marks voids (rasterio's read(masked=True), np.ma.masked_equal): the
            # values under it are placeholders, never heights
            declared = np.ma.getmaskarray(heights)
            heights = np.ma.getdata(heights)
        self.name = str(name)
        self.params = dict(params or {})
        self.lean = bool(lean)
        self.crs = crs
        self.transform = transform
        if transform is not None:
            dx, dy, north_up = pixel_size(transform)
            if spacing is not None and check_spacing(spacing) != (dx, dy):
                raise ValueError(f"spacing: {spacing!r} disagrees with the transform's pixel "
                                 f"size ({dx:g}, {dy:g})")
            given_north = "-y" if north_up else "+y"
            if north is not None and north != given_north:
                raise ValueError(f"north: {north!r} disagrees with the transform (north is "
                                 f"{given_north})")
            north = given_north
        else:
            dx, dy = check_spacing(1.0 if spacing is None else spacing)
        self.spacing = dx if dx == dy else (dx, dy)
        if north is None:
            north = self.params.get("north", "-y")
        if north not in ("-y", "+y"):
            raise ValueError(f"north: expected '-y' (row 0 is north) or '+y' (rows run "
                             f"north), got {north!r}")
        self.north = north
        # params["north"] mirrors it for scripts written before the field had it
        if north == "+y":
            self.params["north"] = "+y"
        else:
            self.params.pop("north", None)
        if is_dask(heights):
            if heights.ndim != 2:
                raise ValueError(f"heights: expected a 2D array (rows, cols), got shape "
                                 f"{heights.shape}")
            self.heights = heights
        else:
            h = check_heights(heights, finite=False)
            given = None if nodata_mask is None or is_dask(nodata_mask) else np.asarray(nodata_mask)
            if given is not None and given.shape == h.shape and given.dtype == bool:
                declared = given if declared is None else declared | given
            _check_float32_range(heights, h, declared)
            if isinstance(heights, np.memmap) and h.dtype == heights.dtype and \
                    heights.flags.c_contiguous and np.shares_memory(h, heights):
                h = heights  # a memory-mapped file stays a np.memmap: used in place
            self.heights = h
        self.rows, self.cols = (int(v) for v in self.heights.shape)
        self.unit, self.unit_metres = self._resolve_unit(unit, dx, dy)
        if self.unit_metres is None:
            self.params.pop("unit_metres", None)
        else:
            given = self.params.get("unit_metres")
            if given is not None and not math.isclose(float(given), self.unit_metres,
                                                      rel_tol=1e-12):
                raise ValueError(f"params['unit_metres']: {given!r} disagrees with the unit "
                                 f"{self.unit!r} ({self.unit_metres!r} m); give unit= only")
            # mirrored for scripts written before the field had it
            self.params["unit_metres"] = self.unit_metres
        self.height_unit = self.unit if height_unit is None else str(height_unit)
        if self.height_unit not in (self.unit, "cell"):
            raise ValueError(f"height_unit: expected {self.unit!r} (the pixel size's unit) or "
                             f"'cell', got {height_unit!r}")
        if self.height_unit == "cell" and dx != dy:
            raise ValueError(f"height_unit: 'cell' needs square pixels, got spacing "
                             f"({dx:g}, {dy:g}); give the heights in {self.unit!r}")
        self.nodata_mask = self._mask(nodata_mask, declared)
        self.build_stats: dict[str, dict] = {}
        self._cache: dict[str, object] = {}

    def _resolve_unit(self, unit, dx, dy):
        """``(unit, metres per unit or None)``: the CRS's linear unit when there is a CRS
        (rasterio's name and factor; a geographic CRS and a contradicting ``unit`` raise),
        else ``unit`` checked against :data:`algos.georef.LINEAR_UNITS` (default ``"cell"``
        for spacing 1, else ``"map unit"``: no real unit)."""
        if self.crs is not None:
            bounds, pixel = None, (dx, dy)
            if self.transform is not None:
                from rasterio.coords import BoundingBox
                from rasterio.transform import array_bounds

                west, south, east, north = array_bounds(self.rows, self.cols, self.transform)
                bounds = BoundingBox(min(west, east), min(south, north), max(west, east),
                                     max(south, north))
                pixel = (self.transform.a, self.transform.e)
            name, metres = crs_unit(self.crs, "crs", bounds=bounds, pixel=pixel,
                                    source="IN.tif", heights_converted="heights_converted_from"
                                    in self.params)
            if unit is not None and UNIT_ALIASES.get(unit, unit) != name:
                raise ValueError(f"unit: {unit!r} contradicts the CRS's linear unit {name!r} "
                                 f"({metres!r} m); the CRS's unit is the field's unit: leave "
                                 "unit out")
            return name, metres
        if unit is None:
            return ("cell" if (dx, dy) == (1.0, 1.0) else "map unit"), None
        name = unit_name(unit)
        return name, LINEAR_UNITS.get(name)

    def _mask(self, given, declared=None):
        """The void mask: given, else where numpy heights are not finite (None: none);
        with a masked array's mask (``declared``) its masked samples too."""
        if declared is not None and given is None:
            mask = ~np.isfinite(self.heights) | declared
            return mask if mask.any() else None
        if given is not None:
            if is_dask(given):
                return given
            mask = np.asarray(given)
            if mask.shape != self.heights.shape or mask.dtype != bool:
                raise ValueError(f"nodata_mask: expected a bool array of shape "
                                 f"{self.heights.shape}, got {mask.dtype} {mask.shape}")
            if declared is not None:
                mask = mask | declared
            return mask if mask.any() else None
        if is_dask(self.heights):
            return None
        step = band_rows(self.cols)
        bands = [(r0, ~np.isfinite(self.heights[r0:r0 + step]))
                 for r0 in range(0, self.rows, step)]
        if not any(b.any() for _, b in bands):
            return None
        return np.concatenate([b for _, b in bands])

    # ---- construction -----------------------------------------------------------------
    @classmethod
    def from_dataarray(cls, array, name=None, *, spacing=None, unit=None):
        """A HeightField from a 2D ``xarray.DataArray``: its values (a dask-backed one stays
        lazy), its CRS, transform and nodata through rioxarray (``rio.crs``,
        ``rio.transform()``, ``rio.nodata``; NaN is a void too). Without rioxarray, or
        without spatial coordinates, ``spacing`` (default 1: cell units) describes the
        pixels. The CRS's linear unit is the field's unit; without a CRS, ``unit`` names
        it (as for the constructor; default none: curvature refuses the field). A
        geographic CRS is refused (:func:`algos.georef.check_crs`), and so is an array
        read from a raster placed by GCPs, RPCs or geolocation arrays
        (:func:`algos.georef.check_dataarray_georeferencing`). Raw values are decoded by
        the scale, offset and fill attributes they carry (:func:`algos.decode.decode`:
        rioxarray's default ``open_rasterio`` keeps counts with ``scale_factor`` and
        ``add_offset``)."""
        if array.ndim != 2:
            raise ValueError(f"heights: expected a 2D DataArray, got dims {array.dims}")
        data = array.data
        crs = transform = nodata = None
        try:
            import rioxarray  # noqa: F401  (registers the .rio accessor)
        except ImportError:
            rio = None
        else:
            rio = array.rio
        if rio is not None:
            try:
                crs = rio.crs
                transform = rio.transform(recalc=True)
                nodata = rio.nodata if rio.encoded_nodata is None else None
            except Exception:  # no spatial dimensions: a plain array
                crs = transform = None
        if rio is not None:
            # rows are y: an array stored (x, y) would be traced with east and south swapped
            try:
                x_dim, y_dim = rio.x_dim, rio.y_dim
            except Exception:  # no spatial dimensions
                x_dim = y_dim = None
            if x_dim is not None and tuple(array.dims) == (x_dim, y_dim):
                raise ValueError(f"heights: the DataArray's dims {tuple(array.dims)} put x "
                                 f"first; rows must be y: pass "
                                 f"array.transpose({y_dim!r}, {x_dim!r})")
        if transform is not None and crs is None and tuple(transform)[:6] == \
                (1.0, 0.0, 0.0, 0.0, 1.0, 0.0):
            transform = None  # rioxarray's answer for an array without coordinates
        if transform is not None and spacing is not None:
            raise ValueError("spacing: the DataArray's coordinates give the pixel size; "
                             "leave spacing out")
        what = f"DataArray {array.name!r}"
        if transform is None or tuple(transform)[:6] == (1.0, 0.0, 0.0, 0.0, 1.0, 0.0):
            check_dataarray_georeferencing(array, what)
        if crs is not None:
            unit = check_crs(crs, what)
            check_height_units(array.attrs.get("units"), unit, what)
        # raw values with their scale, offset and fill values in attrs are decoded here;
        # rioxarray's encoded nodata belongs to values its decoder has masked already
        extra = None if nodata is None or (isinstance(nodata, float) and math.isnan(nodata)) \
            else [nodata]
        data, mask = decode(array, data, what, extra_fills=extra)
        if mask is not None and not is_dask(data):
            mask = np.asarray(mask) | ~np.isfinite(data)  # NaN samples are voids too
        return cls(data, name if name is not None else str(array.name or "DataArray"),
                   spacing=None if transform is not None else spacing, unit=unit, crs=crs,
                   transform=transform, nodata_mask=mask,
                   params=dict(source="xarray.DataArray"))

    # ---- units and orientation ----------------------------------------------------------
    @property
    def shape(self):
        return (self.rows, self.cols)

    @property
    def dx(self) -> float:
        """Pixel size along x (columns), in ``unit``."""
        return self.spacing[0] if isinstance(self.spacing, tuple) else self.spacing

    @property
    def dy(self) -> float:
        """Pixel size along y (rows), in ``unit``."""
        return self.spacing[1] if isinstance(self.spacing, tuple) else self.spacing

    @property
    def north_up(self) -> bool:
        """Row 0 is the northern edge."""
        return self.north == "-y"

    def to_north_up(self, array):
        """``array`` (rows, cols, or (K, rows, cols)) in the stored orientation, flipped to
        north-up when the rows run north; its own inverse (outputs go back the same way).
        The one place where orientation is handled."""
        if self.north_up:
            return array
        return array[..., ::-1, :]

    def north_up_row(self, row):
        """The row index (a number or an array, fractions allowed) of the same point
        counted north-up; its own inverse. The point version of :meth:`to_north_up`."""
        return row if self.north_up else (self.rows - 1) - row

    def grid_to_map(self, col, row):
        """Map coordinates ``(x, y)`` of the grid point ``(col, row)`` (vertex ``(i, j)``
        is ``H[j, i]``, fractions allowed); vertices are pixel centres."""
        if self.transform is None:
            raise ValueError(f"{self.name}: not georeferenced (no transform); give grid "
                             "coordinates (col, row) instead")
        t = self.transform
        c, r = float(col) + 0.5, float(row) + 0.5  # vertices are pixel centres
        return t.a * c + t.b * r + t.c, t.d * c + t.e * r + t.f

    def map_to_grid(self, x, y, *, what=None):
        """Grid ``(col, row)`` (floats, vertex units, stored orientation) of the map point
        ``(x, y)``; raises ValueError, echoing ``what`` (default the typed pair) when the
        point lies outside the footprint ``[0, cols-1] x [0, rows-1]``."""
        typed = what if what is not None else f"({x}, {y})"
        if self.transform is None:
            raise ValueError(f"observer {typed}: {self.name} is not georeferenced (no "
                             "transform); give grid coordinates (col, row) instead")
        try:
            x, y = float(x), float(y)
        except (TypeError, ValueError):
            raise TypeError(f"observer {typed}: expected two numbers") from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"observer {typed}: not a finite position")
        t = self.transform  # axis-aligned (checked on construction)
        col, row = (x - t.c) / t.a - 0.5, (y - t.f) / t.e - 0.5
        # exact at vertices: (x, y) computed from a vertex comes back to it
        col = round(col) if abs(col - round(col)) < 1e-9 else col
        row = round(row) if abs(row - round(row)) < 1e-9 else row
        if not (0 <= col <= self.cols - 1 and 0 <= row <= self.rows - 1):
            lo_x, lo_y = self.grid_to_map(0, 0)
            hi_x, hi_y = self.grid_to_map(self.cols - 1, self.rows - 1)
            raise ValueError(
                f"observer {typed}: outside {self.name}, whose vertices span x "
                f"{min(lo_x, hi_x):.10g}..{max(lo_x, hi_x):.10g} and y "
                f"{min(lo_y, hi_y):.10g}..{max(lo_y, hi_y):.10g} (CRS {self.crs})")
        return float(col), float(row)

    # ---- the kernels' view ----------------------------------------------------------------
    @property
    def cell_heights(self) -> np.ndarray:
        """The heights in cell units (the kernels' unit), C-contiguous float32, finite:
        ``heights`` itself when they already are in cells, else ``heights / spacing``.
        Needs square pixels and no voids; computed once."""
        if "cell_heights" not in self._cache:
            if is_dask(self.heights):
                raise TypeError(f"heights: {self.name} holds a dask array; first hits need it "
                                "in memory (the terrain products take it tiled)")
            if self.nodata_mask is not None:
                row, col = (int(v) for v in np.argwhere(self.nodata_mask)[0])
                value = self.heights[row, col]
                # a masked or nodata-valued sample stores a finite value: say it is a void
                what = (f"{value} (nodata)" if not np.isfinite(value)
                        else f"a void (nodata; stored value {value})")
                raise ValueError(f"heights: sample (row {row}, col {col}) is {what}; first "
                                 "hits need every sample: fill the voids first "
                                 "(HeightField.filled)")
            if self.height_unit == "cell" or (self.dx == 1.0 and self.dy == 1.0):
                # no void mask means every sample was found finite on construction
                h = check_heights(self.heights, finite=False)
            elif self.dx == self.dy:
                h = check_heights(np.asarray(self.heights, dtype=np.float64) / self.dx)
            else:
                raise ValueError(f"heights: {self.name} has rectangular pixels "
                                 f"({self.dx:g} x {self.dy:g} {self.unit}); first hits and "
                                 "renders work in cell units and need square pixels")
            # a copy made here goes on huge pages; the caller's array stays where it is
            self._cache["cell_heights"] = hugepages.adopt(h, owner=self.heights)
        return self._cache["cell_heights"]

    @property
    def hmin(self) -> float:
        """Lowest cell height."""
        if "hmin" not in self._cache:
            self._cache["hmin"] = float(self.cell_heights.min())
        return self._cache["hmin"]

    @property
    def hmax(self) -> float:
        """Highest cell height."""
        if "hmax" not in self._cache:
            self._cache["hmax"] = float(self.cell_heights.max())
        return self._cache["hmax"]

    @property
    def checksum(self) -> str:
        """SHA-256 of the heights' float32 bytes (C order, little-endian)."""
        data = np.ascontiguousarray(self.heights, dtype="<f4")
        return hashlib.sha256(data.tobytes()).hexdigest()

    def filled(self, policy="min", value=None) -> "HeightField":
        """A copy whose void vertices hold a height, an explicit policy: ``"min"`` the
        lowest valid height, ``"value"`` the given ``value``. The products do not need
        it (voids are handled, see :mod:`algos.terrain`); first hits do."""
        if self.nodata_mask is None:
            return self
        h = np.array(self.heights, dtype=np.float32)
        if policy == "min":
            valid = h[~self.nodata_mask]
            if valid.size == 0:
                raise ValueError(f"{self.name}: every sample is nodata; nothing to fill with")
            fill = valid.min()
        elif policy == "value":
            if value is None or not math.isfinite(float(value)):
                raise ValueError(f"value: policy='value' needs a finite value, got {value!r}")
            fill = float(value)
        else:
            raise ValueError(f"policy: expected 'min' or 'value', got {policy!r}")
        h[self.nodata_mask] = fill
        params = dict(self.params, filled=policy if policy == "min" else float(fill))
        return HeightField(h, self.name, spacing=self.spacing, unit=self.unit,
                           height_unit=self.height_unit, crs=self.crs, transform=self.transform,
                           north=None if self.transform is not None else self.north,
                           params=params, lean=self.lean,
                           nodata_mask=np.zeros(self.shape, dtype=bool))

    # ---- acceleration structures (first hits) ----------------------------------------------
    def _build(self, name, make):
        if name not in self._cache:
            start = time.perf_counter()
            value = make()
            seconds = time.perf_counter() - start
            arrays = value if isinstance(value, (list, tuple)) else [value]
            nbytes = sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
            if name.startswith("row_max"):  # shares `values` with cellmax
                nbytes -= value[0].nbytes
            if name.startswith("mip") and value[0] is not None:  # level 0 is cellmax
                nbytes -= value[0].nbytes
            self._cache[name] = value
            self.build_stats[name] = {"seconds": seconds, "bytes": int(nbytes)}
        return self._cache[name]

    def store(self, name: str, value, stats: dict) -> None:
        """Keep a structure built outside this module (the Embree scene) with its build
        statistics (``{"seconds", "bytes", ...}``, reported in :attr:`build_stats`)."""
        self._cache[name] = value
        self.build_stats[name] = dict(stats)

    def stored(self, name: str):
        """A structure kept by :meth:`store` (or built here), or None."""
        return self._cache.get(name)

    @staticmethod
    def _key(name, kind):
        return name if kind == "corners" else f"{name}/{kind}"

    def cellmax_for(self, kind="corners") -> np.ndarray:
        h = self.cell_heights

        def make():  # in bands: the only full-size array is the result
            out = hugepages.empty((self.rows - 1, self.cols - 1), np.float32)
            step = band_rows(self.cols)
            for r0 in range(0, self.rows - 1, step):
                r1 = min(self.rows - 1, r0 + step)
                out[r0:r1] = cellmax_rows(h, kind, r0, r1)
            return out

        return self._build(self._key("cellmax", kind), make)

    def zrange_for(self, kind="corners") -> tuple[float, float]:
        """Lowest and highest surface height over the field, for the box clip."""
        if kind == "corners":
            return self.hmin, self.hmax
        h = self.cell_heights.astype(np.float64)
        fourth = h[:-1, 1:] + h[1:, :-1] - h[:-1, :-1]
        return min(self.hmin, float(fourth.min())), max(self.hmax, float(fourth.max()))

    def row_max_for(self, kind="corners"):
        return self._build(self._key("row_max", kind),
                           lambda: range_max(self.cellmax_for(kind), RMQ_BLOCK_SHIFT))

    def col_max_for(self, kind="corners"):
        return self._build(self._key("col_max", kind),
                           lambda: range_max(self.cellmax_for(kind).T, RMQ_BLOCK_SHIFT))

    def mip_for(self, kind="corners", from_level=0) -> list:
        """The maximum mipmap; with ``from_level`` > 0 (the lean layout) the levels below
        it are ``None`` and the rest are built from the heights in bands, without the
        full-size cell maxima."""
        if from_level <= 0:
            return self._build(self._key("mip", kind), lambda: max_mipmap(self.cellmax_for(kind)))

        def make():
            return [None] * from_level + max_mipmap(
                tile_max_rows(self.cell_heights, kind, from_level))

        return self._build(self._key(f"mip{from_level}", kind), make)

    # the structures for the three surfaces that stay within their corners
    cellmax = property(lambda self: self.cellmax_for())
    row_max = property(lambda self: self.row_max_for())
    col_max = property(lambda self: self.col_max_for())
    mip = property(lambda self: self.mip_for())

    @property
    def nbytes(self) -> int:
        """Bytes of the heights plus every structure built so far."""
        return self.heights.nbytes + sum(s["bytes"] for s in self.build_stats.values()
                                         if isinstance(s.get("bytes"), int))


#: The same class under its first-hit name (kept: outside scripts import it).
Field = HeightField

#: The largest float32, the type heights are kept in
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _check_float32_range(source, stored, voids=None) -> None:
    """ValueError naming the first sample that is finite in ``source`` (float64 or wider)
    but beyond float32's range, so infinite in its float32 copy ``stored``, unless
    ``voids`` (bool, the same shape) marks it; in bands of rows."""
    source = np.asarray(source)
    if source.dtype.kind != "f" or source.dtype.itemsize <= 4:
        return
    step = band_rows(stored.shape[1])
    for r0 in range(0, stored.shape[0], step):
        over = np.isinf(stored[r0:r0 + step]) & np.isfinite(source[r0:r0 + step])
        if voids is not None:
            over &= ~voids[r0:r0 + step]
        if over.any():
            row, col = (int(v) for v in np.argwhere(over)[0])
            row += r0
            raise ValueError(f"heights: sample (row {row}, col {col}) = {float(source[row, col])!r} "
                             "is beyond float32's range, the type heights are kept in "
                             f"(it rounds to infinity; the largest float32 is {FLOAT32_MAX:.8g}); "
                             "mark it as a void (NaN, nodata_mask, a masked array) or rescale "
                             "the heights")


def bound_kind(surface: str) -> str:
    """Which surface bounds a surface needs: "plane3" for plane3, else "corners"."""
    return "plane3" if surface == "plane3" else "corners"


def as_field(heights, name: str = "heights") -> HeightField:
    """A :class:`HeightField` for ``heights``: returned as is when it already is one, a
    2D array of real numbers wrapped (cell units), a DataArray through
    :meth:`HeightField.from_dataarray`. Anything else raises TypeError naming ``name``
    and what is accepted."""
    if isinstance(heights, HeightField):
        return heights
    if is_dataarray(heights):
        return HeightField.from_dataarray(heights)
    if isinstance(heights, (str, bytes, dict)) or heights is None:
        raise TypeError(f"{name}: expected a 2D array of real numbers, an algos.HeightField "
                        f"(datasets_gen.HeightField is the same class) or an xarray.DataArray, "
                        f"got {type(heights).__name__}")
    try:
        as_float_array(heights, name)
    except TypeError as exc:
        raise TypeError(f"{exc}; {name} takes a 2D array of real numbers, an "
                        f"algos.HeightField or an xarray.DataArray (got "
                        f"{type(heights).__name__})") from None
    return HeightField(heights)
